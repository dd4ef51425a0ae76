"""Input dead time: exact sampled simulation of ``H(p) e^{-tau p}``, for any ``tau >= 0``.

A transport delay ``tau`` between the static input block and the linear block
(``y = h(H(p) e^{-tau p} g(u))``; for a Hammerstein model it is the same as
delaying ``u``) is simulated exactly, not rounded to a multiple of the
sample time ``T``.  Write ``tau = d T + theta`` with ``0 <= theta < T``.  The
delayed signal ``w(t) = v(t - tau)`` changes its law once inside each sample
interval, at ``k T + theta``:

* first-order hold (``v`` linear between samples): ``w`` is linear on
  ``[kT, kT + theta]`` and on ``[kT + theta, (k+1)T]``, with
  ``w(kT) = a v[k-d-1] + (1 - a) v[k-d]`` (``a = theta / T``) and
  ``w(kT + theta) = v[k-d]``;
* zero-order hold: ``w = v[k-d-1]`` on the first part and ``v[k-d]`` on the second.

Each part is integrated exactly (the matrix exponential of the linear block
over ``theta`` and over ``T - theta``), so the sampled output equals that of
the continuous system driven by the exactly delayed input.  Before the
record the samples of ``v`` are zero, as the state at rest (``x = 0``) says
(the same hold joins them to the record's first sample); a record that starts
elsewhere needs its initial state estimated.  ``tau = 0`` is the undelayed
simulation.

Examples
--------
>>> import numpy as np
>>> d, a = split_delay(0.37, 0.1)
>>> d, round(a, 12)
(3, 0.7)
>>> t = np.arange(6) * 0.5
>>> v = np.r_[0.0, np.ones(5)]                        # a unit step at t = 0.5 s (zero-order hold)
>>> np.round(delayed_response([1.0], [1.0, 0.0], v, 0.5, 0.75, intersample="zoh"), 6).tolist()
[0.0, 0.0, 0.0, 0.25, 0.75, 1.25]
"""

from __future__ import annotations

import math

import numpy as np

from .._checks import (ESTIMATE, as_signal, check_delay, check_dt, check_intersample, check_transfer_function,
                       uniform_grid)
from .. import _core
from ..exceptions import ParameterError
from ._simulate import companion_realization, discretize

__all__ = ["check_delay", "split_delay", "delayed_response", "delayed_values", "delay_matrices", "simulate_delayed",
           "ESTIMATE"]

def split_delay(delay: float, dt: float) -> tuple[int, float]:
    """``(d, a)`` with ``delay = (d + a) dt``, ``d`` an integer and ``0 <= a < 1``.

    A delay within 1e-9 of a whole number of samples counts as that whole number.
    """
    q = float(delay) / float(dt)
    d = math.floor(q)
    a = q - d
    if a > 1.0 - 1e-9:
        d, a = d + 1, 0.0
    elif a < 1e-9:
        a = 0.0
    return int(d), float(a)


def delay_matrices(num, den, dt: float, delay: float, intersample: str = "foh"):
    """``(M, Pa, Pb, Pc, C, D, d, a)``: the exact recursion of ``H(p) e^{-delay p}`` on samples of ``dt``.

    ``x[k+1] = M x[k] + Pa w0[k] + Pb w1[k] + Pc w0[k+1]`` and
    ``z[k] = C x[k] + D w0[k]``, where ``w0[k]`` is the delayed input at
    ``k dt`` and ``w1[k]`` its value at ``k dt + a dt`` (see the module notes);
    ``x`` is the state of the controllable canonical realisation.
    """
    hold = check_intersample(intersample)
    num, den = check_transfer_function(num, den, name="linear block")
    A, B, C, D = companion_realization(num, den)
    d, a = split_delay(delay, dt)
    n = A.shape[1]
    if a == 0.0:
        Ad1, B01, B11 = np.eye(n)[None], np.zeros((1, n)), np.zeros((1, n))
    else:
        Ad1, B01, B11 = discretize(A, B, a * dt, hold)
    Ad2, B02, B12 = discretize(A, B, (1.0 - a) * dt, hold)
    M = Ad2[0] @ Ad1[0]
    Pa = Ad2[0] @ B01[0]
    Pb = Ad2[0] @ B11[0] + B02[0]
    return M, Pa, Pb, B12[0].copy(), C[0], float(D[0]), d, a


