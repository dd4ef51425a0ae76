/* The normal-equation pass (family HC_NORMAL): a point and its forward-difference neighbours side by side across
 * vector lanes, built once per instruction set (table.cpp picks the one the processor runs).
 *
 * Lane 0 simulates the point, lane j the point with parameter j - 1 moved by a step; lane g's signal is P[g] @ Phi.
 * Per sample the pass adds r^2, d_j r and d_j d_k to running sums, with r = y - yhat_0 and d_j = yhat_0 - yhat_{j+1}
 * (the step times the forward-difference derivative of r: the caller divides by the steps once, at the end), so the
 * Jacobian is never stored; or, with the outputs option, it stores every lane's output sample instead.  Each lane's
 * arithmetic is kernels.hpp's.  A long record may be passed a block of samples at a time: the lanes' states X and
 * previous signals VP are read and written back, begin is the index of the block's first sample in the record.
 *
 * Arguments (hc_arg), in order:
 *   [map]      with an output map: its code (enum hc_map);
 *   E (R, n+, n+2+), C (R, n+), D (R,)   the linear blocks: lanes past the R given share row 0's (neighbours that move
 *                                        only the signal, the offset or the initial state);
 *   X (lanes, n+), Y0 (lanes,), VP (lanes,)   the lanes' states, offsets and previous signal samples (lanes counted
 *                                        by VP's length, 2 .. HC_MAX_LANES);
 *   P (lanes, K), Phi (K+, N), HP (lanes, m), HX (nx,), y (N,), begin (an integer);
 *   acc: the sums [f, sum d r (p), sum d d^T (p x p)] (p = lanes - 1; the lower triangle of the last is read, all of
 *        it written), or with the outputs option an (N, lanes) array of the lanes' outputs.
 * Options: bit 0 a direct term, bit 1 an offset (without them D, Y0 are not read: the caller has seen them all zero),
 * bit 2 an output map, bit 3 the outputs.  A non-finite signal sample not yet in the state (zero-order hold: the last
 * one) reaches no sum when the direct term is left out: the sum of squares is then NaN, as it would be with d = 0.
 * Returns 0, or 1 if the arrays do not fit the pass (sizes, or an output map's parameters and data).
 *
 * The summing passes of orders up to BLOCK_SUM_MAX_ORDER without a map add a block's sums of d r and d d^T to acc at
 * its end (from zero); the others carry acc's values through the block.  (Two ways of adding that give the same
 * bits on a record passed whole, and each the same bits as the pass it replaces did on one passed in blocks.)
 */
#include "kernels.hpp"
#include "isa.h"

