"""Compiled scalar forms of the static nonlinearities, called inside the simulation kernels.

An output nonlinearity ``h`` (Wiener and Hammerstein-Wiener models) acts on
every simulated sample, so the kernels apply it in the same compiled pass as
the linear recursion instead of storing the whole output first.  Each function
here has the signature ``map(z, p, extra) -> float``: ``z`` one sample, ``p``
the parameter vector of one candidate, ``extra`` fixed data of the family
(the breakpoints of a piecewise-linear map, else an empty array).  They agree
with the vectorised :meth:`~hammerstein_ctrl.nonlinearities.Nonlinearity.evaluate`
to rounding; :attr:`~hammerstein_ctrl.nonlinearities.Nonlinearity.compiled_map`
names the function of a family.

Examples
--------
>>> import numpy as np
>>> float(saturation_map(3.0, np.array([2.0, 1.0]), np.empty(0)))
2.0
>>> float(piecewise_linear_map(0.5, np.array([-1.0, 0.0, 2.0]), np.array([-1.0, 0.0, 1.0])))
1.0
"""

from __future__ import annotations

import numpy as np

from ._jit import cached_njit

__all__ = ["tanh_map", "coulomb_map", "polynomial_map", "saturation_map", "deadzone_map",
           "piecewise_linear_map"]


@cached_njit()
def tanh_map(z, p, extra):  # pragma: no cover - compiled
    return p[0] * np.tanh(p[1] * z)


@cached_njit()
def coulomb_map(z, p, extra):  # pragma: no cover - compiled
    s = 1.0 if z > 0.0 else (-1.0 if z < 0.0 else 0.0)
    return p[0] * z + p[1] * s + p[2]


@cached_njit()
def polynomial_map(z, p, extra):  # pragma: no cover - compiled
    acc = 0.0
    for i in range(p.size - 1, -1, -1):
        acc = acc * z + p[i]
    return acc * z


@cached_njit()
def _clip(z, a):  # pragma: no cover - compiled
    """``numpy.clip(z, -a, a)`` for ``a >= 0``: NaN if ``z`` or ``a`` is NaN (``min``/``max`` would drop it)."""
    if np.isnan(z) or np.isnan(a):
        return np.nan
    return min(max(z, -a), a)


@cached_njit()
def saturation_map(z, p, extra):  # pragma: no cover - compiled
    return p[0] * _clip(z, abs(p[1]))


@cached_njit()
def deadzone_map(z, p, extra):  # pragma: no cover - compiled
    return p[0] * (z - _clip(z, abs(p[1])))


@cached_njit()
def piecewise_linear_map(z, p, extra):  # pragma: no cover - compiled
    n = extra.size
    k = 0
    # segment: the last breakpoint <= z, clipped to the first and last segments
    lo, hi = 0, n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if extra[mid] <= z:
            lo = mid
        else:
            hi = mid
    k = min(lo, n - 2)
    w = (z - extra[k]) / (extra[k + 1] - extra[k])
    return p[k] * (1.0 - w) + p[k + 1] * w
