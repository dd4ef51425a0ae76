/* Kernels that simulate candidates one to three at a time with the state in registers (family HC_SINGLE), and the
 * single evaluation from transfer-function coefficients (HC_COEFFICIENT).
 *
 * A candidate's recursion is latency-bound (each sample waits for the last), so independent candidates are stepped
 * side by side up to PAIR_MAX_ORDER: pairs, and three together for orders up to TRIO_MAX_ORDER where three are left
 * (on the EMPS, order 2, three together took 69 us where a pair and a single took 84).  Each candidate's arithmetic is kernels.hpp's, the
 * same whatever its neighbours.
 *
 * Arguments (hc_arg), in order:
 *   [map]       with an output map: its code (enum hc_map);
 *   E (B, n+, n+2+), C (B, n+), D (B,), X0 (B, n+), Y0 (B,);
 *   V (B, N)    the signals, or P (B, K), Phi (K+, N): the signal of candidate b is P[b] @ Phi;
 *   [HP (B, m), HX (nx,)]   with an output map: its parameters (a row per candidate) and fixed data;
 *   y (N,), out (B,)        "sse": the sum of squared errors against y (inf where it overflows or is not finite);
 *   out (B, N+)             "outputs": the simulated output.
 * Returns 0, or 1 if the output map's parameters or data do not fit its code.
 */
#include "kernels.hpp"

