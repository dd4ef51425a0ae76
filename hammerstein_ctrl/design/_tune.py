"""PID tuning from an identified block-oriented model, with every controller verified before it is returned.

One front door, :func:`tune_pid`, and one result, :class:`PIDResult`.  Every
rule returns a controller that has been checked on the model:

* the **linearised loop** at the operating point (``h'(z0) H(p) g'(u0)``,
  :mod:`hammerstein_ctrl.design._operating_point`): closed-loop poles, gain, phase
  and delay margins, the peak sensitivity ``Ms`` and complementary
  sensitivity ``Mt``;
* the **nonlinear loop** (:mod:`hammerstein_ctrl.simulate._loop`: the sampled plant,
  the actuator limits with back-calculation anti-windup) started at rest at
  the operating point: a step of the reference from there, its figures
  relative to the operating point, and whether it settles within 2 %.

``success`` is True only when the loop is stable, ``Ms`` and ``Mt`` stay
within the robustness target (``max_sensitivity=1.6`` by default, or a
``phase_margin``) and the nonlinear loop tracks the step; otherwise
``message`` says why and what to do.  No rule hands out a silently unstable
controller.

The rules:

* ``"robust"`` (default): Åström and Hägglund's design for load disturbances
  under a robustness constraint (:func:`~hammerstein_ctrl.design.ms_constrained_pid`):
  the largest integral gain with ``Ms, Mt <= max_sensitivity``, no
  conditional stability and a crossover the model can vouch for.  It needs
  no delay, tuning constant or actuator limits, and handles right-half-plane
  zeros, light damping and integrators.
* ``"simc"`` / ``"imc"``: Skogestad's SIMC and IMC/lambda rules on the
  half-rule reduction of the plant (:func:`approximate`).  With ``tau_c``
  left out they start from the model's own time scale and *detune* (``tau_c``
  x 1.5 at a time) until the robustness target holds; a ``tau_c`` given is
  kept, and the result says whether it is robust.
* ``"nspsa"`` / ``"auto"``: the gains minimising IAE, ISE or ITAE of the
  nonlinear loop with a penalty on ``Ms`` above the target, by N-SPSA
  (seeded) or Nelder-Mead, from any start (the robust design, or a P, PI or
  PID given as ``start``).

:func:`closed_loop` returns the loop as a ``control.interconnect``
(continuous, or sampled with the exact discrete plant), started at the
operating point; :func:`analyze_loop` its figures; ``pid.to_discrete(dt)`` a
digital controller verified on the exact discrete plant.

Examples
--------
>>> import control as ct
>>> from hammerstein_ctrl import HammersteinModel, Coulomb
>>> emps = HammersteinModel(ct.tf([1], [1, 3.138764, 0]), Coulomb(), [0.544501, -0.398365, 0.045066])
>>> pid = tune_pid(emps)
>>> pid.success, pid.stable, bool(pid.Ms <= 1.6 + 1e-6), round(pid.operating_point.u0, 4)
(True, True, True, 0.6488)
>>> type(pid.controller).__name__
'TransferFunction'
"""

from __future__ import annotations

import math
import numpy as np
from .._checks import MAX_MAGNITUDE
from .. import config
from ..exceptions import ParameterError, UnknownNameError
from ..blocks._model import pade_order_of
from ..simulate._loop import check_limits
from ._operating_point import operating_point, small_signal
from ._robust import FILTER_RATIO, default_bandwidth, frequency_grid, loop_figures, ms_constrained_pid
from ._approximate import _operating_point, _rational, _siso_model, approximate
from ._pid import (CRITERIA, DEFAULT_MAXFEV, DETUNE_FACTOR, MAX_DETUNE, MAX_OVERSHOOT, MS_SLACK, PIDResult, RULES,
                   TuningCost, _check_dt, _default_step, _imc, _reference, _simc, _start_tau_c, _tuning_grid, _verified,
                   _with_hold)

__all__ = ["tune_pid"]


# ---------------------------------------------------------------------------
# tune_pid
# ---------------------------------------------------------------------------
def _check_rule(rule) -> str:
    key = str(rule).strip().lower().replace("-", "")
    if key not in RULES:
        raise UnknownNameError(f"unknown tuning rule {rule!r}; known: {', '.join(RULES)}")
    return key


def _check_criterion(criterion) -> str:
    key = str(criterion).strip().lower()
    if key not in CRITERIA:
        raise UnknownNameError(f"unknown cost criterion {criterion!r}; known: {', '.join(CRITERIA)}")
    return key