def _delayed_samples(v: np.ndarray, d: int, a: float, hold: str) -> tuple[np.ndarray, np.ndarray]:
    """``(w0, w1)``: the delayed input at ``k dt`` and at ``k dt + a dt`` (zero samples before the record)."""
    N = v.size
    padded = np.concatenate((np.zeros(min(d + 1, N + 1)), v))       # padded[j + d + 1] = v[j], zeros before
    k = np.arange(N)
    start = min(d + 1, N + 1)
    return delayed_values(padded[np.clip(k - d + start, 0, None)], padded[np.clip(k - d - 1 + start, 0, None)],
                          a, hold)


def delayed_values(now, before, a: float, hold: str):
    """``(w0, w1)`` from ``now = v[k - d]`` and ``before = v[k - d - 1]`` (numbers or arrays): the delayed input
    at ``k dt`` and at ``k dt + a dt`` (see the module notes)."""
    if hold == "zoh":
        return (before if a > 0 else now), now
    return a * before + (1.0 - a) * now, now


def delayed_response(num, den, v, dt: float, delay: float, *, x0=None, intersample: str = "foh") -> np.ndarray:
    """Sampled output of ``num(p)/den(p) e^{-delay p}`` driven by ``v`` (exact, any ``delay >= 0``).

    Parameters
    ----------
    num, den : array_like
        Continuous-time transfer function (descending powers, proper).
    v : array_like, shape (N,)
        Input samples, held or interpolated as ``intersample`` says.
    dt : float
        Sample time.
    delay : float
        Dead time in seconds (``>= 0``; need not be a multiple of ``dt``).
    x0 : array_like, optional
        State at ``t = 0`` of the controllable canonical realisation; default 0.
    intersample : {"foh", "zoh"}, default "foh"

    Returns
    -------
    ndarray, shape (N,)
        With ``delay = 0`` this is the undelayed exact simulation
        (``control.forced_response`` for first-order hold).
    """
    dt = check_dt(dt)
    tau = check_delay(delay, estimate=False)
    v = as_signal(v, "v")
    hold = check_intersample(intersample)
    M, Pa, Pb, Pc, C, D, d, a = delay_matrices(num, den, dt, min(tau, dt * (v.size + 1)), hold)
    n = M.shape[0]
    state = np.zeros(n) if x0 is None else np.asarray(x0, dtype=float).reshape(-1)
    if state.size != n:
        raise ParameterError(f"x0 must have {n} entries (the linear block's order), got {state.size}")
    w0, w1 = _delayed_samples(v, d, a, hold)
    out = np.empty(v.size)
    M, Pa, Pb, Pc, C, state, w0, w1 = (np.ascontiguousarray(x, dtype=float) for x in (M, Pa, Pb, Pc, C, state, w0, w1))
    if _core.hc_delayed_recursion(M, Pa, Pb, Pc, C, D, n, state, w0, w1, v.size, out):
        raise MemoryError("no memory for the delayed recursion's state")
    return out


def simulate_delayed(model, t, u, *, x0=None, intersample: str = "foh") -> np.ndarray:
    """Simulate a block model with a dead time: ``h(H e^{-tau p} g(u)) + offset`` (``tau = model.delay``).

    Parameters
    ----------
    model : BlockModel
    t, u : array_like, shape (N,)
        Uniform time grid and input samples.
    x0 : array_like, optional
        Initial state of the linear block; default 0.
    intersample : {"foh", "zoh"}, default "foh"

    Returns
    -------
    ndarray, shape (N,)

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Tanh
    >>> m = HammersteinModel(ct.tf([1], [1, 1]), Tanh(), [2.0, 1.0], delay=0.25)
    >>> t = np.arange(4) * 0.5
    >>> np.round(simulate_delayed(m, t, [0.0, 1, 1, 1], intersample="zoh"), 4).tolist()   # a step, 0.25 s late
    [0.0, 0.0, 0.3369, 0.8037]
    """
    t = np.asarray(t, dtype=float)
    _, dt = uniform_grid(t)
    u = as_signal(u, "u")
    if u.size != t.size:
        raise ParameterError(f"u has {u.size} samples but t has {t.size}")
    num, den = check_transfer_function(*model.coefficients(), name="linear block")
    v = as_signal(model.g(u), "g(u)")
    z = delayed_response(num, den, v, dt, model.delay, x0=x0, intersample=intersample)
    with np.errstate(all="ignore"):
        return np.asarray(model.h(z), dtype=float) + model.offset
