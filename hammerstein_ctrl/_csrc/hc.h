/* The compiled core of hammerstein_ctrl (the extension module hammerstein_ctrl._core): the declarations every C and
 * C++ source of it shares.
 *
 * The core is built once, when the package is installed (meson-python), and shipped in the platform wheels: nothing
 * is compiled when the package runs.  Its arithmetic is the source's: every file is compiled without fast-math and
 * without contraction into fused multiply-adds (meson.build), so a result does not depend on the compiler's
 * optimisation level or on the instruction set the code was built for.
 *
 * Two kinds of functions cross into Python:
 *   - the library functions (hc_*, declared below), whose Python wrappers are generated at build time from these
 *     prototypes (generate_wrappers.py): each array argument is checked to be C-ordered, of the C type and, where
 *     the function writes it, writeable;
 *   - the kernels, int64_t kernel(const hc_arg *args), found by their number in the kernel table
 *     (hc_kernel_number) and run by the module's call(number, spec, *args), which checks every array against a
 *     description of its shapes first.  A kernel returns 0, or k > 0 if it refused its arguments (the caller knows
 *     the k-th message).  The library's own C calls kernels directly (the Levenberg-Marquardt loop, the single
 *     evaluation from coefficients).
 */
#ifndef HC_H
#define HC_H

#include <stdint.h>
#ifndef __cplusplus
#include <stdbool.h>
#endif

/* No contraction into fused multiply-adds in any file that includes this header: MSVC before VS 2022 contracted
 * under /fp:precise where AVX2 was allowed (gcc and clang get -ffp-contract=off from meson.build). */
#if defined(_MSC_VER) && !defined(__clang__)
#pragma fp_contract(off)
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* An integer argument that may be negative (a code, a lag); an int64_t argument is a size, a count or a flag, which
 * the Python wrappers refuse below zero. */
typedef int64_t hc_signed;

/* One argument of a kernel: an array's first element and its dimensions; an integer argument has data NULL and its
 * value in shape[0], a float data NULL and its bits in shape[0]. */
typedef struct {
    void *data;
    int64_t shape[3];
} hc_arg;
typedef int64_t (*hc_kernel)(const hc_arg *args);

/* The kernel families of the table (hc_kernel_number). */
enum hc_family {
    HC_SINGLE = 0,   /* candidates one to three at a time, the state in registers: "sse" or "outputs" */
    HC_LANES = 1,    /* candidates side by side across vector lanes: sums of squares */
    HC_NORMAL = 2,   /* a point and its forward-difference neighbours: normal-equation sums, or the lanes' outputs */
    HC_COEFFICIENT = 3, /* the discretisation of transfer-function rows, then an HC_SINGLE "sse" kernel with a basis */
    HC_ANY_ORDER = 4,   /* a state-space model of any order, one candidate at a time (n = E.shape[1] - 2) */
};
/* Highest order (state dimension) the kernels are built for; the lanes kernels' highest. */
#define HC_MAX_ORDER 10
#define HC_LANES_MAX_ORDER 8
/* Most basis signals of a kernel that forms each candidate's signal from a basis. */
#define HC_MAX_BASIS 8
/* Most lanes (a point and its neighbours) of a normal-equation pass. */
#define HC_MAX_LANES 16

/* The kernel of a family for the given order n, hold (0 first order, 1 zero order) and options: for HC_SINGLE,
 * option bit 0 "sse" (else outputs), bit 1 a basis (else the signals themselves), bit 2 an output map; for HC_LANES,
 * bit 0 a direct term, bit 1 an offset; for HC_NORMAL, bit 0 a direct term, bit 1 an offset, bit 2 an output map,
 * bit 3 the lanes' outputs (else the sums); HC_COEFFICIENT takes none; HC_ANY_ORDER (n is ignored) bit 0 "sse".  Its number in the table (>= 0), or -1 if
 * there is none; hc_kernel_at gives the function of a number (NULL if out of range). */
int64_t hc_kernel_number(int64_t family, int64_t n, int64_t hold, int64_t options);
hc_kernel hc_kernel_at(int64_t number);
/* Fills the kernel table (the module's initialisation, once, before any kernel runs). */
void hc_core_init(void);
/* The instruction set the vector kernels run with on this processor ("avx2" or "baseline"). */
const char *hc_vector_isa(void);

