"""SPSA, norm-limited SPSA (NL-SPSA) and normalized SPSA (N-SPSA).

All three share Spall's simultaneous-perturbation iteration (paper Eq. 6-7):
at iteration ``k = 1, 2, ..., k_max`` draw ``Delta ~ Bernoulli(+-1)^n``, evaluate
``f+ = f(theta + c(k) Delta)`` and ``f- = f(theta - c(k) Delta)`` (two
evaluations) and step ``theta <- theta - s``.  They differ in ``s``:

* **SPSA** (Spall 1992): ``s = a(k) (f+ - f-) / (2 c(k) Delta)``.
* **NL-SPSA** (Tanaka, Azuma & Sugie 2015; Ahmad et al. 2016): the same ``s``
  with its Euclidean norm limited to ``delta``: if ``||s|| > delta`` then
  ``s <- delta s / ||s||``.
* **N-SPSA** (the paper, Eq. 9-12, Algorithm 4.2): ``s = a(k) hbar / (2 c(k) Delta)``
  with ``hbar = f~+ - f~-``, ``f~± = f± / max(f+, f-)``, and ``hbar = 1`` on a tie.

The paper's final estimate is the last iterate ``theta(k_max)`` (paper
section 4.3, step 3), evaluated once more to score it: ``estimate="last"``, a
run of ``k_max`` iterations then uses ``2 k_max + 1`` evaluations.  By default
(``estimate="best"``) the start ``theta(0)`` is evaluated too (one more
evaluation) and the result is the best point evaluated, the start and the
last iterate included, so a run never returns a point worse than one it has
seen; the last iterate stays in ``last_x`` and ``last_fun``.  The paper's
presets ask for ``"last"``.

Corner cases the paper leaves open, decided here:

* **N-SPSA normalisation** divides by ``max(|f+|, |f-|)``.  For the non-negative
  objectives of identification this is exactly Eq. (12); for negative values it
  keeps ``hbar`` a descent direction (dividing by a negative maximum would flip it).
* ``max = 0`` (both values zero) is a tie: ``hbar = 1``.
* NaN values count as ``+inf`` (a failed evaluation is the worst possible).
  With one infinite value the normalised values are its sign (±1) and 0 for the
  finite one, so ``hbar = ±1``; two equal infinities are a tie (``hbar = 1``).
  ``hbar`` therefore always lies in [-2, 2] and N-SPSA cannot overflow.
* **NL-SPSA** with an infinite difference steps ``delta`` along
  ``-sign(f+ - f-) Delta / sqrt(n)`` (the limit of the normalised step); with
  an undefined difference (NaN, or inf - inf) it does not move.
* **Divergence.**  A run stops with ``status = 2`` and ``success = False``
  ("diverged") when an iterate becomes non-finite (SPSA with an infinite
  difference), when the better of the two values of an iteration exceeds
  ``divergence_factor`` (default 1e6) times its value at the first iteration,
  or when the iterate's norm exceeds ``divergence_factor * max(1, ||x0||)``.
  This is how SPSA's expected blow-up on the paper's problems is reported: on
  the EMPS its first step throws the parameters from O(1) to 1e7-1e9 (the
  paper's Table 8 lists +-1.5662e6), where the model's output is nearly zero
  and the objective stays finite but useless.

Examples
--------
>>> import numpy as np
>>> from hammerstein_ctrl.optimize import nspsa, StepGain, PerturbationGain
>>> f = lambda x: float(np.sum((x - 1.0) ** 2))
>>> r = nspsa(f, np.zeros(3), a=StepGain(0.1, 10, 0.602), c=PerturbationGain(0.1), maxiter=500, seed=1)
>>> r.nfev, bool(r.fun < 1e-6), bool(r.fun <= r.last_fun)
(1002, True, True)
"""

from __future__ import annotations

import math
from types import SimpleNamespace
import time

import numpy as np

from ..exceptions import ParameterError
from ._common import (CALLBACK_STOP, COMPLETED, DIVERGED, CountedObjective, History, as_bounds, as_rng, as_x0,
                      call_back, check_budget, make_result,)
from ._gains import PerturbationGain, StepGain, as_gain

__all__ = ["spsa", "nlspsa", "nspsa", "normalized_difference", "iterations_for_budget", "auto_scale",
           "DEFAULT_MAXITER", "AUTO", "CALIBRATION_PAIRS", "AUTO_PERTURBATION", "AUTO_FIRST_STEP",
           "AUTO_SCALE_FLOOR"]

