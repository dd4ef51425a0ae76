"""Fit a Hammerstein model to a record in one call.

``identify(data, structure)`` needs nothing else: the default method
``"auto"`` (:mod:`hammerstein_ctrl.fit._auto`) starts from points computed from the
data and refines them by least squares.  The paper's methods remain available
by name with their own settings.

Every result says how far it can be trusted.  It carries the parameters'
covariance (:mod:`~hammerstein_ctrl.assess`: ``res.stderr``,
``res.conf_int()``, ``res.propagate``), the verdicts of
:mod:`~hammerstein_ctrl.assess._diagnostics` and the residual analysis of
:mod:`~hammerstein_ctrl.assess._residuals` (``res.warnings``, each also issued
as an :class:`~hammerstein_ctrl.exceptions.IdentificationWarning`).
``success`` is True only when the result can be used: it is False, with a
specific ``message`` that says what to do, when a least-squares method did not
converge, when the model is unstable (unless ``allow_unstable``; a pole within
its uncertainty of the imaginary axis counts as marginal, not unstable), when
the record does not determine a parameter, when the model fits no better than
the best static affine gain ``y = k u + c`` (fit % <= 0 included), when the
linear model of the same order fits as well (an F-test on the whitened
residuals, :mod:`~hammerstein_ctrl.assess._significance`), or when a search stalled
at its starting value.  Residuals that the input still
explains (a missing order, a wrong nonlinearity) are warnings: the model is
usable, and the warning says what seems missing.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> case = hc.presets.trs()
>>> res = hc.identify(case.data, case.structure)
>>> bool(res.fun < 178.5), res.success, res.method
(True, False, 'auto')
>>> res.message.split(":")[0]   # the linear model of the same order fits as well
'the nonlinearity is not significant'
>>> res = hc.identify(case.data, case.structure, method="nspsa", x0=case.x0, seed=0,
...                   **{k: v for k, v in case.minimize_kwargs("nspsa").items() if k != "method"})
>>> round(res.fun, 1), res.nfev, type(res.model.linear).__name__
(178.5, 2001, 'TransferFunction')
>>> round(res.fit_percent)   # the reconstruction's noise floor: the true system scores 31 % too
31
"""

from __future__ import annotations

import time
import warnings as _warnings
from dataclasses import dataclass

import numpy as np

from .._linalg import single_threaded_blas
from ..data._iodata import IOData
from ._experiments import RecordsCost, duplicated_records
from ..assess._diagnostics import (FAILURE, STILL_IMPROVING, WARNING, Verdict, budget_advice, identifiability_verdicts,
                                   late_improvement, linear_verdicts, offset_verdict, row_pole_verdicts)
from ..exceptions import IdentificationWarning, ParameterError
from ._baselines import static_affine_sse, static_affine_sse_columns
from ..data._metrics import channel_report, fit_percent, fit_report
from ._mimo_fit import monic_drift_verdicts
from ._routes import route
from ._nested import significance_verdicts
from ..assess._significance import rounding_sse
from ._objective import HammersteinCost
from ._result import IdentificationResult
from ..optimize import BUDGET_EXHAUSTED, COMPLETED, DIVERGED, SCIPY_METHODS, canonical_method, minimize
from ..optimize._normal_lm import _cosine     # MINPACK's gtol measure, as LM's own convergence test
from ..assess._residuals import residual_analysis
from ..assess._uncertainty import channel_uncertainty, estimate_uncertainty, fit_noise_model, _check_noise

__all__ = ["identify", "IdentificationResult", "AUTO"]   # the result type lives in hammerstein_ctrl.fit._result

#: Name of the default method (see :mod:`hammerstein_ctrl.fit._auto`).
AUTO = "auto"
#: Methods that stop on a convergence test (running out of budget is then a failure).
_CONVERGING = ("lm",) + SCIPY_METHODS