def _robustness_target(max_sensitivity, phase_margin) -> float:
    """The ``Ms`` target: given, or the one that guarantees ``phase_margin`` (``2 arcsin(1/(2 Ms))``)."""
    if max_sensitivity is not None and phase_margin is not None:
        raise ParameterError("give max_sensitivity or phase_margin, not both")
    if phase_margin is not None:
        pm = float(phase_margin)
        if not 0 < pm < 90:
            raise ParameterError(f"phase_margin must be between 0 and 90 degrees, got {phase_margin!r}")
        return 1.0 / (2.0 * math.sin(math.radians(pm) / 2.0))
    ms = config.get("control.max_sensitivity") if max_sensitivity is None else float(max_sensitivity)
    if not 1.0 < ms < 10.0:
        raise ParameterError(f"max_sensitivity must be between 1 and 10 (1.4-2.0 is usual), got {max_sensitivity!r}")
    return ms


def tune_pid(model, rule: str = "robust", *, kind: str = "pid", max_sensitivity: float | None = None,
             phase_margin: float | None = None, bandwidth: float | None = None, u0: float | None = None,
             y0: float | None = None, dt: float | None = None, u_limit=None, tau_c: float | None = None,
             reference="step", step: float | None = None, t_final: float | None = None, criterion: str = "itae",
             max_overshoot: float | None = MAX_OVERSHOOT, start=None, maxfev: int = DEFAULT_MAXFEV, seed=0,
             options: dict | None = None) -> PIDResult:
    """Tune a PID for a block-oriented model, and verify it (module notes).

    Parameters
    ----------
    model : BlockModel
        A Hammerstein, Wiener or Hammerstein-Wiener model with a stable or
        integrating (one integrator) linear block; strictly proper, with named
        nonlinearity families, for the nonlinear verification.
    rule : {"robust", "simc", "imc", "nspsa", "auto"}, default "robust"
    kind : {"pid", "pi"}, default "pid"
        ``"pid"`` lets the design drop the derivative (it may return a PI).
    max_sensitivity : float, optional
        Robustness target: the largest ``Ms`` and ``Mt`` (default 1.6).
    phase_margin : float, optional
        Or a phase margin in degrees (the target is then the ``Ms`` that guarantees it).
    bandwidth : float, optional
        Largest gain crossover of the robust design (rad/s; default twice the
        model's fastest pole or zero).
    u0, y0 : float, optional
        The operating point (:func:`~hammerstein_ctrl.design.operating_point`):
        the loop regulates around it and starts at rest there.
    dt : float, optional
        Controller sampling interval: adds ``dt/2`` to the delay of SIMC/IMC
        and to the plant of the robust design (the hold), bounds the robust
        design's bandwidth, and is the step of the simulations.  The
        verdict then includes the digital loop of :meth:`PIDResult.to_discrete`
        at ``dt`` (Tustin controller, plant with its input held): ``success``
        means ``to_discrete(dt)`` succeeds too.
    u_limit : (lo, hi), optional
        Actuator limits (``lo < hi``), with back-calculation anti-windup.
    tau_c : float, optional
        SIMC ``tau_c`` / IMC ``lambda``.  Default: chosen and detuned until the
        robustness target holds.
    reference : "step" or array_like
        Model-based tuning's reference: a step of ``step`` or samples at
        ``dt`` (relative to ``y0``).
    step : float, optional
        Step of the reference from ``y0`` (tuning and verification); default
        one the actuator can make (half its room).
    t_final : float, optional
        Horizon of the simulations.
    criterion : {"iae", "ise", "itae"}, default "itae"
    max_overshoot : float or None, default 0.1
        Step overshoot beyond which model-based tuning is penalised.
    start : (kp, ki, kd), optional
        Start of model-based tuning (default: the robust design); zeros allowed.
    maxfev, seed, options
        Model-based tuning's budget, seed and optimiser options.

    Returns
    -------
    PIDResult
        ``success``, ``message`` and the verification's figures with the gains.

    Raises
    ------
    ParameterError, UnknownNameError, DataError
        Unstable or non-finite model, unknown rule or criterion, a reference
        shorter than two samples, ``lo >= hi``, an unreachable operating point.

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> model = hc.HammersteinModel(([1.0], [1.0, 3.0, 2.0]), hc.Tanh(), [2.0, 1.0])
    >>> pid = tune_pid(model)
    >>> [round(v, 2) for v in (pid.kp, pid.ki, pid.kd)]
    [8.52, 21.18, 1.71]
    """
    model = _siso_model(model, "tune_pid")
    key, crit = _check_rule(rule), _check_criterion(criterion)
    limits = check_limits(u_limit)
    dt = _check_dt(dt)
    if kind not in ("pid", "pi"):
        raise ParameterError(f"kind must be 'pid' or 'pi', got {kind!r}")
    ms = _robustness_target(max_sensitivity, phase_margin)
    _check_scalars(step=step, tau_c=tau_c, t_final=t_final, bandwidth=bandwidth)
    _check_range(model)
    delayed, model = model, _rational(model)
    op = _operating_point(model, u0, y0, u_limit)
    P = small_signal(model, op)
    num, den = np.asarray(P.num[0][0], float), np.asarray(P.den[0][0], float)
    _check_range(num=num, den=den)
    record = {"notes": list(op.notes), "max_sensitivity": ms}
    if delayed is not model:
        record["notes"].append(f"dead time {delayed.delay:.4g} s: the loop figures use its Pade approximant "
                               f"of order {pade_order_of()}")
    if key in ("simc", "imc"):
        gains, record = _rule_design(model, key, op, dt, limits, tau_c, step, ms, num, den, record, delayed)
    else:
        if bandwidth is None and dt is not None:    # the plant's, not the hold's approximant's poles
            bandwidth = default_bandwidth(num, den, dt)
        gains = _robust_design(model, op, *_with_hold(num, den, dt), ms=ms, kind=kind, bandwidth=bandwidth, dt=dt,
                               limits=limits, step=step, record=record)
    extra = {}
    if key in ("nspsa", "auto"):
        gains, extra = _tune_model_based(model, key, gains if start is None else _start(start), op, dt=dt,
                                         u_limit=u_limit, reference=reference, step=step, t_final=t_final,
                                         criterion=crit, max_overshoot=max_overshoot, maxfev=maxfev, seed=seed,
                                         options=options, ms=ms, kind=kind, record=record, bandwidth=bandwidth)
    _check_gains(gains)
    return _verified(model, key, gains, op, record, dt=dt, limits=limits, u_limit=u_limit, step=step,
                     t_final=t_final, ms=ms, **extra)


