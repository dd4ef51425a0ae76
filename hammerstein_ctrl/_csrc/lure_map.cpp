/* Lur'e loops with any built-in map in the feedback (hammerstein_ctrl.lure, smooth and piecewise-smooth maps).
 *
 * The loop x' = A x + B (u - g(z)), z = Cz x, y = C x + y0, is written with the map's slope s at 0 moved into the
 * linear part (A - s B Cz: exact), so that only the rest r(z) = g(z) - s z is approximated: it is taken as linear
 * between the instants where it is computed (sub of them per sample), the input by its own hold (exact).  Each
 * step is the exact first-order-hold recursion x1 = Ad x0 + B0 w0 + B1 w1 with w1 = u1 - r(z1), z1 = Cz x1: one
 * scalar equation z + beta r(z) = a (beta = Cz B1 >= 0 small), solved by the secant method, or where that does not
 * settle by Newton's method on a central-difference slope, falling back to bisection when Newton leaves its bracket.  Sums run left to right; no fused multiply-add.
 */
#include <cmath>
#include <cstdint>

#include "hc.h"
#include "maps.hpp"

namespace {

constexpr int64_t MAX_N = HC_MAX_ORDER;
constexpr int MAX_NEWTON = 60;

struct Rest {
    int64_t code;
    const double *p;
    int64_t m;
    const double *x;
    int64_t nx;
    double slope;

    inline double operator()(double z) const
    {
        return apply_map(code, z, p, m, x, nx) - slope * z;
    }
};

/* The secant iteration on z + beta r(z) = a from a, its first step along the slope m of the last sample's equation
 * (1 + beta r', updated here): a few evaluations of the map where beta r' is small (the usual case: beta shrinks with
 * the step).  Returns the root and r at it in *rz, or NaN when it does not settle in MAX_SECANT steps. */
constexpr int MAX_SECANT = 8;

double secant(const Rest &r, double a, double beta, double &m, double &rz)
{
    double z0 = a, r0 = r(a), f0 = beta * r0;
    double scale = std::fabs(a) + std::fabs(f0) + 1e-300;   /* the size of the terms: rounding is relative to it */
    if (std::fabs(f0) <= 4e-16 * scale) {
        rz = r0;
        return a;
    }
    double z1 = a - f0 / m, r1 = r(z1);
    double f1 = z1 + beta * r1 - a;
    for (int it = 0; it < MAX_SECANT; it++) {
        if (std::fabs(f1) <= 4e-16 * scale) {
            rz = r1;
            return z1;
        }
        double den = f1 - f0;
        if (den == 0.0 || !is_finite(den))
            return NAN;
        double slope = den / (z1 - z0);
        if (slope > 0.0 && is_finite(slope))
            m = slope;
        double z2 = z1 - f1 * (z1 - z0) / den;
        z0 = z1;
        f0 = f1;
        z1 = z2;
        r1 = r(z1);
        f1 = z1 + beta * r1 - a;
        if (std::fabs(z1 - z0) <= 1e-15 * scale) {
            rz = r1;
            return z1;
        }
    }
    return NAN;
}

/* The root of z + beta r(z) = a near a (beta >= 0): the secant iteration, else Newton on a central-difference
 * slope inside a bracket that bisection keeps when a Newton step leaves it or the slope is not positive. */
double solve(const Rest &r, double a, double beta, double &m, double &rz)
{
    if (beta == 0.0) {
        rz = r(a);
        return a;
    }
    double quick = secant(r, a, beta, m, rz);
    if (is_finite(quick))
        return quick;
    m = 1.0;
    auto phi = [&](double z) { return z + beta * r(z) - a; };
    double z = a - beta * r(a);
    double f = phi(z);
    rz = NAN;
    if (f == 0.0 || !is_finite(f)) {
        rz = r(z);
        return f == 0.0 ? z : NAN;
    }
    /* a bracket: step away from z until phi changes sign */
    double step = 1e-3 * (1.0 + std::fabs(z)) + std::fabs(f);
    double lo = z, hi = z, flo = f, fhi = f;
    for (int i = 0; i < 200 && flo * fhi > 0.0; i++) {
        if (f > 0.0) {
            lo = lo - step;
            flo = phi(lo);
        } else {
            hi = hi + step;
            fhi = phi(hi);
        }
        step *= 2.0;
        if (!is_finite(flo) || !is_finite(fhi))
            return NAN;
    }
    if (flo * fhi > 0.0)
        return NAN;
    if (f > 0.0) {
        hi = z;
        fhi = f;
    } else {
        lo = z;
        flo = f;
    }
    for (int it = 0; it < MAX_NEWTON; it++) {
        double h = 1e-7 * (1.0 + std::fabs(z));
        double d = (phi(z + h) - phi(z - h)) / (2.0 * h);
        double next = d > 0.0 ? z - f / d : 0.5 * (lo + hi);
        if (!(next > lo && next < hi))
            next = 0.5 * (lo + hi);
        double fn = phi(next);
        if (fn == 0.0) {
            rz = r(next);
            return next;
        }
        if ((fn > 0.0) == (fhi > 0.0)) {
            hi = next;
            fhi = fn;
        } else {
            lo = next;
            flo = fn;
        }
        if (std::fabs(next - z) <= 1e-15 * (1.0 + std::fabs(next)) || hi - lo <= 1e-15 * (1.0 + std::fabs(next))) {
            rz = r(next);
            return next;
        }
        z = next;
        f = fn;
    }
    rz = r(z);
    return z;
}

}  // namespace

