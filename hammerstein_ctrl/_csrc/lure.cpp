/* Exact sampled simulation of a Lur'e loop with friction (hammerstein_ctrl.lure): a linear block, sign friction fed
 * back on one signal.
 *
 *     x' = A x + B w,   y = C x,   z = Cz x            (z: the output, or its derivative)
 *     w  = u - k z - fc sign(z) - c                      (friction on z; fc >= 0)
 *
 * with the input u held between samples (zero-order hold) or linear between them (first-order hold).  Between the
 * instants where z changes sign the loop is linear with a constant friction force, so it is solved exactly: the
 * sampled recursion of the block with k folded into A (one matrix exponential per candidate) and +-fc added to the
 * input.  A sample in which z changes sign is split at the crossing (a bracketed root search on the exact solution,
 * evaluated by its Taylor series); at z = 0 the motion continues in the direction the forces push, or sticks: z stays
 * 0 while the friction force that keeps it there, f_eq, lies within [-fc, fc] (Filippov's sliding solution,
 * x' = A_s x), and slips again where |f_eq| reaches fc.
 *
 * Limits: a sign change of z that starts and ends inside one sample (two crossings between samples) is not seen
 * unless the quadratic estimate of the turn says it may be (then it is located exactly); a sample holds at most
 * MAX_EVENTS switches (the rest of it keeps the last mode).  z must be driven directly by w (Cz B != 0: relative
 * degree 1 from w to z).
 *
 * Time inside a sample is normalised (0 to 1); Adt = A dt, Bdt = B dt.  Sums run left to right in the order written.
 */
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "hc.h"

