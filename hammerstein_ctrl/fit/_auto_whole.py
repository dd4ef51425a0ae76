"""The automatic method for structures simulated as a whole: Lur'e loops (friction or any map, also inside a known
control loop) and Wiener-Hammerstein models."""

from __future__ import annotations

import time
import numpy as np
from .. import config
from .._linalg import single_threaded_blas
from ..exceptions import ParameterError
from ._initialize import Budget
from ._linear_starts import stabilize
from ..blocks._lure import sign_map
from ._lure_fit import hammerstein_start, hammerstein_structure_of, linear_structure_of, map_starts
from ._wh_fit import bla_structure, split_starts, start_record
from ._objective import HammersteinCost
from ..optimize import COMPLETED, OptimizeResult, as_rng, as_x0
from ._auto import (MAX_RESTARTS, MIN_REFINE_BUDGET, _Merged, _acceptable, _perturbed, _refine, _restart_point,
                    _restarts_around_first, _result, _search, _total, _unrefined, auto_minimize)

__all__ = ["auto_lure", "auto_known_loop", "auto_wiener_hammerstein"]


#: Scalings of the Coulomb level tried from the Hammerstein start of a Lur'e fit (its minima are close in J).
LURE_FRICTION_SCALES = (1.0, 0.5, 1.5)
#: Refinements of a Lur'e fit from perturbations of its current best, after its starts.
LURE_RESTARTS = 12
#: Share of the budget of a Lur'e fit spent on the Hammerstein fit that starts it.
LURE_START_SHARE = 0.3


@single_threaded_blas()
def auto_lure(cost, x0=None, *, maxfev: int | None = None, seed=None, allow_unstable: bool = False,
              callback=None):
    """:func:`auto_minimize` for a Lur'e loop (a :class:`~hammerstein_ctrl.fit.LureCost`).

    Starts come from ``auto`` on the Hammerstein structure with the same poles
    and Coulomb friction on the input (:func:`~hammerstein_ctrl.fit._lure_fit.hammerstein_start`),
    with its Coulomb level scaled by :data:`LURE_FRICTION_SCALES`, plus the
    user's ``x0``; Levenberg-Marquardt refines each, restarts perturb the best.
    Parameters and return value as :func:`auto_minimize`.
    """
    started = time.perf_counter()
    budget = Budget(_total(maxfev))
    rng = as_rng(seed)
    if not sign_map(cost.structure.nonlinearity):
        return _auto_map_loop(cost, x0, budget, rng, allow_unstable, callback, started)
    hs = hammerstein_structure_of(cost.structure)
    first = auto_minimize(HammersteinCost(cost.data, hs), maxfev=max(MIN_REFINE_BUDGET,
                                                                     int(LURE_START_SHARE * budget.maxfev)),
                          seed=rng, allow_unstable=True)
    budget.charge(min(int(first.nfev), budget.remaining))
    starts = []
    if np.all(np.isfinite(first.x)):
        base = hammerstein_start(cost.structure, hs, first.x)
        for scale in LURE_FRICTION_SCALES:
            x = base.copy()
            x[cost.structure.level_index] *= scale
            starts.append(x)
    if x0 is not None:
        starts.append(cost.structure.check_beta(as_x0(x0)).copy())
    if not starts:
        return first
    merged, next_restart = _Merged(), _restarts_around_first(rng, cost.structure.linear)

    reserve = int(LURE_POLISH_SHARE * budget.remaining)
    search = Budget(int(budget.nfev) + max(1, int(budget.remaining) - reserve))   # the same count, less the reserve
    search.charge(budget.nfev)
    best, runs = _search(cost, starts, next_restart, search, merged, allow_unstable, callback)
    if best is not None:
        best, more = _explore(cost, best, rng, search, merged, allow_unstable)
        runs += more
    budget.charge(search.nfev - budget.nfev)
    if best is None:
        return _unrefined(cost, starts, len(starts), budget, merged, started)
    best, more = _polish(cost, best, budget, merged)
    return _result(cost, best, budget, runs + more, len(starts), merged, allow_unstable, started)