def identify(
    data: IOData,
    structure,
    method: str = AUTO,
    x0=None,
    maxfev: int | None = None,
    seed=None,
    options: dict | None = None,
    bounds=None,
    *,
    maxiter: int | None = None,
    callback=None,
    reject_unstable: bool = False,
    offset: bool | None = None,
    initial_state: str | None = None,
    allow_unstable: bool = False,
    uncertainty: bool = True,
    noise: str = "colored",
    loop=None,
    match: str = "both",
    closed_loop: bool = False,
) -> IdentificationResult:
    """Identify a Hammerstein model from an input/output record.

    Parameters
    ----------
    data : IOData or list of IOData
        Estimation record; its ``intersample`` ("foh"/"zoh") is honoured.  A
        ``nonlinear_benchmarks`` record (``u``, ``y``, ``sampling_time``) works too.
        A list of records of one plant (same sampling time and intersample
        behaviour) is fitted jointly: the blocks are shared, each record has
        its own offset and initial state when the structure estimates them
        (:mod:`~hammerstein_ctrl.fit._experiments`; ``x`` and ``structure.param_names``
        then list the block parameters once and the record's nuisance
        parameters as ``y0[k]``, ``xi0[k]``, ...).
    structure : HammersteinStructure, WienerStructure, HammersteinWienerStructure or a MIMO structure
        The model structure (the paper's cases: ``hc.presets.trs().structure``,
        ``...emps()``).  A record with several inputs or outputs takes a MIMO
        structure (:mod:`~hammerstein_ctrl.blocks`: ``MIMOHammersteinStructure``, ...).
    method : str, default "auto"
        ``"auto"`` (data-driven starts, least-squares refinement, restarts;
        needs no ``x0`` or tuning), or any method of
        :func:`hammerstein_ctrl.minimize` (``"nspsa"``, ``"nlspsa"``,
        ``"spsa"``, ``"amvo-sca"``, ``"lm"``, or a scipy method).
    x0 : array_like, optional
        Initial beta.  Optional for ``"auto"`` (then one more start; the
        offset and initial state may be left out) and with finite ``bounds``
        (the centre of the box); required otherwise.
    maxfev, maxiter, seed, options, bounds, callback
        Passed to :func:`hammerstein_ctrl.minimize` (``auto`` uses ``maxfev``,
        ``seed`` and ``callback``).
    reject_unstable : bool, default False
        Score unstable candidates as ``inf`` (see :class:`HammersteinCost`).
    offset : bool, optional
        Estimate a constant output offset ``y0`` (overrides the structure's setting).
    initial_state : {"zero", "estimate"}, optional
        Start ``H`` from rest or estimate ``x(0)`` (overrides the structure's setting).
    allow_unstable : bool, default False
        Accept a final model with a right-half-plane pole as a success.
    uncertainty : bool, default True
        Compute the covariance, the verdicts and the residual analysis (a few
        per cent of an EMPS identification's time).  Without them ``success``
        reports only the optimiser's stop and the basic checks.
    noise : {"colored", "white"}, default "colored"
        Noise description of the covariance
        (:data:`~hammerstein_ctrl.assess._uncertainty.NOISE_MODELS`): an
        autoregressive model of the residuals whose order BIC picks (the plain
        white formula when they are white), or the white formula regardless.
    loop : KnownLoop, optional
        The control loop the record was measured in (:mod:`~hammerstein_ctrl.fit`):
        the plant (a :class:`~hammerstein_ctrl.blocks.LureStructure`) is then fitted
        by simulating that loop from its reference, matching ``match``.
    match : {"output", "input", "both"}, default "both"
        With ``loop``: the measured signals the simulated loop must reproduce.
    closed_loop : bool, default False
        The record was measured inside a feedback loop (the input depends on
        past outputs), fitted here in open loop: the residual tests are then
        those valid in closed loop (:mod:`~hammerstein_ctrl.assess._residuals`:
        whitened residuals against past inputs); the open-loop tests would
        find the controller's link between them.  Implied by ``loop``.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    ParameterError, UnknownNameError, DataError
        On a bad structure, method, initial point or record.

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Tanh())
    >>> t = np.arange(1000) * 0.05
    >>> u = 2 * np.sin(0.4 * t) + np.sin(1.3 * t)
    >>> data = hc.IOData(u, s.model([1.0, 2.0, 0.8]).simulate(t, u), dt=0.05)
    >>> res = identify(data, s)
    >>> res.success, np.round(res.x, 4).tolist()
    (True, [1.0, 2.0, 0.8])
    """
    started = time.perf_counter()
    noise = _check_noise(noise)
    if loop is not None:
        return _in_loop(data, structure, loop, match, method=method, x0=x0, seed=seed, maxfev=maxfev, noise=noise,
                        unused=dict(options=options, bounds=bounds, maxiter=maxiter, callback=callback,
                                    offset=offset, initial_state=initial_state))
    records = _as_records(data)
    way = route(structure, records)
    if offset is not None or initial_state is not None:
        structure = structure.with_options(offset=offset, initial_state=initial_state)
    key = AUTO if str(method).strip().lower() == AUTO else canonical_method(method)
    cost = way.make(records, structure, reject_unstable)
    with single_threaded_blas():
        if key == AUTO:
            res = _run_auto(way, cost, x0, maxfev, seed, options, bounds, maxiter, callback, allow_unstable)
        else:
            x0 = _starting_point(cost.structure, x0, bounds)
            res = minimize(cost, x0, method=key, maxfev=maxfev, maxiter=maxiter, seed=seed,
                           options=options, callback=callback, bounds=bounds)
        checks = _Checks(allow_unstable, uncertainty, noise, maxfev, seed, bounds is not None, bool(closed_loop))
        if way.mimo:
            result = _mimo_result(cost, res, key, x0, started, checks)
        else:
            result = _result(cost, res, key, x0, started, checks)
    for v in result.verdicts:
        _warnings.warn(v.message, IdentificationWarning, stacklevel=2)
    return result


