"""PID tuning from an identified Hammerstein model.

Two ways, one result type (:class:`PIDResult`):

* **Rule-based** (``rule="simc"`` or ``"imc"``): the model is linearised at an
  operating point ``u0`` (small-signal gain ``g'(u0)``), reduced to a
  second-order-plus-delay model by Skogestad's *half rule*, and tuned with
  SIMC (Skogestad 2003; with its integrating-process variant, which is the
  EMPS position loop: an integrator with a lag) or with IMC/lambda tuning
  (Rivera, Morari and Skogestad 1986).  The approximation used is recorded in
  ``result.approximation``.
* **Model-based** (``rule="nspsa"`` or ``"auto"``): the gains minimise a
  closed-loop cost (IAE, ISE or ITAE of a step or of a given reference) of the
  *nonlinear* sampled loop with the actuator limit and back-calculation
  anti-windup (:mod:`hammerstein_ctrl.loop_sim`), with penalties for an
  unstable linearised loop, a diverging simulation and step overshoot above
  ``max_overshoot``.  The search runs in ``log |gain|`` from the SIMC design,
  with N-SPSA (seeded, deterministic) or, for ``"auto"``, Nelder-Mead.  This is
  the data-driven PID tuning the paper names as future work.

:func:`closed_loop` returns the loop as a ``control.interconnect`` (controller,
actuator limit with anti-windup, plant), :func:`analyze_loop` its margins,
peak sensitivity ``Ms`` (linearised loop, python-control) and step figures
(``control.step_info`` on the nonlinear sampled loop).

Examples
--------
>>> import control as ct
>>> from hammerstein_ctrl import HammersteinModel, Coulomb
>>> emps = HammersteinModel(ct.tf([1], [1, 3.138764, 0]), Coulomb(), [0.544501, -0.398365, 0.045066])
>>> pid = tune_pid(emps, "simc", tau_c=0.2)
>>> pid.approximation["kind"], round(pid.kp, 3), round(pid.kd, 3)
('integrating', 40.301, 9.183)
>>> type(pid.controller).__name__
'TransferFunction'
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._checks import as_signal
from .exceptions import DataError, ParameterError, UnknownNameError
from .model import HammersteinModel
from .loop_sim import (
    back_calculation_gain,
    check_limits,
    sampled_loop_iosys,
    sampled_plant,
    saturation_iosys,
    simulate_loops,
)

__all__ = ["PIDResult", "tune_pid", "closed_loop", "analyze_loop", "approximate", "pid_controller",
           "LoopCost", "loop_figure", "RULES", "CRITERIA"]

#: Tuning rules accepted by :func:`tune_pid`.
RULES = ("simc", "imc", "nspsa", "auto")
#: Closed-loop cost criteria.
CRITERIA = ("iae", "ise", "itae")
#: Derivative filter: ``tf = Td / FILTER_RATIO`` (the classical N = 10).
FILTER_RATIO = 10.0
#: SIMC's integral time ``tau_I = min(tau1, SIMC_TI_FACTOR (tau_c + theta))``.
SIMC_TI_FACTOR = 4.0
#: Default horizon of the tuning simulation, in closed-loop time scales ``tau_c + theta``.
HORIZON_FACTOR = 20.0
#: Samples of the tuning simulation when no ``dt`` is given.
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


# ---------------------------------------------------------------------------
# the small-signal model and the half rule
# ---------------------------------------------------------------------------
def _slope(model, u0: float) -> float:
    if not isinstance(model, HammersteinModel):
        raise ParameterError(
            "PID tuning supports Hammerstein models (y = H g(u)), not a "
            f"{getattr(model, 'kind', type(model).__name__)} model: the compiled loop simulates no output nonlinearity")
    try:
        u0 = float(u0)
    except (TypeError, ValueError):
        raise ParameterError(f"u0 must be a number, got {u0!r}") from None
    if not math.isfinite(u0):
        raise ParameterError(f"the operating point u0 must be finite, got {u0!r}")
    with np.errstate(all="ignore"):
        slope = float(np.asarray(model.nonlinearity.derivative(np.array([u0]), model.params)).ravel()[0])
    if not math.isfinite(slope) or slope == 0.0:
        raise ParameterError(
            f"g'(u0) = {slope:g} at the operating point u0 = {u0:g}: the small-signal gain vanishes "
            "there (e.g. inside a dead zone or beyond a saturation); choose another u0"
        )
    return slope


def _polynomials(model):
    num = np.trim_zeros(np.asarray(model.linear.num[0][0], dtype=float), "f")
    den = np.trim_zeros(np.asarray(model.linear.den[0][0], dtype=float), "f")
    if num.size == 0 or not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
        raise ParameterError("the model's linear block has non-finite or no coefficients")
    if not np.all(np.isfinite(model.params)):
        raise ParameterError("the model's nonlinearity parameters are not finite")
    return num / den[0], den / den[0]


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


def approximate(model, u0: float = 0.0, dt: float | None = None) -> dict:
    """Skogestad's half-rule reduction of the small-signal model at ``u0``.

    Returns a record with ``kind`` (``"integrating"``: ``k e^{-theta s}/(s (tau2 s + 1))``,
    or ``"self-regulating"``: ``K e^{-theta s}/((tau1 s + 1)(tau2 s + 1))``),
    ``gain`` (``k`` or ``K``), ``tau1``, ``tau2``, ``theta``, ``slope`` (``g'(u0)``),
    ``u0``, ``dt`` and ``notes``.  Inverse-response zeros and half of the
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
    slope = _slope(model, u0)
    num, den = _polynomials(model)
    n_int, lags, notes = _split_poles(den)
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
    if dt is not None:
        theta += float(dt) / 2
        notes.append(f"digital control: dt/2 = {float(dt) / 2:.4g} added to the delay")
    record = {"kind": "integrating" if n_int else "self-regulating", "gain": float(gain),
              "tau1": math.inf if n_int else float(kept[0]), "tau2": float(kept[-1]),
              "theta": float(theta), "slope": slope, "u0": float(u0), "dt": dt, "notes": notes}
    return record


# ---------------------------------------------------------------------------
# tuning rules
# ---------------------------------------------------------------------------
def _series_to_parallel(kc: float, ti: float, td: float) -> tuple[float, float, float]:
    """Series PID ``Kc (1 + 1/(Ti s))(1 + Td s)`` in parallel form ``(kp, ki, kd)``."""
    return kc * (1 + td / ti), kc / ti, kc * td


def _simc(a: dict, tau_c: float):
    t = tau_c + a["theta"]
    if a["kind"] == "integrating":
        kc, ti = 1.0 / (a["gain"] * t), SIMC_TI_FACTOR * t
    else:
        kc, ti = a["tau1"] / (a["gain"] * t), min(a["tau1"], SIMC_TI_FACTOR * t)
    return _series_to_parallel(kc, ti, a["tau2"])


def _imc(a: dict, lam: float):
    """IMC/lambda PID; for a self-regulating plant on its first-order-plus-delay form (noted in ``a``)."""
    th = a["theta"]
    if a["kind"] == "integrating":
        kc = (2 * lam + th) / (a["gain"] * (lam + th) ** 2)
        return _series_to_parallel(kc, 2 * lam + th, a["tau2"])
    tau = a["tau1"] + a["tau2"] / 2  # half rule once more: tau2 split between tau1 and the delay
    th = th + a["tau2"] / 2
    a["notes"].append(f"IMC on the first-order-plus-delay form: tau = {tau:.4g}, delay = {th:.4g}")
    kc = (2 * tau + th) / (a["gain"] * (2 * lam + th))
    return kc, kc / (tau + th / 2), kc * tau * th / (2 * tau + th)


def _default_tau_c(a: dict, limits, u0: float, step: float, notes: list) -> float:
    """``tau_c = theta`` (tight control) or larger, so the proportional kick fits the actuator."""
    lo, hi = limits
    tau = a["theta"]
    if math.isfinite(lo) or math.isfinite(hi):
        room = min(hi - u0, u0 - lo)
        if not room > 0:
            raise ParameterError(f"the operating point u0 = {u0:g} is not inside the actuator limits {limits}")
        scale = 1.0 if a["kind"] == "integrating" else a["tau1"]
        tau_input = scale * abs(step) / (abs(a["gain"]) * room) - a["theta"]
        if tau_input > tau:
            notes.append(f"tau_c = {tau_input:.4g} so that kp * |step| stays within the actuator room {room:.4g}")
            tau = tau_input
    if not tau > 0:
        raise ParameterError("no delay and no actuator limits to choose tau_c from: give tau_c (or u_limit, dt)")
    return tau


def pid_controller(kp: float, ki: float, kd: float, tf: float):
    """Parallel PID with filtered derivative, ``kp + ki/s + kd s/(tf s + 1)``.

    Examples
    --------
    >>> pid_controller(2.0, 1.0, 0.5, 0.05).num[0][0].tolist()
    [0.6, 2.05, 1.0]
    """
    import control

    if kd == 0.0:
        return control.tf([kp, ki], [1.0, 0.0], inputs="e", outputs="uc", name="pid")
    if not tf > 0:
        raise ParameterError("a derivative term needs a filter time constant tf > 0")
    return control.tf([kp * tf + kd, kp + ki * tf, ki], [tf, 1.0, 0.0], inputs="e", outputs="uc", name="pid")


@dataclass
class PIDResult:
    """A tuned PID ``kp + ki/s + kd s/(tf s + 1)`` (parallel form).

    Attributes
    ----------
    kp, ki, kd, tf : float
        Gains and derivative-filter time constant.
    rule : str
    controller : control.TransferFunction
        The parallel-form controller (input ``e``, output ``uc``).
    iosys : control.StateSpace
        The same controller as a python-control I/O system.
    approximation : dict
        The small-signal reduction used (see :func:`approximate`) and ``tau_c``.
    u0 : float
        Operating point of the linearisation.
    dt : float or None
        Sampling interval of the design (model-based tuning simulates at it).
    linearized : control.TransferFunction
        ``g'(u0) H(p)``.
    cost : float or None
        Model-based tuning: the loop cost reached (``criterion``).
    optimize_result : OptimizeResult or None
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

    @property
    def kt(self) -> float:
        """Back-calculation anti-windup gain ``1/Tt``."""
        return back_calculation_gain(abs(self.kp), abs(self.ki), abs(self.kd))

    @property
    def gains(self) -> np.ndarray:
        """``[kp, ki, kd, tf, kt]``, the row :func:`~hammerstein_ctrl.loop_sim.simulate_loops` takes."""
        return np.array([self.kp, self.ki, self.kd, self.tf, self.kt])


def _make_result(model, kp, ki, kd, rule, approx, u0, dt, **extra) -> PIDResult:
    import control

    tf = abs(kd / kp) / FILTER_RATIO if kd != 0 else 0.0
    controller = pid_controller(kp, ki, kd, tf)
    return PIDResult(kp=float(kp), ki=float(ki), kd=float(kd), tf=float(tf), rule=rule,
                     controller=controller, iosys=control.ss(controller, inputs="e", outputs="uc", name="pid"),
                     approximation=approx, u0=float(u0), dt=dt,
                     linearized=model.linearize(u0), **extra)


# ---------------------------------------------------------------------------
# references and loop costs
# ---------------------------------------------------------------------------
def _reference(reference, step: float, dt: float, t_final: float) -> tuple[np.ndarray, bool]:
    """(samples, is_step)."""
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


class LoopCost:
    """Closed-loop cost of PID gains on the nonlinear sampled loop, in ``log |gain|``.

    ``cost(theta)`` with ``theta = log([|kp|, |ki|, |kd|])`` (the signs are those
    of the plant's gain); ``cost.batch(thetas)`` evaluates many candidates in
    one compiled simulation.  Penalties (in multiples of the do-nothing cost
    ``J0``, the criterion of ``e = r``): ``PENALTY_FACTOR`` for an unstable
    linearised loop or a diverging simulation, ``OVERSHOOT_WEIGHT`` per unit of
    step overshoot beyond ``max_overshoot``.
    """

    def __init__(self, model, r, dt, *, u_limit=None, criterion="itae", sign=1.0, is_step=True,
                 max_overshoot=MAX_OVERSHOOT, u0=0.0):
        self.model, self.r, self.dt, self.u_limit = model, np.asarray(r, float), float(dt), u_limit
        self.criterion, self.sign, self.is_step = criterion, float(sign), is_step
        self.max_overshoot = max_overshoot
        num, den = _polynomials(model)
        self._num = num * _slope(model, u0)
        self._den = den
        self.J0 = float(_criterion(self.r[None, :], self.dt, criterion)[0])
        self._plant = sampled_plant(model, self.dt)

    def gains(self, thetas) -> np.ndarray:
        """Rows ``kp, ki, kd, tf`` for log-gains."""
        K = self.sign * np.exp(np.atleast_2d(np.asarray(thetas, dtype=float)))
        tf = np.abs(K[:, 2] / K[:, 0]) / FILTER_RATIO
        return np.column_stack([K, tf])

    def unstable(self, G: np.ndarray) -> np.ndarray:
        """Whether the linearised continuous loop has a closed-loop pole with Re >= 0."""
        out = np.zeros(G.shape[0], dtype=bool)
        for i, (kp, ki, kd, tf) in enumerate(G[:, :4]):
            char = np.polyadd(np.polymul(self._den, [tf, 1.0, 0.0]),
                              np.polymul(self._num, [kp * tf + kd, kp + ki * tf, ki]))
            out[i] = not np.all(np.isfinite(char)) or np.any(np.roots(char).real >= 0)
        return out

    def evaluate(self, G: np.ndarray) -> dict:
        """Criterion, overshoot and flags of gain rows ``G`` (no penalties)."""
        Y, U = simulate_loops(self._plant, G, self.r, self.dt, u_limit=self.u_limit)
        diverged = ~np.all(np.isfinite(Y), axis=1)
        with np.errstate(all="ignore"):
            value = _criterion(self.r - Y, self.dt, self.criterion)
        overshoot = _overshoot(Y, self.r) if self.is_step else np.zeros(G.shape[0])
        return {"value": value, "overshoot": overshoot, "diverged": diverged, "Y": Y, "U": U}

    def batch(self, thetas) -> np.ndarray:
        """Penalised cost of each row of ``thetas``."""
        with np.errstate(all="ignore"):
            G = self.gains(thetas)
        ok = np.all(np.isfinite(G), axis=1)
        G[~ok] = 1.0
        res = self.evaluate(G)
        bad = res["diverged"] | self.unstable(G) | ~ok
        value = np.where(bad, PENALTY_FACTOR * self.J0, res["value"])
        excess = np.maximum(0.0, res["overshoot"] - self.max_overshoot) if self.max_overshoot is not None else 0.0
        return value + OVERSHOOT_WEIGHT * self.J0 * np.where(bad, 0.0, excess)

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


def _loop_grid(approx: dict, tau_c: float, dt, t_final) -> tuple[float, float]:
    """(dt, t_final) of the tuning simulation."""
    if t_final is None:
        t_final = HORIZON_FACTOR * (tau_c + approx["theta"])
    if not (math.isfinite(t_final) and t_final > 0):
        raise ParameterError(f"t_final must be positive and finite, got {t_final!r}")
    if dt is None:
        dt = t_final / DEFAULT_SAMPLES
    return float(dt), float(t_final)


def tune_pid(model, rule: str = "simc", *, u0: float = 0.0, dt: float | None = None, u_limit=None,
             tau_c: float | None = None, reference="step", step: float = 1.0, t_final: float | None = None,
             criterion: str = "itae", max_overshoot: float | None = MAX_OVERSHOOT,
             maxfev: int = DEFAULT_MAXFEV, seed=0, options: dict | None = None) -> PIDResult:
    """Tune a PID for a Hammerstein model.

    Parameters
    ----------
    model : HammersteinModel
        Stable or integrating (one integrator) plant, strictly proper for
        model-based tuning.
    rule : {"simc", "imc", "nspsa", "auto"}
        See the module notes.
    u0 : float, default 0
        Operating point of the linearisation (``g'(u0)`` must not vanish).
    dt : float, optional
        Controller sampling interval: adds ``dt/2`` to the delay of the rules
        and is the step of the tuning simulation (default ``t_final / 2000``).
    u_limit : (lo, hi), optional
        Actuator limits (``lo < hi``).
    tau_c : float, optional
        SIMC closed-loop time constant / IMC lambda.  Default: the effective
        delay (Skogestad's tight control), raised if needed so that
        ``kp * |step|`` fits between ``u0`` and the actuator limits.
    reference : "step" or array_like
        The reference of the tuning simulation: a step of ``step`` or samples
        at ``dt`` (at least two).
    step : float, default 1
        Step amplitude.
    t_final : float, optional
        Horizon of a step (default ``20 (tau_c + theta)``).
    criterion : {"iae", "ise", "itae"}, default "itae"
    max_overshoot : float or None, default 0.1
        Step overshoot beyond which model-based tuning is penalised.
    maxfev : int, default 601
        Evaluation budget of model-based tuning.
    seed : int or Generator, default 0
    options : dict, optional
        Optimiser options (N-SPSA: ``a``, ``c`` gain sequences).

    Returns
    -------
    PIDResult

    Raises
    ------
    ParameterError, UnknownNameError, DataError
        Unstable or non-finite model, ``g'(u0) = 0``, unknown rule or
        criterion, a reference shorter than two samples, ``lo >= hi``.
    """
    key = _check_rule(rule)
    crit = _check_criterion(criterion)
    limits = check_limits(u_limit)
    if dt is not None and not (math.isfinite(float(dt)) and float(dt) > 0):
        raise ParameterError(f"dt must be a positive finite number, got {dt!r}")
    approx = approximate(model, u0, dt)
    if tau_c is None:
        tau_c = _default_tau_c(approx, limits, float(u0), step if isinstance(reference, str) else
                               float(np.max(np.abs(as_signal(reference, "reference")))), approx["notes"])
    elif not (math.isfinite(tau_c) and tau_c > 0):
        raise ParameterError(f"tau_c must be positive and finite, got {tau_c!r}")
    approx["tau_c"] = float(tau_c)
    gains = _simc(approx, tau_c) if key != "imc" else _imc(approx, tau_c)
    if key in ("simc", "imc"):
        return _make_result(model, *gains, key, approx, u0, dt)
    return _tune_model_based(model, key, gains, approx, u0=u0, dt=dt, u_limit=u_limit, reference=reference,
                             step=step, t_final=t_final, criterion=crit, max_overshoot=max_overshoot,
                             maxfev=maxfev, seed=seed, options=options)


#: N-SPSA defaults in log-gain space: perturbations of 5 %, a(k) = 1/(k + A)^0.602 (measured on EMPS).
NSPSA_A = 1.0
NSPSA_C = 0.05


def _tune_model_based(model, key, start, approx, *, u0, dt, u_limit, reference, step, t_final, criterion,
                      max_overshoot, maxfev, seed, options) -> PIDResult:
    from threadpoolctl import threadpool_limits

    from .optimize import PerturbationGain, StepGain, minimize

    dt, t_final = _loop_grid(approx, approx["tau_c"], dt, t_final)
    r, is_step = _reference(reference, step, dt, t_final)
    sign = math.copysign(1.0, approx["gain"])
    cost = LoopCost(model, r, dt, u_limit=u_limit, criterion=criterion, sign=sign, is_step=is_step,
                    max_overshoot=max_overshoot, u0=u0)
    x0 = np.log(np.abs(np.asarray(start, dtype=float)))
    if not np.all(np.isfinite(x0)):
        raise ParameterError(f"model-based tuning needs a non-zero PID start, got gains {start}")
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
    kp, ki, kd, _ = cost.gains(candidates[best])[0]
    approx["start"] = {"kp": float(start[0]), "ki": float(start[1]), "kd": float(start[2]),
                       "cost": float(values[0])}
    return _make_result(model, kp, ki, kd, key, approx, u0, dt, criterion=criterion, cost=float(values[best]),
                        optimize_result=res)


# ---------------------------------------------------------------------------
# loops and their analysis
# ---------------------------------------------------------------------------
def _continuous_pid_iosys(pid: PIDResult):
    """Continuous PID with back-calculation: inputs ``e, u``, output ``uc``; states ``I, xf``."""
    import control

    kp, ki, kd, tf, kt = pid.gains

    def parts(x, e):
        deriv = kd * (e - x[1]) / tf if kd != 0 else 0.0
        return kp * e + x[0] + deriv

    def rhs(t, x, u, p):
        e, act = u[0], u[1]
        return np.array([ki * e + kt * (act - parts(x, e)), (e - x[1]) / tf if kd != 0 else 0.0])

    return control.nlsys(rhs, lambda t, x, u, p: np.array([parts(x, u[0])]), inputs=["e", "u"],
                         outputs=["uc"], states=["I", "xf"], name="pid")


def closed_loop(model, pid: PIDResult, u_limit=None, *, dt: float | None = None, name: str = "loop"):
    """The PID loop around the nonlinear plant as a ``control.interconnect``.

    Error junction ``e = r - y``, the PID with back-calculation anti-windup
    (it reads the actuator's output ``u``), the actuator limit
    ``u = clip(uc, lo, hi)`` and the plant.  With ``dt`` the loop is the
    sampled one of :mod:`hammerstein_ctrl.loop_sim` (plant ``to_iosys(dt)``
    with the input held, the PID discretised); without, it is continuous
    (plant ``to_iosys()``).  Input ``r``; outputs ``y`` and ``u``.

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Coulomb
    >>> m = HammersteinModel(ct.tf([1], [1, 3.14, 0]), Coulomb(), [0.54, -0.4, 0.045])
    >>> loop = closed_loop(m, tune_pid(m, "simc", tau_c=0.2), u_limit=(-4, 4))
    >>> loop.input_labels, loop.output_labels, loop.nstates
    (['r'], ['y', 'u'], 4)
    """
    import control

    if not isinstance(pid, PIDResult):
        raise ParameterError(f"pid must be a PIDResult (from tune_pid), got {type(pid).__name__}")
    if dt is not None:
        return sampled_loop_iosys(model, pid.gains, dt, u_limit=u_limit, name=name)
    check_limits(u_limit)
    err = control.summing_junction(inputs=["r", "-y"], output="e", name="error")
    plant = model.to_iosys(name="plant", inputs="u", outputs="y")
    return control.interconnect([err, _continuous_pid_iosys(pid), saturation_iosys(u_limit), plant],
                                inputs=["r"], outputs=["y", "u"], name=name)


def _margins(pid: PIDResult) -> dict:
    import control

    L = pid.controller * pid.linearized
    gm, pm, _, wpc, wgc, _ = control.stability_margins(L)
    S = control.feedback(1, L)
    poles = np.asarray(control.feedback(L, 1).poles())
    w0 = wgc if np.isfinite(wgc) and wgc > 0 else 1.0
    omega = np.logspace(np.log10(w0) - 4, np.log10(w0) + 4, 4000)
    ms = float(np.max(np.abs(control.frequency_response(S, omega).magnitude)))
    return {"gain_margin": float(gm), "phase_margin": float(pm), "w_phase_crossover": float(wpc),
            "w_gain_crossover": float(wgc), "Ms": ms, "poles": poles,
            "stable": bool(np.all(poles.real < 0))}


def _step_figures(y: np.ndarray, t: np.ndarray, final: float) -> dict:
    import control

    if not np.all(np.isfinite(y)):
        return {"diverged": True}
    try:
        info = control.step_info(y, t, yfinal=final)
    except IndexError:  # the response never reaches the rise-time thresholds
        return {"RiseTime": math.nan, "SettlingTime": math.nan, "Overshoot": math.nan}
    return {k: float(v) for k, v in info.items()}


def analyze_loop(model, pid: PIDResult, *, u_limit=None, reference="step", step: float = 1.0,
                 dt: float | None = None, t_final: float | None = None) -> dict:
    """Margins, ``Ms`` and closed-loop poles of the linearised loop; step figures and costs of the nonlinear one.

    The nonlinear loop is the sampled one (:func:`simulate_loops`, equal to
    ``control.input_output_response`` of ``closed_loop(..., dt=dt)``) at
    ``dt`` (default: the design's, else ``t_final / 2000``).

    Returns
    -------
    dict
        ``gain_margin``, ``phase_margin``, ``w_gain_crossover``,
        ``w_phase_crossover``, ``Ms``, ``poles``, ``stable``; ``step_info``
        (python-control's figures, overshoot in %), ``iae``, ``ise``,
        ``itae``, ``max_overshoot`` (fraction) and the response ``t, r, y, u``.
    """
    out = _margins(pid)
    dt, t_final = _loop_grid(pid.approximation, pid.approximation["tau_c"], dt or pid.dt, t_final)
    r, is_step = _reference(reference, step, dt, t_final)
    Y, U = simulate_loops(model, pid.gains[None, :], r, dt, u_limit=u_limit)
    t = dt * np.arange(r.size)
    with np.errstate(all="ignore"):
        for crit in CRITERIA:
            out[crit] = float(_criterion(r - Y[0], dt, crit))
    out["step_info"] = _step_figures(Y[0], t, r[-1]) if is_step else {}
    out["max_overshoot"] = float(_overshoot(Y, r)[0]) if is_step else math.nan
    out.update(t=t, r=r, y=Y[0], u=U[0])
    return out



def loop_figure(reports: dict, *, u_limit=None, title: str | None = None):
    """Output and actuator signals of one or more :func:`analyze_loop` reports, by label.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    fig, (ax_y, ax_u) = plt.subplots(2, 1, sharex=True, figsize=(7, 5), constrained_layout=True)
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
