/* Small dense linear algebra of hammerstein_ctrl, part of its compiled core (hammerstein_ctrl._core).
 *
 * Every matrix is a C-ordered (row-major) block of doubles.  The arithmetic is
 * written in the order the results are defined in (sums left to right, no
 * fused multiply-add: the build passes -ffp-contract=off), so a result does
 * not depend on the compiler's optimisation level.
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>

#include "hc.h"

/* Largest 1-norm for which the degree-13 Pade approximant is accurate to unit roundoff without scaling
 * (Higham 2005, Table 2.3). */
static const double PADE13_THETA = 5.371920351148152;

/* Coefficients b_0 .. b_13 of the degree-13 Pade approximant (Higham 2005). */
static const double B13[14] = {
    64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
    129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
    40840800.0, 960960.0, 16380.0, 182.0, 1.0,
};

/* Most sweeps of the Jacobi eigenvalue method. */
#define JACOBI_MAX_SWEEPS 60
/* Square work matrices of one exponential: A, A^2, A^4, A^6, W, T, U, V, Q. */
#define EXPM_WORK 9

/* Largest absolute column sum of the n x n matrix M (a NaN column sum is passed over, as Python's max does). */
double hc_one_norm(const double *M, int64_t n)
{
    double norm = 0.0;
    for (int64_t j = 0; j < n; j++) {
        double s = 0.0;
        for (int64_t i = 0; i < n; i++)
            s += fabs(M[i * n + j]);
        norm = s > norm ? s : norm;
    }
    return norm;
}

static void matmul(const double *X, const double *Y, double *out, int64_t n)
{
    for (int64_t i = 0; i < n; i++)
        for (int64_t j = 0; j < n; j++) {
            double s = 0.0;
            for (int64_t k = 0; k < n; k++)
                s += X[i * n + k] * Y[k * n + j];
            out[i * n + j] = s;
        }
}

/* out = cx X + cy Y + cz Z, or out + cx X + cy Y + cz Z with add, summed left to right. */
static void combine3(const double *X, double cx, const double *Y, double cy, const double *Z, double cz, double *out,
                     bool add, int64_t n)
{
    for (int64_t i = 0; i < n * n; i++) {
        double s = cx * X[i];
        if (add)
            s = out[i] + s;
        out[i] = (s + cy * Y[i]) + cz * Z[i];
    }
}

static void copy(const double *src, double *dst, int64_t count)
{
    for (int64_t i = 0; i < count; i++)
        dst[i] = src[i];
}

/* Overwrite B (n x m) with A^-1 B: Gaussian elimination with partial pivoting, A (n x n) destroyed.  A singular A
 * leaves non-finite entries in B: NaN when elimination meets a zero pivot, else whatever the tiny pivots give. */
void hc_solve_in_place(double *A, int64_t n, double *B, int64_t m)
{
    for (int64_t col = 0; col < n; col++) {
        int64_t piv = col;
        double best = fabs(A[col * n + col]);
        for (int64_t r = col + 1; r < n; r++)
            if (fabs(A[r * n + col]) > best) {
                best = fabs(A[r * n + col]);
                piv = r;
            }
        if (piv != col) {
            for (int64_t c = 0; c < n; c++) {
                double t = A[col * n + c];
                A[col * n + c] = A[piv * n + c];
                A[piv * n + c] = t;
            }
            for (int64_t c = 0; c < m; c++) {
                double t = B[col * m + c];
                B[col * m + c] = B[piv * m + c];
                B[piv * m + c] = t;
            }
        }
        double d = A[col * n + col];
        if (d == 0.0) {
            for (int64_t i = 0; i < n * m; i++)
                B[i] = NAN;
            return;
        }
        for (int64_t r = col + 1; r < n; r++) {
            double f = A[r * n + col] / d;
            if (f != 0.0) {
                for (int64_t c = col; c < n; c++)
                    A[r * n + c] -= f * A[col * n + c];
                for (int64_t c = 0; c < m; c++)
                    B[r * m + c] -= f * B[col * m + c];
            }
        }
    }
    for (int64_t col = n - 1; col >= 0; col--) {
        double d = A[col * n + col];
        for (int64_t c = 0; c < m; c++) {
            double s = B[col * m + c];
            for (int64_t k = col + 1; k < n; k++)
                s -= A[col * n + k] * B[k * m + c];
            B[col * m + c] = s / d;
        }
    }
}

/* Largest order whose exponential keeps its work memory on the stack (9 n^2 doubles: 18 KiB); larger ones allocate.
 * The simulator's augmented matrices have at most MAX_ORDER + 2 = 12 rows. */
#define EXPM_STACK_ORDER 16

/* T = A6 (b[k+12] A6 + b[k+10] A4 + b[k+8] A2) + b[k+6] A6 + b[k+4] A4 + b[k+2] A2 + b[k] I: with k = 0 the even
 * part V of the Pade numerator, with k = 1 the odd part before its product with A (U = A T); W is work. */
