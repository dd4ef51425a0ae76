"""The ``auto`` identification method: data-driven starts, least-squares refinement, restarts.

1. **Starts** from the data alone (:func:`~hammerstein_ctrl.fit._initialize.initial_points`:
   a scan of stable linear blocks over the record's bandwidth with the output
   fitted by linear least squares, refined on the reduced residual), plus the
   user's ``x0`` if given, with its right-half-plane poles reflected
   (:func:`~hammerstein_ctrl.fit._linear_starts.stabilize`) and its offset/initial
   state filled in by least squares when it leaves them out.
2. **Refinement** of every start by Levenberg-Marquardt on the residual
   vector (:func:`~hammerstein_ctrl.optimize.levenberg_marquardt`), the budget
   shared out over the starts still to run.
3. **Restarts** from seeded random perturbations of the best start while the
   best model is unstable (unless allowed) or fits worse than a constant.

Every simulated candidate, including those of the starts and of the
finite-difference Jacobians, counts against ``maxfev``.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> case = hc.presets.trs()
>>> r = auto_minimize(case.cost, maxfev=2000, seed=0)
>>> bool(r.fun < 178.5), r.success
(True, True)
"""

from __future__ import annotations

import time

import numpy as np

from .. import config
from .._linalg import single_threaded_blas
from .._checks import as_count
from ..exceptions import ParameterError
from ._initialize import Budget, initial_points, nuisance_estimate, points_for
from ._linear_starts import stabilize
from ._objective import HammersteinCost
from ..optimize import (BUDGET_EXHAUSTED, COMPLETED, SOLVER_FAILED, History, OptimizeResult, as_rng, as_x0,
                        levenberg_marquardt)
from ..simulate._simulate import unstable
from ..blocks._structure import LinearStructure

__all__ = ["auto_minimize", "RESTART_SPREAD", "MAX_RESTARTS", "distinct_minima", "SAME_MINIMUM"]

#: A budget that never runs out, for work charged to the real budget as a whole afterwards.
UNCOUNTED = 1 << 62

#: Relative size of the random perturbations of a restart.
RESTART_SPREAD = 0.3
#: Smallest parameter scale of a perturbation (for parameters at zero).
RESTART_FLOOR = 1e-3
#: Most restarts tried when no start gives an acceptable model.
MAX_RESTARTS = 8
#: Relative tolerances of the refinements (MINPACK's ftol/xtol/gtol).  Tighter
#: values only crawl along flat valleys such as tanh's ``d0 d1 = const``, where
#: J changes in the ninth digit.
REFINE_TOL = 1e-8
#: Fewest evaluations worth giving one refinement.
MIN_REFINE_BUDGET = 10


class _Merged:
    """Histories of several refinements laid end to end on one evaluation axis."""

    def __init__(self):
        self.history = History()
        self.best = np.inf
        self.rows = 0
        self.ends: list[float] = []          # J where each refinement ended

    def add(self, hist: dict, offset: int):
        for nfev, fun in zip(hist["nfev"], hist["fun"]):
            self.best = min(self.best, fun)
            self.rows += 1
            self.history.append(self.rows, offset + int(nfev), fun, self.best, self.best)


def _total(maxfev) -> int:
    """The evaluation budget: ``maxfev``, or the default of :mod:`~hammerstein_ctrl.config`."""
    return config.get("auto.maxfev") if maxfev is None else as_count(maxfev, "maxfev", minimum=1)


def _user_start(cost, x0, budget: Budget):
    """The user's x0, completed with offset/initial state and stabilised."""
    s = cost.structure
    x = as_x0(x0)
    if x.size == s.n_core and s.n_params > s.n_core:
        x = nuisance_estimate(cost.data, s, x, budget)
    x = s.check_beta(x).copy()
    k = s.linear.n_params
    x[:k] = stabilize(s.linear, x[:k])
    return x


