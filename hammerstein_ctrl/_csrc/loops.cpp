/* Loops over a record's samples that are not a candidate's recursion: the sampled PID and controller loops around a
 * block model (hammerstein_ctrl.loop_sim), the exact recursion of a linear block with an input dead time
 * (hammerstein_ctrl.delay), and the lagged cross-products of two signals (hammerstein_ctrl.residual_analysis).
 * Sums run left to right in the order written; no fused multiply-add.
 */
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "hc.h"
#include "maps.hpp"

namespace {

/* Largest plant order of the loops. */
constexpr int64_t MAX_N = HC_MAX_ORDER;

/* A static block: a built-in map (code, its parameters and fixed data), or the identity (code < 0). */
struct Static {
    int64_t code;
    const double *p;
    int64_t m;
    const double *x;
    int64_t nx;

    inline double operator()(double u) const
    {
        return code < 0 ? u : apply_map(code, u, p, m, x, nx);
    }
    bool fits() const
    {
        return code < 0 || (code < HC_MAP_COUNT && m >= map_params(code, nx) &&
                            !(code == HC_MAP_PIECEWISE_LINEAR && nx < 2) && !(code == HC_MAP_POLYNOMIAL && m < 1));
    }
};

/* A plant: its exact zero-order-hold step (Ad n x n, Bd), C, initial state, offset, and its static blocks. */
struct Plant {
    const double *Ad, *Bd, *C, *x0;
    int64_t n;
    double offset;
    Static g, h;

    /* y = h(C x) + offset */
    inline double output(const double *x) const
    {
        double z = 0.0;
        for (int64_t i = 0; i < n; i++)
            z += C[i] * x[i];
        return h(z) + offset;
    }
    /* Sample k: the output y and the clipped input u = clip(uc) recorded, then the plant stepped under g(u); false
     * (the rest of the record cut) where |y| passed the bound.  *u receives the input. */
    inline bool drive(double *x, double y, double uc, double lo, double hi, double bound, int64_t k, double *Y,
                      double *U, int64_t N, double *u) const;

    /* x <- Ad x + Bd v */
    inline void step(double *x, double v) const
    {
        double next[MAX_N];
        for (int64_t i = 0; i < n; i++) {
            double s = Bd[i] * v;
            for (int64_t j = 0; j < n; j++)
                s += Ad[i * n + j] * x[j];
            next[i] = s;
        }
        std::memcpy(x, next, (size_t)n * sizeof(double));
    }
};

/* Python's min(max(uc, lo), hi). */
inline double clip(double uc, double lo, double hi)
{
    double a = lo > uc ? lo : uc;
    return hi < a ? hi : a;
}

/* After a divergence at sample k: the outputs inf, the inputs NaN. */
inline void cut(double *Y, double *U, int64_t k, int64_t N)
{
    for (int64_t j = k + 1; j < N; j++) {
        Y[j] = INFINITY;
        U[j] = NAN;
    }
}

inline bool Plant::drive(double *x, double y, double uc, double lo, double hi, double bound, int64_t k, double *Y,
                         double *U, int64_t N, double *u) const
{
    *u = clip(uc, lo, hi);
    Y[k] = y;
    U[k] = *u;
    if (!(std::fabs(y) <= bound)) {
        cut(Y, U, k, N);
        return false;
    }
    step(x, g(*u));
    return true;
}

Plant plant_of(const double *Ad, const double *Bd, const double *C, const double *x0, int64_t n, double offset,
               int64_t code, const double *p, int64_t m, const double *bp, int64_t nbp, int64_t hcode,
               const double *hp, int64_t hm, const double *hbp, int64_t nhbp)
{
    Plant P;
    P.Ad = Ad;
    P.Bd = Bd;
    P.C = C;
    P.x0 = x0;
    P.n = n;
    P.offset = offset;
    P.g = Static{code, p, m, bp, nbp};
    P.h = Static{hcode, hp, hm, hbp, nhbp};
    return P;
}

/* A discrete controller's state (nc numbers, on the heap with room for its next value) in the loops below. */
struct ControllerState {
    double *xc = nullptr, *next = nullptr;
    int64_t nc = 0;