DEFAULT_MAXITER = 1000
#: Value of ``a``/``c``/``scale`` asking for calibration from the problem itself.
AUTO = "auto"
#: What a run returns: the best point evaluated (the start included) or the paper's last iterate.
ESTIMATES = ("best", "last")
#: Gradient estimates at x0 used to calibrate ``a`` (two evaluations each, counted).
CALIBRATION_PAIRS = 4
#: Automatic ``c``: perturbations of this fraction of each parameter's scale.
AUTO_PERTURBATION = 0.1
#: Automatic ``a``: the first step moves a parameter by about this fraction of its scale.
AUTO_FIRST_STEP = 0.05
#: Automatic ``a``: decay exponent.  N-SPSA's normalised difference does not
#: shrink with the gradient far from the optimum, so the step must decay by
#: itself: ``1/k``, Spall's asymptotically optimal rate, not the robust 0.602
#: (measured: EMPS mean J 0.24 over 6 seeds against 0.29 with 0.602, TRS 178.9 for both).
AUTO_ALPHA = 1.0
#: Automatic ``scale``: a parameter's scale is ``|x0_i|``, but at least this
#: fraction of the largest ``|x0_j|`` (and at least :data:`AUTO_SCALE_MIN`).
AUTO_SCALE_FLOOR = 0.1
AUTO_SCALE_MIN = 1e-3
#: Spall's stability constant ``A`` as a fraction of the iterations.
AUTO_A_FRACTION = 0.1


def normalized_difference(f_plus: float, f_minus: float) -> float:
    """N-SPSA's ``hbar`` (the paper's equation 11-12) with the corner cases documented above.

    Examples
    --------
    >>> normalized_difference(2.0, 1.0)
    0.5
    >>> normalized_difference(3.0, 3.0), normalized_difference(0.0, 0.0)
    (1.0, 1.0)
    >>> normalized_difference(float("inf"), 5.0), normalized_difference(float("nan"), 5.0)
    (1.0, 1.0)
    >>> normalized_difference(-2.0, -1.0)   # f+ better: move towards theta+
    -0.5
    """
    fp = math.inf if f_plus != f_plus else f_plus
    fm = math.inf if f_minus != f_minus else f_minus
    m = max(abs(fp), abs(fm))
    if m == 0.0:
        return 1.0
    if math.isinf(m):
        tp = math.copysign(1.0, fp) if math.isinf(fp) else 0.0
        tm = math.copysign(1.0, fm) if math.isinf(fm) else 0.0
    else:
        tp, tm = fp / m, fm / m
    h = tp - tm
    return 1.0 if h == 0.0 else h


def _norm_limited(step: np.ndarray, diff: float, delta: np.ndarray, limit: float) -> np.ndarray:
    """NL-SPSA's step: ``step`` with its norm clipped to ``limit``, safe for inf/NaN."""
    if math.isnan(diff):
        return np.zeros_like(delta)
    norm = math.sqrt(float(step @ step)) if math.isfinite(diff) else math.inf
    if math.isfinite(norm):
        return step * (limit / norm) if norm > limit else step
    # infinite difference or overflow in the raw step: keep only the direction
    return (limit * math.copysign(1.0, diff) / math.sqrt(delta.size)) * delta


def _nanmin2(a: float, b: float) -> float:
    if a != a:
        return b
    if b != b:
        return a
    return min(a, b)


def iterations_for_budget(maxfev, maxiter, monitor: int = 0, reserved: int = 0) -> int:
    """``k_max`` of a run: ``maxiter``, else what ``maxfev`` pays for, else :data:`DEFAULT_MAXITER`.

    A run costs ``reserved`` evaluations (gain calibration), ``2 k_max + 1``
    evaluations plus the monitor's evaluations of the iterate; ``k_max`` is
    the largest count whose total fits in ``maxfev`` (``(maxfev - 1) // 2``
    without a monitor or calibration), so ``maxfev`` is never exceeded.

    Examples
    --------
    >>> iterations_for_budget(1_000_000, None), iterations_for_budget(None, None)
    (499999, 1000)
    >>> k = iterations_for_budget(201, None, monitor=50); 2 * k + 1 + _monitor_count(k, 50) <= 201
    True
    """
    maxfev, maxiter = check_budget(maxfev, maxiter)
    if maxfev is None:
        return DEFAULT_MAXITER if maxiter is None else maxiter
    if maxfev < reserved + 1:
        raise ParameterError(f"automatic gains need maxfev >= {reserved + 1} ({reserved // 2} calibration "
                             f"pairs and the final evaluation), got {maxfev}")
    paid = maxfev - reserved
    kmax = (paid - 1) // 2 if maxiter is None else min(maxiter, (paid - 1) // 2)
    while kmax > 0 and 2 * kmax + 1 + _monitor_count(kmax, monitor) > paid:
        kmax -= 1
    return kmax