def _in_loop(data, structure, loop, match, *, method, x0, seed, maxfev, noise, unused) -> IdentificationResult:
    """``identify(..., loop=)``: :func:`~hammerstein_ctrl.fit.identify_in_loop`, which takes ``auto`` only."""
    from ._in_loop import identify_in_loop

    if str(method).strip().lower() != AUTO or x0 is not None:
        raise ParameterError("a fit inside a known loop runs method='auto' with no x0")
    given = [name for name, value in unused.items() if value is not None]
    if given:
        raise ParameterError(f"a fit inside a known loop does not take {', '.join(given)}")
    result = identify_in_loop(_as_record(data), structure, loop, match=match, seed=seed, maxfev=maxfev, noise=noise)
    for v in result.verdicts:
        _warnings.warn(v.message, IdentificationWarning, stacklevel=3)
    return result


def _as_records(data) -> tuple:
    """One record, or several (a list or tuple of records) fitted together."""
    if isinstance(data, (list, tuple)) and data and all(hasattr(d, "u") and hasattr(d, "y") for d in data):
        return tuple(_as_record(d) for d in data)
    if isinstance(data, (list, tuple)) and not data:
        raise ParameterError("data is an empty list: give one record or a list of records")
    return (_as_record(data),)


def _as_record(data) -> IOData:
    """An IOData from an IOData or a ``nonlinear_benchmarks``-style record (``u, y, sampling_time``)."""
    from ..data._inputs import as_iodata

    try:
        return as_iodata(data)
    except ParameterError:
        raise ParameterError(f"data must be an IOData record (or an object with u, y and sampling_time), "
                             f"got {type(data).__name__}") from None


def _starting_point(structure, x0, bounds):
    if x0 is None:
        if bounds is None:
            raise ParameterError(
                f"give an initial point x0 = [{', '.join(structure.param_names)}] (or bounds), "
                "or use method='auto', which needs none"
            )
        from ..optimize._common import as_bounds

        lo, hi = as_bounds(bounds, structure.n_params)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ParameterError("x0 can only default to the centre of finite bounds")
        x0 = 0.5 * (lo + hi)
    x0 = structure.check_beta(x0)
    if x0.ndim != 1:
        raise ParameterError("x0 must be one beta vector")
    if getattr(getattr(structure, "linear", None), "estimates_delay", False) and not x0[structure.n_core - 1] >= 0:
        raise ParameterError(f"x0's delay must be a dead time >= 0 (seconds), got {x0[structure.n_core - 1]!r}")
    return x0