namespace {

/* Orders up to this take three candidates side by side where three are left (at 4 states three cost as much as a
 * pair and a single). */
constexpr int TRIO_MAX_ORDER = 2;
/* Orders up to this step candidates in pairs; above, one at a time (a recursion of five states or more has the
 * independent work of a pair within one candidate: its rows). */
constexpr int PAIR_MAX_ORDER = 4;

enum { OPT_SSE = 1, OPT_BASIS = 2, OPT_MAP = 4 };

struct SingleArgs {
    const double *E, *C, *D, *X0, *Y0, *V, *P, *Phi, *HP, *y;
    double *out;
    int64_t batch, N, K, erows, ecols, ccols, xcols, vcols, pcols, phirows, hm, ocols;
    OutputMap h;
};

/* The arguments of a kernel with the given options, read from args; false if the map does not fit them. */
inline bool read_args(const hc_arg *args, int options, SingleArgs &s)
{
    int i = 0;
    if (options & OPT_MAP)
        s.h.code = args[i++].shape[0];
    const hc_arg &E = args[i++], &C = args[i++], &D = args[i++], &X0 = args[i++], &Y0 = args[i++];
    s.E = (const double *)E.data;
    s.erows = E.shape[1];
    s.ecols = E.shape[2];
    s.C = (const double *)C.data;
    s.ccols = C.shape[1];
    s.D = (const double *)D.data;
    s.X0 = (const double *)X0.data;
    s.xcols = X0.shape[1];
    s.Y0 = (const double *)Y0.data;
    s.batch = E.shape[0];
    if (options & OPT_BASIS) {
        const hc_arg &P = args[i++], &Phi = args[i++];
        s.P = (const double *)P.data;
        s.K = P.shape[1];
        s.pcols = P.shape[1];
        s.Phi = (const double *)Phi.data;
        s.N = Phi.shape[1];
        s.V = nullptr;
    } else {
        const hc_arg &V = args[i++];
        s.V = (const double *)V.data;
        s.vcols = V.shape[1];
        s.N = V.shape[1];
        s.P = s.Phi = nullptr;
        s.K = 0;
    }
    s.HP = nullptr;
    s.hm = 0;
    if (options & OPT_MAP) {
        const hc_arg &HP = args[i++], &HX = args[i++];
        s.HP = (const double *)HP.data;
        s.hm = HP.shape[1];
        s.h.x = (const double *)HX.data;
        s.h.nx = HX.shape[0];
        if (s.h.code < 0 || s.h.code >= HC_MAP_COUNT || s.hm < map_params(s.h.code, s.h.nx) ||
            (s.h.code == HC_MAP_PIECEWISE_LINEAR && s.h.nx < 2) || (s.h.code == HC_MAP_POLYNOMIAL && s.hm < 1))
            return false;
    }
    if (options & OPT_SSE) {
        s.y = (const double *)args[i++].data;
        s.out = (double *)args[i++].data;
        s.ocols = 1;
    } else {
        s.y = nullptr;
        s.out = (double *)args[i].data;
        s.ocols = args[i].shape[1];
    }
    return true;
}

/* G candidates b0 .. b0 + G - 1 over the record. */
template <int N, bool ZOH, int OPT, int G>
void run_group(const SingleArgs &s, int64_t b0)
{
    constexpr bool SSE = OPT & OPT_SSE, BASIS = OPT & OPT_BASIS, MAP = OPT & OPT_MAP;
    Block<N, ZOH> blk[G];
    double x[G][N], o[G], vp[G], J[G];
    const double *hp[G];
    auto signal = [&](int g, int64_t i) HC_LAMBDA {
        int64_t b = b0 + g;
        return BASIS ? combination(s.P + b * s.pcols, s.Phi + i, s.K, s.N) : s.V[b * s.vcols + i];
    };
    auto out_of = [&](int g, double v) HC_LAMBDA {
        return output<N, ZOH, true, true, MAP>(blk[g], x[g], v, o[g], s.h, hp[g], s.hm);
    };
    unroll<G>([&](int g) HC_LAMBDA {
        int64_t b = b0 + g;
        blk[g].load(s.E + b * s.erows * s.ecols, s.ecols, s.C + b * s.ccols, s.D[b]);
        unroll<N>([&](int r) HC_LAMBDA { x[g][r] = s.X0[b * s.xcols + r]; });
        o[g] = s.Y0[b];
        hp[g] = MAP ? s.HP + b * s.hm : nullptr;
        vp[g] = signal(g, 0);
        double yh = out_of(g, vp[g]);
        if (SSE) {
            double e = s.y[0] - yh;
            J[g] = e * e;
        } else {
            s.out[b * s.ocols] = yh;
        }
    });
    double chunk[BASIS ? G : 1][BASIS ? CHUNK : 1];
    const double *v[G];
    for (int64_t first = 1; first < s.N; first += CHUNK) {
        int64_t len = s.N - first < CHUNK ? s.N - first : CHUNK;
        unroll<G>([&](int g) HC_LAMBDA {
            int64_t b = b0 + g;
            if (BASIS) {
                basis_signals(s.P + b * s.pcols, s.Phi, s.N, s.K, first, len, chunk[g]);
                v[g] = chunk[g];
            } else {
                v[g] = s.V + b * s.vcols + first;
            }
        });
        for (int64_t j = 0; j < len; j++) {
            int64_t i = first + j;
            double yi = SSE ? s.y[i] : 0.0;
            unroll<G>([&](int g) HC_LAMBDA {
                double vi = v[g][j];
                blk[g].advance(x[g], vp[g], vi);
                double yh = out_of(g, vi);
                if (SSE) {
                    double e = yi - yh;
                    J[g] += e * e;
                } else {
                    s.out[(b0 + g) * s.ocols + i] = yh;
                }
                vp[g] = vi;
            });
            if (SSE && (i & CHECK_MASK) == 0) { /* stop once every sum has overflowed (or is NaN) */
                bool alive = false;
                unroll<G>([&](int g) HC_LAMBDA { alive = alive || J[g] <= OVERFLOW_LIMIT; });
                if (!alive)
                    first = s.N;
                if (!alive)
                    break;
            }
        }
    }
    if (SSE)
        unroll<G>([&](int g) HC_LAMBDA { s.out[b0 + g] = J[g] <= OVERFLOW_LIMIT ? J[g] : INFINITY; });
}

template <int N, bool ZOH, int OPT>
int64_t single_kernel(const hc_arg *args)
{
    SingleArgs s;
    if (!read_args(args, OPT, s))
        return 1;
    int64_t b0 = 0;
    /* with an output map, the map's work hides the recursion's latency: one candidate at a time */
    constexpr bool MAP = OPT & OPT_MAP;
    if constexpr (N <= PAIR_MAX_ORDER && !MAP) {
        while (s.batch - b0 >= 2 && !(N <= TRIO_MAX_ORDER && s.batch - b0 == 3)) {
            run_group<N, ZOH, OPT, 2>(s, b0);
            b0 += 2;
        }
    }
    if constexpr (N <= TRIO_MAX_ORDER && !MAP) {
        if (s.batch - b0 == 3) {
            run_group<N, ZOH, OPT, 3>(s, b0);
            b0 += 3;
        }
    }
    while (b0 < s.batch) {
        run_group<N, ZOH, OPT, 1>(s, b0);
        b0 += 1;
    }
    return 0;
}

/* Whether the kernel of order N with the options OPT is built: the signals V ("sse" or "outputs", with an output
 * map up to HC_LANES_MAX_ORDER) and, up to that order too, a basis in "sse" mode without a map. */
constexpr bool built(int N, int OPT)
{
    bool basis = OPT & OPT_BASIS, map = OPT & OPT_MAP, sse = OPT & OPT_SSE;
    if (basis)
        return sse && !map && N <= HC_LANES_MAX_ORDER;
    return !map || N <= HC_LANES_MAX_ORDER;
}

/* Table entry I: order I / 16 + 1, hold (I / 8) % 2, options I % 8 (NULL where not built). */
struct MakeSingle {
    template <int I>
    static constexpr hc_kernel at = built(I / 16 + 1, I % 8) ? &single_kernel<I / 16 + 1, (I / 8) % 2 == 1, I % 8>
                                                             : nullptr;
};

/* Any order n (a static block, n = 0, or the state dimension of a state-space model past HC_MAX_ORDER): signals V,
 * "sse" (SSE) or "outputs", one candidate at a time, the state in memory; n = E.shape[1] - 2.  Returns 0, or 3 if no
 * memory could be had. */
template <bool ZOH, bool SSE>
int64_t any_order_kernel(const hc_arg *args)
{
    SingleArgs s;
    read_args(args, SSE ? OPT_SSE : 0, s);
    int64_t n = s.erows - 2, ec = s.ecols;
    double *x = (double *)malloc((size_t)(2 * n + 1) * sizeof(double)), *next = x + n;
    if (x == nullptr)
        return 3;
    for (int64_t b = 0; b < s.batch; b++) {
        const double *E = s.E + b * s.erows * ec, *c = s.C + b * s.ccols, *v = s.V + b * s.vcols;
        double d = s.D[b], o = s.Y0[b], J = 0.0;
        for (int64_t r = 0; r < n; r++)
            x[r] = s.X0[b * s.xcols + r];
        for (int64_t i = 0; i < s.N; i++) {
            if (i > 0) {
                for (int64_t r = 0; r < n; r++) {
                    double t = E[r * ec] * x[0];
                    for (int64_t k = 1; k < n; k++)
                        t += E[r * ec + k] * x[k];
                    double q = ZOH ? 0.0 : E[r * ec + n + 1], p = ZOH ? E[r * ec + n] : E[r * ec + n] - q;
                    next[r] = ZOH ? t + p * v[i - 1] : t + (p * v[i - 1] + q * v[i]);
                }
                memcpy(x, next, (size_t)n * sizeof(double));
            }
            double z = n > 0 ? c[0] * x[0] : 0.0;      /* a static block (n = 0): the direct term alone */
            for (int64_t r = 1; r < n; r++)
                z += c[r] * x[r];
            double yh = (z + d * v[i]) + o;
            if (SSE) {
                double e = s.y[i] - yh;
                J += e * e;
                if ((i & CHECK_MASK) == 0 && !(J <= OVERFLOW_LIMIT))
                    break;
            } else {
                s.out[b * s.ocols + i] = yh;
            }
        }
        if (SSE)
            s.out[b] = J <= OVERFLOW_LIMIT ? J : INFINITY;
    }
    free(x);
    return 0;
}

}  // namespace

