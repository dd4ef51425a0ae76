"""The small-signal model a PID rule is designed on: the linearised plant at the operating point, reduced by the
half rule to a first- or second-order lag with dead time."""

from __future__ import annotations

import math
import numpy as np
from .._checks import require_siso_model
from ..exceptions import ParameterError
from ._operating_point import OperatingPoint, operating_point

__all__ = ["approximate"]


#: Relative size below which a pole counts as an integrator.
INTEGRATOR_TOL = 1e-9
# ---------------------------------------------------------------------------
# the small-signal model and the half rule
# ---------------------------------------------------------------------------
def _polynomials(model):
    num = np.trim_zeros(np.asarray(model.linear.num[0][0], dtype=float), "f")
    den = np.trim_zeros(np.asarray(model.linear.den[0][0], dtype=float), "f")
    if num.size == 0 or not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
        raise ParameterError("the model's linear block has non-finite or no coefficients")
    for params in (getattr(model, "input_params", None), getattr(model, "output_params", None)):
        if params is not None and not np.all(np.isfinite(params)):
            raise ParameterError("the model's nonlinearity parameters are not finite")
    return num / den[0], den / den[0]


def _rational(model):
    """The model itself, or with its dead time replaced by a Pade approximant
    (:meth:`~hammerstein_ctrl.blocks.BlockModel.without_delay`) for the loop analyses."""
    return model.without_delay() if getattr(model, "delay", 0) else model


def _split_poles(den: np.ndarray):
    """(number of integrators, lag time constants, notes); raises for unstable models."""
    poles = np.roots(den)
    scale = max(1.0, float(np.max(np.abs(poles)))) if poles.size else 1.0
    integrators = np.abs(poles) <= INTEGRATOR_TOL * scale
    rest = poles[~integrators]
    if np.any(rest.real >= 0):
        raise ParameterError(f"the model is unstable (poles {np.round(poles, 6).tolist()}); "
                             "PID rules need a stable or integrating plant")
    if integrators.sum() > 1:
        raise ParameterError("the model has more than one integrator; PID rules cover at most one")
    lags, notes = [], []
    for p in rest:
        if p.imag > 0:
            notes.append(f"complex pole pair {p:.4g}: two lags 1/|p| = {1 / abs(p):.4g}")
        if p.imag != 0:
            lags.append(1.0 / abs(p))
        else:
            lags.append(-1.0 / p.real)
    return int(integrators.sum()), sorted(lags, reverse=True), notes


def _zero_constants(num: np.ndarray):
    """Time constants ``T0`` of ``num(s)/num(0) = prod(T0 s + 1)`` (pairs as one lead)."""
    out = []
    for z in np.roots(num):
        if abs(z) == 0:
            raise ParameterError("the model has a zero at p = 0 (no static gain); PID rules do not apply")
        if z.imag < 0:
            continue
        out.append(-2 * z.real / abs(z) ** 2 if z.imag > 0 else -1.0 / z.real)
    return out


def _cancel_leads(lags: list, leads: list, notes: list) -> tuple[list, float]:
    """Apply each lead ``T0 > 0`` to the nearest lag; returns (lags, static factor)."""
    factor = 1.0
    for t0 in sorted(leads, reverse=True):
        above = [t for t in lags if t >= t0]
        if above:
            tau = min(above)
            lags[lags.index(tau)] = tau - t0
            notes.append(f"lead T0 = {t0:.4g} cancelled against lag {tau:.4g} -> {tau - t0:.4g}")
        elif lags:
            tau = max(lags)
            lags.remove(tau)
            factor *= t0 / tau
            notes.append(f"lead T0 = {t0:.4g} over lag {tau:.4g} replaced by the gain {t0 / tau:.4g}")
        else:
            notes.append(f"lead T0 = {t0:.4g} with no lag to cancel: ignored")
    return sorted([t for t in lags if t > 0], reverse=True), factor


def _operating_point(model, u0, y0, u_limit) -> OperatingPoint:
    """The operating point, after the checks that apply to every rule (a finite, stable or integrating plant)."""
    num, den = _polynomials(model)
    _split_poles(den)
    return operating_point(model, u0, y0, u_limit=u_limit)