def _run_auto(way, cost, x0, maxfev, seed, options, bounds, maxiter, callback, allow_unstable):
    unused = [name for name, value in (("options", options), ("bounds", bounds), ("maxiter", maxiter))
              if value is not None]
    if unused:
        raise ParameterError(f"method 'auto' does not take {', '.join(unused)}; use maxfev (and x0, seed)")
    return way.auto(cost, x0, maxfev=maxfev, seed=seed, allow_unstable=allow_unstable, callback=callback)


@dataclass(frozen=True)
class _Checks:
    """What :func:`identify` was asked to check."""

    allow_unstable: bool
    uncertainty: bool
    noise: str
    maxfev: int | None
    seed: object = None
    bounded: bool = False
    closed_loop: bool = False


def _duplicate_verdicts(cost) -> list[Verdict]:
    """A warning for records passed more than once (their noise counted as many times)."""
    groups = duplicated_records(cost.records) if isinstance(cost, RecordsCost) else []
    if not groups:
        return []
    said = "; ".join(f"records {', '.join(map(str, g))} ({cost.records[g[0]].name!r})" for g in groups)
    worst = max(len(g) for g in groups)
    return [Verdict("duplicated-records", WARNING,
                    f"the same samples are passed more than once: {said}: their noise counts as independent, so the "
                    f"standard errors are too small (by up to sqrt({worst}) = {np.sqrt(worst):.3g}); pass each record "
                    "once")]


def _no_model(res) -> list[Verdict]:
    """The failure of a fit that gave no finite parameters or no finite output (else nothing)."""
    if not np.all(np.isfinite(np.asarray(res.x, dtype=float))):
        return [Verdict("no-model", FAILURE, "no model: the optimiser returned no finite parameters")]
    if not np.isfinite(res.fun):
        return [Verdict("no-model", FAILURE, "the final model cannot be simulated (non-finite output)")]
    return []


def _stalled(cost, res, key: str, x0) -> list[Verdict]:
    """The failure of a search from ``x0`` (not a converging method) that did not improve on it (else nothing)."""
    if key not in _CONVERGING and key != AUTO and x0 is not None and res.status != DIVERGED:
        f0 = cost(x0)
        if np.isfinite(f0) and res.fun >= f0:
            return [Verdict("stalled", FAILURE, f"stalled: no improvement on the initial point (J = {f0:.6g})")]
    return []


#: Largest cosine between the residual and a parameter's output derivative at a point a converging search
#: calls its optimum: 0 at a minimum (MINPACK's gtol test measures the same); optima measured show about 1e-6
#: (4.8e-7 and 1.8e-6 on the EMPS), a search stalled in a badly scaled block 0.068 (EMPS, order 6, dead zone).
STATIONARY_COSINE = 0.05
#: Coefficient size past which a stalled search's verdict calls the block badly scaled.
LARGE_COEFFICIENT = 1e6
#: Normalised RMS error below which a fit is exact but for rounding: its residual is rounding and no gradient
#: test applies (a noise-free record fitted to J = 1e-18).
EXACT_NRMSE = 1e-6


