/* The linear algebra of one Levenberg-Marquardt iteration on the normal equations (hammerstein_ctrl.optimize.normal_lm),
 * part of the compiled core (hammerstein_ctrl._core).
 *
 * gram is the p x p Gram matrix J^T J (C order), gradient J^T r, fun the sum of squares r^T r.  Sums run left to
 * right with no fused multiply-add (the build passes -ffp-contract=off).  PYMAX is Python's max(a, b): b only if
 * b > a, so a NaN b is passed over and a NaN a kept.
 */
#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "hc.h"

#define PYMAX(a, b) ((b) > (a) ? (b) : (a))


/* Largest cosine between the residual vector and a Jacobian column (MINPACK's gtol measure); NaN wins, as in
 * numpy's max, and never passes the gtol test. */
double hc_lm_cosine(const double *gram, const double *gradient, int64_t p, double fun)
{
    double best = 0.0;
    if (!(fun > 0))
        return best;
    double root = sqrt(fun);
    for (int64_t j = 0; j < p; j++) {
        double norm = sqrt(PYMAX(gram[j * p + j], 0.0));
        if (norm > 0) {
            double c = fabs(gradient[j]) / (norm * root);
            if (isnan(c))
                return c;
            best = PYMAX(best, c);
        }
    }
    return best;
}

/* MINPACK's xtol test on the step delta (out[0]: 1 or 0) and the reduction of the sum of squares its linear model
 * predicts (out[1]). */
void hc_lm_step_measures(const double *gram, const double *gradient, const double *scale, const double *delta,
                         const double *x, int64_t p, double xtol, double *out)
{
    double step = 0.0, size = 0.0, predicted = 0.0;
    for (int64_t i = 0; i < p; i++) {
        double s = scale[i] * delta[i], t = scale[i] * x[i];
        step += s * s;
        size += t * t;
        double curvature = 0.0;
        for (int64_t j = 0; j < p; j++)
            curvature += gram[i * p + j] * delta[j];
        predicted -= delta[i] * (2.0 * gradient[i] + curvature);
    }
    out[0] = sqrt(step) <= xtol * sqrt(size);
    out[1] = predicted;
}

/* Column norms of J from the Gram matrix (1 for a zero or non-finite one), never below floor. */
void hc_lm_norms(const double *gram, int64_t p, const double *floor, double *norms)
{
    for (int64_t j = 0; j < p; j++) {
        double v = sqrt(PYMAX(gram[j * p + j], 0.0));
        norms[j] = PYMAX(v > 0 && isfinite(v) ? v : 1.0, floor[j]);
    }
}

static bool finite_matrix(const double *A, int64_t count)
{
    for (int64_t i = 0; i < count; i++)
        if (!isfinite(A[i]))
            return false;
    return true;
}

/* Whether the symmetric A (p x p) has a non-finite entry or a condition number of limit or more (w: p + p*p work). */
static bool ill(const double *A, int64_t p, double limit, double *work)
{
    if (p < 1)
        return false;
    if (!finite_matrix(A, p * p))
        return true;
    double *w = work, *copy = work + p;
    for (int64_t i = 0; i < p * p; i++)
        copy[i] = A[i];
    hc_symmetric_eigenvalues(copy, p, w);
    return !(w[0] > w[p - 1] / limit);
}

/* One iteration's linear algebra: the damped Gauss-Newton step delta = -(G + mu diag(scale^2))^-1 g, mu = lam times
 * the largest scaled curvature, and out = [cosine, ill (only if check), solved, small, predicted] (flags as 1 or 0).
 * work holds 2 p^2 + 2 p doubles. */
void hc_lm_iteration(const double *gram, const double *gradient, int64_t p, double fun, const double *scale,
                     double lam, const double *x, int64_t check, double limit, double xtol, double *work,
                     double *delta, double *out)
{
    double *A = work, *z = work + p * p, *rest = work + p * p + p;
    for (int64_t i = 0; i < p; i++)
        for (int64_t j = 0; j < p; j++)
            A[i * p + j] = gram[i * p + j] / (scale[i] * scale[j]);
    bool is_ill = check ? ill(A, p, limit, rest) : false;
    double top = DBL_MIN;
    for (int64_t i = 0; i < p; i++)
        top = PYMAX(top, A[i * p + i]);
    for (int64_t i = 0; i < p; i++)
        A[i * p + i] += lam * top;
    bool solved = false;
    for (int64_t i = 0; i < p; i++)
        delta[i] = 0.0;
    if (finite_matrix(A, p * p)) {
        for (int64_t i = 0; i < p; i++)
            z[i] = -gradient[i] / scale[i];
        hc_solve_in_place(A, p, z, 1);  /* a singular damped matrix gives a non-finite step: the caller raises lam */
        solved = true;
        for (int64_t i = 0; i < p; i++) {
            delta[i] = z[i] / scale[i];
            solved = solved && isfinite(delta[i]);
        }
    }
    double measures[2];
    hc_lm_step_measures(gram, gradient, scale, delta, x, p, xtol, measures);
    out[0] = hc_lm_cosine(gram, gradient, p, fun);
    out[1] = is_ill;
    out[2] = solved;
    out[3] = measures[0];
    out[4] = measures[1];
}

/* Nielsen's rule: the damping lam after an accepted step of gain ratio rho, lowered by the factor limit at most. */
double hc_lm_lowered_damping(double lam, double rho, double limit)
{
    return lam * PYMAX(limit, 1.0 - pow(2.0 * rho - 1.0, 3.0));
}

/* MINPACK's code after an accepted step: 1 (ftol), 2 (xtol: small), 3 (both), or 0 (go on). */
int hc_lm_accepted_code(double actual, double predicted, double f_old, double ftol, int64_t small)
{
    bool converged_f = actual <= ftol * f_old && predicted <= ftol * f_old;
    return converged_f ? (small ? 3 : 1) : (small ? 2 : 0);
}