extern "C" {

/* The kernels of any order: [hold * 2 + sse] (signals V, no map). */
const hc_kernel *hc_any_order_table(void)
{
    static const hc_kernel table[4] = {any_order_kernel<false, false>, any_order_kernel<false, true>,
                                       any_order_kernel<true, false>, any_order_kernel<true, true>};
    return table;
}

const hc_kernel *hc_single_table(void)
{
    return kernel_table<MakeSingle>(std::make_integer_sequence<int, 16 * HC_MAX_ORDER>{});
}

/* The single evaluation from coefficients: args are the kernel's number (an integer: an HC_SINGLE "sse" kernel with a
 * basis), num (B, l + 1), den (B, n + 1), dt and max_norm (floats), then the kernel's X0, Y0, P, Phi, y, out.  The
 * rows are realised and discretised (hc_tf_discrete), then the kernel runs.  Returns 0 after the kernel ran; 1 where
 * a row is not usable or its exponential needs more than the compiled Pade (out untouched); 2 if num has more
 * coefficients than den (an improper block) or the kernel is not an "sse" kernel with a basis of den's order; 3 if
 * no memory could be had; else the kernel's own refusal plus 3. */
int64_t hc_coefficient_pass(const hc_arg *args)
{
    int64_t number = args[0].shape[0];
    const double *num = (const double *)args[1].data, *den = (const double *)args[2].data;
    int64_t batch = args[1].shape[0], nnum = args[1].shape[1], nden = args[2].shape[1], n = nden - 1, m = nden + 1;
    double dt = float_arg(args[3]), max_norm = float_arg(args[4]);
    if (nnum > nden || n < 1 || n > HC_MAX_ORDER ||
        (number != hc_kernel_number(HC_SINGLE, n, 0, OPT_SSE | OPT_BASIS) &&
         number != hc_kernel_number(HC_SINGLE, n, 1, OPT_SSE | OPT_BASIS)))
        return 2;
    hc_kernel kernel = hc_kernel_at(number);
    size_t rows = (size_t)(batch > 0 ? batch : 1);
    double *E = (double *)malloc(rows * (size_t)(m * m + n + 1) * sizeof(double));
    bool *flags = (bool *)malloc(2 * rows * sizeof(bool));
    int64_t status = 3;
    if (E != nullptr && flags != nullptr) {
        double *C = E + rows * (size_t)(m * m), *D = C + rows * (size_t)n;
        status = 1;
        if (hc_tf_discrete(num, den, batch, nnum, nden, dt, max_norm, E, C, D, flags, flags + rows)) {
            hc_arg kernel_args[9] = {{E, {batch, m, m}}, {C, {batch, n, 0}}, {D, {batch, 0, 0}}, args[5], args[6],
                                     args[7], args[8], args[9], args[10]};
            int64_t refused = kernel(kernel_args);
            status = refused ? refused + 3 : 0;
        }
    }
    free(E);
    free(flags);
    return status;
}

}  // extern "C"