def _not_a_minimum(cost, res, key: str, checks: _Checks, report: dict) -> list[Verdict]:
    """The failure of a converging search that stopped where J still falls (else nothing).

    Asked of LM and ``auto`` fits of a single record with no output nonlinearity
    that report convergence, without bounds (at an active bound the gradient
    need not vanish), along the linear block's coefficients: J is smooth in them
    there, while a static map's parameter may sit at a kink (a dead zone of
    width 0) and an output map's kinks (a saturation) reach every derivative,
    where the gradient need not vanish either.  One normal-equation pass at the
    fit, outside the budget.
    """
    if (key not in ("lm", AUTO) or checks.bounded or int(res.status) != COMPLETED or type(cost) is not HammersteinCost
            or cost.structure.output_nonlinearity is not None or report["nrmse"] < EXACT_NRMSE):
        return []
    x = np.asarray(res.x, dtype=float)
    with np.errstate(all="ignore"):
        ne = cost.normal_equations(x)
    if not ne.finite:
        return []
    cosine = np.array([_cosine(ne.gram[j:j + 1, j:j + 1], ne.gradient[j:j + 1], ne.fun)    # one coefficient at a time
                       for j in range(cost.structure.linear.n_params)])
    if not cosine.size or cosine.max() <= STATIONARY_COSINE:
        return []
    names, j = cost.structure.param_names, int(np.argmax(cosine))
    large = [f"{n} = {v:.3g}" for n, v in zip(names, x) if abs(v) > LARGE_COEFFICIENT]
    why = (f"the coefficients are very large ({', '.join(large)}): a badly scaled block, often more poles than the "
           "record shows; try a lower order, or fix some coefficients" if large else
           "start again from it (x0=res.x, method='lm') or raise maxfev")
    return [Verdict("not-a-minimum", FAILURE,
                    f"not a minimum: the search stopped where J still falls along {names[j]} (the residual and its "
                    f"derivative make a cosine of {cosine[j]:.2g}, 0 at a minimum): {why}", (names[j],))]


def _basic_verdicts(cost, res, key: str, x0, report: dict) -> list[Verdict]:
    """Failures that need no uncertainty: no finite model, no better than a constant, a stalled search."""
    missing = _no_model(res)
    if missing:
        return missing
    out = []
    if report["fit_percent"] <= 0:
        out.append(Verdict("no-better", FAILURE, f"fit {report['fit_percent']:.1f} % is no better than a constant"))
    elif res.fun >= static_affine_sse(cost.data):
        out.append(Verdict("no-better", FAILURE,
                           f"J = {res.fun:.6g} is no better than the best static affine gain y = k u + c"))
    return out + _stalled(cost, res, key, x0)


def _trust_verdicts(cost, x, r, model, checks: _Checks):
    """``(verdicts, uncertainty, analysis)`` at a finite, simulable fit with residuals ``r``."""
    structure, data = cost.structure, cost.data
    unc = None
    if checks.uncertainty:
        unc, _ = estimate_uncertainty(cost, x, noise=checks.noise, residuals=r)
    verdicts, _ = linear_verdicts(structure, x, unc, data.dt, allow_unstable=checks.allow_unstable)
    if unc is None:
        return verdicts, None, None
    explained = {n for v in verdicts for n in v.params}
    verdicts = identifiability_verdicts(structure, x, unc, model=model, data=data, exempt=explained) + verdicts
    verdicts += _duplicate_verdicts(cost)
    noise = unc.noise if checks.noise == "colored" else fit_noise_model(r, cost.n_params)   # noise= is the SEs'
    simpler, _ = significance_verdicts(cost, r, noise=noise, seed=checks.seed, x=x)
    if any(v.code == "not-significant" for v in simpler):   # its failures stand, warnings on details would be noise
        return [v for v in verdicts if v.severity == FAILURE] + simpler, unc, None
    verdicts += simpler
    offset = offset_verdict(structure, r, unc)
    if offset is not None:
        verdicts.append(offset)
    analysis = residual_analysis(r, data.u, dt=data.dt, output=data.y, name=data.name, noise=noise,
                                 closed_loop=checks.closed_loop)
    if float(r @ r) <= rounding_sse(data.y):   # an exact fit: what structure the residuals have is the arithmetic's
        return verdicts, unc, analysis
    if analysis.findings:
        verdicts.append(Verdict("inadequate", WARNING, analysis.verdict()))
    if analysis.coloured:
        verdicts.append(_poor_fit(r, data.y, analysis) or Verdict("coloured", WARNING, analysis.colour_verdict()))
    return verdicts, unc, analysis


#: A fit below this fit % whose residuals are more than :data:`POOR_FIT_RATIO` times their unpredictable part
#: misses most of an output it could have followed: it fails.
POOR_FIT_PERCENT = 25.0
POOR_FIT_RATIO = 100.0


