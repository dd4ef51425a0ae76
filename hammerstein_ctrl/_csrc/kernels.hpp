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

/* Inlined whatever the compiler's inlining budget: a candidate's step (written with the lambdas and unroll below)
 * must become straight-line code with its state in registers, as it would be written out by hand.  (MSVC inlines
 * small lambdas by itself; its attribute for them is not portable across its versions.) */
#if defined(__GNUC__) || defined(__clang__)
#define HC_INLINE inline __attribute__((always_inline))
#define HC_LAMBDA __attribute__((always_inline))
#elif defined(_MSC_VER)
#define HC_INLINE __forceinline
#define HC_LAMBDA
#else
#define HC_INLINE inline
#define HC_LAMBDA
#endif

/* Before a loop over the lanes of a group: vectorise it as a loop (GCC would otherwise unroll a short loop whole
 * first and then pack its statements into vectors, with shuffles). */
#if defined(__GNUC__) && !defined(__clang__)
#define HC_LANE_LOOP _Pragma("GCC unroll 1") _Pragma("GCC ivdep")
#else
#define HC_LANE_LOOP
#endif

namespace {

/* A sum of squares above this is treated as overflowed. */
constexpr double OVERFLOW_LIMIT = 1.7e308;
/* Samples between overflow checks of a sum of squares (a power of two, minus one). */
constexpr int64_t CHECK_MASK = 1023;

template <class F, int... I>
HC_INLINE void unroll_sequence(F &&f, std::integer_sequence<int, I...>)
{
    (f(I), ...);
}

/* f(0), f(1), ..., f(COUNT - 1), written out (the order of a sum is kept). */
template <int COUNT, class F>
HC_INLINE void unroll(F &&f)
{
    unroll_sequence(f, std::make_integer_sequence<int, COUNT>{});
}

/* a where mask is all ones, b where it is zero: a select by the bits (which the compiler vectorises, where a
 * conditional on a flag would keep a loop scalar). */
HC_INLINE double pick(uint64_t mask, double a, double b)
{
    uint64_t x, y;
    std::memcpy(&x, &a, sizeof x);
    std::memcpy(&y, &b, sizeof y);
    x = (x & mask) | (y & ~mask);
    std::memcpy(&a, &x, sizeof a);
    return a;
}

/* The mask of pick for a flag. */
HC_INLINE uint64_t mask_of(bool flag)
{
    return flag ? ~(uint64_t)0 : 0;
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

    HC_INLINE void load(const double *e, int64_t ecols, const double *crow, double direct)
    {
        unroll<N>([&](int r) HC_LAMBDA {
            unroll<N>([&](int k) HC_LAMBDA { a[r][k] = e[r * ecols + k]; });
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
    HC_INLINE void advance(double *x, double vp, double vi) const
    {
        double next[N];
        unroll<N>([&](int r) HC_LAMBDA {
            double s = a[r][0] * x[0];
            unroll<N - 1>([&](int k) HC_LAMBDA { s += a[r][k + 1] * x[k + 1]; });
            next[r] = ZOH ? s + p[r] * vp : s + (p[r] * vp + q[r] * vi);
        });
        unroll<N>([&](int r) HC_LAMBDA { x[r] = next[r]; });
    }

    /* C x, summed left to right. */
    HC_INLINE double linear(const double *x) const
    {
        double z = c[0] * x[0];
        unroll<N - 1>([&](int r) HC_LAMBDA { z += c[r + 1] * x[r + 1]; });
        return z;
    }
};

/* An output map and its data (code < 0: none). */
struct OutputMap {
    int64_t code = -1;
    const double *x = nullptr;
    int64_t nx = 0;

    HC_INLINE double operator()(double z, const double *p, int64_t m) const
    {
        return apply_map(code, z, p, m, x, nx);
    }
};

/* The output ((C x) + d v) (then the map) + o: without the direct term or the offset (DIRECT, OFFSET false) those
 * terms are left out, which adds exactly nothing when they are zero (and v finite). */
template <int N, bool ZOH, bool DIRECT, bool OFFSET, bool MAP>
HC_INLINE double output(const Block<N, ZOH> &blk, const double *x, double v, double o, const OutputMap &h,
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
HC_INLINE double combination(const double *P, const double *phi, int64_t K, int64_t step)
{
    double v = P[0] * phi[0];
    for (int64_t k = 1; k < K; k++)
        v += P[k] * phi[k * step];
    return v;
}

/* Samples whose signals a kernel forms at a time (basis_signals). */
constexpr int64_t CHUNK = 128;

/* v[j] = P[0] Phi[0][first + j] + P[1] Phi[1][first + j] + ... (added basis row by basis row) for the len <= CHUNK
 * samples from first: one candidate's signals (P: its K coefficients; Phi: rows of stride samples), in loops over the
 * samples that the compiler vectorises.  The same operations as combination, sample by sample. */
HC_INLINE void basis_signals(const double *P, const double *Phi, int64_t stride, int64_t K, int64_t first,
                             int64_t len, double *v)
{
    const double *phi = Phi + first;
    double c = P[0];
    for (int64_t j = 0; j < len; j++)
        v[j] = c * phi[j];
    for (int64_t k = 1; k < K; k++) {
        phi = Phi + k * stride + first;
        c = P[k];
        for (int64_t j = 0; j < len; j++)
            v[j] += c * phi[j];
    }
}

/* Orders whose lane kernels are written out per lane (the state in registers); above, loops over the order with the
 * lanes innermost. */
constexpr int FIXED_MAX_ORDER = 4;

/* The discretised blocks and states of W lanes side by side (one column per lane), of the order N, or for N = 0 of
 * an order n known at run time (up to HC_MAX_ORDER).  Each lane's arithmetic is Block's, operation for operation;
 * the loops over the lanes are the ones the compiler vectorises. */
template <int N, bool ZOH, int W>
struct LaneBlocks {
    static constexpr int M = N > 0 ? N : HC_MAX_ORDER;
    int64_t n = N;
    alignas(64) double a[M][M][W], p[M][W], q[M][W], c[M][W], x[M][W];

    /* Lane w's block from its row of E (rows of ecols columns) and C, its state from xrow. */
    void load(int w, const double *e, int64_t ecols, const double *crow, const double *xrow)
    {
        for (int64_t r = 0; r < n; r++) {
            for (int64_t k = 0; k < n; k++)
                a[r][k][w] = e[r * ecols + k];
            q[r][w] = ZOH ? 0.0 : e[r * ecols + n + 1];
            p[r][w] = ZOH ? e[r * ecols + n] : e[r * ecols + n] - q[r][w];
            c[r][w] = crow[r];
            x[r][w] = xrow[r];
        }
    }

    /* Every lane's state advanced: x <- Ad x + drive (signal vp before, vi now). */
    HC_INLINE void advance(const double *vp, const double *vi)
    {
        if constexpr (N > 0) {
            HC_LANE_LOOP
            for (int w = 0; w < W; w++) {
                double next[N];
                unroll<N>([&](int r) HC_LAMBDA {
                    double t = a[r][0][w] * x[0][w];
                    unroll<N - 1>([&](int k) HC_LAMBDA { t += a[r][k + 1][w] * x[k + 1][w]; });
                    next[r] = ZOH ? t + p[r][w] * vp[w] : t + (p[r][w] * vp[w] + q[r][w] * vi[w]);
                });
                unroll<N>([&](int r) HC_LAMBDA { x[r][w] = next[r]; });
            }
        } else {
            alignas(64) double next[M][W];
            for (int64_t r = 0; r < n; r++) {
                HC_LANE_LOOP
                for (int w = 0; w < W; w++)
                    next[r][w] = a[r][0][w] * x[0][w];
                for (int64_t k = 1; k < n; k++) {
                    HC_LANE_LOOP
                    for (int w = 0; w < W; w++)
                        next[r][w] += a[r][k][w] * x[k][w];
                }
                HC_LANE_LOOP
                for (int w = 0; w < W; w++)
                    next[r][w] = ZOH ? next[r][w] + p[r][w] * vp[w] : next[r][w] + (p[r][w] * vp[w] + q[r][w] * vi[w]);
            }
            for (int64_t r = 0; r < n; r++) {
                HC_LANE_LOOP
                for (int w = 0; w < W; w++)
                    x[r][w] = next[r][w];
            }
        }
    }

    /* z[w] = C x of every lane, summed left to right. */
    HC_INLINE void linear(double *z) const
    {
        if constexpr (N > 0) {
            HC_LANE_LOOP
            for (int w = 0; w < W; w++) {
                double t = c[0][w] * x[0][w];
                unroll<N - 1>([&](int r) HC_LAMBDA { t += c[r + 1][w] * x[r + 1][w]; });
                z[w] = t;
            }
        } else {
            HC_LANE_LOOP
            for (int w = 0; w < W; w++)
                z[w] = c[0][w] * x[0][w];
            for (int64_t r = 1; r < n; r++) {
                HC_LANE_LOOP
                for (int w = 0; w < W; w++)
                    z[w] += c[r][w] * x[r][w];
            }
        }
    }
};

/* vi[w] = P[0][w] phi[0] + P[1][w] phi[1] + ... for the W lanes of a group (rows of P: basis signals), the K terms
 * written out, so that the loop over the lanes is the one the compiler vectorises. */
template <int K, int W>
HC_INLINE void lane_signals_of(const double (*P)[W], const double *phi, double *vi)
{
    HC_LANE_LOOP
    for (int w = 0; w < W; w++) {
        double v = P[0][w] * phi[0];
        unroll<K - 1>([&](int k) HC_LAMBDA { v += P[k + 1][w] * phi[k + 1]; });
        vi[w] = v;
    }
}

/* lane_signals_of for the runtime count K (1 .. HC_MAX_BASIS; a branch per sample that the processor predicts). */
template <int W>
HC_INLINE void lane_signals(const double (*P)[W], const double *phi, int64_t K, double *vi)
{
    switch (K) {
    case 1: lane_signals_of<1, W>(P, phi, vi); break;
    case 2: lane_signals_of<2, W>(P, phi, vi); break;
    case 3: lane_signals_of<3, W>(P, phi, vi); break;
    case 4: lane_signals_of<4, W>(P, phi, vi); break;
    case 5: lane_signals_of<5, W>(P, phi, vi); break;
    case 6: lane_signals_of<6, W>(P, phi, vi); break;
    case 7: lane_signals_of<7, W>(P, phi, vi); break;
    default: lane_signals_of<8, W>(P, phi, vi); break;
    }
}

/* A table of kernels, entry I MAKE::template at<I> (a kernel, or NULL where none is built). */
template <class MAKE, int... I>
inline const hc_kernel *kernel_table(std::integer_sequence<int, I...>)
{
    static const hc_kernel table[] = {MAKE::template at<I>...};
    return table;
}

}  // namespace

#endif
