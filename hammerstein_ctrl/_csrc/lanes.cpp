/* Sums of squared errors of candidates side by side across vector lanes (family HC_LANES), built once per instruction
 * set (table.cpp picks the one the processor runs).
 *
 * Candidates go in groups of LANES (the last padded: its unused lanes repeat its first candidate); a group's
 * quantities sit in arrays with one column per candidate, so the compiler steps the whole group with vector
 * instructions.  Orders up to FIXED_MAX_ORDER step each lane written out (its signal, state, output and sum in one
 * loop over the lanes, for each number of basis signals); higher orders run loops over the order with the lanes
 * innermost.  Each candidate's arithmetic is kernels.hpp's on the signal P[b] @ Phi, operation for operation, so a
 * sum is bit-identical to an HC_SINGLE "sse" kernel's with a basis.
 *
 * Arguments (hc_arg): E (B, n+, n+2+), C (B, n+), D (B,), X0 (B, n+), Y0 (B,), P (B, K), Phi (K+, N), y (N,),
 * out (B,).  Options: bit 0 a direct term, bit 1 an offset; without them D, Y0 are not read (the caller has seen
 * them all zero) and the lanes add a zero direct term and offset, which leaves every sum of squares as it is: a
 * zero's sign does not reach a square, and a non-finite signal sample gives inf either way (the last one reaches
 * the output only through the direct term under zero-order hold: it scores inf as it would with d = 0).  Returns 0,
 * or 1 for a basis of no signals or more than HC_MAX_BASIS.
 */
#include "kernels.hpp"
#include "isa.h"

namespace {

enum { OPT_DIRECT = 1, OPT_OFFSET = 2 };
/* Candidates of a group: two AVX2 vectors, one AVX-512 vector. */
constexpr int LANES = 8;

struct LaneArgs {
    const double *E, *C, *D, *X0, *Y0, *P, *Phi, *y;
    double *out;
    int64_t batch, N, K, erows, ecols, ccols, xcols;
    bool direct, offset;
};

/* A group's blocks, states, output terms and basis coefficients (candidates b0 .. b0 + m - 1, padded). */
template <int N, bool ZOH>
struct Group {
    LaneBlocks<N, ZOH, LANES> blk;
    alignas(64) double d[LANES], o[LANES], vp[LANES], J[LANES], P[HC_MAX_BASIS][LANES];

    Group(const LaneArgs &s, int64_t b0, int64_t m, int64_t n)
    {
        blk.n = n;
        for (int w = 0; w < LANES; w++) {
            int64_t b = w < m ? b0 + w : b0;
            blk.load(w, s.E + b * s.erows * s.ecols, s.ecols, s.C + b * s.ccols, s.X0 + b * s.xcols);
            d[w] = s.direct ? s.D[b] : 0.0;
            o[w] = s.offset ? s.Y0[b] : 0.0;
            for (int64_t k = 0; k < s.K; k++)
                P[k][w] = s.P[b * s.K + k];
        }
    }


    /* Whether a sum of the m candidates is still finite (checked every CHECK_MASK + 1 samples). */
    bool alive(int64_t m) const
    {
        bool any = false;
        for (int64_t w = 0; w < m; w++)
            any = any || J[w] <= OVERFLOW_LIMIT;
        return any;
    }