def _poor_fit(r, y, analysis) -> Verdict | None:
    """A failure for a fit that explains little (:data:`POOR_FIT_PERCENT`) of an output whose misfit is
    predictable (:data:`POOR_FIT_RATIO`): a poor optimum or a wrong structure, not noise."""
    if analysis.predictability <= POOR_FIT_RATIO:
        return None
    y = np.asarray(y, dtype=float).reshape(-1)
    fit = fit_percent(y, y - r)                 # a constant output is refused before any fit
    if fit >= POOR_FIT_PERCENT:
        return None
    return Verdict("poor-fit", FAILURE, (
        f"the model misses most of the output (fit {fit:.1f} %) and what it misses is predictable (the residuals' "
        f"power is {analysis.predictability:.3g} times their unpredictable part): a poor local optimum or a wrong "
        f"structure, not noise; try another seed or start, another family, or another structure"))


#: Codes of the failures of a fit that a simpler model matches: more evaluations would not help.
_SIMPLER = ("not-significant", "worse-than-nested")
#: Codes of failures after which ``auto`` tries the structure with an output offset.
_OFFSET_PROBED = ("no-better", "unstable")
#: The offset probe is reported when it lowers J below this fraction of the failed fit's.
OFFSET_PROBE_GAIN = 0.5


def _offset_probe(cost, res, verdicts, checks: _Checks, seed) -> Verdict | None:
    """A failed ``auto`` fit of a structure without an offset, tried again with one (as ``offset=True`` would).

    Asked only when the fit failed as a forgotten offset makes it fail (no
    better than a constant, unstable, or out of budget); the verdict names
    the offset when it lowers J to below :data:`OFFSET_PROBE_GAIN` of the failed fit's.
    """
    from ._auto import auto_minimize

    structure = cost.structure
    failed = any(v.code in _OFFSET_PROBED for v in verdicts) or int(res.status) == BUDGET_EXHAUSTED
    if structure.offset or not failed or any(v.code == "offset-missing" for v in verdicts):
        return None
    probe = HammersteinCost(cost.data, structure.with_options(offset=True), reject_unstable=cost.reject_unstable)
    with np.errstate(all="ignore"):
        try:
            alt = auto_minimize(probe, maxfev=checks.maxfev, seed=seed, allow_unstable=checks.allow_unstable)
        except ParameterError:          # maps with no automatic start (custom ones): the probe says nothing
            return None
    if not (alt.success and alt.fun < OFFSET_PROBE_GAIN * res.fun):
        return None
    fit = fit_report(cost.data.y, probe.simulate(alt.x))["fit_percent"]
    return Verdict("offset-missing", FAILURE,
                   f"the output has an offset this structure cannot produce: with offset=True (--offset) the same "
                   f"structure fits {fit:.1f} % (J = {alt.fun:.4g} against {res.fun:.4g}, y0 = {alt.x[-1]:.4g})")


def _out_of_budget(res, key: str) -> bool:
    return int(res.status) == BUDGET_EXHAUSTED and key in _CONVERGING + (AUTO,)


def _message(res, key: str, verdicts, checks: _Checks) -> str:
    """The result's message: the failures (with what to do), or the optimiser's own words."""
    message = str(res.message)
    failures = [v.message for v in verdicts if v.severity == FAILURE]
    if _out_of_budget(res, key) and not any(v.code == "monic-drift" for v in verdicts):   # more would not help it
        improvement = late_improvement(res.history)
        if improvement > STILL_IMPROVING:       # the budget first: what the fit shows so far may still change
            failures.insert(0, budget_advice(verdicts, checks.maxfev, improvement))
        elif not any(v.code in _SIMPLER for v in verdicts):   # a simpler model as good: more would not help
            failures.append(budget_advice(verdicts, checks.maxfev, improvement))
    if failures:
        return "; ".join(dict.fromkeys(failures)) + f" [{message}]"
    warned = [v for v in verdicts if v.severity != FAILURE]
    if warned:
        return message + f" ({len(warned)} warning{'s' if len(warned) > 1 else ''}: see warnings)"
    return message