static void pade_part(const double *A2, const double *A4, const double *A6, int k, double *W, double *T, int64_t n)
{
    combine3(A6, B13[k + 12], A4, B13[k + 10], A2, B13[k + 8], W, false, n);
    matmul(A6, W, T, n);
    combine3(A6, B13[k + 6], A4, B13[k + 4], A2, B13[k + 2], T, true, n);
    for (int64_t i = 0; i < n; i++)
        T[i * n + i] += B13[k];
}

static void expm_work(const double *M, int64_t n, double *out, double norm, double *work)
{
    int64_t s = norm > PADE13_THETA ? (int64_t)ceil(log2(norm / PADE13_THETA)) : 0;
    int64_t nn = n * n;
    double *A = work, *A2 = work + nn, *A4 = work + 2 * nn, *A6 = work + 3 * nn, *W = work + 4 * nn;
    double *T = work + 5 * nn, *U = work + 6 * nn, *V = work + 7 * nn, *Q = work + 8 * nn;
    double scale = ldexp(1.0, (int)-s);
    for (int64_t i = 0; i < nn; i++)
        A[i] = M[i] * scale;
    matmul(A, A, A2, n);
    matmul(A2, A2, A4, n);
    matmul(A4, A2, A6, n);
    pade_part(A2, A4, A6, 1, W, T, n);
    matmul(A, T, U, n);
    pade_part(A2, A4, A6, 0, W, T, n);
    for (int64_t i = 0; i < nn; i++) {  /* P = V + U (in T), Q = V - U */
        Q[i] = T[i] - U[i];
        T[i] = T[i] + U[i];
    }
    hc_solve_in_place(Q, n, T, n);
    for (int64_t k = 0; k < s; k++) {
        matmul(T, T, V, n);
        copy(V, T, nn);
    }
    copy(T, out, nn);
}

/* out = expm(M), M n x n: degree-13 Pade with scaling and squaring (Higham 2005); NaN if M is not finite (or, for
 * an order above EXPM_STACK_ORDER, if no work memory could be had).  M is read before out is written: they may be
 * one matrix. */
void hc_expm(const double *M, int64_t n, double *out)
{
    double norm = hc_one_norm(M, n);
    if (!isfinite(norm)) {
        for (int64_t i = 0; i < n * n; i++)
            out[i] = NAN;
        return;
    }
    if (n <= EXPM_STACK_ORDER) {
        double work[EXPM_WORK * EXPM_STACK_ORDER * EXPM_STACK_ORDER];
        expm_work(M, n, out, norm, work);
        return;
    }
    double *work = malloc(sizeof(double) * EXPM_WORK * n * n);
    if (work == NULL) {
        for (int64_t i = 0; i < n * n; i++)
            out[i] = NAN;
        return;
    }
    expm_work(M, n, out, norm, work);
    free(work);
}

/* The augmented matrix [[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]] (n+2 x n+2, into M, zeroed here), C (n) and D of
 * the companion realisation of num (l+1 coefficients, descending, l <= n) over den (n+1, den[0] != 0); of 1/p if
 * not ok (the coefficients are then not read). */
static void augmented_row(const double *num, int64_t nnum, const double *den, int64_t nden, double dt, bool ok,
                          double *M, double *C, double *D)
{
    int64_t n = nden - 1, m = n + 2, shift = n - (nnum - 1);
    for (int64_t i = 0; i < m * m; i++)
        M[i] = 0.0;
    double lead = ok ? den[0] : 1.0;
    double d = shift == 0 ? (ok ? num[0] : 0.0) / lead : 0.0;
    *D = d;
    for (int64_t r = 0; r < n; r++) {
        double a = (ok ? den[r + 1] : 0.0) / lead;
        M[r] = (-a) * dt;
        if (r > 0)
            M[r * m + r - 1] = dt;
        int64_t j = r + 1 - shift;
        C[r] = (j >= 0 ? (ok ? num[j] : 0.0) / lead : 0.0) - d * a;
    }
    if (n > 0)
        M[n] = dt;
    M[n * m + n + 1] = 1.0;
}

/* augmented_row for each of the batch rows of num (batch x nnum) and den (batch x nden): M (batch, n+2, n+2),
 * C (batch, n), D (batch). */
void hc_tf_augmented(const double *num, const double *den, int64_t batch, int64_t nnum, int64_t nden, double dt,
                     double *M, double *C, double *D)
{
    int64_t n = nden - 1, m = n + 2;
    for (int64_t b = 0; b < batch; b++)
        augmented_row(num + b * nnum, nnum, den + b * nden, nden, dt, true, M + b * m * m, C + b * n, D + b);
}

/* Exact discretisation of each row's num/den over dt into E (batch, n+2, n+2), C (batch, n), D (batch), with ok
 * (finite coefficients, den[0] != 0; other rows are replaced by 1/p) and big (the augmented matrix's 1-norm above
 * max_norm: E holds the augmented matrix).  Returns whether every row is ok and none big. */
