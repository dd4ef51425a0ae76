"""Sampled PID loops around a Hammerstein plant: fast compiled simulation and its python-control twin.

The loop, sampled with interval ``dt`` (a digital controller driving the plant
through a DAC, so the plant input is held between samples), is at each
sample ``k``:

.. code-block:: text

    y[k]   = C x[k] + offset                    plant output (strictly proper H)
    e[k]   = r[k] - y[k]
    D[k]   = tf/(tf+dt) D[k-1] + kd/(tf+dt) (e[k] - e[k-1])   filtered derivative
    uc[k]  = kp e[k] + I[k] + D[k]              controller output
    u[k]   = clip(uc[k], lo, hi)                actuator limit
    I[k+1] = I[k] + dt (ki e[k] + kt (u[k] - uc[k]))          back-calculation anti-windup
    x[k+1] = Ad x[k] + Bd g(u[k])               exact ZOH step of the plant

(backward-difference derivative, forward-Euler integral, Åström and
Hägglund's computer implementation).  :func:`simulate_loops` runs a batch of
candidate gains through this recursion in compiled code;
:func:`sampled_loop_iosys` builds the same loop as a ``control.interconnect``
of a summing junction, the PID (:func:`discrete_pid_iosys`), an actuator
saturation block and the plant's exact ``to_iosys(dt)`` export, so that
``control.input_output_response`` checks the compiled path.

Examples
--------
>>> import numpy as np, control as ct
>>> from hammerstein_ctrl import HammersteinModel, Coulomb
>>> plant = HammersteinModel(ct.tf([1], [1, 3.14, 0]), Coulomb(), [0.54, -0.4, 0.045])
>>> r = np.full(500, 0.1); gains = [[20.0, 10.0, 5.0, 0.03]]
>>> Y, U = simulate_loops(plant, gains, r, 1e-3, u_limit=(-4.0, 4.0))
>>> loop = sampled_loop_iosys(plant, gains[0], 1e-3, u_limit=(-4.0, 4.0))
>>> y = ct.input_output_response(loop, np.arange(500) * 1e-3, r).outputs[0]
>>> bool(np.allclose(Y[0], y, rtol=1e-9, atol=1e-12))
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._jit import cached_njit
from .exact_export import model_settings, sampled_iosys, sampled_matrices
from .exceptions import DataError, ParameterError
from .nonlinearities import Coulomb, DeadZone, PiecewiseLinear, Polynomial, Saturation, Tanh

__all__ = ["simulate_loops", "sampled_plant", "SampledPlant", "sampled_loop_iosys", "discrete_pid_iosys",
           "saturation_iosys", "back_calculation_gain", "check_limits", "NONLINEARITY_CODES"]

#: Compiled evaluations of the named nonlinearity families (code per class).
NONLINEARITY_CODES = {Tanh: 0, Coulomb: 1, Polynomial: 2, Saturation: 3, DeadZone: 4, PiecewiseLinear: 5}

#: A simulated output beyond this multiple of the reference's size counts as diverged.
DIVERGENCE_RATIO = 1e6


def back_calculation_gain(kp: float, ki: float, kd: float) -> float:
    """``kt = 1/Tt`` with Åström and Hägglund's ``Tt = sqrt(Ti Td)`` (``Ti`` for a PI).

    Examples
    --------
    >>> back_calculation_gain(2.0, 1.0, 0.0)    # Ti = 2
    0.5
    >>> round(back_calculation_gain(2.0, 1.0, 0.5), 6)    # Ti = 2, Td = 0.25
    1.414214
    """
    if ki <= 0 or kp <= 0:
        return 0.0
    ti = kp / ki
    td = kd / kp
    return 1.0 / (math.sqrt(ti * td) if td > 0 else ti)


def check_limits(u_limit) -> tuple[float, float]:
    """``(lo, hi)`` of an actuator, ``(-inf, inf)`` for None; ``lo < hi`` required."""
    if u_limit is None:
        return -math.inf, math.inf
    try:
        lo, hi = (float(v) for v in u_limit)
    except (TypeError, ValueError):
        raise ParameterError(f"u_limit must be a pair (lo, hi), got {u_limit!r}") from None
    if math.isnan(lo) or math.isnan(hi) or not lo < hi:
        raise ParameterError(f"actuator limits need lo < hi, got lo = {lo!r}, hi = {hi!r}")
    return lo, hi


def _nonlinearity_arrays(model):
    nl = model.nonlinearity
    code = NONLINEARITY_CODES.get(type(nl))
    if code is None:
        raise ParameterError(
            f"the compiled loop simulator supports the named nonlinearity families, not {nl!r}"
        )
    bp = nl.breakpoints if isinstance(nl, PiecewiseLinear) else np.zeros(2)
    return code, np.ascontiguousarray(model.params, dtype=float), np.ascontiguousarray(bp, dtype=float)


@cached_njit()
def _g(code, p, bp, u):  # pragma: no cover - compiled
    if code == 0:
        return p[0] * math.tanh(p[1] * u)
    if code == 1:
        s = 1.0 if u > 0 else (-1.0 if u < 0 else 0.0)
        return p[0] * u + p[1] * s + p[2]
    if code == 2:
        acc = p[p.size - 1]
        for i in range(p.size - 2, -1, -1):
            acc = acc * u + p[i]
        return acc * u
    if code == 3 or code == 4:
        a = abs(p[1])
        c = min(max(u, -a), a)
        return p[0] * c if code == 3 else p[0] * (u - c)
    n = bp.size
    idx = np.searchsorted(bp, u, side="right") - 1
    idx = min(max(idx, 0), n - 2)
    w = (u - bp[idx]) / (bp[idx + 1] - bp[idx])
    return p[idx] * (1.0 - w) + p[idx + 1] * w


@cached_njit()
def _loops(Ad, Bd, C, x0, offset, code, p, bp, G, r, dt, lo, hi, bound, Y, U):  # pragma: no cover
    batch, N = Y.shape
    n = x0.size
    x = np.empty(n)
    xn = np.empty(n)
    for b in range(batch):
        kp, ki, kd, tf, kt = G[b, 0], G[b, 1], G[b, 2], G[b, 3], G[b, 4]
        ad = tf / (tf + dt)
        bd = kd / (tf + dt)
        x[:] = x0
        integ, deriv, ep = 0.0, 0.0, 0.0
        for k in range(N):
            y = offset
            for i in range(n):
                y += C[i] * x[i]
            e = r[k] - y
            deriv = ad * deriv + bd * (e - ep)
            uc = kp * e + integ + deriv
            u = min(max(uc, lo), hi)
            Y[b, k] = y
            U[b, k] = u
            if not abs(y) <= bound:
                for j in range(k + 1, N):
                    Y[b, j] = np.inf
                    U[b, j] = np.nan
                break
            v = _g(code, p, bp, u)
            for i in range(n):
                s = Bd[i] * v
                for j in range(n):
                    s += Ad[i, j] * x[j]
                xn[i] = s
            x[:] = xn
            integ += dt * (ki * e + kt * (u - uc))
            ep = e


def _gain_table(gains) -> np.ndarray:
    """``(B, 5)`` rows ``kp, ki, kd, tf, kt`` (``kt`` defaulted by :func:`back_calculation_gain`)."""
    G = np.atleast_2d(np.asarray(gains, dtype=float))
    if G.ndim != 2 or G.shape[1] not in (4, 5):
        raise ParameterError(f"gains must be rows (kp, ki, kd, tf[, kt]), got shape {G.shape}")
    if G.shape[1] == 4:
        kt = [back_calculation_gain(*np.abs(row[:3])) for row in G]
        G = np.column_stack([G, kt])
    if np.any(G[:, 3] < 0) or not np.all(np.isfinite(G)):
        raise ParameterError("gains must be finite and the filter time constant tf >= 0")
    return np.ascontiguousarray(G)


@dataclass(frozen=True)
class SampledPlant:
    """The arrays of a plant's exact ZOH step, computed once for many loop simulations."""

    Ad: np.ndarray
    Bd: np.ndarray
    C: np.ndarray
    x0: np.ndarray
    offset: float
    code: int
    params: np.ndarray
    breakpoints: np.ndarray
    dt: float


