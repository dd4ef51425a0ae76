/* Levenberg-Marquardt's compiled loop around the normal-equation pass of a plain cost (hammerstein_ctrl.optimize.
 * normal_lm), part of the compiled core (hammerstein_ctrl._core).
 *
 * The loop takes the steps of the Python loop one after another while each trial point is accepted, with the same
 * library functions in the same order (so the same bits), and returns where the Python loop must take the next
 * iteration.  The pass is a normal-equation kernel of the core (hc_kernel_at).  No fused multiply-add (the
 * build passes -ffp-contract=off).
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "hc.h"

/* normal_lm's codes: hand back (the Python loop takes the next iteration), alone (its trials without neighbours),
 * go on. */
#define HAND_BACK 0
#define HAND_BACK_ALONE (-1)
#define GO_ON (-2)
/* Most parameters (the point and its neighbours fill the lanes of one pass), and the largest augmented matrix. */
#define MAX_P (HC_MAX_LANES - 1)
#define MAX_M (HC_MAX_ORDER + 2)

/* The settings' entries (normal_lm._loop_settings). */
enum { FTOL, XTOL, GTOL, ILL, DT, MAX_NORM, REL_STEP, MAX_DAMPING, DECREASE_LIMIT };

static void copy(double *dst, const double *src, int64_t n)
{
    memcpy(dst, src, (size_t)n * sizeof(double));
}

/* The top of an iteration: a termination code, HAND_BACK or GO_ON with the trial point x + delta. */
static int trial_step(const double *x, int64_t p, double fun, const double *gradient, const double *gram,
                      const double *scale, double lam, const int64_t *counts, const double *settings, double *trial,
                      bool *small, double *predicted)
{
    double work[2 * MAX_P * MAX_P + 2 * MAX_P], delta[MAX_P], out[5];
    if (fun == 0.0)
        return 1;
    hc_lm_iteration(gram, gradient, p, fun, scale, lam, x, settings[ILL] > 0 ? 1 : 0, settings[ILL], settings[XTOL],
                    work, delta, out);
    *small = out[3] != 0.0;
    *predicted = out[4];
    for (int64_t i = 0; i < p; i++)
        trial[i] = x[i] + delta[i];
    if (out[0] <= settings[GTOL])
        return 4;
    if (out[1] != 0.0 || out[2] == 0.0)
        return HAND_BACK;
    if (counts[0] >= counts[1])
        return 5;
    if (counts[2] < p + 1)
        return HAND_BACK;
    return GO_ON;
}

/* The pass at trial with its forward-difference neighbours (steps h): sums = [f, sum d r, sum d d^T]; false where the
 * general pass must take the point (a row for scipy's exponential, a direct term other than the kernel's). */
static bool run_pass(hc_kernel kernel, const double *trial, int64_t p, const double *settings, const double *num0,
                     int64_t nnum, const double *den0, int64_t nden, const int64_t *num_pos, int64_t k,
                     const int64_t *den_pos, int64_t kd, int64_t has_g, int64_t direct, const double *Phi, int64_t K,
                     int64_t N, const double *y, double *h, double *sums)
{
    const double upper = INFINITY, lower = -INFINITY;
    int64_t lanes = p + 1, n_linear = k + kd, rows = 1 + n_linear, n = nden - 1, m = nden + 1;
    int64_t width = has_g ? p - n_linear : 1;
    double X[HC_MAX_LANES * MAX_P], num[HC_MAX_LANES * MAX_M], den[HC_MAX_LANES * MAX_M];
    double E[HC_MAX_LANES * MAX_M * MAX_M], C[HC_MAX_LANES * HC_MAX_ORDER], D[HC_MAX_LANES];
    double P[HC_MAX_LANES * MAX_P], zeros[HC_MAX_LANES * HC_MAX_ORDER], Y0[HC_MAX_LANES], VP[HC_MAX_LANES], none[1];
    bool ok[HC_MAX_LANES], big[HC_MAX_LANES];
    hc_forward_steps(trial, p, &upper, 1, &lower, 1, settings[REL_STEP], h);
    hc_neighbours(trial, p, h, X);
    hc_fill_coefficients(X, rows, p, num0, nnum, den0, nden, num_pos, k, den_pos, kd, num, den);
    bool clean = hc_tf_discrete(num, den, rows, nnum, nden, settings[DT], settings[MAX_NORM], E, C, D, ok, big);
    bool any = false;
    for (int64_t b = 0; b < rows; b++)
        any = any || D[b] != 0.0;
    if (!clean || ((nnum == nden && any) ? 1 : 0) != direct)
        return false;
    for (int64_t b = 0; b < lanes; b++)
        for (int64_t j = 0; j < width; j++)
            P[b * width + j] = has_g ? X[b * p + n_linear + j] : 1.0;
    memset(zeros, 0, sizeof zeros);
    memset(Y0, 0, sizeof Y0);
    memset(VP, 0, sizeof VP);
    memset(sums, 0, (size_t)(1 + p * lanes) * sizeof(double));
    hc_arg args[13] = {
        {E, {rows, m, m}}, {C, {rows, n, 0}}, {D, {rows, 0, 0}}, {zeros, {lanes, n, 0}}, {Y0, {lanes, 0, 0}},
        {VP, {lanes, 0, 0}}, {P, {lanes, width, 0}}, {(void *)Phi, {K, N, 0}}, {none, {lanes, 0, 0}},
        {none, {0, 0, 0}}, {(void *)y, {N, 0, 0}}, {NULL, {0, 0, 0}}, {sums, {1 + p * lanes, 0, 0}}};
    return kernel(args) == 0;
}