bool hc_tf_discrete(const double *num, const double *den, int64_t batch, int64_t nnum, int64_t nden, double dt,
                    double max_norm, double *E, double *C, double *D, bool *ok, bool *big)
{
    int64_t n = nden - 1, m = n + 2;
    bool clean = true;
    for (int64_t b = 0; b < batch; b++) {
        const double *nb = num + b * nnum, *db = den + b * nden;
        bool good = db[0] != 0;
        for (int64_t j = 0; j < nnum; j++)
            good = good && isfinite(nb[j]);
        for (int64_t j = 0; j < nden; j++)
            good = good && isfinite(db[j]);
        ok[b] = good;
        clean = clean && good;
    }
    for (int64_t b = 0; b < batch; b++) {
        double *Eb = E + b * m * m;
        augmented_row(num + b * nnum, nnum, den + b * nden, nden, dt, ok[b], Eb, C + b * n, D + b);
        big[b] = hc_one_norm(Eb, m) > max_norm;
        clean = clean && !big[b];
        if (!big[b])
            hc_expm(Eb, m, Eb);
    }
    return clean;
}

/* One Jacobi rotation of the symmetric A (n x n) zeroing A[p, q]; false if it is already negligible. */
static bool rotate(double *A, int64_t n, int64_t p, int64_t q)
{
    double apq = A[p * n + q], app = A[p * n + p], aqq = A[q * n + q];
    if (fabs(apq) <= 2.220446049250313e-16 * (sqrt(fabs(app)) * sqrt(fabs(aqq))) || apq == 0.0)
        return false;
    double theta = (aqq - app) / (2.0 * apq);
    double t = 1.0 / (fabs(theta) + sqrt(theta * theta + 1.0));
    if (theta < 0.0)
        t = -t;
    double c = 1.0 / sqrt(t * t + 1.0);
    double s = t * c;
    for (int64_t k = 0; k < n; k++) {
        double akp = A[k * n + p], akq = A[k * n + q];
        A[k * n + p] = c * akp - s * akq;
        A[k * n + q] = s * akp + c * akq;
    }
    for (int64_t k = 0; k < n; k++) {
        double apk = A[p * n + k], aqk = A[q * n + k];
        A[p * n + k] = c * apk - s * aqk;
        A[q * n + k] = s * apk + c * aqk;
    }
    return true;
}

/* Eigenvalues w (ascending) of the symmetric, finite A (n x n, destroyed): cyclic Jacobi, each rotation skipped
 * once |a_pq| <= eps sqrt(|a_pp a_qq|), the test that gives small eigenvalues of definite matrices to high relative
 * accuracy (Demmel and Veselic 1992). */
void hc_symmetric_eigenvalues(double *A, int64_t n, double *w)
{
    for (int sweep = 0; sweep < JACOBI_MAX_SWEEPS; sweep++) {
        bool rotated = false;
        for (int64_t p = 0; p < n - 1; p++)
            for (int64_t q = p + 1; q < n; q++)
                rotated = rotate(A, n, p, q) || rotated;
        if (!rotated)
            break;
    }
    for (int64_t i = 0; i < n; i++) {  /* insertion sort of the diagonal */
        double v = A[i * n + i];
        int64_t j = i;
        while (j > 0 && w[j - 1] > v) {
            w[j] = w[j - 1];
            j--;
        }
        w[j] = v;
    }
}

/* Rows num (batch x nnum) and den (batch x nden) of num0 and den0 with the free coefficients of each row of theta
 * (batch rows of stride doubles, stride >= k + kd) written at num_pos (k) and then den_pos (kd). */
void hc_fill_coefficients(const double *theta, int64_t batch, int64_t stride, const double *num0, int64_t nnum,
                          const double *den0, int64_t nden, const int64_t *num_pos, int64_t k, const int64_t *den_pos,
                          int64_t kd, double *num, double *den)
{
    for (int64_t b = 0; b < batch; b++) {
        const double *tb = theta + b * stride;
        double *nb = num + b * nnum, *db = den + b * nden;
        copy(num0, nb, nnum);
        copy(den0, db, nden);
        for (int64_t j = 0; j < k; j++)
            nb[num_pos[j]] = tb[j];
        for (int64_t j = 0; j < kd; j++)
            db[den_pos[j]] = tb[k + j];
    }
}

/* The Frobenius norm of T^-1 for an upper-triangular T (n x n, C order; its strict lower triangle not read), by
 * back substitution, column by column of the identity; not finite where T is singular or the inverse overflows
 * (NaN if no work memory could be had). */
double hc_triangular_inverse_norm(const double *T, int64_t n)
{
    double total = 0.0, *x = malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
    if (x == NULL)
        return NAN;
    for (int64_t j = 0; j < n; j++) {
        for (int64_t i = j; i >= 0; i--) {
            double s = i == j ? 1.0 : 0.0;
            for (int64_t k = i + 1; k <= j; k++)
                s -= T[i * n + k] * x[k];
            x[i] = s / T[i * n + i];
            total += x[i] * x[i];
        }
    }
    free(x);
    return sqrt(total);
}
