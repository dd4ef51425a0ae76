/* Loops over the samples of a record, compiled with the package's C library (hammerstein_ctrl._native): the
 * signals of a batch of candidates from a basis (hammerstein_ctrl.objective), and the whitening filter of the
 * parameter covariance run backwards (hammerstein_ctrl.uncertainty).  No fused multiply-add (the build passes
 * -ffp-contract=off); arrays are C-ordered.
 */
#include <stdint.h>
#include <stdlib.h>

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
