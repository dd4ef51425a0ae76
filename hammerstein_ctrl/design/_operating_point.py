"""Operating points of a block-oriented model: the equilibrium a loop regulates around, and the plant there.

A model ``y = h(H(p) g(u)) + offset`` rests at an input ``u0`` when its
linear block is at the equilibrium of the constant signal ``v0 = g(u0)``:

* a self-regulating ``H`` (no pole at the origin) rests at any ``u0``, with
  ``z0 = H(0) v0`` and ``y0 = h(z0) + offset``; given ``y0`` instead, ``u0``
  is the input whose static output it is;
* an integrating ``H`` (one pole at the origin) rests only where ``g(u0) = 0``
  (for Coulomb friction with an offset, where the force balances the offset),
  at any output ``y0``.

:func:`operating_point` finds the equilibrium (its state ``x0`` in the
model's controllable canonical realisation, the one ``initial_state`` and
``to_ss()`` use) and the small-signal gain ``h'(z0) g'(u)`` of the plant
there; :func:`small_signal` is the plant ``h'(z0) H(p) g'(u)`` a controller
is designed on.  Where ``g`` is flat at ``u0`` (inside a dead zone, beyond a
saturation) the slope is taken at the nearest input where it is not, and
the point says so in its ``notes``.

Examples
--------
>>> import control as ct
>>> from hammerstein_ctrl import HammersteinModel, Coulomb, Tanh
>>> emps = HammersteinModel(ct.tf([1], [1, 3.138764, 0]), Coulomb(), [0.544501, -0.398365, 0.045066])
>>> op = operating_point(emps)
>>> op.integrating, round(op.u0, 6), round(op.gain, 6)       # the force balances the offset d2
(True, 0.648849, 0.544501)
>>> m = HammersteinModel(ct.tf([2.0], [1, 3, 2]), Tanh(), [1.5, 0.8], offset=0.5)
>>> op = operating_point(m, y0=1.5)
>>> round(op.u0, 6), round(op.y0, 6), op.x0.round(6).tolist()
(1.005899, 1.5, [0.0, 0.5])
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import require_siso_model
from ..exceptions import ParameterError

__all__ = ["OperatingPoint", "operating_point", "small_signal", "static_output", "rest_model", "gain_factors",
           "SEARCH_SPAN"]

#: Widest input searched for an equilibrium when no actuator limits bound it.
SEARCH_SPAN = 1e6
#: Points of the scans that bracket an equilibrium.
SCAN_POINTS = 2001


@dataclass(frozen=True)
class OperatingPoint:
    """An equilibrium of a model and its small-signal gain.

    Attributes
    ----------
    u0, y0 : float
        Input and output at rest.
    v0, z0 : float
        ``g(u0)`` and ``H``'s output there.
    x0 : ndarray
        ``H``'s state (controllable canonical realisation).
    integrating : bool
        Whether ``H`` has a pole at the origin.
    gain : float
        ``h'(z0) g'(u_slope)``: the small-signal gain from the input to the output apart from ``H``.
    u_slope : float
        Where ``g'`` was taken (``u0`` unless ``g`` is flat there).
    notes : tuple of str
    """

    u0: float
    y0: float
    v0: float
    z0: float
    x0: np.ndarray
    integrating: bool
    gain: float
    u_slope: float
    notes: tuple = ()


def _poly(model):
    num = np.trim_zeros(np.asarray(model.linear.num[0][0], dtype=float), "f")
    den = np.trim_zeros(np.asarray(model.linear.den[0][0], dtype=float), "f")
    return num / den[0], den / den[0]


def _finite(value, label):
    if value is None:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{label} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ParameterError(f"{label} must be finite, got {value!r}")
    return v


def static_output(model, u) -> np.ndarray:
    """The output at rest for constant inputs ``u`` (self-regulating ``H``): ``h(H(0) g(u)) + offset``."""
    model = require_siso_model(model, "static_output")
    num, den = _poly(model)
    if den[-1] == 0:
        raise ParameterError("an integrating plant has no static output (it rests only where g(u) = 0)")
    u = np.atleast_1d(np.asarray(u, dtype=float))
    return model.h(num[-1] / den[-1] * model.g(u)) + model.offset


def _bracket_root(fun, center: float, lo: float, hi: float, what: str, *, jumps: bool = False) -> float:
    """The root of ``fun`` nearest ``center`` in ``[lo, hi]`` (a sign change on a scan, then bisection).

    With ``jumps``, a point where ``fun`` jumps across zero counts when no root does (the rest point of a
    discontinuous map in the set-valued sense, e.g. inside Coulomb friction's band).
    """
    from scipy.optimize import brentq

    if fun(np.array([center]))[0] == 0:
        return center
    def outward(edge):                       # geometric steps: roots near the centre are found first
        span = abs(edge - center)
        if span == 0:
            return np.array([center])
        steps = np.geomspace(1e-9 * max(1.0, span), span, SCAN_POINTS)
        return np.concatenate([[center], center + np.sign(edge - center) * steps])

    left, right = outward(lo), outward(hi)
    best, jump = None, None
    for grid in (right, left):
        values = fun(grid)
        scale = float(np.max(np.abs(values[np.isfinite(values)]), initial=1.0))
        for i in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) <= 0):
            a, b = sorted((grid[i], grid[i + 1]))
            root = a if fun(np.array([a]))[0] == 0 else brentq(lambda t: fun(np.array([t]))[0], a, b, xtol=1e-14)
            if abs(fun(np.array([root]))[0]) <= 1e-9 * scale:        # a root, not a jump across zero
                if best is None or abs(root - center) < abs(best - center):
                    best = root
                break
            if jump is None or abs(root - center) < abs(jump - center):
                jump = root
    if best is None and jumps and jump is not None:
        return float(jump)
    if best is None:
        raise ParameterError(f"no input in [{lo:g}, {hi:g}] {what}")
    return float(best)


def _input_range(u_limit):
    if u_limit is None:
        return -SEARCH_SPAN, SEARCH_SPAN
    lo, hi = (float(v) for v in u_limit)
    return max(lo, -SEARCH_SPAN), min(hi, SEARCH_SPAN)


def _slope_at(model, u: float, z0: float) -> float:
    with np.errstate(all="ignore"):
        dg = float(np.asarray(model.input_nonlinearity.derivative(np.array([u]), model.input_params)).ravel()[0]) \
            if model.input_nonlinearity is not None else 1.0
        dh = float(np.asarray(model.output_nonlinearity.derivative(np.array([z0]), model.output_params)).ravel()[0]) \
            if model.output_nonlinearity is not None else 1.0
    return dg * dh


def _nonflat_slope(model, u0: float, z0: float, lo: float, hi: float, notes: list) -> tuple[float, float]:
    """``(slope, where)``: the small-signal gain at ``u0``, or at the nearest input where it does not vanish."""
    slope = _slope_at(model, u0, z0)
    if math.isfinite(slope) and slope != 0:
        return slope, u0
    scale = max(abs(u0), 1e-3)
    for step in scale * np.geomspace(1e-3, 1e6, 200):
        for u in (u0 + step, u0 - step):
            if lo <= u <= hi:
                s = _slope_at(model, u, z0)
                if math.isfinite(s) and s != 0:
                    notes.append(f"the plant is flat at u0 = {u0:.4g} (g'(u0) = 0, e.g. a dead zone): the small-signal "
                                 f"gain is taken at u = {u:.4g}, the nearest input where it is not")
                    return s, u
    raise ParameterError(f"the plant's small-signal gain vanishes at u0 = {u0:g} and at every input within reach "
                         "(a dead zone or saturation over the whole actuator range)")


def _rest_state(model, v0: float, z0: float) -> np.ndarray:
    """``x`` with ``A x + B v0 = 0`` and ``C x + D v0 = z0`` (least squares: exact where it exists)."""
    from ..simulate._export import linear_ss

    ss = linear_ss(model)
    A, B, C, D = (np.asarray(M, dtype=float) for M in (ss.A, ss.B, ss.C, ss.D))
    M = np.vstack([A, C])
    rhs = np.concatenate([-B[:, 0] * v0, [z0 - D[0, 0] * v0]])
    return np.linalg.lstsq(M, rhs, rcond=None)[0]


def operating_point(model, u0=None, y0=None, *, u_limit=None) -> OperatingPoint:
    """The equilibrium of ``model`` at ``u0`` or ``y0`` (module notes).

    Parameters
    ----------
    model : BlockModel
    u0 : float, optional
        The input at rest (self-regulating plant).  Default: the one giving
        ``y0``; with neither, 0 (or the middle of the actuator range if 0 is
        outside it).  An integrating plant rests only where ``g(u0) = 0``:
        its ``u0`` is that input (the one nearest the given ``u0``, or 0).
    y0 : float, optional
        The output at rest.  Default: the static output at ``u0``; for an
        integrating plant, ``h(0) + offset``.
    u_limit : (lo, hi), optional
        Actuator limits: ``u0`` must lie inside them.

    Raises
    ------
    ParameterError
        If the output ``y0`` is not reachable, an integrating plant has no
        input where ``g(u) = 0``, or ``u0`` and ``y0`` disagree.
    """
    model = require_siso_model(model, "operating_point")
    u0, y0 = _finite(u0, "u0"), _finite(y0, "y0")
    lo, hi = _input_range(u_limit)
    num, den = _poly(model)
    integrating = den[-1] == 0
    notes: list = []
    if integrating:
        if np.sum(np.isclose(den[::-1], 0.0, atol=0)[:2]) > 1 and den.size > 2 and den[-2] == 0:
            raise ParameterError("the plant has more than one integrator: no operating point to regulate around")
        start = 0.0 if u0 is None else u0
        start = min(max(start, lo), hi)
        u_rest = _bracket_root(lambda u: model.g(u), start, lo, hi, "where g(u) = 0: an integrating plant cannot rest",
                               jumps=True)
        below, above = (float(model.g(np.array([u_rest + d]))[0]) for d in (-1e-9 * max(1.0, abs(u_rest)),
                                                                              1e-9 * max(1.0, abs(u_rest))))
        if abs(float(model.g(np.array([u_rest]))[0])) > 1e-9 * max(abs(below), abs(above), 1.0):
            notes.append(f"g jumps across zero at u = {u_rest:.6g} (from {below:.4g} to {above:.4g}, e.g. Coulomb "
                         "friction): the plant rests there only in the set-valued sense; expect the loop to dither")
        if u0 is not None and abs(u_rest - u0) > 1e-9 * max(1.0, abs(u0)):
            notes.append(f"an integrating plant rests only where g(u) = 0: u0 = {u_rest:.6g}, not {u0:g}")
        u0, v0 = u_rest, 0.0
        z0 = 0.0 if y0 is None else _inverse_output(model, y0)
        y_rest = float(model.h(np.array([z0]))[0]) + model.offset
    else:
        if y0 is not None and u0 is None:
            center = 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)
            u0 = _bracket_root(lambda u: static_output(model, u) - y0, center, lo, hi,
                               f"gives the output y0 = {y0:g} at rest")
        elif u0 is None:
            u0 = 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)
        if not lo <= u0 <= hi:
            raise ParameterError(f"u0 = {u0:g} is outside the actuator limits [{lo:g}, {hi:g}]")
        v0 = float(model.g(np.array([u0]))[0])
        z0 = num[-1] / den[-1] * v0
        y_rest = float(static_output(model, u0)[0])
        if y0 is not None and abs(y_rest - y0) > 1e-6 * max(1.0, abs(y0)):
            raise ParameterError(f"u0 = {u0:g} and y0 = {y0:g} disagree: the output at rest at u0 is {y_rest:.6g}")
    slope, where = _nonflat_slope(model, u0, z0, lo, hi, notes)
    return OperatingPoint(float(u0), float(y_rest), float(v0), float(z0), _rest_state(model, v0, z0), bool(integrating),
                          float(slope), float(where), tuple(notes))


def _inverse_output(model, y0: float) -> float:
    """``z`` with ``h(z) + offset = y0`` (the identity without ``h``)."""
    target = y0 - model.offset
    if model.output_nonlinearity is None:
        return target
    return _bracket_root(lambda z: model.h(z) - target, 0.0, -SEARCH_SPAN, SEARCH_SPAN,
                         f"of H's output gives y0 = {y0:g}: the output nonlinearity cannot reach it")


def small_signal(model, op: OperatingPoint):
    """``h'(z0) H(p) g'(u)`` at the operating point, as a ``control.TransferFunction``.

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Tanh
    >>> m = HammersteinModel(ct.tf([2.0], [1, 3, 2]), Tanh(), [1.5, 0.8])
    >>> small_signal(m, operating_point(m)).num[0][0].round(12).tolist()
    [2.4]
    """
    model = require_siso_model(model, "small_signal")
    return op.gain * model.linear


def rest_model(model, op: OperatingPoint):
    """The same model starting at rest at the operating point (its initial state ``op.x0``).

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Tanh
    >>> m = HammersteinModel(ct.tf([2.0], [1, 3, 2]), Tanh(), [1.5, 0.8], offset=0.5)
    >>> op = operating_point(m, u0=1.0)
    >>> import numpy as np
    >>> y = rest_model(m, op).simulate(np.arange(0, 1, 0.1), np.ones(10))
    >>> bool(np.allclose(y, op.y0))
    True
    """
    model = require_siso_model(model, "rest_model")
    from ..blocks._model import BlockModel

    return BlockModel.build(model.linear, input_nonlinearity=model.input_nonlinearity, input_params=model.input_params,
                            output_nonlinearity=model.output_nonlinearity, output_params=model.output_params,
                            offset=model.offset, initial_state=op.x0, intersample=model.intersample,
                            name=getattr(model, "name", None))


def gain_factors(model, op: OperatingPoint, inputs, outputs=()) -> tuple[float, ...]:
    """The small-signal gain over a range, as multiples of the operating point's: ``(lowest, middle, highest)``.

    ``inputs`` are the inputs the loop visits (the step's target at rest,
    the proportional kick); ``outputs`` the outputs of ``H`` it visits (for an
    output nonlinearity).  Slopes of the other sign or zero (a dead zone,
    beyond a saturation) do not count: they add no gain to the loop.

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Polynomial
    >>> m = HammersteinModel(ct.tf([2.0], [1, 3, 2]), Polynomial(3), [2.0, 0.0, 0.8])
    >>> [round(k, 3) for k in gain_factors(m, operating_point(m), [0.0, 1.0])]
    [1.0, 1.483, 2.2]
    """
    model = require_siso_model(model, "gain_factors")
    u = np.linspace(min(inputs), max(inputs), 9) if len(inputs) else np.array([op.u0])
    z = np.linspace(min(outputs), max(outputs), 9) if len(outputs) else np.array([op.z0])
    slopes = np.array([_slope_at(model, ui, zi) for ui in u for zi in z])
    ratio = slopes / op.gain
    ratio = ratio[np.isfinite(ratio) & (ratio > 0)]
    if ratio.size == 0:
        return (1.0,)
    lo, hi = float(min(ratio.min(), 1.0)), float(max(ratio.max(), 1.0))
    return (lo, float(np.sqrt(lo * hi)), hi) if hi > lo * (1 + 1e-9) else (1.0,)