def _monitor_count(kmax: int, monitor: int) -> int:
    """Monitor evaluations of a ``kmax``-iteration run (at multiples of ``every`` below ``kmax``)."""
    return (kmax - 1) // max(1, kmax // monitor) if monitor and kmax > 0 else 0


def auto_scale(x0) -> np.ndarray:
    """Per-parameter scales from the initial point (see :data:`AUTO_SCALE_FLOOR`).

    Examples
    --------
    >>> auto_scale([-2.0, 0.0, 5.0, -5.0, 0.0]).tolist()
    [2.0, 0.5, 5.0, 5.0, 0.5]
    """
    x = np.abs(np.asarray(x0, dtype=float))
    return np.maximum(x, max(AUTO_SCALE_FLOOR * float(x.max(initial=0.0)), AUTO_SCALE_MIN))


def _raw_step(variant: str, f_plus: float, f_minus: float) -> float:
    """The scalar the SPSA family multiplies by ``a(k) / (2 c(k) Delta)``."""
    return normalized_difference(f_plus, f_minus) if variant == "nspsa" else f_plus - f_minus


def _calibrate(variant: str, obj, theta, scale, kmax: int, rng, c=None):
    """Spall's practical gains from the problem: ``(StepGain, PerturbationGain)`` in scaled units.

    ``c`` perturbs each parameter by :data:`AUTO_PERTURBATION` of its scale;
    ``a`` is set from the median magnitude of :data:`CALIBRATION_PAIRS`
    gradient estimates at ``theta`` so that the first step moves each
    parameter by about :data:`AUTO_FIRST_STEP` of its scale, with
    ``alpha =`` :data:`AUTO_ALPHA`, ``gamma = 0.101`` and ``A = 10 %`` of the iterations.
    """
    c = PerturbationGain(AUTO_PERTURBATION) if c is None else c
    A = AUTO_A_FRACTION * max(kmax, 1)
    mags = []
    for _ in range(CALIBRATION_PAIRS):
        delta = rng.integers(0, 2, theta.size) * 2.0 - 1.0
        f_plus, f_minus = obj.many(np.stack([theta + c(1) * scale * delta, theta - c(1) * scale * delta]))
        h = abs(_raw_step(variant, float(f_plus), float(f_minus))) / (2.0 * c(1))
        if math.isfinite(h) and h > 0:
            mags.append(h)
    g = float(np.median(mags)) if mags else 1.0
    a = StepGain(AUTO_FIRST_STEP * (1.0 + A) ** AUTO_ALPHA / g, A, AUTO_ALPHA)
    return a, c


def _tag(value):
    return value if isinstance(value, str) else None


def _scale_vector(scale, theta, auto: bool) -> np.ndarray:
    """Parameter scales: given, automatic, or ones (the paper's unscaled iteration)."""
    if scale is None:
        return auto_scale(theta) if auto else np.ones(theta.size)
    if isinstance(scale, str):
        if scale != AUTO:
            raise ParameterError(f"scale must be 'auto' or one positive number per parameter, got {scale!r}")
        return auto_scale(theta)
    s = np.asarray(scale, dtype=float).reshape(-1)
    if s.size != theta.size or not np.all(np.isfinite(s) & (s > 0)):
        raise ParameterError(f"scale must be {theta.size} positive finite numbers, got {np.shape(scale)}")
    return s


