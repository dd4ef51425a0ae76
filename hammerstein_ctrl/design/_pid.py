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
from dataclasses import dataclass, field

import numpy as np

from .._deprecation import renamed
from .._checks import MAX_MAGNITUDE, as_signal, check_dt, require_siso_model
from .. import config
from ..exceptions import DataError, ParameterError, UnknownNameError
from ..blocks._model import pade_order_of
from ..simulate._loop import (back_calculation_gain, check_limits, sampled_loop_iosys, sampled_plant, saturation_iosys,
                              simulate_loops,)
from ._operating_point import OperatingPoint, operating_point, small_signal, static_output
from ._robust import (FILTER_RATIO, constraints, default_bandwidth, frequency_grid, loop_figures, ms_constrained_pid,
                      pid_polynomials)

__all__ = ["PIDResult", "DiscretePID", "tune_pid", "closed_loop", "analyze_loop", "approximate", "pid_controller",
           "TuningCost", "loop_figure", "RULES", "CRITERIA", "TRACKING_TOLERANCE"]

#: Tuning rules accepted by :func:`tune_pid` (the first is the default).
RULES = ("robust", "simc", "imc", "nspsa", "auto")
#: Closed-loop cost criteria.
CRITERIA = ("iae", "ise", "itae")
#: Default horizon of a model-based tuning simulation, in closed-loop time scales ``tau_c + theta``.
HORIZON_FACTOR = 20.0
#: Samples of a tuning simulation when no ``dt`` is given.
DEFAULT_SAMPLES = 2000
#: A diverged or linearly unstable loop costs this multiple of the do-nothing cost.
PENALTY_FACTOR = 10.0
#: Default bound on step overshoot in model-based tuning (fraction of the step).
MAX_OVERSHOOT = 0.1
#: Penalty per unit of overshoot beyond the bound, in multiples of the do-nothing cost.
OVERSHOOT_WEIGHT = 10.0
#: Default evaluation budget of model-based tuning.
DEFAULT_MAXFEV = 601
#: Relative size below which a pole counts as an integrator.
INTEGRATOR_TOL = 1e-9
#: The nonlinear loop tracks a step when its mean error over the last :data:`SETTLED_SHARE` of the
#: verification run is below this fraction of the step.
TRACKING_TOLERANCE = 0.02
SETTLED_SHARE = 0.05
#: Slack on the robustness target (the design grid and the verification grid differ slightly).
MS_SLACK = 1.02
#: Detuning of SIMC/IMC: ``tau_c`` grows by this factor until the target holds, at most :data:`MAX_DETUNE` times.
DETUNE_FACTOR = 1.5
MAX_DETUNE = 40
#: Longest verification simulation, in samples.
MAX_VERIFY_SAMPLES = 20000
#: A verification run that has not settled is run again this many times longer (same number of samples,
#: unless the controller's own dt fixes the step).
LONGER_HORIZON = 5.0
#: Step overshoot (%) past which the result warns.
LARGE_OVERSHOOT = 50.0


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
# tuning rules
# ---------------------------------------------------------------------------
def _series_to_parallel(kc: float, ti: float, td: float) -> tuple[float, float, float]:
    """Series PID ``Kc (1 + 1/(Ti s))(1 + Td s)`` in parallel form ``(kp, ki, kd)``."""
    return kc * (1 + td / ti), kc / ti, kc * td


def _simc(a: dict, tau_c: float):
    t = tau_c + a["theta"]
    if a["kind"] == "integrating":
        kc, ti = 1.0 / (a["gain"] * t), config.get("control.simc_ti_factor") * t
    else:
        kc, ti = a["tau1"] / (a["gain"] * t), min(a["tau1"], config.get("control.simc_ti_factor") * t)
    return _series_to_parallel(kc, ti, a["tau2"])


def _imc(a: dict, lam: float):
    """IMC/lambda PID; for a self-regulating plant on its first-order-plus-delay form (noted in ``a``)."""
    th = a["theta"]
    if a["kind"] == "integrating":
        kc = (2 * lam + th) / (a["gain"] * (lam + th) ** 2)
        return _series_to_parallel(kc, 2 * lam + th, a["tau2"])
    tau = a["tau1"] + a["tau2"] / 2  # half rule once more: tau2 split between tau1 and the delay
    th = th + a["tau2"] / 2
    kc = (2 * tau + th) / (a["gain"] * (2 * lam + th))
    return kc, kc / (tau + th / 2), kc * tau * th / (2 * tau + th)


