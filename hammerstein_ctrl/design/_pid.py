"""PID controllers from a tuned model: the tuning rules (SIMC, IMC), the result type :class:`PIDResult` and its
digital form :class:`DiscretePID`, the loop cost the gains are tuned on (:class:`TuningCost`), and the verification
every controller passes before it is returned."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._deprecation import renamed
from .._checks import as_signal, check_dt
from .. import config
from ..exceptions import DataError, ParameterError
from ..simulate._loop import back_calculation_gain, check_limits, sampled_plant, simulate_loops
from ._operating_point import OperatingPoint, operating_point, small_signal, static_output
from ._robust import FILTER_RATIO, constraints, default_bandwidth, frequency_grid, loop_figures, pid_polynomials

__all__ = ["PIDResult", "DiscretePID", "pid_controller", "TuningCost", "RULES", "CRITERIA", "TRACKING_TOLERANCE"]

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
        >>> from hammerstein_ctrl import HammersteinModel, Tanh, tune_pid
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

def _check_dt(dt):
    return None if dt is None else check_dt(dt, error=ParameterError)


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


#: ``LoopCost``, the old name of :class:`TuningCost`, for one release with a DeprecationWarning.
__getattr__ = renamed(__name__, {"LoopCost": ("TuningCost", "in_loop has a cost of its own")})