def _check_scalars(**values) -> None:
    """Each given value finite; ``step`` non-zero, the others positive (refused before any design)."""
    for name, value in values.items():
        if value is None:
            continue
        try:
            v = float(value)
        except (TypeError, ValueError, OverflowError):
            v = math.nan
        ok = math.isfinite(v) and (v != 0 if name == "step" else v > 0) and not isinstance(value, bool)
        if not ok:
            raise ParameterError(f"{name} must be a finite, {'non-zero' if name == 'step' else 'positive'} number, "
                                 f"got {value!r}")


#: A model whose gain stays beyond this (or below its inverse) at every frequency cannot be given sensible gains.
_GAIN_RANGE = 1e50
_RESCALE = "rescale the model (its signals' units) so that its gain and time constants are nearer 1"


def _check_range(model=None, *, num=None, den=None) -> None:
    """Refuse a model, or its linearisation ``num/den``, whose numbers a design would overflow with."""
    if model is not None:
        lin = model.linear
        num, den = np.asarray(lin.num[0][0], float), np.asarray(lin.den[0][0], float)
        for label, p in (("input", model.input_params), ("output", model.output_params)):
            if p is not None and np.max(np.abs(p), initial=0.0) > MAX_MAGNITUDE:
                raise ParameterError(f"the {label} nonlinearity's parameters {p.tolist()} exceed {MAX_MAGNITUDE:g} "
                                     f"in magnitude: {_RESCALE}")
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
        raise ParameterError(f"the linear block has non-finite coefficients (num {num.tolist()}, den {den.tolist()})")
    den = np.trim_zeros(den, "f")
    with np.errstate(all="ignore"):
        scaled = np.concatenate([num, den]) / den[0]
    if not np.all(np.isfinite(scaled)) or np.max(np.abs(scaled)) > MAX_MAGNITUDE:
        raise ParameterError(f"the linear block's coefficients (num {num.tolist()}, den {den.tolist()}) span more "
                             f"than {MAX_MAGNITUDE:g}: no design is numerically meaningful; {_RESCALE}")
    if not np.any(num):
        raise ParameterError("the model's gain is zero at this operating point: the controller cannot move the "
                             "output; choose another operating point (u0, y0)")
    s = 1j * frequency_grid(num, den)
    with np.errstate(all="ignore"):     # the gains a design needs are about 1/|P| somewhere on the grid
        gain = np.abs(np.polyval(num, s) / np.polyval(den, s))
    if not (np.max(gain) > _GAIN_RANGE ** -1 and np.min(gain) < _GAIN_RANGE):
        raise ParameterError(f"the model's gain |P(jw)| lies in [{np.min(gain):.3g}, {np.max(gain):.3g}] over its "
                             f"frequencies: a controller would need gains beyond {_GAIN_RANGE:g} or below "
                             f"{_GAIN_RANGE ** -1:g}; {_RESCALE}")


