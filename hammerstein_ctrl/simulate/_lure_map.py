"""Sampled simulation of a Lur'e loop with any static map fed back (smooth or piecewise smooth).

The loop (:mod:`~hammerstein_ctrl.blocks`) is

.. code-block:: text

    x' = A x + B w,   y = C x + y0,   z = Cz x      (z: the output or one of its derivatives)
    w  = u - g(z)

The map's slope at zero, ``s = g'(0)``, is moved into the linear part
(``A - s B Cz``), which is simulated exactly; only the rest
``r(z) = g(z) - s z`` is approximated, taken as linear between the instants at
which it is computed: ``substeps`` per sample, the input between them by its
own hold (exact).  Each step is the exact first-order-hold recursion of the
linear part with the implicit end value of ``r``: one scalar equation
``z + beta r(z) = a``, solved by the secant method (Newton's inside a bracket
where that does not settle).  A map with
no rest (an affine one) is therefore simulated exactly; the error of the rest's
approximation falls with the square of the substeps.  The loop is C in the
compiled core (``lure_map.cpp``) for the built-in families; a custom map runs
the same steps in Python (:func:`python_run`), one sample at a time.

Examples
--------
>>> import numpy as np
>>> from hammerstein_ctrl.blocks import Polynomial
>>> p = loop_setup(np.array([[1.0]]), np.array([[1.0, 2.0, 1.0]]), 0.05, 1, Polynomial(3),
...                np.array([[0.0, 0.0, 0.5]]), 0)
>>> y = run(Polynomial(3), p, np.array([[0.0, 0.0, 0.5]]), np.zeros(1), np.zeros((1, 2)), np.ones(400), False)
>>> round(float(y[0, -1]), 3)            # at rest: y + 0.5 y^3 = 1
0.771
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import _core
from ._discretize import companion_realization, discretize
from .._kernels import MAP_CODES

__all__ = ["MapLoop", "loop_setup", "run", "python_run", "map_slope", "SLOPE_STEP"]

#: Half-width of the central difference that gives a map's slope at zero.
SLOPE_STEP = 1e-6


class MapLoop(NamedTuple):
    """Per-candidate arrays of the substep recursion (rows: candidates)."""

    Ad: np.ndarray
    B0: np.ndarray
    B1: np.ndarray
    C: np.ndarray
    Cz: np.ndarray
    slope: np.ndarray
    substeps: int


def map_slope(nonlinearity, P) -> np.ndarray:
    """``g'(0)`` of each row of parameters ``P`` by a central difference (0 where it is not finite)."""
    P = np.atleast_2d(P)
    with np.errstate(all="ignore"):
        plus = np.array([nonlinearity(np.array([SLOPE_STEP]), p)[0] for p in P])
        minus = np.array([nonlinearity(np.array([-SLOPE_STEP]), p)[0] for p in P])
        s = (plus - minus) / (2 * SLOPE_STEP)
    return np.where(np.isfinite(s), s, 0.0)


def loop_setup(num, den, dt: float, substeps: int, nonlinearity, P, derivative: int) -> MapLoop:
    """The substep recursion of each candidate ``num/den`` with its map's slope at 0 moved into ``A``;
    ``derivative``: the derivative of the output that the map reads (below the relative degree)."""
    A, B, C, _ = companion_realization(num, den)
    Cz = C.copy()
    for _ in range(derivative):
        Cz = np.einsum("bi,bij->bj", Cz, A)
    s = map_slope(nonlinearity, P)
    with np.errstate(all="ignore"):
        A_eff = A - s[:, None, None] * B[:, :, None] * Cz[:, None, :]
        Ad, B0, B1 = discretize(A_eff, B, dt / substeps, "foh")
    return MapLoop(*(np.ascontiguousarray(a) for a in (Ad, B0, B1, C, Cz, s)), int(substeps))


def run(nonlinearity, loop: MapLoop, P, y0, X0, u, zoh: bool) -> np.ndarray:
    """Outputs ``(B, N)`` of the loops; rows that cannot be simulated are NaN."""
    u = np.ascontiguousarray(u, dtype=float)
    P = np.ascontiguousarray(np.atleast_2d(P), dtype=float)
    batch, n = loop.C.shape
    out = np.empty((batch, u.size))
    code = nonlinearity.compiled_map
    finite = np.all(np.isfinite(loop.Ad.reshape(batch, -1)), axis=1) & np.all(np.isfinite(P), axis=1)
    if code is None:
        for b in range(batch):
            out[b] = python_run(nonlinearity, loop, b, P[b], float(y0[b]), X0[b], u, zoh) if finite[b] else np.nan
        return out
    extra = np.ascontiguousarray(nonlinearity.map_extra(), dtype=float)
    with np.errstate(all="ignore"):
        _core.hc_lure_map_run(loop.Ad, loop.B0, loop.B1, loop.C, loop.Cz, batch, n, MAP_CODES[code], P, P.shape[1],
                              extra, extra.size, loop.slope, np.ascontiguousarray(y0, dtype=float),
                              np.ascontiguousarray(X0, dtype=float), u, u.size, loop.substeps, int(zoh), out)
    out[~finite] = np.nan
    return out