/* The steps of the compiled loop from x (normal_lm._Passes.loop): state = [fun, lam, nu]; counts = [steps taken,
 * step limit, evaluations left, passes logged]; with start, the loop begins with the pass at x and fills gradient,
 * gram, steps and scale.  Row i of the logs holds pass i's point, steps, and the sums of squares of the point and
 * its neighbours.  Returns a termination code, HAND_BACK or HAND_BACK_ALONE. */
int hc_lm_loop(int64_t kernel_number, double *x, int64_t p, double *state, double *gradient, double *gram, double *steps,
               double *scale, int64_t *counts, const double *settings, int64_t start, const double *num0, int64_t nnum,
               const double *den0, int64_t nden, const int64_t *num_pos, int64_t k, const int64_t *den_pos,
               int64_t kd, int64_t has_g, int64_t direct, const double *Phi, int64_t K, int64_t N, const double *y,
               double *log_x, double *log_steps, double *log_values)
{
    hc_kernel kernel = hc_kernel_at(kernel_number);
    double trial[MAX_P], h[MAX_P], sums[1 + MAX_P * (MAX_P + 1)], new_gradient[MAX_P], new_gram[MAX_P * MAX_P],
        values[MAX_P + 1], norms[MAX_P], floor[MAX_P];
    if (kernel == NULL || p < 1 || p > MAX_P || nden < 2 || nden > HC_MAX_ORDER + 1 || nnum < 1 || nnum > nden ||
        k < 0 || kd < 0 || k + kd > p || K < 1 || K > HC_MAX_BASIS)
        return HAND_BACK;               /* not a pass of this loop: the general one takes it */
    bool summing = false;               /* the summing pass of den's order (a direct term or not), nothing else */
    for (int64_t hold = 0; hold < 2; hold++)
        summing = summing || kernel_number == hc_kernel_number(HC_NORMAL, nden - 1, hold, direct ? 1 : 0);
    if (!summing)
        return HAND_BACK;
    while (true) {
        bool small = false;
        double predicted = 0.0;
        int code = GO_ON;
        copy(trial, x, p);
        if (!start)
            code = trial_step(x, p, state[0], gradient, gram, scale, state[1], counts, settings, trial, &small,
                              &predicted);
        if (code != GO_ON)
            return code;
        if (!run_pass(kernel, trial, p, settings, num0, nnum, den0, nden, num_pos, k, den_pos, kd, has_g, direct,
                      Phi, K, N, y, h, sums))
            return HAND_BACK;
        double fun = sums[0];
        hc_divide_by_steps(sums, h, p, new_gradient, new_gram);
        values[0] = fun;
        hc_neighbour_values(fun, new_gradient, new_gram, h, p, values + 1);
        for (int64_t j = 0; j < p + 1; j++)
            if (!isfinite(values[j]))
                values[j] = INFINITY;
        if (!hc_finite_sums(fun, new_gradient, new_gram, p))
            return HAND_BACK;
        int64_t row = counts[3];
        copy(log_x + row * p, trial, p);
        copy(log_steps + row * p, h, p);
        copy(log_values + row * (p + 1), values, p + 1);
        counts[2] -= p + 1;
        counts[3] += 1;
        if (start) {
            copy(gradient, new_gradient, p);
            copy(gram, new_gram, p * p);
            copy(steps, h, p);
            memset(floor, 0, sizeof floor);
            hc_lm_norms(gram, p, floor, norms);
            copy(scale, norms, p);
            state[0] = fun;
            start = 0;
            continue;
        }
        counts[0] += 1;
        if (fun < state[0] && predicted > 0) {          /* accepted */
            double actual = state[0] - fun;
            state[1] = hc_lm_lowered_damping(state[1], actual / predicted, settings[DECREASE_LIMIT]);
            state[2] = 2.0;
            copy(x, trial, p);
            copy(gradient, new_gradient, p);
            copy(gram, new_gram, p * p);
            copy(steps, h, p);
            hc_lm_norms(gram, p, scale, norms);
            copy(scale, norms, p);
            code = hc_lm_accepted_code(actual, predicted, state[0], settings[FTOL], small ? 1 : 0);
            state[0] = fun;
            if (code)
                return code;
            continue;
        }
        state[1] *= state[2];                           /* rejected */
        state[2] *= 2.0;
        if (small)
            return 2;
        if (state[1] > settings[MAX_DAMPING])
            return 6;
        return HAND_BACK_ALONE;
    }
}
