/* The two loops of MINPACK (hammerstein_ctrl.optimize._minpack) that run over a whole residual vector, part of the
 * compiled core (hammerstein_ctrl._core), in the arithmetic of scipy's C translation: sums added
 * left to right, pow(q, 2.0) as q * q, no fused multiply-add (the build passes -ffp-contract=off).
 */
#include <math.h>
#include <stdint.h>

#include "hc.h"

/* w -= (sum(v * w) / v[0]) * v over n elements: w through the Householder reflection of v (scaled so that v[0] is
 * its 1 + |.|), the sum added left to right, then the update. */
void hc_reflect(const double *v, double *w, int64_t n)
{
    double s = 0.0;
    for (int64_t i = 0; i < n; i++)
        s += v[i] * w[i];
    double t = s / v[0];
    for (int64_t i = 0; i < n; i++)
        w[i] -= t * v[i];
}

/* MINPACK's enorm of the n > 0 elements of x: three sums of squares, scaled where squares would overflow
 * (components of at least rgiant / n) or underflow (at most rdwarf). */
double hc_enorm(const double *x, int64_t n, double rdwarf, double rgiant)
{
    double s1 = 0.0, s2 = 0.0, s3 = 0.0, x1max = 0.0, x3max = 0.0, q;
    double agiant = rgiant / (double)n;
    for (int64_t i = 0; i < n; i++) {
        double xabs = fabs(x[i]);
        if (xabs <= rdwarf || xabs >= agiant) {
            if (xabs > rdwarf) {
                if (xabs > x1max) {
                    q = x1max / xabs;
                    s1 = 1.0 + s1 * (q * q);
                    x1max = xabs;
                } else {
                    q = xabs / x1max;
                    s1 += q * q;
                }
            } else if (xabs > x3max) {
                q = x3max / xabs;
                s3 = 1.0 + s3 * (q * q);
                x3max = xabs;
            } else if (xabs != 0.0) {
                q = xabs / x3max;
                s3 += q * q;
            }
        } else {
            s2 += xabs * xabs;
        }
    }
    if (s1 != 0.0)
        return x1max * sqrt(s1 + (s2 / x1max) / x1max);
    if (s2 != 0.0) {
        if (s2 >= x3max)
            return sqrt(s2 * (1.0 + (x3max / s2) * (x3max * s3)));
        return sqrt(x3max * ((s2 / x3max) + (x3max * s3)));
    }
    return x3max * sqrt(s3);
}