def _start_tau_c(a: dict, limits, u0: float, step: float, notes: list) -> float:
    """The first ``tau_c`` of an automatic SIMC/IMC design: the effective delay, else the model's smallest kept
    time scale (``tau2``, else ``tau1``), raised so that the proportional kick of ``step`` fits the actuator."""
    tau = a["theta"] if a["theta"] > 0 else (a["tau2"] if a["tau2"] > 0 else
                                               (a["tau1"] if math.isfinite(a["tau1"]) else 1.0))
    lo, hi = limits
    if math.isfinite(lo) or math.isfinite(hi):
        room = min(hi - u0, u0 - lo)
        scale = 1.0 if a["kind"] == "integrating" else a["tau1"]
        tau_input = scale * abs(step) / (abs(a["gain"]) * room) - a["theta"]
        if tau_input > tau:
            notes.append(f"tau_c = {tau_input:.4g} so that kp * |step| stays within the actuator room {room:.4g}")
            tau = tau_input
    return tau


def pid_controller(kp: float, ki: float, kd: float, tf: float):
    """Parallel PID with filtered derivative, ``kp + ki/s + kd s/(tf s + 1)``.

    Examples
    --------
    >>> pid_controller(2.0, 1.0, 0.5, 0.05).num[0][0].tolist()
    [0.6, 2.05, 1.0]
    """
    import control

    if kd != 0.0 and not tf > 0:
        raise ParameterError("a derivative term needs a filter time constant tf > 0")
    num, den = pid_polynomials(kp, ki, kd, tf)
    return control.tf(num, den, inputs="e", outputs="uc", name="pid")


@dataclass
class DiscretePID:
    """A digital PID (:meth:`PIDResult.to_discrete`), verified on the exact discrete plant.

    Attributes
    ----------
    controller : control.TransferFunction
        ``e -> u`` with sampling interval ``dt`` (add the operating point's
        input to its output, as :func:`closed_loop` does).
    dt : float
    method : str
        The discretisation of the continuous PID (``control.sample_system``'s).
    stable, Ms, Mt, gain_margin, phase_margin, poles
        Of the loop with the plant sampled with its input held (a DAC).
    success : bool
        Stable and within the robustness target of the continuous design.
    message : str
    """

    controller: object = field(repr=False)
    dt: float
    method: str
    stable: bool
    Ms: float
    Mt: float
    gain_margin: float
    phase_margin: float
    poles: np.ndarray = field(repr=False)
    success: bool = False
    message: str = ""