def _acceptable(cost, x, fun, allow_unstable: bool) -> bool:
    """Finite, better than a constant, and stable (a pole within its uncertainty of the imaginary axis counts
    as marginal, not unstable: :func:`~hammerstein_ctrl.assess._diagnostics.linear_verdicts`)."""
    if hasattr(cost, "trivial_sse"):                # a cost of its own scale (weighted, several signals)
        trivial = cost.trivial_sse()
    else:
        y = np.asarray(cost.data.y, dtype=float)
        trivial = float(np.sum((y - y.mean(axis=0)) ** 2))
    if not (np.isfinite(fun) and fun < trivial):
        return False
    s = cost.structure
    if allow_unstable:
        return True
    if hasattr(s, "unstable"):          # every linear block of the structure (each row of a MIMO one, both W-H blocks)
        rejected = s.unstable(x)[0]
    else:
        rejected = unstable(s.linear.coefficients(x[:s.linear.n_params])[1])[0]
    if not rejected:
        return True
    return _marginal_rows(cost, x) if str(s.kind).startswith("mimo") else _marginal(cost, x)


def _marginal(cost, x) -> bool:
    """Whether every right-half-plane pole at ``x`` lies within its uncertainty of the imaginary axis.

    The covariance is the white one from the cost's normal equations (one
    pass, outside the budget: it judges a refinement already made).
    """
    from ..assess._diagnostics import linear_verdicts
    from ..assess._uncertainty import residual_jacobian
    from ..assess._propagation import white_covariance

    x = np.asarray(x, dtype=float)
    with np.errstate(all="ignore"):
        if hasattr(cost, "normal_equations"):
            ne = cost.normal_equations(x)
            gram, fun, finite = ne.gram, ne.fun, ne.finite
        else:                               # a cost with residuals only (a Lur'e loop): its Jacobian
            r, J = residual_jacobian(cost, x)
            gram, fun = J.T @ J, float(r @ r)
            finite = bool(np.all(np.isfinite(gram)) and np.isfinite(fun))
    if not finite:
        return False
    unc = white_covariance(gram, fun, len(cost.data))
    return linear_verdicts(cost.structure, x, unc, cost.data.dt)[1]


def _marginal_rows(cost, x) -> bool:
    """:func:`_marginal` for a MIMO cost: every right-half-plane pole of every row within its uncertainty of the
    axis (the white covariance of each output's noise; outside the budget)."""
    from ..assess._diagnostics import row_pole_verdicts
    from ..assess._uncertainty import channel_uncertainty

    x = np.asarray(x, dtype=float)
    with np.errstate(all="ignore"):
        unc = channel_uncertainty(cost, x, cost.residuals(x), cost.structure.n_outputs, noise="white")
    return not any(v.code == "unstable" for v in row_pole_verdicts(cost.structure, x, unc, cost.data.output_names))


def _refine(cost, start, budget: Budget, share: int, merged: _Merged):
    res = levenberg_marquardt(cost, start, maxfev=share, ftol=REFINE_TOL, xtol=REFINE_TOL, gtol=REFINE_TOL)
    merged.add(res.history, budget.nfev)
    merged.ends.append(float(res.fun))
    budget.charge(res.nfev)
    return res


#: Refinements ending within this relative difference of J are counted as one minimum.
SAME_MINIMUM = 1e-6


def distinct_minima(ends) -> np.ndarray:
    """The different J values where refinements ended (ascending; within :data:`SAME_MINIMUM` relative: one).

    Examples
    --------
    >>> distinct_minima([2.0, 1.0, 1.0 + 1e-9, np.inf]).tolist()
    [1.0, 2.0]
    """
    out: list[float] = []
    for v in sorted(float(e) for e in ends if np.isfinite(e)):
        if not out or v > out[-1] * (1.0 + SAME_MINIMUM) + np.finfo(float).tiny:
            out.append(v)
    return np.array(out)


def _perturbed(anchor, rng) -> np.ndarray:
    """A seeded random relative perturbation of ``anchor`` (a restart point before stabilisation)."""
    x = np.array(anchor, dtype=float)
    x += RESTART_SPREAD * np.maximum(np.abs(x), RESTART_FLOOR) * rng.standard_normal(x.size)
    return x


def _restart_point(anchor, rng, linear) -> np.ndarray:
    """A seeded random relative perturbation of ``anchor``, with the linear block stabilised."""
    x = _perturbed(anchor, rng)
    x[:linear.n_params] = stabilize(linear, x[:linear.n_params])
    return x


