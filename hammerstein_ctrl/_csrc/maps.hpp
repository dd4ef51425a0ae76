/* The built-in static maps of hammerstein_ctrl.nonlinearities as the compiled passes apply them to one sample.
 *
 * Each is the family's formula (Nonlinearity.formula, the vectorised numpy form) written for one sample, operation for
 * operation in the formula's order, with numpy's scalar semantics: sign of a zero or NaN is itself, minimum and
 * maximum return a NaN argument (the first if both), else their first argument between equals.  The tests hold each
 * against the formula.  p is the parameter row of one candidate (m values: the polynomial's degree is its length),
 * x the map's fixed data (the breakpoints of the piecewise-linear map, nx of them).
 *
 * Included by every translation unit that applies a map, inside its own unnamed namespace: each unit, built for its
 * instruction set, keeps its own copy.
 */
#ifndef HC_MAPS_HPP
#define HC_MAPS_HPP

#include <cmath>
#include <cstdint>

#include "hc.h"

namespace {

/* isnan and isfinite of one double, defined here with internal linkage: the standard library's are inline
 * functions, which an unoptimised build emits as shared weak symbols, and the copies compiled for AVX2 must never
 * stand in for the baseline's. */
inline bool is_nan(double x)
{
    return x != x;
}

inline bool is_finite(double x)
{
    return x - x == 0.0;
}

inline double np_sign(double x)
{
    return x > 0 ? 1.0 : (x < 0 ? -1.0 : x);
}

inline double np_minimum(double a, double b)
{
    return is_nan(a) ? a : (is_nan(b) ? b : (b < a ? b : a));
}

inline double np_maximum(double a, double b)
{
    return is_nan(a) ? a : (is_nan(b) ? b : (b > a ? b : a));
}

inline double clip(double z, double a)
{
    return np_minimum(np_maximum(z, -a), a);
}

/* The piecewise-linear map: the segment of the last breakpoint <= z (clipped to the first and last), interpolated. */
inline double piecewise_linear(double z, const double *p, const double *x, int64_t nx)
{
    int64_t lo = 0, hi = nx - 1;
    while (hi - lo > 1) {
        int64_t mid = (lo + hi) / 2;
        if (x[mid] <= z)
            lo = mid;
        else
            hi = mid;
    }
    int64_t k = lo < nx - 2 ? lo : nx - 2;
    double w = (z - x[k]) / (x[k + 1] - x[k]);
    return p[k] * (1.0 - w) + p[k + 1] * w;
}

/* The map of the given code (enum hc_map) at z. */
inline double apply_map(int64_t code, double z, const double *p, int64_t m, const double *x, int64_t nx)
{
    switch (code) {
    case HC_MAP_TANH:
        return p[0] * std::tanh(p[1] * z);
    case HC_MAP_COULOMB:
        return p[0] * z + p[1] * np_sign(z) + p[2];
    case HC_MAP_POLYNOMIAL: {
        double acc = p[m - 1];
        for (int64_t i = m - 2; i >= 0; i--)
            acc = acc * z + p[i];
        return acc * z;
    }
    case HC_MAP_SATURATION:
        return p[0] * clip(z, std::fabs(p[1]));
    case HC_MAP_DEADZONE:
        return p[0] * (z - clip(z, std::fabs(p[1])));
    case HC_MAP_PIECEWISE_LINEAR:
        return piecewise_linear(z, p, x, nx);
    case HC_MAP_SIGMOID:
        return p[0] * 0.5 * (1.0 + std::tanh(0.5 * p[1] * (z - p[2])));
    case HC_MAP_FRICTION:
        return std::fabs(p[0]) * np_sign(z) + p[1];
    default:
        return NAN;
    }
}

/* The fewest parameters each map reads (the polynomial: one; a piecewise-linear map reads one per breakpoint). */
inline int64_t map_params(int64_t code, int64_t nx)
{
    static const int64_t fewest[HC_MAP_COUNT] = {2, 3, 1, 2, 2, 0, 3, 2};
    if (code == HC_MAP_PIECEWISE_LINEAR)
        return nx;
    return code >= 0 && code < HC_MAP_COUNT ? fewest[code] : 0;
}

}  // namespace

#endif
