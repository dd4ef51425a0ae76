/* The built-in static maps (maps.hpp) applied to rows of samples, for Python and the tests. */
#include "maps.hpp"

extern "C" int hc_map_rows(int64_t code, const double *z, int64_t n, const double *P, int64_t batch, int64_t m,
                           const double *extra, int64_t nx, double *out)
{
    if (code < 0 || code >= HC_MAP_COUNT || m < map_params(code, nx) || (code == HC_MAP_PIECEWISE_LINEAR && nx < 2) ||
        (code == HC_MAP_POLYNOMIAL && m < 1))
        return 1;
    for (int64_t b = 0; b < batch; b++)
        for (int64_t i = 0; i < n; i++)
            out[b * n + i] = apply_map(code, z[i], P + b * m, m, extra, nx);
    return 0;
}