def _gains(variant, obj, theta, scale, kmax, rng, a, c, auto, *, calibrate: bool = True):
    """The gain sequences: given, or calibrated at ``theta`` (counted evaluations).

    A budget too small to calibrate falls back to Spall's default gains in scaled units.
    """
    if c is not None and _tag(c) is None:
        c = as_gain(c, PerturbationGain, "c")
    if auto:
        if calibrate:
            cal_a, cal_c = _calibrate(variant, obj, theta, scale, kmax, rng, None if _tag(c) or c is None else c)
        else:
            cal_a, cal_c = StepGain.spall(AUTO_FIRST_STEP, max(kmax, 1)), PerturbationGain(AUTO_PERTURBATION)
        a = cal_a if a is None or _tag(a) else a
        c = cal_c if c is None or _tag(c) else c
    else:  # one gain given: the other keeps Spall's default
        a = StepGain.spall(AUTO_FIRST_STEP, max(kmax, 1)) if a is None else a
        c = PerturbationGain(AUTO_PERTURBATION) if c is None else c
    for value, label, kind in ((a, "a", StepGain), (c, "c", PerturbationGain)):
        if _tag(value) is not None:
            raise ParameterError(f"option {label!r} must be a {kind.__name__}, a number or 'auto', got {value!r}")
    return as_gain(a, StepGain, "a"), as_gain(c, PerturbationGain, "c")