def auto_known_loop(cost, starts, *, maxfev: int | None = None, seed=None, allow_unstable: bool = False,
                    callback=None):
    """Levenberg-Marquardt on a known loop's residuals (a :class:`~hammerstein_ctrl.fit.KnownLoopCost` of a block
    structure) from ``starts`` (the open-loop fit), restarts from seeded perturbations of the best while it is not
    acceptable.  Parameters and return value as :func:`auto_minimize`."""
    started = time.perf_counter()
    budget = Budget(_total(maxfev))
    rng = as_rng(seed)
    starts = [cost.structure.check_beta(as_x0(x)).copy() for x in starts]
    if not starts:
        raise ParameterError("the open-loop fit that starts a loop fit found no finite parameters")
    merged, next_restart = _Merged(), _restarts_around_first(rng, cost.structure.linear)

    best, runs = _search(cost, starts, next_restart, budget, merged, allow_unstable, callback)
    if best is None:
        return _unrefined(cost, starts, len(starts), budget, merged, started)
    return _result(cost, best, budget, runs, len(starts), merged, allow_unstable, started)


#: Best-scoring map candidates of a Lur'e loop's linear start handed to the refinement.
LURE_MAP_STARTS = 3


def _auto_map_loop(cost, x0, budget: Budget, rng, allow_unstable: bool, callback, started):
    """:func:`auto_lure` for a map that is not sign-type: ``auto`` on the linear model of the same orders, its
    loop with the map's candidates (:func:`~hammerstein_ctrl.fit._lure_fit.map_starts`) scored by J, the best
    :data:`LURE_MAP_STARTS` and the user's ``x0`` refined."""
    s = cost.structure
    ls = linear_structure_of(s)
    first = auto_minimize(HammersteinCost(cost.data, ls), maxfev=max(MIN_REFINE_BUDGET,
                                                                       int(LURE_START_SHARE * budget.maxfev)),
                          seed=rng, allow_unstable=True)
    budget.charge(min(int(first.nfev), budget.remaining))
    starts = map_starts(s, ls, first.x, cost.data) if np.all(np.isfinite(first.x)) else []
    if starts:
        scores = cost.batch(np.array(starts))
        budget.charge(min(len(starts), budget.remaining))
        starts = [starts[i] for i in np.argsort(scores, kind="stable")[:LURE_MAP_STARTS] if np.isfinite(scores[i])]
    starts = [_stabilized(s.linear, x) for x in starts]
    if x0 is not None:
        starts.append(_stabilized(s.linear, s.check_beta(as_x0(x0))))
    if not starts:
        raise ParameterError(f"no automatic start for the map {s.nonlinearity!r} of a Lur'e loop (it has neither a "
                             "basis nor a scale parameter, or the linear model found none): give x0")
    merged = _Merged()
    best, runs = _search(cost, starts, _restarts_around_first(rng, s.linear), budget, merged, allow_unstable,
                         callback)
    if best is None:
        return _unrefined(cost, starts, len(starts), budget, merged, started)
    return _result(cost, best, budget, runs, len(starts), merged, allow_unstable, started)


def _stabilized(linear, x) -> np.ndarray:
    x = np.array(x, dtype=float)
    x[:linear.n_params] = stabilize(linear, x[:linear.n_params])
    return x


#: Share of a friction loop's budget kept for the derivative-free polish of the best refinement.
LURE_POLISH_SHARE = 0.3
#: Relative tolerance (on J, and on the simplex's size) of that polish.
POLISH_TOL = 1e-9


def _polish(cost, best, budget: Budget, merged: _Merged):
    """``(best, refinements run)`` after Nelder-Mead from the best refinement (deterministic: the same point for
    every seed that reaches the basin).  Stick-slip makes J piecewise smooth: forward differences across a
    sticking event mislead Levenberg-Marquardt, which then stops short on its step test (on the EMPS, 2e-4 of J
    above the optimum); the simplex needs no derivative."""
    from ..optimize import minimize

    if budget.remaining < MIN_REFINE_BUDGET:
        return best, 0
    scale = max(float(best.fun), np.finfo(float).tiny)
    res = minimize(cost, best.x, method="nelder-mead", maxfev=int(budget.remaining),
                   options={"xatol": POLISH_TOL * max(1.0, float(np.max(np.abs(best.x)))),
                            "fatol": POLISH_TOL * scale})
    merged.add(res.history, budget.nfev)
    budget.charge(min(int(res.nfev), int(budget.remaining)))
    if not res.fun < best.fun:
        return best, 1
    status = COMPLETED if res.status == COMPLETED else best.status
    message = f"{best.message.rstrip('.')}; polished by Nelder-Mead ({res.message.rstrip('.')})"
    return OptimizeResult({**best, "x": np.asarray(res.x, dtype=float), "fun": float(res.fun), "status": status,
                           "message": message}), 1