extern "C" int hc_lure_map_run(const double *Ad, const double *B0, const double *B1, const double *C,
                               const double *Cz, int64_t batch, int64_t n, int64_t code, const double *P, int64_t m,
                               const double *extra, int64_t nx, const double *slope, const double *y0,
                               const double *X0, const double *u, int64_t N, int64_t sub, int64_t zoh, double *out)
{
    if (n < 1 || n > MAX_N || sub < 1 || code < 0 || code >= HC_MAP_COUNT || m < map_params(code, nx))
        return 1;
    for (int64_t b = 0; b < batch; b++) {
        const double *A = Ad + b * n * n, *b0 = B0 + b * n, *b1 = B1 + b * n, *c = C + b * n, *cz = Cz + b * n;
        const Rest r{code, P + b * m, m, extra, nx, slope[b]};
        double *y = out + b * N;
        double x[MAX_N], v[MAX_N];
        for (int64_t i = 0; i < n; i++)
            x[i] = X0[b * n + i];
        double beta = 0.0, z = 0.0, yk = y0[b];
        for (int64_t i = 0; i < n; i++) {
            beta += cz[i] * b1[i];
            z += cz[i] * x[i];
            yk += c[i] * x[i];
        }
        double rz = r(z), m = 1.0;
        y[0] = yk;
        bool ok = is_finite(yk);
        for (int64_t k = 1; k < N && ok; k++) {
            double ua = u[k - 1], du = zoh ? 0.0 : (u[k] - u[k - 1]) / (double)sub;
            for (int64_t j = 0; j < sub; j++) {
                double us = ua + du * (double)j, ue = zoh ? ua : ua + du * (double)(j + 1);
                double w0 = us - rz, a = 0.0;
                for (int64_t i = 0; i < n; i++) {
                    double acc = 0.0;
                    for (int64_t l = 0; l < n; l++)
                        acc += A[i * n + l] * x[l];
                    v[i] = acc + b0[i] * w0 + b1[i] * ue;
                    a += cz[i] * v[i];
                }
                z = solve(r, a, beta, m, rz);
                for (int64_t i = 0; i < n; i++)
                    x[i] = v[i] - b1[i] * rz;
            }
            yk = y0[b];
            for (int64_t i = 0; i < n; i++)
                yk += c[i] * x[i];
            y[k] = yk;
            ok = is_finite(yk);
        }
        if (!ok)
            for (int64_t k = 0; k < N; k++)
                y[k] = NAN;
    }
    return 0;
}
