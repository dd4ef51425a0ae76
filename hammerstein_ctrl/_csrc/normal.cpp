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

struct NormalArgs {
    const double *E, *C, *D, *Y0, *P, *Phi, *HP, *y;
    double *X, *VP, *acc;
    int64_t rows, erows, ecols, ccols, xcols, lanes, K, N, hm, acols, begin, n;
    bool direct, offset;
    OutputMap h;
};

/* The arguments of a pass with the given options, read and checked; false if they do not fit. */
inline bool read_normal(const hc_arg *args, int options, int64_t n, NormalArgs &s)
{
    int i = 0;
    if (options & OPT_MAP)
        s.h.code = args[i++].shape[0];
    const hc_arg &E = args[i], &C = args[i + 1], &D = args[i + 2], &X = args[i + 3], &Y0 = args[i + 4],
                 &VP = args[i + 5], &P = args[i + 6], &Phi = args[i + 7], &HP = args[i + 8], &HX = args[i + 9],
                 &y = args[i + 10], &begin = args[i + 11], &acc = args[i + 12];
    s.n = n;
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

/* The running sums of a pass over W lanes, kept by lane: f, G[a] = sum d_a r and H[a][b] = sum d_a d_b, with
 * d_a = yhat_0 - yhat_a for lane a (lane 0's is zero: neighbour j is lane j + 1).  Only the rows of the neighbours
 * are added to, each over its lower triangle rounded up to whole vectors of four (W is a multiple of 8), so that
 * every loop runs over whole vectors. */
template <int W>
struct Sums {
    double f;
    alignas(64) double G[W], H[W][W];
    int64_t p;

    /* From acc (carry, the lower triangle of the neighbours' square) or zero (block sums), f always from acc. */
    void start(const double *acc, int64_t np, bool carry)
    {
        p = np;
        f = acc[0];
        for (int a = 0; a < W; a++) {
            int64_t j = a - 1;
            G[a] = carry && 0 <= j && j < p ? acc[1 + j] : 0.0;
            for (int b = 0; b < W; b++) {
                int64_t k = b - 1;
                H[a][b] = carry && 0 <= k && k <= j && j < p ? acc[1 + p + j * p + k] : 0.0;
            }
        }
    }

    /* One sample's terms from the lanes' outputs yh. */
    HC_INLINE void add(double yi, const double *yh)
    {
        alignas(64) double d[W];
        double y0 = yh[0], r = yi - y0;
        f += r * r;
        HC_LANE_LOOP
        for (int w = 0; w < W; w++)
            d[w] = y0 - yh[w];
        HC_LANE_LOOP
        for (int w = 0; w < W; w++)
            G[w] += d[w] * r;
        for (int64_t a = 1; a <= p; a++) {    /* the row's lower triangle, rounded up to whole vectors of 4 */
            const int64_t end = (a + 4) & ~(int64_t)3;
            HC_LANE_LOOP
            for (int64_t b = 0; b < end; b++)
                H[a][b] += d[a] * d[b];
        }
    }

    /* Into acc: the sums (carried) or added to acc's (block sums); the triangle mirrored. */
    void store(double *acc, bool carry) const
    {
        acc[0] = f;
        for (int64_t j = 0; j < p; j++) {
            acc[1 + j] = carry ? G[j + 1] : acc[1 + j] + G[j + 1];
            for (int64_t k = 0; k <= j; k++) {
                double v = carry ? H[j + 1][k + 1] : acc[1 + p + j * p + k] + H[j + 1][k + 1];
                acc[1 + p + j * p + k] = v;
                acc[1 + p + k * p + j] = v;
            }
        }
    }
};

/* The pass over W lanes, of order N (0: s.n at run time). */
template <int N, bool ZOH, bool MAP, bool OUTPUTS, int W>
void normal_lanes(const NormalArgs &s)
{
    constexpr bool BLOCK_SUMS = N > 0 && N <= BLOCK_SUM_MAX_ORDER && !MAP && !OUTPUTS;
    LaneBlocks<N, ZOH, W> blk;
    blk.n = s.n;
    alignas(64) double d[W], o[W], vp[W], vi[W], z[W], yh[W], P[HC_MAX_BASIS][W];
    double f[HC_MAX_BASIS] = {0.0};
    const double *hp[W];
    const int64_t K = s.K, lanes = s.lanes;
    for (int w = 0; w < W; w++) {
        int64_t b = w < lanes ? w : 0, e = b < s.rows ? b : 0;
        blk.load(w, s.E + e * s.erows * s.ecols, s.ecols, s.C + e * s.ccols, s.X + b * s.xcols);
        d[w] = s.direct ? s.D[e] : 0.0;
        o[w] = s.offset ? s.Y0[b] : 0.0;
        hp[w] = MAP ? s.HP + b * s.hm : nullptr;
        vp[w] = s.VP[b];
        for (int64_t k = 0; k < K; k++)
            P[k][w] = s.P[b * K + k];
    }
    const uint64_t direct = mask_of(s.direct), offset = mask_of(s.offset);
    Sums<W> sums;
    if (!OUTPUTS)
        sums.start(s.acc, lanes - 1, !BLOCK_SUMS);
    /* the lanes' outputs of sample i from their states and signals, then its sums (or its row of outputs) */
    auto sample = [&](int64_t i) HC_LAMBDA {
        blk.linear(z);
        HC_LANE_LOOP
        for (int w = 0; w < W; w++) {     /* each term computed, then taken or not */
            double v = pick(direct, z[w] + d[w] * vi[w], z[w]);
            if (MAP && w < lanes)           /* a padding lane's output reaches no sum: not worth its map */
                v = s.h(v, hp[w], s.hm);
            yh[w] = pick(offset, v + o[w], v);
        }
        if (OUTPUTS) {
            for (int64_t w = 0; w < lanes; w++)
                s.acc[i * s.acols + w] = yh[w];
        } else {
            sums.add(s.y[i], yh);
        }
    };
    int64_t start = 0;
    if (s.begin == 0 && s.N > 0) {
        for (int64_t k = 0; k < K; k++)
            f[k] = s.Phi[k * s.N];
        lane_signals<W>(P, f, K, vi);
        for (int w = 0; w < W; w++)
            vp[w] = vi[w];
        sample(0);
        start = 1;
    }
    for (int64_t i = start; i < s.N; i++) {
        for (int64_t k = 0; k < K; k++)
            f[k] = s.Phi[k * s.N + i];
        lane_signals<W>(P, f, K, vi);
        blk.advance(vp, vi);
        for (int w = 0; w < W; w++)
            vp[w] = vi[w];
        sample(i);
    }
    bool finite = true;
    for (int64_t w = 0; w < lanes; w++) {
        for (int64_t r = 0; r < s.n; r++)
            s.X[w * s.xcols + r] = blk.x[r][w];
        s.VP[w] = vp[w];
        finite = finite && is_finite(vp[w]);
    }
    if (OUTPUTS)
        return;
    if (!finite)
        sums.f = NAN;
    sums.store(s.acc, !BLOCK_SUMS);
}

template <int N, bool ZOH, int OPT>
int64_t normal_kernel(const hc_arg *args)
{
    constexpr bool MAP = OPT & OPT_MAP, OUTPUTS = OPT & OPT_OUTPUTS;
    /* a pass with an output map steps its lanes one by one through the map anyway: one form of it serves every
     * order and lane count */
    constexpr int ORDER = N <= FIXED_MAX_ORDER && !MAP ? N : 0;
    NormalArgs s;
    if (!read_normal(args, OPT, N, s))
        return 1;
    if (s.lanes <= 8 && !MAP)
        normal_lanes<ORDER, ZOH, MAP, OUTPUTS, 8>(s);
    else
        normal_lanes<ORDER, ZOH, MAP, OUTPUTS, 16>(s);
    return 0;
}

/* Table entry I: order I / 32 + 1, hold (I / 16) % 2, options I % 16.  A pass with an output map steps its lanes
 * one by one (a map is no vector operation): only the baseline's build has it. */
struct MakeNormal {
    template <int I>
    static constexpr hc_kernel at = HC_BASELINE || !(I % 16 & OPT_MAP)
                                        ? &normal_kernel<I / 32 + 1, (I / 16) % 2 == 1, I % 16>
                                        : nullptr;
};

}  // namespace

extern "C" const hc_kernel *HC_ISA_NAME(hc_normal_table)(void)
{
    return kernel_table<MakeNormal>(std::make_integer_sequence<int, 32 * HC_MAX_ORDER>{});
}