def _explore(cost, best, rng, budget: Budget, merged: _Merged, allow_unstable: bool):
    """``(best, refinements run)`` after :data:`LURE_RESTARTS` refinements from perturbations of the current
    best: stick-slip makes J piecewise smooth, with local minima close in J that the starts alone miss."""
    key = (_acceptable(cost, best.x, best.fun, allow_unstable), -best.fun)
    runs = 0
    for _ in range(LURE_RESTARTS):
        share = int(budget.remaining // max(1, LURE_RESTARTS - runs))
        if share < MIN_REFINE_BUDGET:
            break
        res = _refine(cost, _restart_point(best.x, rng, cost.structure.linear), budget, share, merged)
        runs += 1
        new = (_acceptable(cost, res.x, res.fun, allow_unstable), -res.fun)
        if new > key:
            best, key = res, new
    return best, runs


#: Share of the budget given to the linear model that starts a Wiener-Hammerstein fit.
WH_BLA_SHARE = 0.4


def _stabilized_blocks(structure, x) -> np.ndarray:
    """``x`` with each linear block of a Wiener-Hammerstein structure stabilised."""
    x = np.array(x, dtype=float)
    for linear, at in structure.block_layout:
        x[at:at + linear.n_params] = stabilize(linear, x[at:at + linear.n_params])
    return x


def _block_restarts(rng, structure):
    """:func:`_search`'s ``next_restart`` for a structure of several linear blocks: seeded perturbations of the
    best, each block stabilised (:data:`MAX_RESTARTS` of them)."""
    spent = [0]

    def next_restart(anchor):
        if spent[0] >= MAX_RESTARTS:
            return None
        spent[0] += 1
        return _stabilized_blocks(structure, _perturbed(anchor, rng))

    return next_restart


@single_threaded_blas()
def auto_wiener_hammerstein(cost, x0=None, *, maxfev: int | None = None, seed=None, allow_unstable: bool = False,
                            callback=None):
    """:func:`auto_minimize` for a Wiener-Hammerstein structure (a
    :class:`~hammerstein_ctrl.fit.WienerHammersteinCost`).

    A linear model of the whole order is fitted first (``auto`` on
    :func:`~hammerstein_ctrl.fit._wh_fit.bla_structure`, :data:`WH_BLA_SHARE` of the
    budget); the splits of its poles and zeros between the blocks are scored by
    the least-squares fit of the map (:func:`~hammerstein_ctrl.fit._wh_fit.split_starts`,
    one evaluation each); Levenberg-Marquardt refines the best splits and the
    user's ``x0``, restarts perturb the best while it is not acceptable.
    Parameters and return value as :func:`auto_minimize`; the default budget is
    ``config.defaults["auto.wh_maxfev"]``.
    """
    started = time.perf_counter()
    budget = Budget(config.get("auto.wh_maxfev") if maxfev is None else _total(maxfev))
    rng = as_rng(seed)
    s = cost.structure
    record = start_record(cost)
    bla = auto_minimize(HammersteinCost(record, bla_structure(s)), seed=rng, allow_unstable=True,
                        maxfev=max(MIN_REFINE_BUDGET, int(WH_BLA_SHARE * budget.maxfev)))
    budget.charge(min(int(bla.nfev), budget.remaining))
    starts, scored = split_starts(cost, bla.x, record=record) if np.all(np.isfinite(bla.x)) else ([], 0)
    budget.charge(min(scored, budget.remaining))
    starts = [_stabilized_blocks(s, x) for x in starts]
    if x0 is not None:
        starts.append(_stabilized_blocks(s, s.check_beta(as_x0(x0))))
    if not starts:
        raise ParameterError(f"no automatic start for the map {s.nonlinearity!r} of a Wiener-Hammerstein structure "
                             "(it has neither a basis nor a scale parameter): give x0")
    merged = _Merged()
    best, runs = _search(cost, starts, _block_restarts(rng, s), budget, merged, allow_unstable, callback)
    if best is None:
        return _unrefined(cost, starts, len(starts), budget, merged, started)
    return _result(cost, best, budget, runs, len(starts), merged, allow_unstable, started)