namespace {

enum { OPT_DIRECT = 1, OPT_OFFSET = 2, OPT_MAP = 4, OPT_OUTPUTS = 8 };
constexpr int BLOCK_SUM_MAX_ORDER = 4;
/* Most neighbours, and the entries of the lower triangle of their products. */
constexpr int MAX_P = HC_MAX_LANES - 1;
constexpr int MAX_TRIANGLE = MAX_P * (MAX_P + 1) / 2;

struct NormalArgs {
    const double *E, *C, *D, *Y0, *P, *Phi, *HP, *y;
    double *X, *VP, *acc;
    int64_t rows, erows, ecols, ccols, xcols, lanes, K, N, hm, acols, begin;
    bool direct, offset;
    OutputMap h;
};

/* The arguments of a pass with the given options, read and checked; false if they do not fit. */
inline bool read_normal(const hc_arg *args, int options, NormalArgs &s)
{
    int i = 0;
    if (options & OPT_MAP)
        s.h.code = args[i++].shape[0];
    const hc_arg &E = args[i], &C = args[i + 1], &D = args[i + 2], &X = args[i + 3], &Y0 = args[i + 4],
                 &VP = args[i + 5], &P = args[i + 6], &Phi = args[i + 7], &HP = args[i + 8], &HX = args[i + 9],
                 &y = args[i + 10], &begin = args[i + 11], &acc = args[i + 12];
    s.E = (const double *)E.data;
    s.rows = E.shape[0];
    s.erows = E.shape[1];
    s.ecols = E.shape[2];
    s.C = (const double *)C.data;
    s.ccols = C.shape[1];
    s.D = (const double *)D.data;
    s.X = (double *)X.data;
    s.xcols = X.shape[1];
    s.Y0 = (const double *)Y0.data;
    s.VP = (double *)VP.data;
    s.lanes = VP.shape[0];
    s.P = (const double *)P.data;
    s.K = P.shape[1];
    s.Phi = (const double *)Phi.data;
    s.N = Phi.shape[1];
    s.HP = (const double *)HP.data;
    s.hm = HP.shape[1];
    s.h.x = (const double *)HX.data;
    s.h.nx = HX.shape[0];
    s.y = (const double *)y.data;
    s.begin = begin.shape[0];
    s.acc = (double *)acc.data;
    s.acols = acc.shape[1];
    s.direct = options & OPT_DIRECT;
    s.offset = options & OPT_OFFSET;
    int64_t p = s.lanes - 1;
    bool fits = 2 <= s.lanes && s.lanes <= HC_MAX_LANES && X.shape[0] >= s.lanes && P.shape[0] >= s.lanes &&
                1 <= s.K && s.K <= HC_MAX_BASIS && Phi.shape[0] >= s.K && y.shape[0] >= s.N && s.rows >= 1 &&
                C.shape[0] >= s.rows;
    if (options & OPT_OUTPUTS)
        fits = fits && acc.shape[0] >= s.N && s.acols >= s.lanes;
    else
        fits = fits && acc.shape[0] >= 1 + p * s.lanes;
    if (s.direct)
        fits = fits && D.shape[0] >= s.rows;
    if (s.offset)
        fits = fits && Y0.shape[0] >= s.lanes;
    if (options & OPT_MAP)
        fits = fits && HP.shape[0] >= s.lanes && s.h.code >= 0 && s.h.code < HC_MAP_COUNT &&
               s.hm >= map_params(s.h.code, s.h.nx) && !(s.h.code == HC_MAP_PIECEWISE_LINEAR && s.h.nx < 2) &&
               !(s.h.code == HC_MAP_POLYNOMIAL && s.hm < 1);
    return fits;
}

template <int N, bool ZOH, int OPT, int W>
void normal_lanes(const NormalArgs &s)
{
    constexpr bool MAP = OPT & OPT_MAP, OUTPUTS = OPT & OPT_OUTPUTS;
    constexpr bool BLOCK_SUMS = N <= BLOCK_SUM_MAX_ORDER && !MAP && !OUTPUTS;
    alignas(64) double a[N][N][W], p[N][W], q[N][W], c[N][W], x[N][W], d[W], o[W], vp[W], vi[W], yh[W];
    alignas(64) double P[HC_MAX_BASIS][W];
    double f[HC_MAX_BASIS] = {0.0};
    const double *hp[W];
    const int64_t K = s.K, lanes = s.lanes, np = lanes - 1;
    for (int w = 0; w < W; w++) {
        int64_t b = w < lanes ? w : 0, e = b < s.rows ? b : 0;
        const double *er = s.E + e * s.erows * s.ecols;
        unroll<N>([&](int r) {
            unroll<N>([&](int k) { a[r][k][w] = er[r * s.ecols + k]; });
            q[r][w] = ZOH ? 0.0 : er[r * s.ecols + N + 1];
            p[r][w] = ZOH ? er[r * s.ecols + N] : er[r * s.ecols + N] - q[r][w];
            c[r][w] = s.C[e * s.ccols + r];
            x[r][w] = s.X[b * s.xcols + r];
        });
        d[w] = s.direct ? s.D[e] : 0.0;
        o[w] = s.offset ? s.Y0[b] : 0.0;
        hp[w] = MAP ? s.HP + b * s.hm : nullptr;
        vp[w] = s.VP[b];
        for (int64_t k = 0; k < K; k++)
            P[k][w] = s.P[b * K + k];
    }
    double fsum = OUTPUTS ? 0.0 : s.acc[0], g[MAX_P] = {0.0}, H[MAX_TRIANGLE] = {0.0};
    if (!OUTPUTS && !BLOCK_SUMS)
        for (int64_t j = 0, t = 0; j < np; j++) {
            g[j] = s.acc[1 + j];
            for (int64_t k = 0; k <= j; k++, t++)
                H[t] = s.acc[1 + np + j * np + k];
        }
    auto signals = [&](int64_t i) {
        for (int64_t k = 0; k < K; k++)
            f[k] = s.Phi[k * s.N + i];
        for (int w = 0; w < W; w++)
            vi[w] = P[0][w] * f[0];
        for (int64_t k = 1; k < K; k++)
            for (int w = 0; w < W; w++)
                vi[w] += P[k][w] * f[k];
    };
    /* lane w's output from its state and its signal sample vi[w] */
    auto lane_output = [&](int w) {
        double z = c[0][w] * x[0][w];
        unroll<N - 1>([&](int r) { z += c[r + 1][w] * x[r + 1][w]; });
        if (s.direct)
            z = z + d[w] * vi[w];
        if (MAP)
            z = s.h(z, hp[w], s.hm);
        if (s.offset)
            z = z + o[w];
        return z;
    };
    /* the sums of sample i (or the outputs' row i) */
    auto add = [&](int64_t i) {
        if (OUTPUTS) {
            for (int64_t w = 0; w < lanes; w++)
                s.acc[i * s.acols + w] = yh[w];
            return;
        }
        double y0 = yh[0], r = s.y[i] - y0, dj[MAX_P];
        fsum += r * r;
        for (int64_t j = 0; j < np; j++)
            dj[j] = y0 - yh[j + 1];
        for (int64_t j = 0; j < np; j++)
            g[j] += dj[j] * r;
        for (int64_t j = 0, t = 0; j < np; j++)
            for (int64_t k = 0; k <= j; k++, t++)
                H[t] += dj[j] * dj[k];
    };
    int64_t start = 0;
    if (s.begin == 0 && s.N > 0) {
        signals(0);
        for (int w = 0; w < W; w++) {
            vp[w] = vi[w];
            yh[w] = lane_output(w);
        }
        add(0);
        start = 1;
    }
    for (int64_t i = start; i < s.N; i++) {
        signals(i);
        for (int w = 0; w < W; w++) {
            double next[N];
            unroll<N>([&](int r) {
                double t = a[r][0][w] * x[0][w];
                unroll<N - 1>([&](int k) { t += a[r][k + 1][w] * x[k + 1][w]; });
                next[r] = ZOH ? t + p[r][w] * vp[w] : t + (p[r][w] * vp[w] + q[r][w] * vi[w]);
            });
            unroll<N>([&](int r) { x[r][w] = next[r]; });
            vp[w] = vi[w];
            yh[w] = lane_output(w);
        }
        add(i);
    }
    for (int64_t w = 0; w < lanes; w++) {
        unroll<N>([&](int r) { s.X[w * s.xcols + r] = x[r][w]; });
        s.VP[w] = vp[w];
        if (!OUTPUTS && !std::isfinite(vp[w]))
            fsum = NAN;
    }
    if (OUTPUTS)
        return;
    s.acc[0] = fsum;
    for (int64_t j = 0, t = 0; j < np; j++) {
        s.acc[1 + j] = BLOCK_SUMS ? s.acc[1 + j] + g[j] : g[j];
        for (int64_t k = 0; k <= j; k++, t++) {
            double v = BLOCK_SUMS ? s.acc[1 + np + j * np + k] + H[t] : H[t];
            s.acc[1 + np + j * np + k] = v;
            s.acc[1 + np + k * np + j] = v;
        }
    }
}

template <int N, bool ZOH, int OPT>
int64_t normal_kernel(const hc_arg *args)
{
    NormalArgs s;
    if (!read_normal(args, OPT, s))
        return 1;
    if (s.lanes <= 8)
        normal_lanes<N, ZOH, OPT & (OPT_MAP | OPT_OUTPUTS), 8>(s);
    else
        normal_lanes<N, ZOH, OPT & (OPT_MAP | OPT_OUTPUTS), 16>(s);
    return 0;
}

/* Table entry I: order I / 32 + 1, hold (I / 16) % 2, options I % 16. */
struct MakeNormal {
    template <int I>
    static int64_t at(const hc_arg *args)
    {
        return normal_kernel<I / 32 + 1, (I / 16) % 2 == 1, I % 16>(args);
    }
};

}  // namespace

extern "C" const hc_kernel *HC_ISA_NAME(hc_normal_table)(void)
{
    return kernel_table<MakeNormal>(std::make_integer_sequence<int, 32 * HC_MAX_ORDER>{});
}