def _plan(variant, theta, *, bounds, maxfev, maxiter, monitor, a, c, norm_limit, divergence_factor, estimate,
          scale) -> SimpleNamespace:
    """The checked settings of a run: the start's evaluation, box, calibration, iterations and scale."""
    if estimate not in ESTIMATES:
        raise ParameterError(f"estimate must be one of {ESTIMATES}, got {estimate!r}")
    start = 1 if estimate == "best" else 0      # the evaluation of theta(0)
    box = as_bounds(bounds, theta.size)
    if box is not None and (np.any(theta < box[0]) or np.any(theta > box[1])):
        raise ParameterError(f"x0 {theta.tolist()} lies outside the bounds")
    if int(monitor) != monitor or monitor < 0:
        raise ParameterError(f"monitor must be a non-negative integer, got {monitor!r}")
    auto = (a is None and c is None) or AUTO in (_tag(a), _tag(c))
    # calibrate only when the budget leaves at least one iteration after it
    calibration = 2 * CALIBRATION_PAIRS if auto and (maxfev is None or maxfev >= 2 * CALIBRATION_PAIRS + 3) else 0
    if start and (maxfev is None or maxfev >= calibration + 2):
        kmax = iterations_for_budget(maxfev, maxiter, int(monitor), reserved=calibration + start)
    else:
        kmax = 0 if start else iterations_for_budget(maxfev, maxiter, int(monitor), reserved=calibration)
    if kmax == 0:       # no iteration: the final evaluation is the start's
        start = 0
    scale = _scale_vector(scale, theta, auto)
    if variant == "nlspsa":
        if norm_limit is None or not (np.isfinite(norm_limit) and norm_limit > 0):
            raise ParameterError(f"NL-SPSA needs a positive finite norm_limit (delta), got {norm_limit!r}")
    if not divergence_factor > 1:
        raise ParameterError(f"divergence_factor must exceed 1, got {divergence_factor!r}")
    every = max(1, kmax // int(monitor)) if monitor else 0
    return SimpleNamespace(start=start, box=box, auto=auto, calibration=calibration, kmax=kmax, scale=scale,
                           every=every)


def _divergence(k: int, theta, f_k: float, f_ref, factor: float, radius: float) -> str | None:
    """Why the run diverged at iteration ``k`` (its objective or its iterate grew without bound), or None."""
    if f_ref is not None and f_k > factor * f_ref:
        return (f"diverged at iteration {k}: objective {f_k:.4g} exceeds "
                f"{factor:g} x its first value {f_ref:.4g}")
    norm = math.sqrt(float(theta @ theta))
    if norm > radius:
        return (f"diverged at iteration {k}: the iterate's norm {norm:.4g} exceeds {radius:.4g} "
                f"({factor:g} x max(1, ||x0||))")
    return None


def _step(variant, theta, k, obj, a, c, rng, plan, norm_limit, pair):
    """One iteration: the perturbed pair, its two evaluations and the update ``(new, f+, f-)``."""
    delta = rng.integers(0, 2, theta.size) * 2.0 - 1.0
    ak, ck = a(k), c(k)
    np.add(theta, ck * plan.scale * delta, out=pair[0])
    np.subtract(theta, ck * plan.scale * delta, out=pair[1])
    if plan.box is not None:
        np.clip(pair, plan.box[0], plan.box[1], out=pair)
    f_plus, f_minus = obj.many(pair)
    f_plus, f_minus = float(f_plus), float(f_minus)
    diff = _raw_step(variant, f_plus, f_minus)
    step = plan.scale * ((ak * diff / (2.0 * ck)) / delta)
    if variant == "nlspsa":
        step = _norm_limited(step, diff, delta, norm_limit)
    new = theta - step
    if plan.box is not None:
        np.clip(new, plan.box[0], plan.box[1], out=new)
    return new, f_plus, f_minus


def _iterate(variant, obj, theta, a, c, rng, plan, *, norm_limit, divergence_factor, radius, callback):
    """The iterations of a run: ``(theta, status, message, nit, history)``."""
    history = History()
    status, message = COMPLETED, f"completed {plan.kmax} iterations"
    f_ref = None
    nit = 0
    pair = np.empty((2, theta.size))
    for k in range(1, plan.kmax + 1):
        new, f_plus, f_minus = _step(variant, theta, k, obj, a, c, rng, plan, norm_limit, pair)
        nit = k
        f_k = _nanmin2(f_plus, f_minus)
        estimate = obj.peek(new) if plan.every and k % plan.every == 0 and k < plan.kmax else math.nan
        history.append(k, obj.nfev, f_k, obj.best_fun, estimate)
        if f_ref is None and math.isfinite(f_k):
            f_ref = max(abs(f_k), np.finfo(float).tiny)
        if not np.all(np.isfinite(new)):
            status = DIVERGED
            message = (f"diverged at iteration {k}: the update became non-finite "
                       f"(f+ = {f_plus:.4g}, f- = {f_minus:.4g})")
            break
        theta = new
        why = _divergence(k, theta, f_k, f_ref, divergence_factor, radius)
        if why is not None:
            status, message = DIVERGED, why
            break
        if call_back(callback, theta, f_k, k, obj.nfev):
            status, message = CALLBACK_STOP, f"stopped by the callback after {k} iterations"
            break
    return theta, status, message, nit, history


def _run(variant: str, fun, x0, *, args=(), a=None, c=None, norm_limit: float | None = None,
         maxiter: int | None = None, maxfev: int | None = None, divergence_factor: float = 1e6, bounds=None,
         seed=None, callback=None, monitor: int = 0, scale=None, estimate: str = "best"):
    started = time.perf_counter()
    theta = as_x0(x0)
    plan = _plan(variant, theta, bounds=bounds, maxfev=maxfev, maxiter=maxiter, monitor=monitor, a=a, c=c,
                 norm_limit=norm_limit, divergence_factor=divergence_factor, estimate=estimate, scale=scale)
    rng = as_rng(seed)
    radius = divergence_factor * max(1.0, math.sqrt(float(theta @ theta)))
    obj = CountedObjective(fun, args, maxfev=2 * plan.kmax + 1 + plan.calibration + plan.start)
    with np.errstate(all="ignore"):
        f_start = obj(theta) if plan.start else math.nan
        a, c = _gains(variant, obj, theta, plan.scale, plan.kmax, rng, a, c, plan.auto,
                      calibrate=plan.calibration > 0)
        theta, status, message, nit, history = _iterate(
            variant, obj, theta, a, c, rng, plan, norm_limit=norm_limit, divergence_factor=divergence_factor,
            radius=radius, callback=callback)
        fun_final = obj(theta)
    history.set_last_estimate(fun_final)
    if status == COMPLETED and not math.isfinite(fun_final) and not plan.start:
        message += "; the final estimate has a non-finite objective"
    if plan.start and math.isfinite(f_start) and not obj.best_fun < f_start:
        message += f"; no point evaluated improved on the start (J = {f_start:.6g}), which is returned"
    return make_result(
        x=theta, fun=fun_final, obj=obj, nit=nit, status=status, message=message,
        history=history, method=variant, started=started, keep_last=not plan.start,
        last_x=theta.copy(), last_fun=float(fun_final),
    )


def spsa(fun, x0, *, a=None, c=None, maxiter=None, maxfev=None, seed=None, args=(),
         bounds=None, callback=None, divergence_factor=1e6, monitor=0, scale=None, estimate="best"):
    """Spall's SPSA (the paper's equation 6-7).

    Parameters
    ----------
    fun : callable
        ``fun(x, *args) -> float``.
    x0 : array_like
        Initial point theta(0).
    a : StepGain, float or "auto", optional
        Step gains ``a(k)``.  ``"auto"`` (the default when neither ``a`` nor
        ``c`` is given) calibrates them from the problem by Spall's practical
        guidelines: ``alpha =`` :data:`AUTO_ALPHA`, ``A`` = 10 % of the iterations, and ``a``
        such that the first steps move each parameter by about
        :data:`AUTO_FIRST_STEP` of its scale, judged from
        :data:`CALIBRATION_PAIRS` gradient estimates at ``x0`` (counted in ``nfev``).
    c : PerturbationGain, float or "auto", optional
        Perturbation gains ``c(k)``; ``"auto"``: :data:`AUTO_PERTURBATION` of
        each parameter's scale, ``gamma = 0.101``.
    maxiter : int, optional
        Iterations ``k_max`` (default: what ``maxfev`` pays for, else 1000).
    maxfev : int, optional
        Evaluation budget, never exceeded (calibration and monitor evaluations
        included): ``k_max = (maxfev - 1) // 2`` with given gains and no monitor
        (see :func:`iterations_for_budget`).
    seed : int or numpy.random.Generator, optional
        Source of the perturbations; the same seed gives the same run.
    args : tuple
        Extra arguments for ``fun``.
    bounds : scipy.optimize.Bounds or sequence of (low, high), optional
        Box; iterates and perturbed points are clipped to it.
    callback : callable, optional
        ``callback(OptimizeResult(x, fun, nit, nfev))`` after each iteration;
        returning True or raising StopIteration stops the run.
    divergence_factor : float, default 1e6
        See the module notes.
    monitor : int, default 0
        Evaluate f at the iterate theta(k) at about this many evenly spaced
        iterations, for convergence curves (``history["estimate"]``).  These
        evaluations never influence the search and are counted in
        ``nfev_monitor``, not in ``nfev``; with ``maxfev`` they are paid from it.
    scale : array_like or "auto", optional
        Per-parameter scales: the iteration runs on ``theta / scale``.  Default:
        ``"auto"`` (:func:`auto_scale`) with automatic gains, else ones (the
        paper's unscaled iteration).
    estimate : {"best", "last"}, default "best"
        The point returned: the best one evaluated, the start included (one
        more evaluation), or the paper's last iterate (module notes).

    Returns
    -------
    hammerstein_ctrl.optimize.OptimizeResult
        ``x, fun, nfev, nit, success, status, message, history, best_x,
        best_fun, last_x, last_fun``.
    """
    return _run("spsa", fun, x0, a=a, c=c, maxiter=maxiter, maxfev=maxfev, seed=seed, args=args,
                bounds=bounds, callback=callback, divergence_factor=divergence_factor, monitor=monitor,
                scale=scale, estimate=estimate)


def nlspsa(fun, x0, *, a=None, c=None, norm_limit=0.01, maxiter=None, maxfev=None, seed=None,
           args=(), bounds=None, callback=None, divergence_factor=1e6, monitor=0, scale=None, estimate="best"):
    """Norm-limited SPSA: SPSA whose update vector's norm is capped at ``norm_limit``.

    Parameters are those of :func:`spsa` plus ``norm_limit`` (the paper's
    ``sat_delta``, default 0.01).
    """
    return _run("nlspsa", fun, x0, a=a, c=c, norm_limit=norm_limit, maxiter=maxiter, maxfev=maxfev,
                seed=seed, args=args, bounds=bounds, callback=callback,
                divergence_factor=divergence_factor, monitor=monitor, scale=scale, estimate=estimate)


def nspsa(fun, x0, *, a=None, c=None, maxiter=None, maxfev=None, seed=None, args=(), bounds=None,
          callback=None, divergence_factor=1e6, monitor=0, scale=None, estimate="best"):
    """Normalized SPSA (the paper's Algorithm 4.2).

    Parameters are those of :func:`spsa`.
    """
    return _run("nspsa", fun, x0, a=a, c=c, maxiter=maxiter, maxfev=maxfev, seed=seed, args=args,
                bounds=bounds, callback=callback, divergence_factor=divergence_factor, monitor=monitor,
                scale=scale, estimate=estimate)