def _check_gains(gains) -> None:
    """Refuse gains beyond :data:`MAX_MAGNITUDE`: the model's gain is outside any numerically sound scale."""
    values = np.asarray(gains[:3], dtype=float)
    if not np.all(np.isfinite(values)) or np.max(np.abs(values)) > MAX_MAGNITUDE:
        raise ParameterError(f"the designed gains (kp, ki, kd) = {values.tolist()} are beyond {MAX_MAGNITUDE:g}: "
                             f"the model's gain is far outside any physical scale; {_RESCALE}")


#: Redesigns of the robust rule over the operating range the loop visits (its gain varies with it).
RANGE_ITERATIONS = 4


def _visited_range(model, op, step: float, kp: float, limits) -> tuple[list, list]:
    """``(inputs, outputs of H)`` a step of ``step`` visits: the rest points before and after it, and the
    proportional kick ``kp * step`` (within the actuator limits)."""
    from ._operating_point import _inverse_output

    lo, hi = limits
    kick = abs(kp * step)
    inputs = [op.u0, min(max(op.u0 + kick, lo), hi), min(max(op.u0 - kick, lo), hi)]
    outputs = [op.z0]
    try:
        after = operating_point(model, y0=op.y0 + step, u_limit=None if not (
            math.isfinite(lo) or math.isfinite(hi)) else (lo, hi)) if not op.integrating else None
    except ParameterError:
        after = None
    if after is not None:
        inputs.append(after.u0)
        outputs.append(after.z0)
    elif op.integrating:
        try:
            outputs.append(_inverse_output(model, op.y0 + step))
        except ParameterError:
            pass
    return inputs, outputs


def _robust_design(model, op, num, den, *, ms, kind, bandwidth, dt, limits, step, record):
    """The robust rule, redesigned until it holds over the range of small-signal gains the step visits."""
    from ._operating_point import gain_factors

    factors = (1.0,)
    gains = ms_constrained_pid(num, den, max_sensitivity=ms, kind=kind, bandwidth=bandwidth, dt=dt)
    for _ in range(RANGE_ITERATIONS):
        size = _default_step(model, op, limits, gains[0]) if step is None else float(step)
        visited = gain_factors(model, op, *_visited_range(model, op, size, gains[0], limits))
        if visited == factors or (len(visited) == 1 and factors == (1.0,)):
            break
        factors = tuple(sorted(set(factors) | set(visited)))
        factors = (min(factors), max(factors)) if len(factors) > 2 else factors
        factors = tuple(sorted(set(factors + (float(np.sqrt(factors[0] * factors[-1])), 1.0))))
        gains = ms_constrained_pid(num, den, max_sensitivity=ms, kind=kind, bandwidth=bandwidth, dt=dt,
                                   gain_factors=factors)
    if factors != (1.0,):
        record["notes"].append(f"designed for the small-signal gain from {factors[0]:.3g} to {factors[-1]:.3g} times "
                               "the operating point's (the range the step visits)")
    record.update(bandwidth=bandwidth, gain_factors=factors)
    return gains


def _start(start) -> tuple[float, float, float]:
    g = np.asarray(start, dtype=float).reshape(-1)
    if g.size != 3 or not np.all(np.isfinite(g)) or not np.any(g):
        raise ParameterError(f"start must be three finite gains (kp, ki, kd), not all zero, got {start!r}")
    return tuple(float(v) for v in g)