@dataclass
class PIDResult:
    """A tuned PID ``kp + ki/s + kd s/(tf s + 1)`` (parallel form), with its verification.

    Attributes
    ----------
    kp, ki, kd, tf : float
        Gains and derivative-filter time constant.
    rule : str
    success : bool
        The controller can be used: stable linearised loop, ``Ms`` and ``Mt``
        within the target, and the nonlinear loop tracks a step from the
        operating point within 2 %.
    message : str
        What was checked, or why it failed and what to do.
    warnings : list of str
    stable : bool
        Every closed-loop pole of the linearised loop in the open left half-plane.
    gain_margin, phase_margin, delay_margin : float
        Of the linearised loop (phase margin in degrees, delay margin in seconds).
    Ms, Mt : float
        Peak sensitivity and complementary sensitivity.
    max_sensitivity : float
        The robustness target the design met (or missed).
    poles : ndarray
        Closed-loop poles of the linearised loop.
    step : dict
        The nonlinear loop's step from the operating point: ``step`` (size),
        ``final_error`` (fraction of the step), ``Overshoot`` (%), ``RiseTime``,
        ``SettlingTime`` (s, python-control's ``step_info`` relative to the
        operating point), ``u_max`` (largest actuator excursion from ``u0``),
        ``saturated`` (fraction of samples at a limit), ``t_final``, ``dt``.
    operating_point : OperatingPoint
    controller : control.TransferFunction
        The parallel-form controller (input ``e``, output ``uc``; add ``u0``).
    iosys : control.StateSpace
        The same controller as a python-control I/O system.
    approximation : dict
        The design's record (the half-rule reduction for SIMC/IMC, ``tau_c``,
        the start of model-based tuning, notes).
    u0 : float
        The operating point's input.
    dt : float or None
        Sampling interval of the design.
    linearized : control.TransferFunction
        ``h'(z0) H(p) g'(u0)``.
    cost, criterion, optimize_result
        Model-based tuning.
    """

    kp: float
    ki: float
    kd: float
    tf: float
    rule: str
    controller: object = field(repr=False)
    iosys: object = field(repr=False)
    approximation: dict = field(repr=False)
    u0: float = 0.0
    dt: float | None = None
    linearized: object = field(default=None, repr=False)
    criterion: str | None = None
    cost: float | None = None
    optimize_result: object = field(default=None, repr=False)
    success: bool = False
    message: str = ""
    warnings: list = field(default_factory=list)
    stable: bool = False
    gain_margin: float = math.nan
    phase_margin: float = math.nan
    delay_margin: float = math.nan
    Ms: float = math.nan
    Mt: float = math.nan
    max_sensitivity: float = math.nan
    poles: np.ndarray = field(default=None, repr=False)
    step: dict = field(default_factory=dict, repr=False)
    operating_point: OperatingPoint | None = field(default=None, repr=False)
    model: object = field(default=None, repr=False)

    @property
    def kt(self) -> float:
        """Back-calculation anti-windup gain ``1/Tt``."""
        return back_calculation_gain(abs(self.kp), abs(self.ki), abs(self.kd))

    @property
    def gains(self) -> np.ndarray:
        """``[kp, ki, kd, tf, kt]``, the row :func:`~hammerstein_ctrl.simulate.simulate_loops` takes."""
        return np.array([self.kp, self.ki, self.kd, self.tf, self.kt])

    def summary(self) -> str:
        """The gains, the verification and the verdict."""
        status = "ok" if self.success else "FAILED"
        st = self.step
        lines = [f"{self.rule} PID: kp = {self.kp:.6g}, ki = {self.ki:.6g}, kd = {self.kd:.6g}, tf = {self.tf:.6g} "
                 f"[{status}: {self.message}]",
                 f"  linearised loop at u0 = {self.u0:.6g}: {'stable' if self.stable else 'UNSTABLE'}, Ms = "
                 f"{self.Ms:.3g}, Mt = {self.Mt:.3g} (target {self.max_sensitivity:.3g}), gain margin "
                 f"{self.gain_margin:.3g}, phase margin {self.phase_margin:.3g} deg, delay margin "
                 f"{self.delay_margin:.3g} s"]
        if st:
            lines.append(f"  nonlinear loop, step {st['step']:.4g} from y0 = {self.operating_point.y0:.6g}: final "
                         f"error {100 * st['final_error']:.2g} %, overshoot {st.get('Overshoot', math.nan):.3g} %, "
                         f"rise {st.get('RiseTime', math.nan):.3g} s, "
                         f"settling {st.get('SettlingTime', math.nan):.3g} s,"
                         f" saturated {100 * st['saturated']:.0f} % of the time")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def _repr_pretty_(self, printer, cycle):
        printer.text(self.summary())

    def to_discrete(self, dt: float, method: str = "tustin") -> DiscretePID:
        """The controller discretised for a digital implementation, verified on the exact discrete plant.

        Parameters
        ----------
        dt : float
            Sampling interval.
        method : str, default "tustin"
            ``control.sample_system``'s method (``"tustin"``, ``"zoh"``,
            ``"backward_diff"``, ...).

        Returns
        -------
        DiscretePID
            ``success`` is False (with the reason) when the digital loop is
            unstable or misses the robustness target of the continuous design.

        Examples
        --------
        >>> import control as ct
        >>> from hammerstein_ctrl import HammersteinModel, Tanh
        >>> m = HammersteinModel(ct.tf([2.0], [1, 3, 2]), Tanh(), [1.5, 0.8])
        >>> d = tune_pid(m).to_discrete(0.01)
        >>> d.success, d.controller.dt
        (True, 0.01)
        """
        dt = _check_dt(dt)
        cd, fig, ok, message = _digital_check(self.controller, self.linearized, dt, self.max_sensitivity, method)
        return DiscretePID(cd, dt, method, fig["stable"], fig["Ms"], fig["Mt"], fig["gain_margin"],
                           fig["phase_margin"], fig["poles"], bool(ok), message)


# ---------------------------------------------------------------------------
# references, steps and loop costs
# ---------------------------------------------------------------------------
def _reference(reference, step: float, dt: float, t_final: float) -> tuple[np.ndarray, bool]:
    """(samples relative to the operating point's output, is_step)."""
    if isinstance(reference, str):
        if reference != "step":
            raise ParameterError(f"reference must be 'step' or an array of samples, got {reference!r}")
        if not (math.isfinite(step) and step != 0):
            raise ParameterError(f"the step amplitude must be finite and non-zero, got {step!r}")
        return np.full(int(round(t_final / dt)) + 1, float(step)), True
    r = as_signal(reference, "reference")
    if r.size < 2:
        raise DataError(f"the reference needs at least two samples, got {r.size}")
    return r, False


def _criterion(E: np.ndarray, dt: float, kind: str) -> np.ndarray:
    t = dt * np.arange(E.shape[-1])
    if kind == "iae":
        return dt * np.sum(np.abs(E), axis=-1)
    if kind == "ise":
        return dt * np.sum(E * E, axis=-1)
    return dt * np.sum(t * np.abs(E), axis=-1)


def _overshoot(Y: np.ndarray, r: np.ndarray) -> np.ndarray:
    final = r[-1]
    with np.errstate(all="ignore"):
        return np.maximum(0.0, np.max(np.sign(final) * (Y - final), axis=-1) / abs(final))