namespace {

/* Most mode switches resolved within one sample. */
constexpr int MAX_EVENTS = 16;
/* Largest 1-norm of A dt over one Taylor segment (longer intervals are split); most segments, beyond which the
 * matrix exponential. */
constexpr double TAYLOR_NORM = 0.5;
constexpr int64_t TAYLOR_MAX = 4;
/* Iterations of the root search (bracketing; each at least halves the bracket every third step). */
constexpr int ROOT_ITERATIONS = 200;
/* Margin of may_turn over the quadratic estimate of how far z turns back inside a sample. */
constexpr double TURN_MARGIN = 4.0;
/* Largest order of the block. */
constexpr int64_t MAX_N = HC_MAX_ORDER;

/* Python's max(a, b): b only if b > a. */
inline double pymax(double a, double b)
{
    return b > a ? b : a;
}

inline double dot(const double *a, const double *x, int64_t n)
{
    double s = 0.0;
    for (int64_t i = 0; i < n; i++)
        s += a[i] * x[i];
    return s;
}

inline void copy(const double *src, double *dst, int64_t n)
{
    std::memcpy(dst, src, (size_t)n * sizeof(double));
}

/* out = p A (a row vector times the n x n matrix A). */
inline void row_times(const double *p, const double *A, int64_t n, double *out)
{
    for (int64_t j = 0; j < n; j++) {
        double acc = 0.0;
        for (int64_t i = 0; i < n; i++)
            acc += p[i] * A[i * n + j];
        out[j] = acc;
    }
}

/* One candidate's matrices (rows of hc_lure_setup's arrays) and scratch vectors. */
struct Loop {
    int64_t n;
    const double *Adt, *Asdt, *Bdt, *Cz, *q, *Phi, *G0, *G1, *Ps;
    double h;
    double xn[MAX_N], xs[MAX_N], t1[MAX_N], t2[MAX_N], pv[MAX_N];
};

/* out = x(delta) of x' = Adt x + Bdt (w0 + s tau) from x(0) = x by the exponential of the augmented matrix. */
void propagate_expm(const double *Adt, const double *Bdt, int64_t n, const double *x, double w0, double s,
                    double delta, double *out)
{
    int64_t m = n + 2;
    double M[(MAX_N + 2) * (MAX_N + 2)], E[(MAX_N + 2) * (MAX_N + 2)];
    for (int64_t i = 0; i < m * m; i++)
        M[i] = 0.0;
    for (int64_t i = 0; i < n; i++) {
        for (int64_t j = 0; j < n; j++)
            M[i * m + j] = Adt[i * n + j] * delta;
        M[i * m + n] = Bdt[i] * delta;
    }
    M[n * m + n + 1] = 1.0;
    hc_expm(M, m, E);
    for (int64_t i = 0; i < n; i++) {
        double acc = E[i * m + n] * w0 + E[i * m + n + 1] * s * delta;
        for (int64_t j = 0; j < n; j++)
            acc += E[i * m + j] * x[j];
        out[i] = acc;
    }
}

/* out = x(delta) of x' = Adt x + Bdt (w0 + s tau) (normalised time) from x(0) = x: a Taylor series where
 * ||Adt|| delta is small (split into pieces with ||Adt|| piece <= TAYLOR_NORM; each piece's series summed until its
 * terms no longer change the sum); past TAYLOR_MAX pieces (a stiff block or a coarse sample) the exponential.
 * t1, t2: scratch.  out may not be x. */
void propagate(const double *Adt, const double *Bdt, int64_t n, const double *x, double w0, double s, double delta,
               double *out, double *t1, double *t2)
{
    double count = std::ceil(hc_one_norm(Adt, n) * delta / TAYLOR_NORM);
    /* as the conversion of the Python original: a count that is not a number, or past 64 bits, is taken as one */
    int64_t pieces = count >= 1.0 && count < 9.2e18 ? (int64_t)count : 1;
    if (pieces > TAYLOR_MAX) {
        propagate_expm(Adt, Bdt, n, x, w0, s, delta, out);
        return;
    }
    double step = delta / (double)pieces;
    copy(x, out, n);
    double w = w0;
    for (int64_t piece = 0; piece < pieces; piece++) {
        /* t1: the current derivative term d_k step^k / k! */
        for (int64_t i = 0; i < n; i++) {
            double acc = Bdt[i] * w;
            for (int64_t j = 0; j < n; j++)
                acc += Adt[i * n + j] * out[j];
            t1[i] = acc * step;
        }
        for (int64_t i = 0; i < n; i++)
            out[i] += t1[i];
        for (int64_t k = 2; k < 60; k++) {
            bool small = true;
            for (int64_t i = 0; i < n; i++) {
                double acc = k == 2 ? Bdt[i] * s * step : 0.0;
                for (int64_t j = 0; j < n; j++)
                    acc += Adt[i * n + j] * t1[j];
                t2[i] = acc * step / (double)k;
            }
            for (int64_t i = 0; i < n; i++) {
                t1[i] = t2[i];
                double next = out[i] + t1[i];
                if (next != out[i])
                    small = false;
                out[i] = next;
            }
            if (small && k > 2)
                break;
        }
        w += s * step;
    }
}

/* Mode at z = 0: +1 or -1 where the forces move z that way, 0 (stick) where friction holds it; force = u - c at
 * that instant (the friction force that keeps z' = 0 is f_eq = force + q x). */
int decide(const Loop &L, const double *x, double force, double fc)
{
    double feq = force + dot(L.q, x, L.n);
    bool up = L.h * (feq - fc) > 0.0, down = L.h * (feq + fc) < 0.0;
    if (up && down)
        return L.h * feq >= 0.0 ? 1 : -1;
    if (up)
        return 1;
    if (down)
        return -1;
    return 0;
}

/* The mode at the start: the side z is on, or decide's choice on z = 0. */
int first_mode(const Loop &L, const double *x, double force, double fc)
{
    double z = dot(L.Cz, x, L.n);
    return z > 0 ? 1 : (z < 0 ? -1 : decide(L, x, force, fc));
}

/* (g, g') at delta of the event function g = p . x(delta) + offset along x' = Adt x + Bdt (w0 + s tau); the state
 * at delta left in xs. */
void event_value(const double *Adt, const double *Bdt, int64_t n, const double *p, const double *x, double w0,
                 double s, double delta, double offset, double *xs, double *t1, double *t2, double *value,
                 double *slope)
{
    propagate(Adt, Bdt, n, x, w0, s, delta, xs, t1, t2);
    double v = offset, d = 0.0, w = w0 + s * delta;
    for (int64_t i = 0; i < n; i++) {
        v += p[i] * xs[i];
        double acc = Bdt[i] * w;
        for (int64_t j = 0; j < n; j++)
            acc += Adt[i * n + j] * xs[j];
        d += p[i] * acc;
    }
    *value = v;
    *slope = d;
}

/* The instant in (0, hi] where g = p . x(tau) + ramp tau + offset changes sign (g(0) = lo_val, g(hi) = hi_val of
 * opposite signs): Newton's method kept inside the bracket (bisection where a step leaves it).  The state there is
 * left in xs. */
double root(const double *Adt, const double *Bdt, int64_t n, const double *p, const double *x, double w0, double s,
            double ramp, double offset, double lo_val, double hi, double hi_val, double *xs, double *t1, double *t2)
{
    double a = 0.0, fa = lo_val, b = hi;
    double m = lo_val != hi_val ? hi * lo_val / (lo_val - hi_val) : 0.5 * hi;
    for (int it = 0; it < ROOT_ITERATIONS; it++) {
        if (!(a < m && m < b))
            m = 0.5 * (a + b);
        double fm, dm;
        event_value(Adt, Bdt, n, p, x, w0, s, m, offset, xs, t1, t2, &fm, &dm);
        fm += ramp * m;
        dm += ramp;
        if (fm == 0.0)
            return m;
        if ((fm > 0) == (fa > 0)) {
            a = m;
            fa = fm;
        } else {
            b = m;
        }
        double step = dm != 0.0 ? fm / dm : INFINITY;
        if (std::fabs(step) <= 2e-16 * pymax(1.0, m) || b - a <= 4e-16 * pymax(1.0, b))
            return m;
        m = m - step;
    }
    return 0.5 * (a + b);
}

/* tau, with *z, where z has the opposite sign inside a slipping segment whose ends share a sign (it turns back
 * towards zero and away again), or -1: the turning point of z (z' = 0) is located and z read there. */
double slip_dip(Loop &L, const double *x, const double *xn, double w0, double s, double rest, int mode, double *z)
{
    int64_t n = L.n;
    *z = 0.0;
    if (!(dot(L.Cz, x, n) * mode > 0.0))       /* leaving the surface (from sticking): no turn back to look for */
        return -1.0;
    row_times(L.Cz, L.Adt, n, L.pv);           /* z' = pv . x + cb (w0 + s tau) */
    double cb = dot(L.Cz, L.Bdt, n);
    double d0 = dot(L.pv, x, n) + cb * w0, d1 = dot(L.pv, xn, n) + cb * (w0 + s * rest);
    if (!(d0 * mode < 0.0 && 0.0 < d1 * mode))
        return -1.0;
    double turn = root(L.Adt, L.Bdt, n, L.pv, x, w0, s, cb * s, cb * w0, d0, rest, d1, L.xs, L.t1, L.t2);
    propagate(L.Adt, L.Bdt, n, x, w0, s, turn, L.xs, L.t1, L.t2);
    double zt = dot(L.Cz, L.xs, n);
    if (zt * mode < 0.0) {
        *z = zt;
        return turn;
    }
    return -1.0;
}

/* Whether z (slipping, signs taken so that its side is positive: z0 > 0) may reach zero inside a sample whose ends
 * are on its side: it heads back (d0 = z'(0) < 0), turns (d1 = z'(1) > 0), and the depth of the turn,
 * d0^2 / (2 (d1 - d0)) for a quadratic, comes within TURN_MARGIN of z0.  Then slip_dip locates the turn exactly. */
inline bool may_turn(double z0, double d0, double d1)
{
    return d0 < 0.0 && 0.0 < d1 && z0 * (d1 - d0) <= TURN_MARGIN * 0.5 * d0 * d0;
}

/* Where z reaches zero in (0, hi] while slipping in direction mode (z(hi) is on the other side).  From z on the
 * mode's side, the bracketed root.  From the surface itself (z(0) = 0, just after an event, its rounding on either
 * side), the root after z turns back: the turn (z' = 0) is located first, so that the search does not return the
 * start.  xn is overwritten. */
double crossing(Loop &L, const double *x, double w0, double s, double hi, double z_hi, int mode)
{
    int64_t n = L.n;
    double z0 = dot(L.Cz, x, n);
    if (z0 * mode > 0.0)
        return root(L.Adt, L.Bdt, n, L.Cz, x, w0, s, 0.0, 0.0, z0, hi, z_hi, L.xs, L.t1, L.t2);
    row_times(L.Cz, L.Adt, n, L.pv);           /* z' = pv . x + cb (w0 + s tau) */
    double cb = dot(L.Cz, L.Bdt, n);
    double d0 = dot(L.pv, x, n) + cb * w0;
    propagate(L.Adt, L.Bdt, n, x, w0, s, hi, L.xs, L.t1, L.t2);
    double d1 = dot(L.pv, L.xs, n) + cb * (w0 + s * hi);
    if (!(d0 * mode > 0.0 && 0.0 > d1 * mode))
        return 0.0;
    double turn = root(L.Adt, L.Bdt, n, L.pv, x, w0, s, cb * s, cb * w0, d0, hi, d1, L.xs, L.t1, L.t2);
    propagate(L.Adt, L.Bdt, n, x, w0, s, turn, L.xn, L.t1, L.t2);
    double z_turn = dot(L.Cz, L.xn, n);
    if (!(z_turn * mode > 0.0))
        return 0.0;
    return turn + root(L.Adt, L.Bdt, n, L.Cz, L.xn, w0 + s * turn, s, 0.0, 0.0, z_turn, hi - turn, z_hi, L.xs, L.t1,
                       L.t2);
}

/* tau, with *f, where the holding force f passes the Coulomb level inside a sticking segment whose ends are within
 * it (it peaks between them), or -1. */
double stick_peak(Loop &L, const double *x, const double *xn, double f0, double s, double rest, double fc, double *f)
{
    int64_t n = L.n;
    *f = 0.0;
    row_times(L.q, L.Asdt, n, L.pv);           /* f' = s + pv . x  (x' = Asdt x while stuck) */
    double e0 = s + dot(L.pv, x, n), e1 = s + dot(L.pv, xn, n);
    if (!(e0 * e1 < 0.0))
        return -1.0;
    double turn = root(L.Asdt, L.Bdt, n, L.pv, x, 0.0, 0.0, 0.0, s, e0, rest, e1, L.xs, L.t1, L.t2);
    propagate(L.Asdt, L.Bdt, n, x, 0.0, 0.0, turn, L.xs, L.t1, L.t2);
    double ft = f0 + s * turn + dot(L.q, L.xs, n);
    if (std::fabs(ft) > fc) {
        *f = ft;
        return turn;
    }
    return -1.0;
}

/* Advance x (in place) over one sample from mode; the mode at its end.  uk: the input at the sample's start, s its
 * slope over the sample (first-order hold; 0 for zero order), c the constant force, fc the Coulomb level. */
int sample(Loop &L, double *x, int mode, double uk, double s, double c, double fc)
{
    int64_t n = L.n;
    double tau = 0.0;
    for (int event = 0; event < MAX_EVENTS + 1; event++) {
        double rest = 1.0 - tau;
        if (mode != 0) {
            double w0 = uk + s * tau - c - mode * fc;
            if (tau == 0.0) {
                for (int64_t i = 0; i < n; i++) {
                    double acc = L.G0[i] * w0 + L.G1[i] * s;
                    for (int64_t j = 0; j < n; j++)
                        acc += L.Phi[i * n + j] * x[j];
                    L.xn[i] = acc;
                }
            } else {
                propagate(L.Adt, L.Bdt, n, x, w0, s, rest, L.xn, L.t1, L.t2);
            }
            double hi = rest, z1 = dot(L.Cz, L.xn, n);
            if (z1 * mode >= 0.0) {
                hi = slip_dip(L, x, L.xn, w0, s, rest, mode, &z1);
                if (hi < 0.0) {
                    copy(L.xn, x, n);
                    return mode;
                }
            }
            double d = crossing(L, x, w0, s, hi, z1, mode);
            propagate(L.Adt, L.Bdt, n, x, w0, s, d, L.xs, L.t1, L.t2);
            copy(L.xs, x, n);
            tau += d;
            mode = decide(L, x, uk + s * tau - c, fc);
            if (mode == 0) {                    /* on z = 0 exactly (the root search leaves ~1e-19) */
                double z = dot(L.Cz, x, n) / L.h;
                for (int64_t i = 0; i < n; i++)
                    x[i] -= L.Bdt[0] != 0.0 ? L.Bdt[i] / L.Bdt[0] * z : 0.0;
            }
        } else {
            double f0 = uk + s * tau - c;
            double now = f0 + dot(L.q, x, n);
            if (std::fabs(now) > fc) {          /* the input stepped past the friction: slips at once */
                mode = now * L.h > 0 ? 1 : -1;
                continue;
            }
            if (tau == 0.0) {
                for (int64_t i = 0; i < n; i++) {
                    double acc = 0.0;
                    for (int64_t j = 0; j < n; j++)
                        acc += L.Ps[i * n + j] * x[j];
                    L.xn[i] = acc;
                }
            } else {
                propagate(L.Asdt, L.Bdt, n, x, 0.0, 0.0, rest, L.xn, L.t1, L.t2);
            }
            double hi = rest, f1 = f0 + s * rest + dot(L.q, L.xn, n);
            if (std::fabs(f1) <= fc) {
                hi = stick_peak(L, x, L.xn, f0, s, rest, fc, &f1);
                if (hi < 0.0) {
                    copy(L.xn, x, n);
                    return 0;
                }
            }
            double sign = f1 > 0 ? 1.0 : -1.0;
            double lo_val = f0 + dot(L.q, x, n) - sign * fc;
            double d = root(L.Asdt, L.Bdt, n, L.q, x, 0.0, 0.0, s, f0 - sign * fc, lo_val, hi, f1 - sign * fc, L.xs,
                            L.t1, L.t2);
            propagate(L.Asdt, L.Bdt, n, x, 0.0, 0.0, d, L.xs, L.t1, L.t2);
            copy(L.xs, x, n);
            tau += d;
            mode = sign * L.h > 0 ? 1 : -1;
        }
        if (tau >= 1.0)
            return mode;
    }
    /* too many switches: finish the sample in the last mode without further checks */
    double start[MAX_N];
    copy(x, start, n);
    if (mode != 0)
        propagate(L.Adt, L.Bdt, n, start, uk + s * tau - c - mode * fc, s, pymax(0.0, 1.0 - tau), x, L.t1, L.t2);
    else
        propagate(L.Asdt, L.Bdt, n, start, 0.0, 0.0, pymax(0.0, 1.0 - tau), x, L.t1, L.t2);
    return mode;
}

/* Sample k's output yk: stored (want_outputs), or its squared error against y[k] added to sse. */
inline void record(double yk, int64_t k, const double *y, double *outb, bool want_outputs, double &sse)
{
    if (want_outputs) {
        outb[k] = yk;
    } else {
        double e = yk - y[k];
        sse += e * e;
    }
}

/* One candidate over the record (any order): its outputs into outb, or its SSE returned. */
double samples(Loop &L, const double *Cb, double *x, int mode, double cb, double fcb, double y0, const double *u,
               int64_t N, const double *y, double *outb, bool want_outputs, bool foh)
{
    int64_t n = L.n;
    double pz[MAX_N];                          /* z' = pz . x + cz w (a turn of z inside a sample: the full check) */
    row_times(L.Cz, L.Adt, n, pz);
    double cz = dot(L.Cz, L.Bdt, n), sse = 0.0;
    for (int64_t k = 0; k < N; k++) {
        double yk = y0;
        for (int64_t i = 0; i < n; i++)
            yk += Cb[i] * x[i];
        record(yk, k, y, outb, want_outputs, sse);
        if (k + 1 == N)
            break;
        double s = foh ? u[k + 1] - u[k] : 0.0;
        if (mode != 0) {                        /* the common case: a whole sample slipping one way */
            double w0 = u[k] - cb - mode * fcb, z1 = 0.0;
            for (int64_t i = 0; i < n; i++) {
                double acc = L.G0[i] * w0 + L.G1[i] * s;
                for (int64_t j = 0; j < n; j++)
                    acc += L.Phi[i * n + j] * x[j];
                L.xn[i] = acc;
                z1 += L.Cz[i] * acc;
            }
            if (z1 * mode >= 0.0 && !may_turn(dot(L.Cz, x, n) * mode, (dot(pz, x, n) + cz * w0) * mode,
                                              (dot(pz, L.xn, n) + cz * (w0 + s)) * mode)) {
                copy(L.xn, x, n);
                continue;
            }
        }
        mode = sample(L, x, mode, u[k], s, cb, fcb);
    }
    return sse;
}

/* samples for two states (a mass: the common case), the state in registers between switches. */
double samples_two(Loop &L, const double *Cb, double *x, int mode, double cb, double fcb, double y0, const double *u,
                   int64_t N, const double *y, double *outb, bool want_outputs, bool foh)
{
    const double *Phi = L.Phi, *A = L.Adt;
    double p00 = Phi[0], p01 = Phi[1], p10 = Phi[2], p11 = Phi[3];
    double g0 = L.G0[0], g1 = L.G0[1], r0 = L.G1[0], r1 = L.G1[1];
    double c0 = Cb[0], c1 = Cb[1], z0 = L.Cz[0], z1 = L.Cz[1];
    double x0 = x[0], x1 = x[1];
    double pz0 = z0 * A[0] + z1 * A[2];        /* z' = pz . x + cz w (a turn of z inside a sample: the full check) */
    double pz1 = z0 * A[1] + z1 * A[3];
    double cz = z0 * L.Bdt[0] + z1 * L.Bdt[1];
    double sse = 0.0, side = (double)mode;
    double shift = cb + side * fcb;            /* the input's constant part while slipping: c + fc sign(z) */
    for (int64_t k = 0; k < N; k++) {
        record(y0 + c0 * x0 + c1 * x1, k, y, outb, want_outputs, sse);
        if (k + 1 == N)
            break;
        double s = foh ? u[k + 1] - u[k] : 0.0;
        if (mode != 0) {
            double w0 = u[k] - shift;
            double n0 = p00 * x0 + p01 * x1 + g0 * w0 + r0 * s;
            double n1 = p10 * x0 + p11 * x1 + g1 * w0 + r1 * s;
            if ((z0 * n0 + z1 * n1) * side >= 0.0 &&
                !may_turn((z0 * x0 + z1 * x1) * side, (pz0 * x0 + pz1 * x1 + cz * w0) * side,
                          (pz0 * n0 + pz1 * n1 + cz * (w0 + s)) * side)) {
                x0 = n0;
                x1 = n1;
                continue;
            }
        }
        x[0] = x0;
        x[1] = x1;
        mode = sample(L, x, mode, u[k], s, cb, fcb);
        x0 = x[0];
        x1 = x[1];
        side = (double)mode;
        shift = cb + side * fcb;
    }
    return sse;
}

/* Candidate b's rows of hc_lure_setup's arrays. */
Loop loop_of(const double *Adt, const double *Asdt, const double *Bdt, const double *Cz, const double *h,
             const double *Q, const double *Phi, const double *G0, const double *G1, const double *Ps, int64_t b,
             int64_t n)
{
    Loop L;
    L.n = n;
    L.Adt = Adt + b * n * n;
    L.Asdt = Asdt + b * n * n;
    L.Bdt = Bdt + b * n;
    L.Cz = Cz + b * n;
    L.q = Q + b * n;
    L.Phi = Phi + b * n * n;
    L.G0 = G0 + b * n;
    L.G1 = G1 + b * n;
    L.Ps = Ps + b * n * n;
    L.h = h[b];
    return L;
}

/* One candidate's matrices from its realisation M (dt = 1: [[A, B, 0], [0, 0, 1], [0, 0, 0]]), C, D. */
void setup_row(const double *M, const double *Crow, double D, double dt, double slope, int64_t feedback, int64_t n,
               double *Adt, double *Asdt, double *Bdt, double *Cz, double *h, double *q, double *Phi, double *G0,
               double *G1, double *Ps, bool *ok)
{
    int64_t m = n + 2;
    double A[MAX_N * MAX_N], B[MAX_N], Ae[MAX_N * MAX_N];
    for (int64_t i = 0; i < n; i++) {
        for (int64_t j = 0; j < n; j++)
            A[i * n + j] = M[i * m + j];
        B[i] = M[i * m + n];
    }
    bool good = std::isfinite(slope) && D == 0.0;
    for (int64_t i = 0; i < n; i++) {
        good = good && std::isfinite(Crow[i]) && std::isfinite(B[i]);
        for (int64_t j = 0; j < n; j++)
            good = good && std::isfinite(A[i * n + j]);
    }
    if (feedback == 0)
        copy(Crow, Cz, n);
    else
        row_times(Crow, A, n, Cz);
    double hb = 0.0;
    for (int64_t i = 0; i < n; i++)
        hb += Cz[i] * B[i];
    *h = hb;
    if (!good || hb == 0.0 || !std::isfinite(hb)) {
        *ok = false;
        return;
    }
    copy(A, Ae, n * n);
    for (int64_t i = 0; i < n; i++)
        for (int64_t j = 0; j < n; j++)
            Ae[i * n + j] -= slope * B[i] * Cz[j];
    for (int64_t j = 0; j < n; j++) {          /* q = Cz Ae / h */
        double acc = 0.0;
        for (int64_t i = 0; i < n; i++)
            acc += Cz[i] * Ae[i * n + j];
        q[j] = acc / hb;
    }
    for (int64_t i = 0; i < n; i++) {
        Bdt[i] = B[i] * dt;
        for (int64_t j = 0; j < n; j++) {
            Adt[i * n + j] = Ae[i * n + j] * dt;
            Asdt[i * n + j] = (Ae[i * n + j] - B[i] * q[j]) * dt;
        }
    }
    double aug[(MAX_N + 2) * (MAX_N + 2)], E[(MAX_N + 2) * (MAX_N + 2)], Es[MAX_N * MAX_N];
    for (int64_t i = 0; i < m * m; i++)
        aug[i] = 0.0;
    for (int64_t i = 0; i < n; i++) {
        for (int64_t j = 0; j < n; j++)
            aug[i * m + j] = Adt[i * n + j];
        aug[i * m + n] = Bdt[i];
    }
    aug[n * m + n + 1] = 1.0;
    hc_expm(aug, m, E);
    hc_expm(Asdt, n, Es);
    bool finite = true;
    for (int64_t i = 0; i < n; i++) {
        for (int64_t j = 0; j < n; j++) {
            Phi[i * n + j] = E[i * m + j];
            Ps[i * n + j] = Es[i * n + j];
            finite = finite && std::isfinite(Phi[i * n + j]) && std::isfinite(Ps[i * n + j]);
        }
        G0[i] = E[i * m + n];
        G1[i] = E[i * m + n + 1];
    }
    *ok = finite;
}

}  // namespace

