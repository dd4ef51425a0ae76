/* Loops over the samples of a record, part of the compiled core (hammerstein_ctrl._core): the
 * signals of a batch of candidates from a basis (hammerstein_ctrl.objective), the whitening filter of the
 * parameter covariance run backwards (hammerstein_ctrl.uncertainty), and the QR factorisation of a regression's
 * columns (hammerstein_ctrl.streamed_lstsq).  No fused multiply-add (the build passes -ffp-contract=off); arrays
 * are C-ordered.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "hc.h"

/* sum_i a[i] b[i] over i < n in a fixed order: eight running sums (lanes 0-7) over blocks of eight, lane l + 4 added
 * to lane l, then (s0 + s1) + (s2 + s3), then the rest one by one.  The eight lanes are independent, so a compiler
 * may keep them in vector registers of any width without changing a bit. */
static double lane_dot(const double *a, const double *b, int64_t n)
{
    double s[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    int64_t i = 0;
    for (; i + 8 <= n; i += 8)
        for (int l = 0; l < 8; l++)
            s[l] += a[i + l] * b[i + l];
    double t[4];
    for (int l = 0; l < 4; l++)
        t[l] = s[l] + s[l + 4];
    double r = (t[0] + t[1]) + (t[2] + t[3]);
    for (; i < n; i++)
        r += a[i] * b[i];
    return r;
}

/* |a| (n values) without overflow or underflow: from the sum of squares, else (a sum past the double range, or
 * below its normal numbers) from the values scaled by the largest. */
static double vector_norm(const double *a, int64_t n)
{
    double s = lane_dot(a, a, n);
    /* past n DBL_MIN the largest square is a normal number, and the squares that are not add at most n
     * subnormal roundings: 1e-16 of the sum */
    if (isnan(s) || (isfinite(s) && s >= (double)n * DBL_MIN))
        return sqrt(s);
    double big = 0.0;
    for (int64_t i = 0; i < n; i++)
        big = fabs(a[i]) > big ? fabs(a[i]) : big;
    if (big == 0.0 || !isfinite(big))
        return big;
    double t = 0.0;
    for (int64_t i = 0; i < n; i++) {
        double v = a[i] / big;
        t += v * v;
    }
    return big * sqrt(t);
}

/* R (w x w, C order, upper triangular) of the Householder QR factorisation of the n x w matrix whose columns are
 * the rows of A (w rows of n values, n >= w; overwritten by the reflectors), with LAPACK's reflectors (dlarfg:
 * R's diagonal entry -sign(alpha) |x|).  A value that is not finite reaches R. */
void hc_qr_rows(double *A, int64_t w, int64_t n, double *R)
{
    memset(R, 0, (size_t)(w * w) * sizeof(double));
    for (int64_t j = 0; j < w && j < n; j++) {
        double *a = A + j * n + j;
        int64_t m = n - j;
        double alpha = a[0], xnorm = vector_norm(a + 1, m - 1), tau = 0.0, beta = alpha;
        if (xnorm != 0.0) {
            beta = -copysign(hypot(alpha, xnorm), alpha);
            tau = (beta - alpha) / beta;
            double d = alpha - beta;
            if (fabs(d) >= DBL_MIN) {          /* its reciprocal is finite */
                double scale = 1.0 / d;
                for (int64_t i = 1; i < m; i++)
                    a[i] *= scale;
            } else {
                for (int64_t i = 1; i < m; i++)
                    a[i] /= d;
            }
        }
        a[0] = 1.0;
        R[j * w + j] = beta;
        for (int64_t k = j + 1; k < w; k++) {
            double *b = A + k * n + j;
            double f = tau * lane_dot(a, b, m);
            for (int64_t i = 0; i < m; i++)
                b[i] -= f * a[i];
            R[j * w + k] = b[0];
        }
        a[0] = beta;
    }
}

/* out[b, start:start + n] = P[b] @ basis for each of the batch rows of P (batch x p; basis p x n, out's rows of
 * width columns): the products added term by term, j = 0 first, as P[b, 0] basis[0] + P[b, 1] basis[1] + ... */
void hc_combine(const double *P, int64_t batch, int64_t p, const double *basis, int64_t n, double *out,
                int64_t columns, int64_t start)
{
    for (int64_t b = 0; b < batch; b++) {
        double *restrict row = out + b * columns + start;
        const double *coef = P + b * p;
        double c = p > 0 ? coef[0] : 0.0;
        for (int64_t i = 0; i < n; i++)
            row[i] = p > 0 ? c * basis[i] : 0.0;     /* no basis rows: the empty sum */
        for (int64_t j = 1; j < p; j++) {
            const double *restrict bj = basis + j * n;
            c = coef[j];
            for (int64_t i = 0; i < n; i++)
                row[i] += c * bj[i];
        }
    }
}

/* out[t, first + c] = (H^T rows[c])_t for the q rows of n samples: w_t = rows_t - sum_i ar[1 + i] w_{t+1+i}
 * (order = ar's length - 1 terms, added i = 0 first), run from the end in double precision; out (double, or float
 * if single) has rows of width columns.  Returns 0, or -1 if no work memory could be had (out untouched). */
static int backward_filter(const double *rows, int64_t q, int64_t n, const double *ar, int64_t order, double *out,
                           float *single, int64_t columns, int64_t first)
{
    double *w = calloc((size_t)(q * (n + order) > 0 ? q * (n + order) : 1), sizeof(double));
    if (w == NULL)
        return -1;
    const double *a = ar + 1;
    for (int64_t t = n - 1; t >= 0; t--)
        for (int64_t c = 0; c < q; c++) {
            double *wc = w + c * (n + order);
            const double *past = wc + t + 1;
            double acc = 0.0;
            for (int64_t i = 0; i < order; i++)
                acc += a[i] * past[i];
            wc[t] = rows[c * n + t] - acc;
            if (single != NULL)
                single[t * columns + first + c] = (float)wc[t];
            else
                out[t * columns + first + c] = wc[t];
        }
    free(w);
    return 0;
}

/* backward_filter into doubles. */
int hc_backward_filter(const double *rows, int64_t q, int64_t n, const double *ar, int64_t order, double *out,
                       int64_t columns, int64_t first)
{
    return backward_filter(rows, q, n, ar, order, out, NULL, columns, first);
}

/* backward_filter into single-precision floats (the recursion still in double precision). */
int hc_backward_filter_single(const double *rows, int64_t q, int64_t n, const double *ar, int64_t order,
                              float *out, int64_t columns, int64_t first)
{
    return backward_filter(rows, q, n, ar, order, NULL, out, columns, first);
}