/* The built-in static maps (hammerstein_ctrl.nonlinearities), by code, as the kernels apply them: */
enum hc_map {
    HC_MAP_TANH = 0,
    HC_MAP_COULOMB = 1,
    HC_MAP_POLYNOMIAL = 2,
    HC_MAP_SATURATION = 3,
    HC_MAP_DEADZONE = 4,
    HC_MAP_PIECEWISE_LINEAR = 5,
    HC_MAP_SIGMOID = 6,
    HC_MAP_FRICTION = 7,
    HC_MAP_COUNT = 8,
};
/* out[b, i] = map(z[i]; P[b]) for every row b of P (batch x m) and sample i (n of them); extra: the map's fixed
 * data (the breakpoints of the piecewise-linear map).  Returns 0, or 1 for an unknown code. */
int hc_map_rows(int64_t code, const double *z, int64_t n, const double *P, int64_t batch, int64_t m,
                const double *extra, int64_t nx, double *out);

/* ---- linalg.c: small dense linear algebra ---- */
double hc_one_norm(const double *M, int64_t n);
void hc_solve_in_place(double *A, int64_t n, double *B, int64_t m);
void hc_expm(const double *M, int64_t n, double *out);
void hc_tf_augmented(const double *num, const double *den, int64_t batch, int64_t nnum, int64_t nden, double dt,
                     double *M, double *C, double *D);
bool hc_tf_discrete(const double *num, const double *den, int64_t batch, int64_t nnum, int64_t nden, double dt,
                    double max_norm, double *E, double *C, double *D, bool *ok, bool *big);
void hc_symmetric_eigenvalues(double *A, int64_t n, double *w);
void hc_fill_coefficients(const double *theta, int64_t batch, int64_t stride, const double *num0, int64_t nnum,
                          const double *den0, int64_t nden, const int64_t *num_pos, int64_t k, const int64_t *den_pos,
                          int64_t kd, double *num, double *den);
double hc_triangular_inverse_norm(const double *T, int64_t n);

/* ---- normal.c: forward-difference steps and the normal equations of a pass's sums ---- */
void hc_forward_steps(const double *x, int64_t n, const double *upper, int64_t nu, const double *lower, int64_t nl,
                      double rel_step, double *h);
bool hc_usable_steps(const double *h, int64_t n);
void hc_neighbours(const double *x, int64_t n, const double *steps, double *X);
void hc_divide_by_steps(const double *sums, const double *steps, int64_t p, double *gradient, double *gram);
void hc_neighbour_values(double fun, const double *gradient, const double *gram, const double *steps, int64_t p,
                         double *values);
bool hc_finite_sums(double fun, const double *gradient, const double *gram, int64_t p);

/* ---- lm.c: one Levenberg-Marquardt iteration's linear algebra ---- */
double hc_lm_cosine(const double *gram, const double *gradient, int64_t p, double fun);
void hc_lm_step_measures(const double *gram, const double *gradient, const double *scale, const double *delta,
                         const double *x, int64_t p, double xtol, double *out);
void hc_lm_norms(const double *gram, int64_t p, const double *floor, double *norms);
void hc_lm_iteration(const double *gram, const double *gradient, int64_t p, double fun, const double *scale,
                     double lam, const double *x, int64_t check, double limit, double xtol, double *work,
                     double *delta, double *out);
double hc_lm_lowered_damping(double lam, double rho, double limit);
int hc_lm_accepted_code(double actual, double predicted, double f_old, double ftol, int64_t small);

/* ---- lm_loop.c: Levenberg-Marquardt's loop around the normal-equation pass ---- */
int hc_lm_loop(int64_t kernel, double *x, int64_t p, double *state, double *gradient, double *gram, double *steps,
               double *scale, int64_t *counts, const double *settings, int64_t start, const double *num0, int64_t nnum,
               const double *den0, int64_t nden, const int64_t *num_pos, int64_t k, const int64_t *den_pos,
               int64_t kd, int64_t has_g, int64_t direct, const double *Phi, int64_t K, int64_t N, const double *y,
               double *log_x, double *log_steps, double *log_values);

/* ---- minpack.c: MINPACK's loops over a residual vector ---- */
void hc_reflect(const double *v, double *w, int64_t n);
double hc_enorm(const double *x, int64_t n, double rdwarf, double rgiant);

/* ---- signal.c: loops over a record's samples ---- */
void hc_qr_rows(double *A, int64_t w, int64_t n, double *R);
void hc_combine(const double *P, int64_t batch, int64_t p, const double *basis, int64_t n, double *out,
                int64_t columns, int64_t start);