def _result(cost, res, key, x0, started, checks: _Checks) -> IdentificationResult:
    structure, data = cost.structure, cost.data
    x = np.asarray(res.x, dtype=float)
    with np.errstate(all="ignore"):
        yhat = cost.simulate(x) if np.all(np.isfinite(x)) else np.full(len(data), np.nan)
    if np.all(np.isfinite(yhat)):
        report = fit_report(data.y, yhat)
    else:
        report = {"fit_percent": -np.inf, "rmse": np.inf, "nrmse": np.inf}
    model = structure.model(x, intersample=data.intersample) if np.all(np.isfinite(x)) else None
    verdicts = _basic_verdicts(cost, res, key, x0, report)
    if not verdicts and np.all(np.isfinite(yhat)):
        verdicts = _not_a_minimum(cost, res, key, checks, report)
    unc = analysis = None
    if model is not None and np.all(np.isfinite(yhat)):
        residuals = np.subtract(data.y, yhat, out=yhat)            # the simulated output is not needed again
        with np.errstate(all="ignore"):
            trust, unc, analysis = _trust_verdicts(cost, x, residuals, model, checks)
        # a fit no better than a constant, or stopped while still improving, is no optimum: verdicts on its
        # parameters would be noise
        still = _out_of_budget(res, key) and late_improvement(res.history) > STILL_IMPROVING
        if not any(v.code == "no-better" for v in verdicts):
            verdicts += [v for v in trust if v.code == "not-significant"] if still else trust
    if key == AUTO and checks.uncertainty and isinstance(cost, HammersteinCost):
        probe = _offset_probe(cost, res, verdicts, checks, checks.seed)
        if probe is not None:
            verdicts.insert(0, probe)
    success = bool(res.success) and not any(v.severity == FAILURE for v in verdicts) and not _out_of_budget(res, key)
    return IdentificationResult(
        model=model, x=x, fun=float(res.fun), nfev=int(res.nfev), fit_percent=report["fit_percent"],
        rmse=report["rmse"], nrmse=report["nrmse"], method=key, success=success,
        message=_message(res, key, verdicts, checks), history=res.history, elapsed=time.perf_counter() - started,
        structure=structure, optimize_result=res,
        covariance=None if unc is None else unc.covariance, warnings=[v.message for v in verdicts],
        verdicts=verdicts, uncertainty=unc, analysis=analysis, **_records_of(cost, x, model),
    )


def _records_of(cost, x, model) -> dict:
    """``data`` of a fit, and for several records also ``records`` and each record's model in ``models``."""
    if not isinstance(cost, RecordsCost):
        return {"data": cost.data}
    models = () if model is None else tuple(
        cost.structure.model(x, k, intersample=rec.intersample, name=rec.name) for k, rec in enumerate(cost.records))
    return {"data": cost.records[0], "records": cost.records, "models": models}


# -- MIMO ------------------------------------------------------------------------------------------
def _mimo_report(data, Y) -> tuple[dict, dict]:
    """``(overall figures, fit % per output)`` (:func:`~hammerstein_ctrl.data.channel_report`)."""
    if not np.all(np.isfinite(Y)):
        return {"fit_percent": -np.inf, "rmse": np.inf, "nrmse": np.inf}, {n: -np.inf for n in data.output_names}
    report = channel_report(data.outputs, Y, data.output_names)
    return report, {n: r["fit_percent"] for n, r in report["outputs"].items()}


def _mimo_basic_verdicts(cost, res, key, x0, fits: dict, Y) -> list[Verdict]:
    """:func:`_basic_verdicts` of a MIMO fit, output by output (``Y``: the simulated outputs at ``res.x``)."""
    missing = _no_model(res)
    if missing:
        return missing
    out = []
    for i, (name, fit) in enumerate(fits.items()):
        y = cost.data.outputs[:, i]
        e = y - Y[:, i]
        if fit <= 0:
            out.append(Verdict("no-better", FAILURE, f"output {name!r}: fit {fit:.1f} % is no better than a "
                               "constant; check that this output responds to the inputs, or raise the orders"))
        elif e @ e >= static_affine_sse_columns(cost.data.inputs, y):
            out.append(Verdict("no-better", FAILURE, f"output {name!r}: fit {fit:.1f} % is no better than the best "
                               "static affine map of the inputs y = K u + c; check that this output responds to the "
                               "inputs, or raise the orders"))
    return out + _stalled(cost, res, key, x0)