def approximate(model, u0: float | None = 0.0, dt: float | None = None, *, op: OperatingPoint | None = None) -> dict:
    """Skogestad's half-rule reduction of the small-signal model at the operating point.

    Returns a record with ``kind`` (``"integrating"``: ``k e^{-theta s}/(s (tau2 s + 1))``,
    or ``"self-regulating"``: ``K e^{-theta s}/((tau1 s + 1)(tau2 s + 1))``),
    ``gain`` (``k`` or ``K``), ``tau1``, ``tau2``, ``theta``, ``slope`` (the
    small-signal gain of the static blocks), ``u0``, ``dt`` and ``notes``.
    The model's own dead time, inverse-response zeros and half of the
    third-largest lag (and all smaller ones) go to the delay; a digital
    controller adds ``dt/2``.

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Tanh
    >>> trs = HammersteinModel(ct.tf([1, -1.816], [1, 4.7681, 0.118]), Tanh(), [-4.7132, 0.1229])
    >>> a = approximate(trs, 0.0, dt=0.1)
    >>> a["kind"], round(a["gain"], 3), round(a["tau1"], 2), round(a["tau2"], 3), round(a["theta"], 3)
    ('self-regulating', 8.915, 40.2, 0.211, 0.601)
    """
    model = _siso_model(model, "approximate")
    op = op if op is not None else _operating_point(model, u0, None, None)
    slope = op.gain
    num, den = _polynomials(model)
    n_int, lags, notes = _split_poles(den)
    notes = list(op.notes) + notes
    theta = 0.0
    leads = []
    for t0 in _zero_constants(num):
        if t0 < 0:
            theta += -t0
            notes.append(f"inverse-response zero: T0 = {-t0:.4g} added to the delay")
        else:
            leads.append(t0)
    lags, factor = _cancel_leads(lags, leads, notes)
    reduced = den[: den.size - 1] if n_int else den
    gain = slope * factor * num[-1] / reduced[-1]
    keep = 1 if n_int else 2
    kept, rest = lags[:keep], lags[keep:]
    if rest:
        kept[-1] += rest[0] / 2
        theta += rest[0] / 2 + sum(rest[1:])
        notes.append(f"half rule: half of the lag {rest[0]:.4g} to tau2, "
                     f"the rest ({rest[0] / 2 + sum(rest[1:]):.4g}) to the delay")
    kept += [0.0] * (keep - len(kept))
    if getattr(model, "delay", 0):
        theta += float(model.delay)
        notes.append(f"the model's dead time {float(model.delay):.4g} s added to the delay")
    if dt is not None:
        theta += float(dt) / 2
        notes.append(f"digital control: dt/2 = {float(dt) / 2:.4g} added to the delay")
    return {"kind": "integrating" if n_int else "self-regulating", "gain": float(gain),
            "tau1": math.inf if n_int else float(kept[0]), "tau2": float(kept[-1]),
            "theta": float(theta), "slope": slope, "u0": op.u0, "dt": dt, "notes": notes}


# ---------------------------------------------------------------------------
def _siso_model(model, what: str):
    """A SISO block-oriented model (or result): MIMO models and Lur'e loops are refused in one line, with what
    to use instead."""
    model = require_siso_model(model, what)
    inner = model.model if getattr(model, "is_identification_result", False) else model
    if getattr(inner, "kind", "") == "lure":
        raise ParameterError(f"{what} takes a block-oriented model; for a Lur'e loop use model.motion_model() (the "
                             f"loop in motion, friction as a constant disturbance) and check the controller "
                             f"through sticking with hammerstein_ctrl.fit.KnownLoop(controller, r).simulate(model)")
    if getattr(inner, "kind", "") == "wiener-hammerstein":
        raise ParameterError(f"{what} takes a Hammerstein, Wiener or Hammerstein-Wiener model; for a "
                             "Wiener-Hammerstein model use model.linearize(u0) (the model about the steady input u0, "
                             "a control.TransferFunction) or model.motion_model(u0)")
    return model