    /* nc states from xc0 (zeros for nullptr); false if no memory could be had. */
    bool open(int64_t count, const double *xc0)
    {
        nc = count;
        xc = (double *)std::malloc((size_t)(2 * nc + 1) * sizeof(double));
        if (xc == nullptr)
            return false;
        next = xc + nc;
        for (int64_t i = 0; i < nc; i++)
            xc[i] = xc0 == nullptr ? 0.0 : xc0[i];
        return true;
    }
    ~ControllerState() { std::free(xc); }
    /* uc + Cc xc, the states added in order. */
    inline double output(const double *Cc, double uc) const
    {
        for (int64_t i = 0; i < nc; i++)
            uc += Cc[i] * xc[i];
        return uc;
    }
    /* xc <- Ac xc + b: row i starts from drive(i), its input's share, then adds Ac's products in order. */
    template <class Drive> inline void step(const double *Ac, Drive drive)
    {
        for (int64_t i = 0; i < nc; i++) {
            double s = drive(i);
            for (int64_t j = 0; j < nc; j++)
                s += Ac[i * nc + j] * xc[j];
            next[i] = s;
        }
        std::memcpy(xc, next, (size_t)nc * sizeof(double));
    }
};

}  // namespace

extern "C" {

/* The sampled PID loops of hammerstein_ctrl.loop_sim around one plant (order n <= HC_MAX_ORDER: Ad, Bd, C, x0,
 * offset; input block code/p/bp and output block hcode/hp/hbp, code -1 the identity), one loop per row of the gains
 * G (batch x 5: kp, ki, kd, tf, kt) over the reference r (N samples): outputs Y and plant inputs U (batch x N).  A
 * loop whose |y| passes bound stops there (the rest of its row inf, NaN).  Returns 0, or 1 if the plant or its blocks
 * do not fit (nothing written). */
int hc_pid_loops(const double *Ad, const double *Bd, const double *C, const double *x0, int64_t n, double offset,
                 hc_signed code, const double *p, int64_t m, const double *bp, int64_t nbp, hc_signed hcode,
                 const double *hp, int64_t hm, const double *hbp, int64_t nhbp, const double *G, int64_t batch,
                 const double *r, int64_t N, double dt, double lo, double hi, double bias, double bound, double *Y,
                 double *U)
{
    Plant P = plant_of(Ad, Bd, C, x0, n, offset, code, p, m, bp, nbp, hcode, hp, hm, hbp, nhbp);
    if (n < 0 || n > MAX_N || !P.g.fits() || !P.h.fits())
        return 1;
    double x[MAX_N];
    for (int64_t b = 0; b < batch; b++) {
        const double *g = G + b * 5;
        double kp = g[0], ki = g[1], kd = g[2], tf = g[3], kt = g[4];
        double ad = tf / (tf + dt), bd = kd / (tf + dt);
        double *Yb = Y + b * N, *Ub = U + b * N;
        std::memcpy(x, x0, (size_t)n * sizeof(double));
        double integ = bias, deriv = 0.0, ep = 0.0;
        for (int64_t k = 0; k < N; k++) {
            double y = P.output(x);
            double e = r[k] - y;
            deriv = ad * deriv + bd * (e - ep);
            double uc = kp * e + integ + deriv, u;
            if (!P.drive(x, y, uc, lo, hi, bound, k, Yb, Ub, N, &u))
                break;
            integ += dt * (ki * e + kt * (u - uc));
            ep = e;
        }
    }
    return 0;
}

/* A linear discrete controller xc+ = Ac xc + Bc e, u = clip(bias + Dc e + Cc xc) (from rest; nc states) around the
 * plant of hc_pid_loops: Y and U (N samples each).  Returns 0; 1 if the plant or its blocks do not fit; 2 if no
 * memory could be had for the controller's state (nothing written). */
int hc_controller_loop(const double *Ad, const double *Bd, const double *C, const double *x0, int64_t n,
                       double offset, hc_signed code, const double *p, int64_t m, const double *bp, int64_t nbp,
                       hc_signed hcode, const double *hp, int64_t hm, const double *hbp, int64_t nhbp,
                       const double *Ac, const double *Bc, const double *Cc, double Dc, int64_t nc, const double *r,
                       int64_t N, double lo, double hi, double bias, double bound, double *Y, double *U)
{
    Plant P = plant_of(Ad, Bd, C, x0, n, offset, code, p, m, bp, nbp, hcode, hp, hm, hbp, nhbp);
    if (n < 0 || n > MAX_N || !P.g.fits() || !P.h.fits())
        return 1;
    double x[MAX_N];
    ControllerState K;
    if (!K.open(nc, nullptr))
        return 2;
    std::memcpy(x, x0, (size_t)n * sizeof(double));
    for (int64_t k = 0; k < N; k++) {
        double y = P.output(x);
        double e = r[k] - y;
        double u, uc = K.output(Cc, bias + Dc * e);
        if (!P.drive(x, y, uc, lo, hi, bound, k, Y, U, N, &u))
            break;
        K.step(Ac, [&](int64_t i) { return Bc[i] * e; });
    }
    return 0;
}

/* The loop of a record measured under a known sampled controller (hammerstein_ctrl.in_loop.KnownLoop) around the
 * plant of hc_pid_loops: u[k] = d[k] + Dc [r[k], y[k]] + Cc xc[k], xc[k+1] = Ac xc[k] + Bc [r[k], y[k]] (Bc nc x 2
 * row-major, Dc two numbers, xc[0] = xc0), no actuator limit.  Y and U (N samples each).  Returns 0; 1 if the plant
 * or its blocks do not fit; 2 if no memory could be had for the controller's state (nothing written). */
int hc_known_loop(const double *Ad, const double *Bd, const double *C, const double *x0, int64_t n, double offset,
                  hc_signed code, const double *p, int64_t m, const double *bp, int64_t nbp, hc_signed hcode,
                  const double *hp, int64_t hm, const double *hbp, int64_t nhbp, const double *Ac, const double *Bc,
                  const double *Cc, const double *Dc, int64_t nc, const double *xc0, const double *r, const double *d,
                  int64_t N, double bound, double *Y, double *U)
{
    Plant P = plant_of(Ad, Bd, C, x0, n, offset, code, p, m, bp, nbp, hcode, hp, hm, hbp, nhbp);
    if (n < 0 || n > MAX_N || !P.g.fits() || !P.h.fits())
        return 1;
    double x[MAX_N];
    ControllerState K;
    if (!K.open(nc, xc0))
        return 2;
    std::memcpy(x, x0, (size_t)n * sizeof(double));
    for (int64_t k = 0; k < N; k++) {
        double y = P.output(x);
        double u, uc = K.output(Cc, d[k] + Dc[0] * r[k] + Dc[1] * y);
        if (!P.drive(x, y, uc, -INFINITY, INFINITY, bound, k, Y, U, N, &u))
            break;
        K.step(Ac, [&](int64_t i) { return Bc[2 * i] * r[k] + Bc[2 * i + 1] * y; });
    }
    return 0;
}

/* The exact recursion of a linear block with an input dead time (hammerstein_ctrl.delay): from x0 (n states),
 * out[k] = D w0[k] + C x[k] and x[k+1] = (Pa w0[k] + Pb w1[k] + Pc w0[k+1]) + M x[k] over N samples.  Returns 0, or
 * 1 if no memory could be had for the state (nothing written). */
int hc_delayed_recursion(const double *M, const double *Pa, const double *Pb, const double *Pc, const double *C,
                         double D, int64_t n, const double *x0, const double *w0, const double *w1, int64_t N,
                         double *out)
{
    double *x = (double *)std::malloc((size_t)(2 * n + 1) * sizeof(double)), *next = x + n;
    if (x == nullptr)
        return 1;
    std::memcpy(x, x0, (size_t)n * sizeof(double));
    for (int64_t k = 0; k < N; k++) {
        double acc = D * w0[k];
        for (int64_t i = 0; i < n; i++)
            acc += C[i] * x[i];
        out[k] = acc;
        if (k + 1 == N)
            break;
        for (int64_t i = 0; i < n; i++) {
            double s = Pa[i] * w0[k] + Pb[i] * w1[k] + Pc[i] * w0[k + 1];
            for (int64_t j = 0; j < n; j++)
                s += M[i * n + j] * x[j];
            next[i] = s;
        }
        std::memcpy(x, next, (size_t)n * sizeof(double));
    }
    std::free(x);
    return 0;
}

/* out[k - first] = sum_t (a_t - mean a)(b_{t-k} - mean b) for k = first .. last over the overlapping samples of a
 * and b (n each): raw products, with the means' share taken out afterwards from the sums over each overlap (its
 * ends differ from the whole record's by |k| samples). */
void hc_lagged_sums(const double *a, const double *b, int64_t n, hc_signed first, hc_signed last, double *out)
{
    double sa = 0.0, sb = 0.0;
    for (int64_t t = 0; t < n; t++)
        sa += a[t];
    for (int64_t t = 0; t < n; t++)
        sb += b[t];
    double ma = sa / (double)n, mb = sb / (double)n;
    for (int64_t k = first; k <= last; k++) {
        int64_t lo = k > 0 ? k : 0, hi = n < n + k ? n : n + k;
        if (hi <= lo) {                 /* a lag of the record's length or more: no overlap, the empty sum */
            out[k - first] = 0.0;
            continue;
        }
        double acc = 0.0;
        for (int64_t t = lo; t < hi; t++)
            acc += a[t] * b[t - k];
        double ra = sa, rb = sb;
        for (int64_t t = 0; t < lo; t++)
            ra -= a[t];
        for (int64_t t = hi; t < n; t++)
            ra -= a[t];
        for (int64_t t = 0; t < lo - k; t++)
            rb -= b[t];
        for (int64_t t = hi - k; t < n; t++)
            rb -= b[t];
        out[k - first] = acc - mb * ra - ma * rb + (double)(hi - lo) * ma * mb;
    }
}

}  // extern "C"
