/* Sums of squared errors of candidates side by side across vector lanes (family HC_LANES), built once per instruction
 * set (table.cpp picks the one the processor runs).
 *
 * Candidates go in groups of 16, then of 8 (the last padded: its unused lanes repeat its first candidate); a group's
 * quantities sit in arrays with one column per candidate, so the compiler steps the whole group with vector
 * instructions.  Each candidate's arithmetic is kernels.hpp's on the signal P[b] @ Phi, operation for operation, so a
 * sum is bit-identical to an HC_SINGLE "sse" kernel's with a basis.
 *
 * Arguments (hc_arg): E (B, n+, n+2+), C (B, n+), D (B,), X0 (B, n+), Y0 (B,), P (B, K), Phi (K+, N), y (N,),
 * out (B,).  Options: bit 0 a direct term, bit 1 an offset (without them D, Y0 are not read: the caller has seen
 * them all zero).  The last signal sample reaches the output only through the direct term (zero-order hold), so a
 * non-finite one scores inf, as it would with d = 0.  Returns 0.
 */
#include "kernels.hpp"
#include "isa.h"

namespace {

enum { OPT_DIRECT = 1, OPT_OFFSET = 2 };
/* Most candidates of a group. */
constexpr int WIDEST = 16;

struct LaneArgs {
    const double *E, *C, *D, *X0, *Y0, *P, *Phi, *y;
    double *out;
    int64_t batch, N, K, erows, ecols, ccols, xcols;
};

/* Candidates b0 .. b0 + m - 1 (m <= W) over the record. */
template <int N, bool ZOH, int OPT, int W>
void lane_group(const LaneArgs &s, int64_t b0, int64_t m)
{
    constexpr bool DIRECT = OPT & OPT_DIRECT, OFFSET = OPT & OPT_OFFSET;
    alignas(64) double a[N][N][W], p[N][W], q[N][W], c[N][W], x[N][W], d[W], o[W], vp[W], vi[W], J[W];
    alignas(64) double P[HC_MAX_BASIS][W];
    double f[HC_MAX_BASIS] = {0.0};
    const int64_t K = s.K;
    for (int w = 0; w < W; w++) {
        int64_t b = w < m ? b0 + w : b0;
        const double *e = s.E + b * s.erows * s.ecols;
        unroll<N>([&](int r) {
            unroll<N>([&](int k) { a[r][k][w] = e[r * s.ecols + k]; });
            q[r][w] = ZOH ? 0.0 : e[r * s.ecols + N + 1];
            p[r][w] = ZOH ? e[r * s.ecols + N] : e[r * s.ecols + N] - q[r][w];
            c[r][w] = s.C[b * s.ccols + r];
            x[r][w] = s.X0[b * s.xcols + r];
        });
        d[w] = DIRECT ? s.D[b] : 0.0;
        o[w] = OFFSET ? s.Y0[b] : 0.0;
        for (int64_t k = 0; k < K; k++)
            P[k][w] = s.P[b * K + k];
    }
    /* the output of lane w from its state (x[.][w]) and signal v */
    auto lane_output = [&](int w, double v) {
        double z = c[0][w] * x[0][w];
        unroll<N - 1>([&](int r) { z += c[r + 1][w] * x[r + 1][w]; });
        if (DIRECT)
            z = z + d[w] * v;
        return OFFSET ? z + o[w] : z;
    };
    auto signals = [&]() {
        for (int w = 0; w < W; w++)
            vi[w] = P[0][w] * f[0];
        for (int64_t k = 1; k < K; k++)
            for (int w = 0; w < W; w++)
                vi[w] += P[k][w] * f[k];
    };
    for (int64_t k = 0; k < K; k++)
        f[k] = s.Phi[k * s.N];
    signals();
    for (int w = 0; w < W; w++) {
        vp[w] = vi[w];
        double e = s.y[0] - lane_output(w, vi[w]);
        J[w] = e * e;
    }
    for (int64_t i = 1; i < s.N; i++) {
        double yi = s.y[i];
        for (int64_t k = 0; k < K; k++)
            f[k] = s.Phi[k * s.N + i];
        signals();
        for (int w = 0; w < W; w++) {
            double next[N];
            unroll<N>([&](int r) {
                double t = a[r][0][w] * x[0][w];
                unroll<N - 1>([&](int k) { t += a[r][k + 1][w] * x[k + 1][w]; });
                next[r] = ZOH ? t + p[r][w] * vp[w] : t + (p[r][w] * vp[w] + q[r][w] * vi[w]);
            });
            unroll<N>([&](int r) { x[r][w] = next[r]; });
            vp[w] = vi[w];
            double e = yi - lane_output(w, vi[w]);
            J[w] += e * e;
        }
        if ((i & CHECK_MASK) == 0) {            /* stop once every candidate of the group has overflowed (or NaN) */
            bool alive = false;
            for (int64_t w = 0; w < m; w++)
                alive = alive || J[w] <= OVERFLOW_LIMIT;
            if (!alive)
                break;
        }
    }
    for (int64_t w = 0; w < m; w++)
        s.out[b0 + w] = J[w] <= OVERFLOW_LIMIT && std::isfinite(vp[w]) ? J[w] : INFINITY;
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
    if (s.K < 1 || s.K > HC_MAX_BASIS)
        return 1;
    int64_t b0 = 0;
    while (s.batch - b0 >= WIDEST) {
        lane_group<N, ZOH, OPT, WIDEST>(s, b0, WIDEST);
        b0 += WIDEST;
    }
    while (b0 < s.batch) {
        int64_t m = s.batch - b0 < WIDEST / 2 ? s.batch - b0 : WIDEST / 2;
        lane_group<N, ZOH, OPT, WIDEST / 2>(s, b0, m);
        b0 += m;
    }
    return 0;
}

/* Table entry I: order I / 8 + 1, hold (I / 4) % 2, options I % 4. */
struct MakeLanes {
    template <int I>
    static int64_t at(const hc_arg *args)
    {
        return lanes_kernel<I / 8 + 1, (I / 4) % 2 == 1, I % 4>(args);
    }
};

}  // namespace

extern "C" const hc_kernel *HC_ISA_NAME(hc_lanes_table)(void)
{
    return kernel_table<MakeLanes>(std::make_integer_sequence<int, 8 * HC_LANES_MAX_ORDER>{});
}