extern "C" {

/* Per-candidate matrices of the loops num/den (batch rows, nden = n + 1 <= HC_MAX_ORDER + 1 coefficients, nnum <=
 * nden), friction slopes k (slope) and feedback 0 (the output) or 1 (its derivative): Adt = (A - k B Cz) dt (the
 * slipping loop), Asdt = A_s dt (sticking: A_s = Ae - B Q), Bdt = B dt, C, Cz, h = Cz B, Q = Cz Ae / h (the holding
 * force is u - c + Q x); Phi, G0, G1 the exact first-order-hold step of the slipping loop, Ps = expm(A_s dt).  Every
 * array holds batch rows (n x n matrices, n vectors, or one value), zeroed first.  ok is false for a candidate with
 * non-finite coefficients or h == 0.  Returns 0, or 1 if n is out of range or no memory could be had. */
int hc_lure_setup(const double *num, int64_t nnum, const double *den, int64_t nden, int64_t batch, double dt,
                  const double *slope, int64_t feedback, double *Adt, double *Asdt, double *Bdt, double *C, double *Cz,
                  double *h, double *Q, double *Phi, double *G0, double *G1, double *Ps, bool *ok)
{
    int64_t n = nden - 1, m = n + 2;
    if (n < 1 || n > MAX_N || nnum < 1 || nnum > nden)
        return 1;
    size_t rows = (size_t)(batch > 0 ? batch : 1);
    double *M = (double *)std::malloc(rows * (size_t)(m * m + 1) * sizeof(double));
    if (M == nullptr)
        return 1;
    double *D = M + rows * (size_t)(m * m);
    hc_tf_augmented(num, den, batch, nnum, nden, 1.0, M, C, D);
    for (int64_t b = 0; b < batch; b++) {
        int64_t nn = b * n * n, nv = b * n;
        for (int64_t i = 0; i < n * n; i++)
            Adt[nn + i] = Asdt[nn + i] = Phi[nn + i] = Ps[nn + i] = 0.0;
        for (int64_t i = 0; i < n; i++)
            Bdt[nv + i] = Cz[nv + i] = Q[nv + i] = G0[nv + i] = G1[nv + i] = 0.0;
        h[b] = 0.0;
        ok[b] = true;
        setup_row(M + b * m * m, C + nv, D[b], dt, slope[b], feedback, n, Adt + nn, Asdt + nn, Bdt + nv, Cz + nv,
                  h + b, Q + nv, Phi + nn, G0 + nv, G1 + nv, Ps + nn, ok + b);
    }
    std::free(M);
    return 0;
}

/* Simulate every candidate (hc_lure_setup's rows, batch of them, order n) over u (N samples; foh: its hold):
 * outputs into out[b] (want_outputs; out batch x N) or the SSE against y into out[b] (out batch x 1); inf for a
 * candidate that is not ok or overflows.  fc, c: the friction levels and constant inputs; X0 (batch x n), Y0: the
 * initial states and output offsets. */
void hc_lure_run(const double *Adt, const double *Asdt, const double *Bdt, const double *C, const double *Cz,
                 const double *h, const double *Q, const double *Phi, const double *G0, const double *G1,
                 const double *Ps, const bool *ok, int64_t batch, int64_t n, const double *fc, const double *c,
                 const double *X0, const double *Y0, const double *u, int64_t N, int64_t foh, const double *y,
                 double *out, int64_t want_outputs)
{
    int64_t width = want_outputs ? N : 1;
    double x[MAX_N];
    for (int64_t b = 0; b < batch; b++) {
        double *outb = out + b * width;
        if (!ok[b] || n < 1 || n > MAX_N || N < 1) {
            for (int64_t k = 0; k < width; k++)
                outb[k] = INFINITY;
            continue;
        }
        Loop L = loop_of(Adt, Asdt, Bdt, Cz, h, Q, Phi, G0, G1, Ps, b, n);
        double cb = c[b], fcb = std::fabs(fc[b]);
        copy(X0 + b * n, x, n);
        int mode = first_mode(L, x, u[0] - cb, fcb);
        double sse = n == 2 ? samples_two(L, C + b * n, x, mode, cb, fcb, Y0[b], u, N, y, outb, want_outputs, foh)
                            : samples(L, C + b * n, x, mode, cb, fcb, Y0[b], u, N, y, outb, want_outputs, foh);
        if (!want_outputs)
            outb[0] = std::isfinite(sse) && sse < 1.7e308 ? sse : INFINITY;
    }
}

/* Every candidate inside a known sampled controller (Ac nc x nc, Bc nc x 2, Cc nc, Dc 2) from its state xc0, with
 * reference r and added input d (N samples): outputs Y[b] and control signals U[b] (batch x N).  At sample k:
 * y_k = C x_k + y0; u_k = Cc xc_k + Dc [r_k, y_k] + d_k; xc_{k+1} = Ac xc_k + Bc [r_k, y_k]; the plant holds u_k
 * over the sample (a DAC: zero-order hold).  A candidate that is not ok gets inf everywhere.  Returns 0, or 1 if
 * no memory could be had for the controller's state (nothing written). */
int hc_lure_loop_run(const double *Adt, const double *Asdt, const double *Bdt, const double *C, const double *Cz,
                     const double *h, const double *Q, const double *Phi, const double *G0, const double *G1,
                     const double *Ps, const bool *ok, int64_t batch, int64_t n, const double *fc, const double *c,
                     const double *X0, const double *Y0, const double *Ac, const double *Bc, const double *Cc,
                     const double *Dc, int64_t nc, const double *xc0, const double *r, const double *d, int64_t N,
                     double *Y, double *U)
{
    double x[MAX_N];
    double *xc = (double *)std::malloc((size_t)(2 * nc + 1) * sizeof(double)), *xcn = xc + nc;
    if (xc == nullptr)
        return 1;
    for (int64_t b = 0; b < batch; b++) {
        double *Yb = Y + b * N, *Ub = U + b * N;
        if (!ok[b] || n < 1 || n > MAX_N) {
            for (int64_t k = 0; k < N; k++)
                Yb[k] = Ub[k] = INFINITY;
            continue;
        }
        Loop L = loop_of(Adt, Asdt, Bdt, Cz, h, Q, Phi, G0, G1, Ps, b, n);
        double cb = c[b], fcb = std::fabs(fc[b]);
        copy(X0 + b * n, x, n);
        copy(xc0, xc, nc);
        int mode = 2;                           /* decided at the first sample, once u_0 is known */
        for (int64_t k = 0; k < N; k++) {
            double yk = Y0[b] + dot(C + b * n, x, n);
            double uk = Dc[0] * r[k] + Dc[1] * yk + d[k] + dot(Cc, xc, nc);
            Yb[k] = yk;
            Ub[k] = uk;
            for (int64_t i = 0; i < nc; i++) {
                double acc = Bc[i * 2] * r[k] + Bc[i * 2 + 1] * yk;
                for (int64_t j = 0; j < nc; j++)
                    acc += Ac[i * nc + j] * xc[j];
                xcn[i] = acc;
            }
            copy(xcn, xc, nc);
            if (mode == 2)
                mode = first_mode(L, x, uk - cb, fcb);
            if (k + 1 < N)
                mode = sample(L, x, mode, uk, 0.0, cb, fcb);
        }
    }
    std::free(xc);
    return 0;
}

}  // extern "C"