def sampled_plant(model, dt: float) -> SampledPlant:
    """Precompute the sampled plant of :func:`simulate_loops` (strictly proper linear block required)."""
    Ad, B0, _, C, D = sampled_matrices(model, dt, "zoh")
    if D != 0.0:
        raise ParameterError("a sampled loop needs a strictly proper linear block (no direct feedthrough)")
    settings = model_settings(model)
    code, p, bp = _nonlinearity_arrays(model)
    return SampledPlant(np.ascontiguousarray(Ad), np.ascontiguousarray(B0), np.ascontiguousarray(C),
                        np.ascontiguousarray(settings["initial_state"]), settings["offset"], code, p, bp,
                        float(dt))


def simulate_loops(model, gains, r, dt: float, *, u_limit=None):
    """Simulate the sampled loop for a batch of PID gains (compiled, exact recursion).

    Parameters
    ----------
    model : HammersteinModel or SampledPlant
        The plant (strictly proper linear block, a named nonlinearity family),
        or its precomputed :func:`sampled_plant` at ``dt``.
    gains : array_like, shape (B, 4) or (B, 5)
        Rows ``kp, ki, kd, tf`` and optionally the back-calculation gain ``kt``.
    r : array_like, shape (N,)
        Reference samples, ``N >= 2``.
    dt : float
        Sampling interval.
    u_limit : (lo, hi), optional
        Actuator limits.

    Returns
    -------
    Y, U : ndarray, shape (B, N)
        Plant outputs and actuator outputs; a diverging run (output beyond
        ``DIVERGENCE_RATIO`` times the reference's size) is cut short with
        ``Y = inf`` and ``U = nan`` from then on.
    """
    r = np.ascontiguousarray(r, dtype=float).reshape(-1)
    if r.size < 2 or not np.all(np.isfinite(r)):
        raise DataError(f"the reference needs at least two finite samples, got {r.size}")
    lo, hi = check_limits(u_limit)
    G = _gain_table(gains)
    plant = model if isinstance(model, SampledPlant) else sampled_plant(model, dt)
    if plant.dt != float(dt):
        raise ParameterError(f"the sampled plant has dt = {plant.dt}, not {dt}")
    bound = DIVERGENCE_RATIO * max(1.0, float(np.max(np.abs(r))))
    Y = np.empty((G.shape[0], r.size))
    U = np.empty_like(Y)
    with np.errstate(all="ignore"):
        _loops(plant.Ad, plant.Bd, plant.C, plant.x0, plant.offset, plant.code, plant.params,
               plant.breakpoints, G, r, float(dt), lo, hi, bound, Y, U)
    return Y, U