def _mimo_trust(cost, x, model, checks: _Checks):
    """``(verdicts, uncertainty, first analysis)`` of a finite MIMO fit (``cost`` weighted as the fit was)."""
    s, data = cost.structure, cost.data
    r = cost.residuals(x)
    if not checks.uncertainty:
        return row_pole_verdicts(s, x, None, data.output_names, allow_unstable=checks.allow_unstable), None, None
    unc = channel_uncertainty(cost, x, r, s.n_outputs, noise=checks.noise)
    stability = row_pole_verdicts(s, x, unc, data.output_names, allow_unstable=checks.allow_unstable)
    explained = {n for v in stability for n in v.params}
    verdicts = identifiability_verdicts(s, x, unc, exempt=explained) + stability
    analysis = None
    for i, (name, e) in enumerate(zip(data.output_names, cost.split(r))):
        verdict = offset_verdict(s, e, unc._replace(noise=unc.channel_noise[i]))
        if verdict is not None:
            verdicts.append(Verdict(verdict.code, verdict.severity, f"output {name!r}: {verdict.message}"))
        for j, u in enumerate(data.inputs.T):
            found = residual_analysis(e, u, dt=data.dt, output=data.outputs[:, i], closed_loop=checks.closed_loop,
                                      name=f"{data.name}: {name} against {data.input_names[j]}")
            analysis = analysis or found
            if found.findings:
                verdicts.append(Verdict("inadequate", "warning", f"output {name!r} against input "
                                        f"{data.input_names[j]!r}: {found.verdict()}"))
    return verdicts, unc, analysis


def _mimo_result(cost, res, key, x0, started, checks: _Checks) -> IdentificationResult:
    """The result of a MIMO fit: per-output figures, the same verdicts and covariance as a SISO fit."""
    s, data = cost.structure, cost.data
    x = np.asarray(res.x, dtype=float)
    finite = bool(np.all(np.isfinite(x)))
    with np.errstate(all="ignore"):
        Y = cost.simulate(x) if finite else np.full(data.outputs.shape, np.nan)
    report, fits = _mimo_report(data, Y)
    model = s.model(x, intersample=data.intersample, input_names=data.input_names,
                    output_names=data.output_names) if finite else None
    verdicts = _mimo_basic_verdicts(cost, res, key, x0, fits, Y) + (monic_drift_verdicts(s, x, data) if finite
                                                                   else [])
    unc = analysis = None
    if model is not None and np.all(np.isfinite(Y)):
        weights = getattr(res, "output_weights", None)
        with np.errstate(all="ignore"):
            trust, unc, analysis = _mimo_trust(cost if weights is None else cost.weighted(weights), x, model, checks)
        still = _out_of_budget(res, key) and late_improvement(res.history) > STILL_IMPROVING
        if not still and not any(v.code == "no-better" for v in verdicts):
            verdicts += trust
    success = bool(res.success) and not any(v.severity == FAILURE for v in verdicts) and not _out_of_budget(res, key)
    return IdentificationResult(
        model=model, x=x, fun=float(res.fun), nfev=int(res.nfev), fit_percent=report["fit_percent"],
        rmse=report["rmse"], nrmse=report["nrmse"], method=key, success=success,
        message=_message(res, key, verdicts, checks), history=res.history, elapsed=time.perf_counter() - started,
        structure=s, optimize_result=res, covariance=None if unc is None else unc.covariance,
        warnings=[v.message for v in verdicts], verdicts=verdicts, uncertainty=unc, analysis=analysis, data=data,
        output_fits=fits)
