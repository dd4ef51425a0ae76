/* Forward-difference steps and the normal equations formed from a pass's sums (hammerstein_ctrl.normal_equations),
 * part of the compiled core (hammerstein_ctrl._core).
 *
 * p is the number of parameters; gram is p x p in C order.  No fused multiply-add (the build passes
 * -ffp-contract=off).  PYMAX is Python's max(a, b): b only if b > a.
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "hc.h"

#define PYMAX(a, b) ((b) > (a) ? (b) : (a))

/* scipy's "2-point" steps rel_step max(1, |x|) with the sign of x (-1 for NaN), kept inside [lower, upper] (one
 * value each, or one for all: nu, nl of 1): a step leaving the box is reversed if the reversed one fits, else it
 * becomes the distance to the farther bound; h = (x + step) - x, exactly representable. */
void hc_forward_steps(const double *x, int64_t n, const double *upper, int64_t nu, const double *lower, int64_t nl,
                      double rel_step, double *h)
{
    for (int64_t i = 0; i < n; i++) {
        double step = rel_step * (x[i] >= 0 ? 1.0 : -1.0) * PYMAX(1.0, fabs(x[i]));
        double up = upper[nu > 1 ? i : 0], lo = lower[nl > 1 ? i : 0];
        if (x[i] + step > up || x[i] + step < lo) {
            if (fabs(step) <= PYMAX(x[i] - lo, up - x[i]))
                step = -step;
            else
                step = up - x[i] >= x[i] - lo ? up - x[i] : lo - x[i];
        }
        h[i] = (x[i] + step) - x[i];
    }
}

/* Whether every one of the n steps is finite and non-zero. */
bool hc_usable_steps(const double *h, int64_t n)
{
    for (int64_t i = 0; i < n; i++)
        if (!(isfinite(h[i]) && h[i] != 0.0))
            return false;
    return true;
}

/* The point x (row 0 of X, (n + 1) x n) and its neighbours x + steps[j] e_j (row j + 1). */
void hc_neighbours(const double *x, int64_t n, const double *steps, double *X)
{
    for (int64_t i = 0; i < n + 1; i++)
        for (int64_t j = 0; j < n; j++)
            X[i * n + j] = x[j];
    for (int64_t j = 0; j < n; j++)
        X[(j + 1) * n + j] += steps[j];
}

/* gradient_j = sums[1 + j] / h_j and gram_jk = sums[1 + p + j p + k] / (h_j h_k): the sums of a pass over the
 * neighbours' differences divided by the steps. */
void hc_divide_by_steps(const double *sums, const double *steps, int64_t p, double *gradient, double *gram)
{
    for (int64_t j = 0; j < p; j++) {
        gradient[j] = sums[1 + j] / steps[j];
        for (int64_t k = 0; k < p; k++)
            gram[j * p + k] = sums[1 + p + j * p + k] / (steps[j] * steps[k]);
    }
}

/* Sum of squares at each neighbour: fun + 2 h_j g_j + h_j^2 G_jj. */
void hc_neighbour_values(double fun, const double *gradient, const double *gram, const double *steps, int64_t p,
                         double *values)
{
    for (int64_t j = 0; j < p; j++) {
        double h = steps[j];
        values[j] = fun + 2.0 * h * gradient[j] + h * h * gram[j * p + j];
    }
}

/* Whether fun, the gradient and the Gram matrix are all finite. */
bool hc_finite_sums(double fun, const double *gradient, const double *gram, int64_t p)
{
    if (!isfinite(fun))
        return false;
    for (int64_t j = 0; j < p; j++)
        if (!isfinite(gradient[j]))
            return false;
    for (int64_t j = 0; j < p * p; j++)
        if (!isfinite(gram[j]))
            return false;
    return true;
}