def _restart_points(anchor, rng, linear):
    """:data:`MAX_RESTARTS` of :func:`_restart_point` around ``anchor``."""
    for _ in range(MAX_RESTARTS):
        yield _restart_point(anchor, rng, linear)


def _restarts_around_first(rng, linear):
    """:func:`_search`'s ``next_restart``: :func:`_restart_points` around the best at the first restart, then the
    next of them (``None`` when they are spent)."""
    restarts = []

    def next_restart(anchor):
        if not restarts:
            restarts.append(_restart_points(anchor, rng, linear))
        return next(restarts[0], None)

    return next_restart


def _search(cost, starts, next_restart, budget: Budget, merged: _Merged, allow_unstable: bool, callback):
    """``(best refinement or None, refinements run)``: each start refined in turn, the budget shared out over
    those still to run, then restarts (``next_restart(best x)``, ``None`` when there are no more) while the best
    is not acceptable."""
    best, best_key, runs = None, None, 0
    queue = list(starts)
    while budget.remaining >= MIN_REFINE_BUDGET:
        if not queue:
            nxt = None if best is None or best_key[0] else next_restart(best.x)
            if nxt is None:
                break
            queue.append(nxt)
        share = int(budget.remaining // len(queue))
        res = _refine(cost, queue.pop(0), budget, max(share, MIN_REFINE_BUDGET), merged)
        runs += 1
        key = (_acceptable(cost, res.x, res.fun, allow_unstable), -res.fun)
        if best is None or key > best_key:
            best, best_key = res, key
        if callback is not None and callback(res):
            break
    return best, runs


# Every auto_* function runs with BLAS held to one thread, as identify does: the start search's regressions
# are thousands of rows by a few columns, where OpenBLAS's threads only add their wake-ups (auto_minimize
# called directly on the EMPS: 84 ms median with two threads, 43 ms with one).
@single_threaded_blas()
def auto_minimize(cost, x0=None, *, maxfev: int | None = None, seed=None, allow_unstable: bool = False,
                  callback=None):
    """Minimise a :class:`~hammerstein_ctrl.fit.HammersteinCost` without tuning.

    Parameters
    ----------
    cost : HammersteinCost
    x0 : array_like, optional
        Used as one more start (stabilised; offset and initial state may be left out).
    maxfev : int, optional
        Budget of simulated candidates (default ``config.defaults["auto.maxfev"]``); never exceeded.
    seed : int or numpy.random.Generator, optional
        Source of the restart perturbations.
    allow_unstable : bool, default False
        Accept a model with a right-half-plane pole without restarting.
    callback : callable, optional
        Called with each refinement's :class:`~hammerstein_ctrl.optimize.OptimizeResult`;
        returning True stops after that refinement.

    Returns
    -------
    hammerstein_ctrl.optimize.OptimizeResult
        ``x, fun, nfev, nit`` (refinements run), ``status``, ``message``,
        ``success`` (the last refinement converged and the model is acceptable),
        ``history`` and ``starts`` (how many starts were refined).
    """
    started = time.perf_counter()
    budget = Budget(_total(maxfev))
    rng = as_rng(seed)
    try:
        starts = initial_points(cost.data, cost.structure, budget)
    except ParameterError:  # a family with no automatic start: the user's x0 is the start
        if x0 is None:
            raise
        starts = []
    found = len(starts)                   # data-driven starts; the user's x0 comes after them
    if x0 is not None:
        starts.append(_user_start(cost, x0, budget))
    merged, next_restart = _Merged(), _restarts_around_first(rng, cost.structure.linear)

    reserve = int(RESCUE_SHARE * budget.remaining) if found and _may_drift(cost.structure) else 0
    search = Budget(int(budget.nfev) + max(1, int(budget.remaining) - reserve))   # the same count, less the reserve
    search.charge(budget.nfev)
    stopped = []

    def watched(res):                   # the user's callback, and whether it stopped the search
        if callback is not None and callback(res):
            stopped.append(True)
            return True
        return False

    best, runs = _search(cost, starts, next_restart, search, merged, allow_unstable, watched)
    budget.charge(search.nfev - budget.nfev)
    if best is None:
        return _unrefined(cost, starts, found, budget, merged, started)
    if reserve and not stopped:
        best, more = _spend_reserve(cost, best, budget, merged, allow_unstable, rng)
        runs += more
    return _result(cost, best, budget, runs, len(starts), merged, allow_unstable, started)


def _spend_reserve(cost, best, budget: Budget, merged: _Merged, allow_unstable: bool, rng):
    """``(best, refinements run)``: the rescue of a drifted search, else the best refinement continued where the
    search's budget ended it."""
    if drifted(cost.structure, best.x) and budget.remaining >= 2 * MIN_REFINE_BUDGET:
        try:
            return _rescue(cost, best, budget, merged, allow_unstable, rng)
        except ParameterError:          # a structure the rescue cannot start (no automatic start for its maps)
            return best, 0
    if best.status == BUDGET_EXHAUSTED and budget.remaining >= MIN_REFINE_BUDGET:
        return _refine(cost, best.x, budget, int(budget.remaining), merged), 1
    return best, 0


#: Share of ``auto``'s budget kept back from the search of a block with a monic numerator of degree >= 1, for a
#: rescue should the search drift (:func:`drifted`); otherwise it continues the best refinement.
RESCUE_SHARE = 0.25


def _may_drift(structure) -> bool:
    """Whether the search can slide along the gain convention's degenerate direction (a zero running off)."""
    lin = structure.linear
    return bool(lin.num_order >= 1 and lin.monic_numerator and structure.linear_counterpart() is not None)


#: A pole or zero of the fitted linear block past this many times the median of its poles' sizes has run off:
#: the search slid toward a lower-order block (the gain convention's degenerate direction).
DRIFT_RATIO = 100.0


def drifted(structure, x) -> bool:
    """Whether the linear block of ``x`` has a pole or zero past :data:`DRIFT_RATIO` times its poles' median size.

    >>> from hammerstein_ctrl import HammersteinStructure, LinearStructure, Tanh
    >>> s = HammersteinStructure(LinearStructure(1, 2), Tanh())
    >>> drifted(s, [2.0, 3.0, 1.5, 2.0, 0.8]), drifted(s, [-8e4, 3.0, 1.5, 2.0, 0.8])
    (False, True)
    """
    lin = structure.linear
    x = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(x)):
        return False
    num, den = lin.coefficients(x[:lin.n_params])
    with np.errstate(all="ignore"):
        poles = np.abs(np.roots(den[0]))
        roots = np.concatenate([poles, np.abs(np.roots(np.trim_zeros(num[0], "f")))])
    size = float(np.median(poles[poles > 0])) if np.any(poles > 0) else 0.0
    return bool(size > 0 and np.max(roots, initial=0.0) > DRIFT_RATIO * size)