def discrete_pid_iosys(gains, dt: float, *, name: str = "pid"):
    """The sampled PID with back-calculation as a discrete :class:`control.NonlinearIOSystem`.

    Inputs ``e`` (error) and ``u`` (the actuator's actual output, for the
    anti-windup), output ``uc``; states ``I`` (integral), ``D`` (filtered
    derivative) and ``e_prev``.  The recursion is the module's.
    """
    import control

    kp, ki, kd, tf, kt = _gain_table(gains)[0]
    ad, bd = tf / (tf + dt), kd / (tf + dt)

    def parts(x, e):
        deriv = ad * x[1] + bd * (e - x[2])
        return deriv, kp * e + x[0] + deriv

    def update(t, x, u, p):
        e, act = u[0], u[1]
        deriv, uc = parts(x, e)
        return np.array([x[0] + dt * (ki * e + kt * (act - uc)), deriv, e])

    def output(t, x, u, p):
        return np.array([parts(x, u[0])[1]])

    return control.nlsys(update, output, inputs=["e", "u"], outputs=["uc"], states=["I", "D", "e_prev"],
                         dt=dt, name=name)


def saturation_iosys(u_limit, *, dt=None, name: str = "actuator"):
    """Static actuator limit ``u = clip(uc, lo, hi)`` as a :class:`control.NonlinearIOSystem`."""
    import control

    lo, hi = check_limits(u_limit)
    return control.nlsys(None, lambda t, x, u, p: np.clip(u[:1], lo, hi), inputs=["uc"], outputs=["u"],
                         dt=dt, name=name)


def sampled_loop_iosys(model, gains, dt: float, *, u_limit=None, name: str = "loop"):
    """The sampled loop as a ``control.interconnect`` (input ``r``; outputs ``y``, ``u``).

    Simulated with ``control.input_output_response`` on a grid of step ``dt``
    it equals :func:`simulate_loops` for the same gains.
    """
    import control

    sampled_plant(model, dt)  # same checks as the compiled path
    plant = sampled_iosys(model, dt, intersample="zoh", name="plant", inputs="u", outputs="y")
    err = control.summing_junction(inputs=["r", "-y"], output="e", dt=dt, name="error")
    return control.interconnect(
        [err, discrete_pid_iosys(gains, dt), saturation_iosys(u_limit, dt=dt), plant],
        inputs=["r"], outputs=["y", "u"], dt=dt, name=name)