int hc_backward_filter(const double *rows, int64_t q, int64_t n, const double *ar, int64_t order, double *out,
                       int64_t columns, int64_t first);
int hc_backward_filter_single(const double *rows, int64_t q, int64_t n, const double *ar, int64_t order,
                              float *out, int64_t columns, int64_t first);

/* ---- lure.cpp: Lur'e loops with sign friction, simulated exactly ---- */
int hc_lure_setup(const double *num, int64_t nnum, const double *den, int64_t nden, int64_t batch, double dt,
                  const double *slope, int64_t feedback, double *Adt, double *Asdt, double *Bdt, double *C, double *Cz,
                  double *h, double *Q, double *Phi, double *G0, double *G1, double *Ps, bool *ok);
void hc_lure_run(const double *Adt, const double *Asdt, const double *Bdt, const double *C, const double *Cz,
                 const double *h, const double *Q, const double *Phi, const double *G0, const double *G1,
                 const double *Ps, const bool *ok, int64_t batch, int64_t n, const double *fc, const double *c,
                 const double *X0, const double *Y0, const double *u, int64_t N, int64_t foh, const double *y,
                 double *out, int64_t want_outputs);
int hc_lure_loop_run(const double *Adt, const double *Asdt, const double *Bdt, const double *C, const double *Cz,
                     const double *h, const double *Q, const double *Phi, const double *G0, const double *G1,
                     const double *Ps, const bool *ok, int64_t batch, int64_t n, const double *fc, const double *c,
                     const double *X0, const double *Y0, const double *Ac, const double *Bc, const double *Cc,
                     const double *Dc, int64_t nc, const double *xc0, const double *r, const double *d, int64_t N,
                     double *Y, double *U);

/* ---- loops.cpp: the PID and controller loops, the dead-time recursion, lagged cross-products ---- */
int hc_pid_loops(const double *Ad, const double *Bd, const double *C, const double *x0, int64_t n, double offset,
                 hc_signed code, const double *p, int64_t m, const double *bp, int64_t nbp, hc_signed hcode,
                 const double *hp, int64_t hm, const double *hbp, int64_t nhbp, const double *G, int64_t batch,
                 const double *r, int64_t N, double dt, double lo, double hi, double bias, double bound, double *Y,
                 double *U);
int hc_controller_loop(const double *Ad, const double *Bd, const double *C, const double *x0, int64_t n,
                       double offset, hc_signed code, const double *p, int64_t m, const double *bp, int64_t nbp,
                       hc_signed hcode, const double *hp, int64_t hm, const double *hbp, int64_t nhbp,
                       const double *Ac, const double *Bc, const double *Cc, double Dc, int64_t nc, const double *r,
                       int64_t N, double lo, double hi, double bias, double bound, double *Y, double *U);
/* ---- lure_map.cpp: Lur'e loops with a built-in map of any kind in the feedback ----
 * Rows b of a batch: the substep recursion Ad (n x n), B0, B1 of A - slope B Cz at dt/sub, C, Cz (n), the map's
 * code, parameters P (m per row) and fixed data extra (nx), its slope at 0, the offset y0 and the initial state X0;
 * writes out (batch x N), NaN rows for loops that could not be simulated.  Returns 0, or 1 for bad sizes. */
int hc_lure_map_run(const double *Ad, const double *B0, const double *B1, const double *C, const double *Cz,
                    int64_t batch, int64_t n, int64_t code, const double *P, int64_t m, const double *extra,
                    int64_t nx, const double *slope, const double *y0, const double *X0, const double *u, int64_t N,
                    int64_t sub, int64_t zoh, double *out);

int hc_known_loop(const double *Ad, const double *Bd, const double *C, const double *x0, int64_t n, double offset,
                  hc_signed code, const double *p, int64_t m, const double *bp, int64_t nbp, hc_signed hcode,
                  const double *hp, int64_t hm, const double *hbp, int64_t nhbp, const double *Ac, const double *Bc,
                  const double *Cc, const double *Dc, int64_t nc, const double *xc0, const double *r, const double *d,
                  int64_t N, double bound, double *Y, double *U);
int hc_delayed_recursion(const double *M, const double *Pa, const double *Pb, const double *Pc, const double *C,
                         double D, int64_t n, const double *x0, const double *w0, const double *w1, int64_t N,
                         double *out);
void hc_lagged_sums(const double *a, const double *b, int64_t n, hc_signed first, hc_signed last, double *out);

#ifdef __cplusplus
}
#endif

#endif