def _secant(rest, a: float, beta: float, m: float):
    """The secant iteration of the compiled loop: ``(root, rest at it, slope)``, the root NaN when it does not
    settle in 8 steps."""
    z0, r0 = a, rest(a)
    f0 = beta * r0
    scale = abs(a) + abs(f0) + 1e-300
    if abs(f0) <= 4e-16 * scale:
        return a, r0, m
    z1 = a - f0 / m
    r1 = rest(z1)
    f1 = z1 + beta * r1 - a
    for _ in range(8):
        if abs(f1) <= 4e-16 * scale:
            return z1, r1, m
        den = f1 - f0
        if den == 0.0 or not np.isfinite(den):
            return np.nan, np.nan, m
        slope = den / (z1 - z0)
        if slope > 0.0 and np.isfinite(slope):
            m = slope
        z2 = z1 - f1 * (z1 - z0) / den
        z0, f0, z1 = z1, f1, z2
        r1 = rest(z1)
        f1 = z1 + beta * r1 - a
        if abs(z1 - z0) <= 1e-15 * scale:
            return z1, r1, m
    return np.nan, np.nan, m


def _solve(rest, a: float, beta: float, m: float):
    """The root of ``z + beta rest(z) = a`` as the compiled loop finds it: ``(root, rest at it, slope)``."""
    if beta == 0.0:
        return a, rest(a), m
    z, rz, m = _secant(rest, a, beta, m)
    if np.isfinite(z):
        return z, rz, m
    z = _bracketed(rest, a, beta)
    return z, rest(z), 1.0


def _bracketed(rest, a: float, beta: float) -> float:
    """Newton's method on a central-difference slope inside a bracket (the compiled loop's fallback)."""
    def phi(z):
        return z + beta * rest(z) - a

    z = a - beta * rest(a)
    f = phi(z)
    if f == 0.0 or not np.isfinite(f):
        return z if f == 0.0 else np.nan
    step, lo, hi, flo, fhi = 1e-3 * (1.0 + abs(z)) + abs(f), z, z, f, f
    for _ in range(200):
        if flo * fhi <= 0.0:
            break
        if f > 0.0:
            lo -= step
            flo = phi(lo)
        else:
            hi += step
            fhi = phi(hi)
        step *= 2.0
    if not flo * fhi <= 0.0:
        return np.nan
    if f > 0.0:
        hi, fhi = z, f
    else:
        lo, flo = z, f
    for _ in range(60):
        h = 1e-7 * (1.0 + abs(z))
        d = (phi(z + h) - phi(z - h)) / (2.0 * h)
        nxt = z - f / d if d > 0.0 else 0.5 * (lo + hi)
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        fn = phi(nxt)
        if fn == 0.0:
            return nxt
        if (fn > 0.0) == (fhi > 0.0):
            hi, fhi = nxt, fn
        else:
            lo, flo = nxt, fn
        if abs(nxt - z) <= 1e-15 * (1.0 + abs(nxt)) or hi - lo <= 1e-15 * (1.0 + abs(nxt)):
            return nxt
        z, f = nxt, fn
    return z


def python_run(nonlinearity, loop: MapLoop, b: int, p, y0: float, x0, u, zoh: bool) -> np.ndarray:
    """One candidate's output by the compiled loop's steps in Python (custom maps, and the tests' twin)."""
    Ad, b0, b1, c, cz, s = loop.Ad[b], loop.B0[b], loop.B1[b], loop.C[b], loop.Cz[b], float(loop.slope[b])
    m = loop.substeps

    def rest(z):
        return float(nonlinearity(np.array([z]), p)[0]) - s * z

    x = np.array(x0, dtype=float)
    beta = float(cz @ b1)
    rz, slope = rest(float(cz @ x)), 1.0
    y = np.empty(u.size)
    y[0] = y0 + c @ x
    for k in range(1, u.size):
        du = 0.0 if zoh else (u[k] - u[k - 1]) / m
        for j in range(m):
            us, ue = u[k - 1] + du * j, u[k - 1] + (0.0 if zoh else du * (j + 1))
            v = Ad @ x + b0 * (us - rz) + b1 * ue
            _, rz, slope = _solve(rest, float(cz @ v), beta, slope)
            x = v - b1 * rz
        y[k] = y0 + c @ x
        if not np.isfinite(y[k]):
            y[:] = np.nan
            break
    return y
