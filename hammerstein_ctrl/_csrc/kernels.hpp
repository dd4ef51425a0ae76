/* The sampled recursion of one candidate (a linear block of order N driven by a signal), shared by every kernel family
 * of the compiled core.
 *
 * For candidate b the kernels read E[b] = expm([[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]]) (n + 2 rows and columns, or
 * more) and run
 *   first-order hold (the input linear between samples):  x[k] = Ad x[k-1] + (Bd0 v[k-1] + Bd1 v[k]),
 *     Ad = E[:n, :n], Bd1 = E[:n, n+1], Bd0 = E[:n, n] - Bd1;
 *   zero-order hold (the input held between samples):     x[k] = Ad x[k-1] + Gamma v[k-1],  Gamma = E[:n, n];
 * from x[0] = X0[b], with output y[k] = ((C x[k]) + d v[k]) + o, or, with an output map h (Wiener and
 * Hammerstein-Wiener models), h((C x[k]) + d v[k]) + o.  A signal formed from a basis is
 *   v = P[0] phi[0] + P[1] phi[1] + ...   (added basis row by basis row).
 * Every sum is added left to right in the order written here (a_r0 x_0 + a_r1 x_1 + ... ; C x likewise), and there
 * is no contraction into fused multiply-adds, so each family gives a candidate the same bits.
 *
 * The candidate's quantities are arrays of the compile-time order N, every loop over them unrolled (unroll below):
 * the recursion runs from registers as written-out code would.  Everything here has internal linkage (an unnamed
 * namespace): a translation unit built for one instruction set keeps its own copy.
 */
#ifndef HC_KERNELS_HPP
#define HC_KERNELS_HPP

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "hc.h"
#include "maps.hpp"

namespace {

/* A sum of squares above this is treated as overflowed. */
constexpr double OVERFLOW_LIMIT = 1.7e308;
/* Samples between overflow checks of a sum of squares (a power of two, minus one). */
constexpr int64_t CHECK_MASK = 1023;

template <class F, int... I>
inline void unroll_sequence(F &&f, std::integer_sequence<int, I...>)
{
    (f(I), ...);
}

/* f(0), f(1), ..., f(COUNT - 1), written out (the order of a sum is kept). */
template <int COUNT, class F>
inline void unroll(F &&f)
{
    unroll_sequence(f, std::make_integer_sequence<int, COUNT>{});
}

/* A float passed by its bits in an argument's shape[0]. */
inline double float_arg(const hc_arg &a)
{
    double value;
    std::memcpy(&value, &a.shape[0], sizeof value);
    return value;
}

/* The discretised block of one candidate, read from its row of E (rows of ecols columns), C, and D. */
template <int N, bool ZOH>
struct Block {
    double a[N][N], p[N], q[N], c[N], d;

    void load(const double *e, int64_t ecols, const double *crow, double direct)
    {
        unroll<N>([&](int r) {
            unroll<N>([&](int k) { a[r][k] = e[r * ecols + k]; });
            if (ZOH) {
                p[r] = e[r * ecols + N];
                q[r] = 0.0;
            } else {
                q[r] = e[r * ecols + N + 1];
                p[r] = e[r * ecols + N] - q[r];
            }
            c[r] = crow[r];
        });
        d = direct;
    }

    /* x <- Ad x + drive, the signal vp before and vi now. */
    inline void advance(double *x, double vp, double vi) const
    {
        double next[N];
        unroll<N>([&](int r) {
            double s = a[r][0] * x[0];
            unroll<N - 1>([&](int k) { s += a[r][k + 1] * x[k + 1]; });
            next[r] = ZOH ? s + p[r] * vp : s + (p[r] * vp + q[r] * vi);
        });
        unroll<N>([&](int r) { x[r] = next[r]; });
    }

    /* C x, summed left to right. */
    inline double linear(const double *x) const
    {
        double z = c[0] * x[0];
        unroll<N - 1>([&](int r) { z += c[r + 1] * x[r + 1]; });
        return z;
    }
};

/* An output map and its data (code < 0: none). */
struct OutputMap {
    int64_t code = -1;
    const double *x = nullptr;
    int64_t nx = 0;

    inline double operator()(double z, const double *p, int64_t m) const
    {
        return apply_map(code, z, p, m, x, nx);
    }
};

/* The output ((C x) + d v) (then the map) + o: without the direct term or the offset (DIRECT, OFFSET false) those
 * terms are left out, which adds exactly nothing when they are zero (and v finite). */
template <int N, bool ZOH, bool DIRECT, bool OFFSET, bool MAP>
inline double output(const Block<N, ZOH> &blk, const double *x, double v, double o, const OutputMap &h,
                     const double *hp, int64_t hm)
{
    double z = blk.linear(x);
    if (DIRECT)
        z = z + blk.d * v;
    if (MAP)
        z = h(z, hp, hm);
    if (OFFSET)
        return z + o;
    return z;
}

/* v = P[0] phi[0] + P[1] phi[1] + ... (K >= 1 terms; P with stride 1, phi with stride step). */
inline double combination(const double *P, const double *phi, int64_t K, int64_t step)
{
    double v = P[0] * phi[0];
    for (int64_t k = 1; k < K; k++)
        v += P[k] * phi[k * step];
    return v;
}

/* A table of COUNT kernels, entry I made by MAKE::template at<I> (one instantiation per entry). */
template <class MAKE, int... I>
inline const hc_kernel *kernel_table(std::integer_sequence<int, I...>)
{
    static const hc_kernel table[] = {&MAKE::template at<I>...};
    return table;
}

}  // namespace

#endif