def _default_step(model, op: OperatingPoint, limits, kp: float | None) -> float:
    """A step of the reference that the actuator can make: the output change for half the actuator's room
    (self-regulating plant), or the step whose proportional kick uses half of it (integrating); 1 without limits
    on an integrating plant, and for a unit input change on a self-regulating one."""
    lo, hi = limits
    u0 = op.u0
    if op.integrating:
        if (math.isfinite(lo) or math.isfinite(hi)) and kp:
            return 0.5 * min(hi - u0, u0 - lo) / abs(kp)
        return 1.0
    if math.isfinite(lo) or math.isfinite(hi):
        target = u0 + 0.5 * (hi - u0) if hi - u0 >= u0 - lo else u0 - 0.5 * (u0 - lo)
    else:
        target = u0 + max(1.0, abs(u0))
    dy = float(static_output(model, target)[0]) - op.y0
    return dy if math.isfinite(dy) and dy != 0 else 1.0


class TuningCost:
    """Closed-loop cost of PID gains on the nonlinear sampled loop started at the operating point.

    ``cost(theta)`` with gains ``[kp, ki, kd] = scale * theta`` (a P, PI or PID
    start is a point like any other); ``cost.batch(thetas)`` evaluates many
    candidates in one compiled simulation.  The reference ``r`` is relative
    to the operating point's output.  Penalties (in multiples of the
    do-nothing cost ``J0``, the criterion of ``e = r``): ``PENALTY_FACTOR``
    for an unstable linearised loop or a diverging simulation,
    ``OVERSHOOT_WEIGHT`` per unit of step overshoot beyond ``max_overshoot``
    and per unit of ``max(Ms, Mt)`` beyond ``max_sensitivity``.
    """

    def __init__(self, model, r, dt, *, u_limit=None, criterion="itae", scale=(1.0, 1.0, 1.0), is_step=True,
                 max_overshoot=MAX_OVERSHOOT, op: OperatingPoint | None = None,
                 max_sensitivity: float | None = None, kind: str = "pid", bandwidth: float | None = None):
        self.model, self.r, self.dt, self.u_limit = model, np.asarray(r, float), float(dt), u_limit
        self.criterion, self.is_step, self.kind = criterion, is_step, kind
        self.max_overshoot = max_overshoot
        self.max_sensitivity = (config.get("control.max_sensitivity") if max_sensitivity is None
                                else float(max_sensitivity))
        self.scale = np.asarray(scale, dtype=float)
        self.op = op if op is not None else operating_point(model)
        P = small_signal(model, self.op)
        self._num, self._den = (np.asarray(c, dtype=float) for c in (P.num[0][0], P.den[0][0]))
        self.bandwidth = default_bandwidth(self._num, self._den, dt) if bandwidth is None else float(bandwidth)
        self._w = frequency_grid(self._num, self._den, bandwidth=self.bandwidth)
        self._P = np.polyval(self._num, 1j * self._w) / np.polyval(self._den, 1j * self._w)
        self.J0 = float(_criterion(self.r[None, :], self.dt, criterion)[0])
        self._plant = sampled_plant(model, self.dt, x0=self.op.x0)

    def gains(self, thetas) -> np.ndarray:
        """Rows ``kp, ki, kd, tf``."""
        K = self.scale * np.atleast_2d(np.asarray(thetas, dtype=float))
        if self.kind == "pi":
            K[:, 2] = 0.0
        with np.errstate(all="ignore"):
            tf = np.where(K[:, 2] != 0, np.abs(K[:, 2] / np.where(K[:, 0] != 0, K[:, 0], 1.0)) / FILTER_RATIO, 0.0)
        return np.column_stack([K, tf])

    def robustness(self, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(unacceptable, peak)``: an unstable or conditionally stable linearised loop, or one crossing over
        above the bandwidth (:func:`~hammerstein_ctrl.design._robust.constraints`); and ``max(Ms, Mt)``."""
        unstable = np.zeros(G.shape[0], dtype=bool)
        for i, (kp, ki, kd, tf) in enumerate(G[:, :4]):
            cn, cd = pid_polynomials(kp, ki, kd, tf)
            char = np.trim_zeros(np.polyadd(np.polymul(self._den, cd), np.polymul(self._num, cn)), "f")
            unstable[i] = not (char.size and np.all(np.isfinite(char))) or np.any(np.roots(char).real >= 0)
        peak, conditional, too_fast = constraints(self._P, self._w, G[:, 0], G[:, 1], G[:, 2], G[:, 3],
                                                  self.max_sensitivity, self.bandwidth)
        return unstable | conditional | too_fast, np.where(np.isfinite(peak), peak, np.inf)

    def evaluate(self, G: np.ndarray) -> dict:
        """Criterion, overshoot and flags of gain rows ``G`` (no penalties)."""
        Y, U = simulate_loops(self._plant, G, self.r + self.op.y0, self.dt, u_limit=self.u_limit, bias=self.op.u0)
        Y -= self.op.y0
        diverged = ~np.all(np.isfinite(Y), axis=1)
        with np.errstate(all="ignore"):
            value = _criterion(self.r - Y, self.dt, self.criterion)
        overshoot = _overshoot(Y, self.r) if self.is_step else np.zeros(G.shape[0])
        return {"value": value, "overshoot": overshoot, "diverged": diverged, "Y": Y, "U": U}

    def batch(self, thetas) -> np.ndarray:
        """Penalised cost of each row of ``thetas``."""
        G = self.gains(thetas)
        ok = np.all(np.isfinite(G), axis=1)
        G[~ok] = 0.0
        res = self.evaluate(G)
        unstable, peak = self.robustness(G)
        bad = res["diverged"] | unstable | ~ok
        value = np.where(bad, PENALTY_FACTOR * self.J0, res["value"])
        excess = np.maximum(0.0, res["overshoot"] - self.max_overshoot) if self.max_overshoot is not None else 0.0
        fragile = np.maximum(0.0, peak - self.max_sensitivity)
        return value + OVERSHOOT_WEIGHT * self.J0 * np.where(bad, 0.0, excess + fragile)

    def __call__(self, theta) -> float:
        return float(self.batch(np.asarray(theta, dtype=float)[None, :])[0])


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


def _check_dt(dt):
    return None if dt is None else check_dt(dt, error=ParameterError)


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


def _tuning_grid(gains, op, num, den, dt, t_final) -> tuple[float, float]:
    """(dt, t_final) of a tuning simulation: ``dt``, else fast enough for the design's loop; ``t_final`` ten times
    its slowest closed-loop time constant."""
    fig = loop_figures(num, den, *gains)
    poles = fig["poles"][np.isfinite(fig["poles"])]
    fastest = max(float(np.max(np.abs(poles), initial=0.0)), fig["w_gain_crossover"] if np.isfinite(
        fig["w_gain_crossover"]) else 0.0, 1e-9)
    slowest = float(np.min(np.abs(poles.real), initial=fastest)) if poles.size else fastest
    if t_final is None:
        t_final = min(10.0 / max(slowest, 1e-12), HORIZON_FACTOR * 50.0 / fastest)
    if not (math.isfinite(t_final) and t_final > 0):
        raise ParameterError(f"t_final must be positive and finite, got {t_final!r}")
    if dt is None:
        dt = max(1.0 / (20.0 * fastest), t_final / MAX_VERIFY_SAMPLES)
    return float(dt), float(t_final)


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


# ---------------------------------------------------------------------------
# verification
# ---------------------------------------------------------------------------
def _step_figures(y: np.ndarray, t: np.ndarray, final: float) -> dict:
    """python-control's ``step_info`` of a response relative to the operating point."""
    import control

    if not np.all(np.isfinite(y)):
        return {"diverged": True}
    try:
        info = control.step_info(y, t, yfinal=final)
    except (IndexError, ValueError):  # the response never reaches the rise-time thresholds
        return {"RiseTime": math.nan, "SettlingTime": math.nan, "Overshoot": math.nan}
    return {k: float(v) for k, v in info.items()}


def _nonlinear_step(model, gains, op, *, u_limit, step, dt, t_final) -> dict:
    """The nonlinear loop's step of ``step`` from rest at the operating point, and its figures."""
    n = int(round(t_final / dt)) + 1
    r = np.full(n, op.y0 + step)
    Y, U = simulate_loops(model, np.asarray(gains)[None, :], r, dt, u_limit=u_limit, bias=op.u0, x0=op.x0)
    y, u = Y[0], U[0]
    t = dt * np.arange(n)
    tail = max(2, int(SETTLED_SHARE * n))
    lo, hi = check_limits(u_limit)
    with np.errstate(all="ignore"):
        final_error = float(np.mean(np.abs(y[-tail:] - r[-tail:])) / abs(step))
        saturated = float(np.mean((u <= lo) | (u >= hi))) if math.isfinite(lo) or math.isfinite(hi) else 0.0
        at_limit_end = bool(np.all((u[-tail:] <= lo) | (u[-tail:] >= hi)))
    out = {"step": float(step), "final_error": final_error if math.isfinite(final_error) else math.inf,
           "u_max": float(np.nanmax(np.abs(u - op.u0))), "saturated": saturated, "limited_at_end": at_limit_end,
           "t_final": float(t_final), "dt": float(dt), "t": t, "r": r, "y": y, "u": u}
    out.update(_step_figures(y - op.y0, t, step))
    return out


def _unreachable(model, op: OperatingPoint, step: float, limits) -> bool:
    """Whether a self-regulating plant needs, at rest after the step, an input outside the actuator limits."""
    lo, hi = limits
    if op.integrating or not (math.isfinite(lo) or math.isfinite(hi)):
        return False
    try:
        operating_point(model, y0=op.y0 + step, u_limit=limits)
    except ParameterError:
        return True
    return False


def _verdict(fig: dict, nl: dict | None, ms: float, op: OperatingPoint) -> tuple[bool, str, list]:
    """``(success, message, warnings)`` of a verified controller."""
    warnings = list(op.notes)
    peak = max(fig["Ms"], fig["Mt"])
    if not fig["stable"]:
        worst = max(fig["poles"], key=lambda p: p.real)
        return False, (f"the linearised loop is unstable (a closed-loop pole at {worst:.4g}): use the default "
                       "rule='robust', or a smaller gain"), warnings
    problems = []
    if peak > ms * MS_SLACK:
        problems.append(f"not robust: Ms = {fig['Ms']:.3g}, Mt = {fig['Mt']:.3g} exceed the target {ms:g} (gain "
                        f"margin {fig['gain_margin']:.3g}, phase margin {fig['phase_margin']:.3g} deg); detune "
                        "(a larger tau_c) or use rule='robust'")
    if nl is not None:
        if nl.get("diverged"):
            problems.append("the nonlinear loop diverges from the operating point")
        elif nl["final_error"] > TRACKING_TOLERANCE:
            if nl.get("unreachable"):
                problems.append(f"the actuator limits cannot hold a step of {nl['step']:.4g} from y0 = {op.y0:.4g} "
                                f"(at rest it needs an input outside them): choose a smaller step or wider limits")
            elif nl["limited_at_end"]:
                problems.append(f"the nonlinear loop is still at an actuator limit after {nl['t_final']:.4g} s "
                                f"({100 * nl['final_error']:.0f} % short of the step): the gains are too high for "
                                "the limits; use rule='robust', or give u_limit to the tuning")
            else:
                problems.append(f"the nonlinear loop has not settled within {nl['t_final']:.4g} s (error "
                                f"{100 * nl['final_error']:.1f} % of the step): a limit cycle or a slow tail; "
                                "look at analyze_loop")
        else:
            if nl["saturated"] > 0.5:
                warnings.append(f"the actuator sits at a limit {100 * nl['saturated']:.0f} % of the step's time")
            if nl.get("Overshoot", 0.0) > LARGE_OVERSHOOT:
                warnings.append(f"the step overshoots by {nl['Overshoot']:.0f} %: a smaller step, a lower "
                                "max_sensitivity, or rule='nspsa' (which bounds it) helps")
    if problems:
        return False, "; ".join(problems), warnings
    tracked = (f"; the nonlinear loop settles a step of {nl['step']:.4g} from y0 = {op.y0:.4g} within "
               f"{100 * TRACKING_TOLERANCE:g} % (overshoot {nl.get('Overshoot', math.nan):.3g} %)") if nl else ""
    return True, (f"verified: stable, Ms = {fig['Ms']:.3g}, Mt = {fig['Mt']:.3g} <= {ms:g}, phase margin "
                  f"{fig['phase_margin']:.3g} deg{tracked}"), warnings


def _digital_check(controller, linearized, dt: float, ms: float, method: str = "tustin", *, tuned: bool = False):
    """``(discrete controller, figures, ok, message)`` of ``controller`` sampled at ``dt`` (``method``) on the
    plant ``linearized`` sampled with its input held: stable, and ``Ms``, ``Mt`` within the target ``ms``
    (``tuned``: the design already took ``dt`` into account, so the advice is to sample faster or detune)."""
    import control

    from ._robust import discrete_loop_figures

    cd = control.sample_system(controller, dt, method=method)
    pd = control.sample_system(linearized, dt, method="zoh")
    L = cd * pd
    fig = discrete_loop_figures(np.asarray(L.num[0][0], float), np.asarray(L.den[0][0], float), dt)
    bound = ms * MS_SLACK
    ok = bool(fig["stable"] and fig["Ms"] <= bound and fig["Mt"] <= bound)
    if ok:
        message = (f"stable on the plant sampled at {dt:g} s with its input held: Ms = {fig['Ms']:.3g}, "
                   f"Mt = {fig['Mt']:.3g}")
    elif not fig["stable"]:
        message = (f"the digital loop at dt = {dt:g} s is unstable (closed-loop poles outside the unit circle): "
                   "sample faster")
    else:
        advice = ("sample faster, or detune (a larger tau_c, a smaller bandwidth)" if tuned
                  else f"sample faster, or tune with dt={dt:g}")
        message = (f"at dt = {dt:g} s the digital loop's Ms = {fig['Ms']:.3g}, Mt = {fig['Mt']:.3g} exceed "
                   f"{ms:g}: {advice}")
    return cd, fig, ok, message


def _with_hold(num, den, dt: float | None):
    """``num/den`` with the half-sample delay of a sampled controller's hold (a second-order Pade approximant),
    for a continuous design whose digital loop must meet the same target; unchanged without ``dt``."""
    if dt is None:
        return num, den
    import control

    pn, pd = control.pade(dt / 2.0, 2)
    return np.polymul(num, pn), np.polymul(den, pd)


def _verified(model, key, gains, op, record, *, dt, limits, u_limit, step, t_final, ms, criterion=None,
              cost=None, optimize_result=None, sim_dt=None) -> PIDResult:
    """The :class:`PIDResult` of ``gains``, with the linearised and the nonlinear loop checked."""
    import control

    kp, ki, kd, tf = gains
    P = small_signal(model, op)
    num, den = np.asarray(P.num[0][0], float), np.asarray(P.den[0][0], float)
    fig = loop_figures(num, den, kp, ki, kd, tf)
    nl = None
    if fig["stable"]:
        step = _default_step(model, op, limits, kp) if step is None else float(step)
        dt_sim, horizon = _tuning_grid((kp, ki, kd, tf), op, num, den, dt or sim_dt, t_final)
        full = (kp, ki, kd, tf, back_calculation_gain(abs(kp), abs(ki), abs(kd)))
        nl = _nonlinear_step(model, full, op, u_limit=u_limit, step=step, dt=dt_sim, t_final=horizon)
        nl["unreachable"] = _unreachable(model, op, step, limits)
        if t_final is None and TRACKING_TOLERANCE < nl["final_error"] < math.inf and not nl["unreachable"]:
            # a slow tail (a dead zone the integral winds through, a near pole-zero pair): look further
            nl = _nonlinear_step(model, full, op, u_limit=u_limit, step=step,
                                 dt=dt_sim if dt is not None else dt_sim * LONGER_HORIZON,
                                 t_final=horizon * LONGER_HORIZON)
            nl["unreachable"] = False
    success, message, warnings = _verdict(fig, nl, ms, op)
    controller = pid_controller(kp, ki, kd, tf)
    if dt is not None and fig["stable"]:        # the controller runs at dt: its digital loop is the one to meet
        _, digital, ok, said = _digital_check(controller, P, dt, ms, tuned=True)
        record["digital"] = {k: digital[k] for k in ("stable", "Ms", "Mt", "gain_margin", "phase_margin")}
        if not ok:
            success, message = False, (f"{said}; {message}" if success else f"{message}; {said}")
    steps = {k: v for k, v in (nl or {}).items() if k not in ("t", "r", "y", "u")}
    return PIDResult(kp=float(kp), ki=float(ki), kd=float(kd), tf=float(tf), rule=key, controller=controller,
                     iosys=control.ss(controller, inputs="e", outputs="uc", name="pid"), approximation=record,
                     u0=op.u0, dt=dt, linearized=P, criterion=criterion, cost=cost, optimize_result=optimize_result,
                     success=success, message=message, warnings=warnings, stable=fig["stable"],
                     gain_margin=fig["gain_margin"], phase_margin=fig["phase_margin"],
                     delay_margin=fig["delay_margin"], Ms=fig["Ms"], Mt=fig["Mt"], max_sensitivity=ms,
                     poles=fig["poles"], step=steps, operating_point=op, model=model)


# ---------------------------------------------------------------------------
# loops and their analysis
# ---------------------------------------------------------------------------
def _continuous_pid_iosys(pid: PIDResult):
    """Continuous PID with back-calculation: inputs ``e, u``, output ``uc`` (the operating point's ``u0`` added);
    states ``I, xf``."""
    import control

    kp, ki, kd, tf, kt = pid.gains
    bias = pid.u0

    def parts(x, e):
        deriv = kd * (e - x[1]) / tf if kd != 0 else 0.0
        return kp * e + x[0] + deriv + bias

    def rhs(t, x, u, p):
        e, act = u[0], u[1]
        return np.array([ki * e + kt * (act - parts(x, e)), (e - x[1]) / tf if kd != 0 else 0.0])

    return control.nlsys(rhs, lambda t, x, u, p: np.array([parts(x, u[0])]), inputs=["e", "u"],
                         outputs=["uc"], states=["I", "xf"], name="pid")


def closed_loop(model, pid: PIDResult, u_limit=None, *, dt: float | None = None, name: str = "loop"):
    """The PID loop around the nonlinear plant as a ``control.interconnect``, at rest at the operating point.

    Error junction ``e = r - y``, the PID (its output plus the operating
    point's input ``u0``) with back-calculation anti-windup (it reads the
    actuator's output ``u``), the actuator limit ``u = clip(uc, lo, hi)`` and
    the plant, whose initial state is the operating point's.  With ``dt`` the
    loop is the sampled one of :mod:`hammerstein_ctrl.simulate._loop` (plant
    ``to_iosys(dt, intersample="zoh")``, the PID discretised); without, it is
    continuous (plant ``to_iosys()``).  Input ``r`` (absolute, e.g.
    ``y0 + step``); outputs ``y`` and ``u``; from zero initial conditions the
    loop is at the operating point.  A model with a dead time enters as its
    Pade form (:meth:`~hammerstein_ctrl.blocks.BlockModel.without_delay`), the
    plant :func:`tune_pid` designed and verified the loop on.

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Coulomb
    >>> m = HammersteinModel(ct.tf([1], [1, 3.14, 0]), Coulomb(), [0.54, -0.4, 0.045])
    >>> loop = closed_loop(m, tune_pid(m, "simc", tau_c=0.2), u_limit=(-4, 4))
    >>> loop.input_labels, loop.output_labels, loop.nstates
    (['r'], ['y', 'u'], 4)
    """
    model = _siso_model(model, "closed_loop")
    import control

    from ._operating_point import rest_model

    if not isinstance(pid, PIDResult):
        raise ParameterError(f"pid must be a PIDResult (from tune_pid), got {type(pid).__name__}")
    model = _rational(model)
    plant_model = rest_model(model, pid.operating_point) if pid.operating_point is not None else model
    if dt is not None:
        return sampled_loop_iosys(plant_model, pid.gains, dt, u_limit=u_limit, bias=pid.u0, name=name)
    check_limits(u_limit)
    err = control.summing_junction(inputs=["r", "-y"], output="e", name="error")
    plant = plant_model.to_iosys(name="plant", inputs="u", outputs="y")
    return control.interconnect([err, _continuous_pid_iosys(pid), saturation_iosys(u_limit), plant],
                                inputs=["r"], outputs=["y", "u"], name=name)


def analyze_loop(model, pid: PIDResult, *, u_limit=None, reference="step", step: float | None = None,
                 dt: float | None = None, t_final: float | None = None) -> dict:
    """Margins, ``Ms``, ``Mt`` and poles of the linearised loop; step figures and costs of the nonlinear one.

    The nonlinear loop is the sampled one (:func:`~hammerstein_ctrl.simulate.simulate_loops`,
    equal to ``control.input_output_response`` of ``closed_loop(..., dt=dt)``)
    started at rest at the operating point; ``reference`` (a step of ``step``,
    default the verification's, or samples) is relative to its output ``y0``,
    and so are the step figures.

    Returns
    -------
    dict
        ``gain_margin``, ``phase_margin``, ``delay_margin``,
        ``w_gain_crossover``, ``w_phase_crossover``, ``Ms``, ``Mt``, ``poles``,
        ``stable``; ``step_info`` (python-control's figures relative to the
        operating point, overshoot in %), ``iae``, ``ise``, ``itae``,
        ``max_overshoot`` (fraction) and the response ``t, r, y, u`` (absolute).
    """
    model = _siso_model(model, "analyze_loop")
    model = _rational(model)
    op = pid.operating_point if pid.operating_point is not None else operating_point(model)
    P = small_signal(model, op)
    num, den = np.asarray(P.num[0][0], float), np.asarray(P.den[0][0], float)
    out = loop_figures(num, den, pid.kp, pid.ki, pid.kd, pid.tf)
    step = pid.step.get("step", 1.0) if step is None else float(step)
    dt, t_final = _tuning_grid((pid.kp, pid.ki, pid.kd, pid.tf), op, num, den, dt or pid.dt or pid.step.get("dt"),
                               t_final or pid.step.get("t_final"))
    r, is_step = _reference(reference, step, dt, t_final)
    Y, U = simulate_loops(model, pid.gains[None, :], r + op.y0, dt, u_limit=u_limit, bias=op.u0, x0=op.x0)
    t = dt * np.arange(r.size)
    with np.errstate(all="ignore"):
        for crit in CRITERIA:
            out[crit] = float(_criterion(r - (Y[0] - op.y0), dt, crit))
    out["step_info"] = _step_figures(Y[0] - op.y0, t, r[-1]) if is_step else {}
    out["max_overshoot"] = float(_overshoot(Y - op.y0, r)[0]) if is_step else math.nan
    out.update(t=t, r=r + op.y0, y=Y[0], u=U[0])
    return out


def loop_figure(reports: dict, *, u_limit=None, title: str | None = None):
    """Output and actuator signals of one or more :func:`analyze_loop` reports, by label.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    from ..data._display import register_figure_formatter

    register_figure_formatter()          # a Figure ending a notebook cell shows once, as a PNG
    fig = Figure(figsize=(7, 5), layout="constrained")
    ax_y, ax_u = fig.subplots(2, 1, sharex=True)
    first = next(iter(reports.values()))
    ax_y.plot(first["t"], first["r"], "k--", lw=1, label="reference")
    for label, rep in reports.items():
        info = rep.get("step_info", {})
        extra = f", overshoot {info['Overshoot']:.1f} %" if "Overshoot" in info else ""
        ax_y.plot(rep["t"], rep["y"], label=f"{label} (ITAE {rep['itae']:.3g}{extra})")
        ax_u.plot(rep["t"], rep["u"], label=label)
    lo, hi = check_limits(u_limit)
    for lim in (lo, hi):
        if math.isfinite(lim):
            ax_u.axhline(lim, color="grey", lw=0.8, ls=":")
    ax_y.set_ylabel("y")
    ax_u.set_ylabel("u (actuator)")
    ax_u.set_xlabel("t [s]")
    ax_y.legend(fontsize=8)
    ax_y.set_title(title or "closed loop on the nonlinear model")
    return fig


#: ``LoopCost``, the old name of :class:`TuningCost`, for one release with a DeprecationWarning.
__getattr__ = renamed(__name__, {"LoopCost": ("TuningCost", "in_loop has a cost of its own")})