    void store(const LaneArgs &s, int64_t b0, int64_t m) const
    {
        for (int64_t w = 0; w < m; w++)
            s.out[b0 + w] = J[w] <= OVERFLOW_LIMIT && is_finite(vp[w]) ? J[w] : INFINITY;
    }
};

/* A group of order N <= FIXED_MAX_ORDER and K basis signals: each sample one loop over the lanes. */
template <int N, bool ZOH, int K>
void fixed_group(const LaneArgs &s, int64_t b0, int64_t m)
{
    Group<N, ZOH> G(s, b0, m, N);
    auto &a = G.blk.a;
    auto &p = G.blk.p;
    auto &q = G.blk.q;
    auto &c = G.blk.c;
    auto &x = G.blk.x;
    /* the output of lane w from its linear part z and signal v */
    auto output = [&](int w, double z, double v) HC_LAMBDA { return (z + G.d[w] * v) + G.o[w]; };
    double f[K];
    auto signal = [&](int w) HC_LAMBDA {
        double v = G.P[0][w] * f[0];
        unroll<K - 1>([&](int k) HC_LAMBDA { v += G.P[k + 1][w] * f[k + 1]; });
        return v;
    };
    auto linear = [&](int w, const double *xs) HC_LAMBDA {
        double z = c[0][w] * xs[0];
        unroll<N - 1>([&](int r) HC_LAMBDA { z += c[r + 1][w] * xs[r + 1]; });
        return z;
    };
    unroll<K>([&](int k) HC_LAMBDA { f[k] = s.Phi[k * s.N]; });
    for (int w = 0; w < LANES; w++) {
        double v = signal(w), xs[N];
        unroll<N>([&](int r) HC_LAMBDA { xs[r] = x[r][w]; });
        G.vp[w] = v;
        double e = s.y[0] - output(w, linear(w, xs), v);
        G.J[w] = e * e;
    }
    for (int64_t i = 1; i < s.N; i++) {
        double yi = s.y[i];
        unroll<K>([&](int k) HC_LAMBDA { f[k] = s.Phi[k * s.N + i]; });
        for (int w = 0; w < LANES; w++) {
            double v = signal(w), next[N];
            unroll<N>([&](int r) HC_LAMBDA {
                double t = a[r][0][w] * x[0][w];
                unroll<N - 1>([&](int k) HC_LAMBDA { t += a[r][k + 1][w] * x[k + 1][w]; });
                next[r] = ZOH ? t + p[r][w] * G.vp[w] : t + (p[r][w] * G.vp[w] + q[r][w] * v);
            });
            unroll<N>([&](int r) HC_LAMBDA { x[r][w] = next[r]; });
            G.vp[w] = v;
            double e = yi - output(w, linear(w, next), v);
            G.J[w] += e * e;
        }
        if ((i & CHECK_MASK) == 0 && !G.alive(m))      /* every candidate has overflowed (or is NaN) */
            break;
    }
    G.store(s, b0, m);
}

/* A group of any order n (up to HC_MAX_ORDER) and any number of basis signals: loops over the order, the lanes
 * innermost. */
template <bool ZOH>
void any_group(const LaneArgs &s, int64_t b0, int64_t m, int64_t n)
{
    Group<0, ZOH> G(s, b0, m, n);
    alignas(64) double vi[LANES], z[LANES];
    double f[HC_MAX_BASIS] = {0.0};
    for (int64_t i = 0; i < s.N; i++) {
        for (int64_t k = 0; k < s.K; k++)
            f[k] = s.Phi[k * s.N + i];
        lane_signals<LANES>(G.P, f, s.K, vi);
        if (i > 0)
            G.blk.advance(G.vp, vi);
        G.blk.linear(z);
        double yi = s.y[i];
        for (int w = 0; w < LANES; w++) {
            G.vp[w] = vi[w];
            double e = yi - ((z[w] + G.d[w] * vi[w]) + G.o[w]);
            G.J[w] = i > 0 ? G.J[w] + e * e : e * e;
        }
        if (i > 0 && (i & CHECK_MASK) == 0 && !G.alive(m))
            break;
    }
    G.store(s, b0, m);
}

/* One group of order n (N its compile-time value, or 0) in the family's way for it. */
template <int N, bool ZOH>
void group(const LaneArgs &s, int64_t b0, int64_t m, int64_t n)
{
    if constexpr (N > 0 && N <= FIXED_MAX_ORDER) {
        switch (s.K) {
        case 1: fixed_group<N, ZOH, 1>(s, b0, m); break;
        case 2: fixed_group<N, ZOH, 2>(s, b0, m); break;
        case 3: fixed_group<N, ZOH, 3>(s, b0, m); break;
        case 4: fixed_group<N, ZOH, 4>(s, b0, m); break;
        case 5: fixed_group<N, ZOH, 5>(s, b0, m); break;
        case 6: fixed_group<N, ZOH, 6>(s, b0, m); break;
        case 7: fixed_group<N, ZOH, 7>(s, b0, m); break;
        default: fixed_group<N, ZOH, 8>(s, b0, m); break;
        }
    } else {
        any_group<ZOH>(s, b0, m, n);
    }
}

template <int N, bool ZOH, int OPT>
int64_t lanes_kernel(const hc_arg *args)
{
    LaneArgs s;
    s.E = (const double *)args[0].data;
    s.erows = args[0].shape[1];
    s.ecols = args[0].shape[2];
    s.batch = args[0].shape[0];
    s.C = (const double *)args[1].data;
    s.ccols = args[1].shape[1];
    s.D = (const double *)args[2].data;
    s.X0 = (const double *)args[3].data;
    s.xcols = args[3].shape[1];
    s.Y0 = (const double *)args[4].data;
    s.P = (const double *)args[5].data;
    s.K = args[5].shape[1];
    s.Phi = (const double *)args[6].data;
    s.N = args[6].shape[1];
    s.y = (const double *)args[7].data;
    s.out = (double *)args[8].data;
    s.direct = OPT & OPT_DIRECT;
    s.offset = OPT & OPT_OFFSET;
    if (s.K < 1 || s.K > HC_MAX_BASIS)
        return 1;
    if (s.N < 1) {
        for (int64_t b = 0; b < s.batch; b++)
            s.out[b] = 0.0;
        return 0;
    }
    constexpr int ORDER = N <= FIXED_MAX_ORDER ? N : 0;
    for (int64_t b0 = 0; b0 < s.batch; b0 += LANES) {
        int64_t m = s.batch - b0 < LANES ? s.batch - b0 : LANES;
        group<ORDER, ZOH>(s, b0, m, N);
    }
    return 0;
}

/* Table entry I: order I / 8 + 1, hold (I / 4) % 2, options I % 4 (read at run time). */
struct MakeLanes {
    template <int I>
    static constexpr hc_kernel at = &lanes_kernel<I / 8 + 1, (I / 4) % 2 == 1, I % 4>;
};

}  // namespace

extern "C" const hc_kernel *HC_ISA_NAME(hc_lanes_table)(void)
{
    return kernel_table<MakeLanes>(std::make_integer_sequence<int, 8 * HC_LANES_MAX_ORDER>{});
}
