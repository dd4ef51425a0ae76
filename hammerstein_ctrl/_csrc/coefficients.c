/* A single evaluation from the transfer functions' coefficients, part of the compiled core
 * (hammerstein_ctrl._native): the exact discretisation, then a generated "sse" kernel with a basis signal
 * (hammerstein_ctrl.kernels.get_coefficient_kernel), in one call from Python through the library's call.
 */
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "_native_kernel.h"

bool hc_tf_discrete(const double *num, const double *den, int64_t batch, int64_t nnum, int64_t nden, double dt,
                    double max_norm, double *E, double *C, double *D, bool *ok, bool *big);

/* args: the kernel's address (an integer), num (B, l + 1), den (B, n + 1), dt and max_norm (floats, their bits in
 * shape[0]), then the kernel's X0, Y0, P, Phi, y, out.  Returns 0 after the kernel ran; 1 where a row is not
 * usable or its exponential needs more than the compiled Pade (out untouched); 2 if num has more coefficients
 * than den (an improper block); 3 if no memory could be had; else the kernel's own refusal plus 3. */
int64_t hc_coefficient_pass(const hc_arg *args)
{
    hc_kernel kernel = (hc_kernel)(intptr_t)args[0].shape[0];
    const double *num = args[1].data, *den = args[2].data;
    int64_t batch = args[1].shape[0], nnum = args[1].shape[1], nden = args[2].shape[1], n = nden - 1, m = nden + 1;
    double dt, max_norm;
    memcpy(&dt, &args[3].shape[0], sizeof dt);
    memcpy(&max_norm, &args[4].shape[0], sizeof max_norm);
    if (nnum > nden || n < 1)
        return 2;
    size_t rows = (size_t)(batch > 0 ? batch : 1);
    double *E = malloc(rows * (size_t)(m * m + n + 1) * sizeof(double));
    bool *flags = malloc(2 * rows * sizeof(bool));
    int64_t status = 3;
    if (E != NULL && flags != NULL) {
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