def _rescue(cost, best, budget: Budget, merged: _Merged, allow_unstable: bool, rng):
    """``(best, refinements run)`` after refinements from linear blocks that did not drift, tried in turn until
    one does not drift: the block with one numerator degree less (fitted with the same static blocks) with a zero
    put back at its fastest pole, then the linear model of the same order; the static blocks fitted to each
    (:func:`~hammerstein_ctrl.fit._initialize.points_for`).  Never worse than ``best``."""
    s, data = cost.structure, cost.data
    key, runs = (_acceptable(cost, best.x, best.fun, allow_unstable), -best.fun), 0
    for sub in _rescue_structures(s):
        share = int(budget.remaining // 2)
        if share < MIN_REFINE_BUDGET:
            break
        fit = auto_minimize(HammersteinCost(data, sub), maxfev=share, seed=rng, allow_unstable=True)
        budget.charge(min(int(fit.nfev), int(budget.remaining)))
        if not np.all(np.isfinite(fit.x)):
            continue
        points = points_for(data, s, _rescue_thetas(s.linear, sub.linear, fit.x[:sub.linear.n_params]), budget)
        for x in points:
            if budget.remaining < MIN_REFINE_BUDGET:
                break
            x = x.copy()
            x[:s.linear.n_params] = stabilize(s.linear, x[:s.linear.n_params])
            res = _refine(cost, x, budget, int(budget.remaining // len(points)), merged)
            runs += 1
            new = (_acceptable(cost, res.x, res.fun, allow_unstable), -res.fun)
            if new > key:
                best, key = res, new
        if not drifted(s, best.x):
            break
    return best, runs


def _rescue_structures(s) -> list:
    """The linear counterpart of ``s`` and, for a monic numerator of degree >= 1, ``s`` with one degree less: the
    linear counterpart first without an output map (the best linear approximation of a Hammerstein plant has its
    linear block's dynamics), last with one (an output map bends them)."""
    lin = s.linear
    lower = []
    if lin.num_order >= 1 and lin.monic_numerator and set(lin.fixed) <= {f"b{lin.num_order}"} and not lin.delay:
        lower.append(s.with_linear(LinearStructure(lin.num_order - 1, lin.den_order)))
    linear = [] if s.linear_counterpart() is None else [s.linear_counterpart()]
    return linear + lower if s.output_nonlinearity is None else lower + linear


def _rescue_thetas(linear, sub, theta) -> list:
    """``linear``'s parameters for the block ``sub(theta)``: the same (same orders) or with a zero at its fastest
    pole put back (one numerator degree less)."""
    if sub.num_order == linear.num_order:
        return [np.asarray(theta, dtype=float)]
    num, den = sub.coefficients(theta)
    with np.errstate(all="ignore"):
        fastest = float(np.max(np.abs(np.roots(den[0])), initial=0.0))
    if not (np.isfinite(fastest) and fastest > 0):
        return []
    full = np.polymul(num[0], [1.0, fastest])          # monic numerator of one degree more
    return [np.concatenate([full[::-1][:-1], den[0][::-1][:-1]])]


def _unrefined(cost, starts, found, budget, merged, started):
    """The result when too little budget is left for any refinement: the best start (not refined), or no point.

    ``found`` of the ``starts`` are data-driven (the user's x0 follows them).
    The start's J is evaluated once more for the report (as ``identify``
    simulates its final model), outside the budget.
    """

    hint = (f"{budget.nfev} of maxfev = {budget.maxfev} evaluations spent, and a refinement needs at least "
            f"{MIN_REFINE_BUDGET}; raise maxfev (the default is {config.get('auto.maxfev')})")
    if starts:
        x = cost.structure.normalize(starts[0])
        fun = float(cost(x))
        which = "the best data-driven start" if found else "the user's x0 (stabilised)"
        message = f"no refinement ran: x is {which}, not refined ({hint})"
    else:
        x, fun = np.full(cost.n_params, np.nan), np.inf
        message = (f"the search for starting points used up its share of the budget without finding one "
                   f"({hint})")
    return OptimizeResult(x=x, fun=fun, nfev=budget.nfev, nit=0, success=False, status=BUDGET_EXHAUSTED,
                          message=message, history=merged.history.as_dict(), method="auto",
                          starts=len(starts), best_x=x.copy() if starts else None, best_fun=fun, nfev_monitor=0,
                          elapsed=time.perf_counter() - started)


def _result(cost, best, budget, runs, n_starts, merged, allow_unstable, started):

    # the best refinement's own status: converged, out of budget, or any other stop (a solver's failure)
    status = best.status if best.status in (COMPLETED, BUDGET_EXHAUSTED) else SOLVER_FAILED
    converged = status == COMPLETED
    x = cost.structure.normalize(best.x)
    ok = _acceptable(cost, x, best.fun, allow_unstable)
    if converged and ok:
        message = f"converged ({best.message.rstrip('.')}) after {runs} refinement(s) from {n_starts} start(s)"
    elif status == BUDGET_EXHAUSTED:
        message = f"best of {runs} refinement(s) did not converge within maxfev = {budget.maxfev}: {best.message}"
    elif not converged:     # the solver stopped on its own limits: more evaluations would not help
        message = f"best of {runs} refinement(s) did not converge: {best.message}"
    else:
        message = f"no acceptable model (unstable or no better than a constant) after {runs} refinement(s)"
    return OptimizeResult(x=x, fun=float(best.fun), nfev=budget.nfev, nit=runs, success=bool(converged and ok),
                          status=status, message=message,
                          history=merged.history.as_dict(), method="auto", starts=n_starts,
                          best_x=x.copy(), best_fun=float(best.fun), nfev_monitor=0,
                          minima=distinct_minima(merged.ends + [float(best.fun)]),
                          elapsed=time.perf_counter() - started)


