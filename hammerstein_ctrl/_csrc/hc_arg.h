/* One argument of a generated kernel built in C (hammerstein_ctrl._kernel_c): an array's first element and its
 * dimensions; an integer argument has data NULL and its value in shape[0], a float data NULL and its bits in
 * shape[0].  A kernel is int64_t kernel(const hc_arg *args) and returns 0, or k if it refused its arguments at its
 * source's k-th raise. */
typedef struct { void *data; int64_t shape[3]; } hc_arg;
typedef int64_t (*hc_kernel)(const hc_arg *args);