def _rule_design(model, key, op, dt, limits, tau_c, step, ms, num, den, record, delayed=None):
    """SIMC or IMC gains; without ``tau_c``, detuned until ``max(Ms, Mt) <= ms``.

    The half rule reads the model with its dead time (``delayed``), the loop figures its rational form.
    """
    a = approximate(model if delayed is None else delayed, dt=dt, op=op)
    a["notes"] = record["notes"] + [n for n in a["notes"] if n not in record["notes"]]
    design = _simc if key == "simc" else _imc
    if tau_c is not None:
        if not (math.isfinite(tau_c) and tau_c > 0):
            raise ParameterError(f"tau_c must be positive and finite, got {tau_c!r}")
        a["tau_c"] = float(tau_c)
        a.update(max_sensitivity=ms)
        return _with_filter(design(a, float(tau_c))), a
    from ._operating_point import gain_factors

    tau = _start_tau_c(a, limits, op.u0, step if step is not None else 0.0, a["notes"])
    for count in range(MAX_DETUNE + 1):
        gains = _with_filter(design(dict(a), tau))
        size = _default_step(model, op, limits, gains[0]) if step is None else float(step)
        factors = gain_factors(model, op, *_visited_range(model, op, size, gains[0], limits))
        held = _with_hold(num, den, dt)             # the digital loop's hold, which the verdict checks
        figs = [loop_figures(k * held[0], held[1], *gains) for k in factors]
        if all(f["stable"] and max(f["Ms"], f["Mt"]) <= ms * MS_SLACK for f in figs):
            if count:
                a["notes"].append(f"detuned {count} time(s) to tau_c = {tau:.4g} for Ms and Mt <= {ms:g}")
            break
        tau *= DETUNE_FACTOR
    a["tau_c"] = float(tau)
    a["max_sensitivity"] = ms
    return gains, a


def _with_filter(gains) -> tuple[float, float, float, float]:
    kp, ki, kd = (float(v) for v in gains)
    return kp, ki, kd, (abs(kd / kp) / FILTER_RATIO if kd != 0 else 0.0)


#: N-SPSA defaults in scaled-gain space: perturbations of 5 %, a(k) = 1/(k + A)^0.602 (measured on EMPS).
NSPSA_A = 0.2
NSPSA_C = 0.05


def _tune_model_based(model, key, start, op, *, dt, u_limit, reference, step, t_final, criterion, max_overshoot,
                      maxfev, seed, options, ms, kind, record, bandwidth=None) -> tuple[tuple, dict]:
    from threadpoolctl import threadpool_limits

    from ..optimize import PerturbationGain, StepGain, minimize

    P = small_signal(model, op)
    num, den = np.asarray(P.num[0][0], float), np.asarray(P.den[0][0], float)
    robust = ms_constrained_pid(num, den, max_sensitivity=ms, kind="pid", dt=dt)
    start = tuple(start[:3])
    scale = np.where(np.asarray(start) != 0, np.abs(start), np.abs(robust[:3]))
    scale = np.where(scale > 0, scale, 1.0)
    dt_sim, horizon = _tuning_grid(_with_filter(start if start[0] else robust[:3]), op, num, den, dt, t_final)
    step = _default_step(model, op, check_limits(u_limit), start[0] or robust[0]) if step is None else float(step)
    r, is_step = _reference(reference, step, dt_sim, horizon)
    cost = TuningCost(model, r, dt_sim, u_limit=u_limit, criterion=criterion, scale=scale, is_step=is_step,
                    max_overshoot=max_overshoot, op=op, max_sensitivity=ms, kind=kind, bandwidth=bandwidth)
    x0 = np.asarray(start, dtype=float) / scale
    if key == "nspsa":
        method = "nspsa"
        opts = {"a": StepGain(NSPSA_A, 0.1 * maxfev / 2), "c": PerturbationGain(NSPSA_C)}
        opts.update(options or {})
    else:
        method, opts = "nelder-mead", dict(options or {})
    with threadpool_limits(1):
        res = minimize(cost, x0, method=method, maxfev=maxfev, seed=seed, options=opts)
        candidates = np.array([x0, res.x, getattr(res, "best_x", res.x)])
        values = cost.batch(candidates)
    best = int(np.nanargmin(values))
    kp, ki, kd, tf = cost.gains(candidates[best])[0]
    record["start"] = {"kp": float(start[0]), "ki": float(start[1]), "kd": float(start[2]), "cost": float(values[0])}
    return (float(kp), float(ki), float(kd), float(tf)), {"criterion": criterion, "cost": float(values[best]),
                                                         "optimize_result": res, "sim_dt": dt_sim}
