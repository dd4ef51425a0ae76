"""The automatic method for several records, a structure with a dead time, and MIMO structures: each builds on the
single-record search of auto_minimize."""

from __future__ import annotations

import time
import numpy as np
from .. import config
from .._linalg import single_threaded_blas
from ..exceptions import ParameterError
from ._initialize import Budget, check_automatic, nuisance_estimate
from ..optimize import as_rng, as_x0
from ._auto import (MAX_RESTARTS, MIN_REFINE_BUDGET, UNCOUNTED, _Merged, _perturbed, _refine, _result, _search, _total,
                    _unrefined, auto_minimize)

__all__ = ["auto_records", "auto_delayed", "auto_mimo"]


@single_threaded_blas()
def auto_records(cost, x0=None, *, maxfev: int | None = None, seed=None, allow_unstable: bool = False,
                 callback=None):
    """:func:`auto_minimize` for several records of one plant (a :class:`~hammerstein_ctrl.fit.RecordsCost`).

    The blocks come from ``auto`` on the longest record; each other record's
    offset and initial state from linear least squares given those blocks;
    then Levenberg-Marquardt refines everything jointly on all the records.
    ``maxfev`` bounds the three stages together, ``config.defaults["auto.records_joint_share"]``
    of it kept for the joint refinement.

    Parameters and return value as :func:`auto_minimize`; ``x0`` may be the
    block parameters, one record's beta, or the whole joint beta.
    """
    started = time.perf_counter()
    total = _total(maxfev)
    rs, longest = cost.structure, int(np.argmax([len(r) for r in cost.records]))
    joint_share = max(MIN_REFINE_BUDGET, int(config.get("auto.records_joint_share") * total))
    single = auto_delayed if rs.base.linear.delay else auto_minimize
    first = single(cost.costs[longest], _record_start(rs, x0, longest), maxfev=max(1, total - joint_share),
                   seed=seed, allow_unstable=allow_unstable, callback=callback)
    budget = Budget(total)
    budget.charge(min(int(first.nfev), total))
    if not np.all(np.isfinite(first.x)) or budget.remaining < MIN_REFINE_BUDGET:
        return first            # nothing to share: its message says why
    core = first.x[:rs.n_core]
    side = Budget(UNCOUNTED)        # each record's regression simulates that record alone: together, about one
    betas = [first.x if k == longest else _nuisance(rec, rs.base, core, side)   # evaluation of all per column
             for k, rec in enumerate(cost.records)]
    budget.charge(min(int(budget.remaining), rs.base.n_params - rs.n_core + 1))
    if budget.remaining < MIN_REFINE_BUDGET:
        return first            # no budget left to refine jointly: the longest record's fit, as its message says
    merged = _Merged()
    merged.add(first.history, 0)
    joint = _refine(cost, rs.glue(betas), budget, int(budget.remaining), merged)   # never worse than its start
    result = _result(cost, joint, budget, first.nit + 1, first.starts, merged, allow_unstable, started)
    result.message = f"{result.message}; blocks started from record {longest}'s fit, then refined on all records"
    return result


def _nuisance(record, structure, core, budget: Budget) -> np.ndarray:
    """A record's offset and initial state by least squares for the blocks ``core`` (with a dead time: on the
    record with its input delayed by the whole samples of it)."""
    from ._delay_fit import delayed_input

    lin = structure.linear
    if not lin.delay:
        return nuisance_estimate(record, structure, core, budget)
    base, i = structure.with_delay(None), structure.n_core - 1
    tau = float(core[i]) if lin.estimates_delay else float(lin.delay)
    x = nuisance_estimate(delayed_input(record, int(round(tau / record.dt))), base,
                          np.delete(core, i) if lin.estimates_delay else core, budget)
    return np.insert(x, base.n_core, tau) if lin.estimates_delay else x


def _record_start(rs, x0, record: int):
    """The user's x0 for the single-record fit of ``record``: the blocks (and that record's nuisance if given)."""
    if x0 is None:
        return None
    x = as_x0(x0)
    if x.size == rs.n_params:
        return rs.local(x, record)
    if x.size in (rs.n_core, rs.base.n_params):
        return x
    raise ParameterError(f"x0 must hold the {rs.n_core} block parameters {list(rs.core_names)}, one record's "
                         f"{rs.base.n_params}, or all {rs.n_params} {list(rs.param_names)}; got {x.size}")


@single_threaded_blas()
def auto_delayed(cost, x0=None, *, maxfev: int | None = None, seed=None, allow_unstable: bool = False,
                 callback=None):
    """:func:`auto_minimize` for a structure with a dead time (a :class:`~hammerstein_ctrl.fit.DelayedCost`).

    Whole-sample dead times ranked by ARX fits
    (:func:`~hammerstein_ctrl.fit._delay_fit.delay_candidates`; the fixed one
    rounded, when the dead time is not estimated) are each fitted without
    delay on the record shifted by that many samples; the best becomes the
    start of Levenberg-Marquardt on everything, the dead time continuous.
    ``maxfev`` bounds all stages together, ``config.defaults["auto.delay_joint_share"]`` of it
    kept for the joint refinement.  ``x0``, if given, is a whole beta of the
    delayed structure, or its block parameters and dead time alone (the
    offset and initial state then by least squares), and is refined directly.

    Parameters and return value as :func:`auto_minimize`.
    """
    from ._delay_fit import delay_candidates, shifted
    from ._objective import HammersteinCost

    started = time.perf_counter()
    total = _total(maxfev)
    budget, merged = Budget(total), _Merged()
    s, data = cost.structure, cost.data
    if x0 is not None:
        x = as_x0(x0)
        if x.size == s.n_core and s.n_params > s.n_core:     # the blocks and dead time: offset and state by LS
            x = _nuisance(data, s, x, budget)
        best = _refine(cost, s.check_beta(x), budget, total, merged)
        return _result(cost, best, budget, 1, 1, merged, allow_unstable, started)
    check_automatic(s, np.asarray(data.u, dtype=float))    # names the delayed structure's whole x0
    if s.linear.estimates_delay:
        shifts = delay_candidates(data, s.linear.den_order)
    else:
        shifts = [int(round(float(s.linear.delay) / data.dt))]
    joint_share = max(MIN_REFINE_BUDGET, int(config.get("auto.delay_joint_share") * total))
    share = max(1, int((total - joint_share) // len(shifts)))
    best_x, best_fun, best_shift, runs = None, np.inf, 0, 0
    for d in shifts:
        if budget.remaining < share + MIN_REFINE_BUDGET:
            break
        part = auto_minimize(HammersteinCost(shifted(data, d), cost.base, reject_unstable=cost.reject_unstable),
                             maxfev=share, seed=seed, allow_unstable=allow_unstable, callback=callback)
        budget.charge(min(int(part.nfev), int(budget.remaining)))   # (its history: J of the shifted record)
        runs += int(part.nit)
        if np.all(np.isfinite(part.x)):
            x = cost.from_base(part.x, d * data.dt)
            fun = cost(x)
            if fun < best_fun:
                best_x, best_fun, best_shift = x, fun, d
    if best_x is None:
        raise ParameterError("no start for the dead-time fit: the fits of the shifted records failed; "
                             "give x0 (the whole beta, with the delay) or a larger maxfev")
    best = _refine(cost, best_x, budget, max(int(budget.remaining), 1), merged)
    result = _result(cost, best, budget, runs + 1, len(shifts), merged, allow_unstable, started)
    result.message = (f"{result.message}; dead time started from {best_shift} sample(s) "
                      f"(of {len(shifts)} whole-sample candidates), then refined continuously")
    top = min(config.get("delay.max_samples"), len(data) // 4)
    if s.linear.estimates_delay and shifts[0] >= top:
        result.message += (f"; the best whole-sample dead time lies at the end of the scan ({top} samples): a longer "
                           "one is possible (raise hc.config.defaults['delay.max_samples'])")
    return result


@single_threaded_blas()
def auto_mimo(cost, x0=None, *, maxfev: int | None = None, seed=None, allow_unstable: bool = False,
              callback=None):
    """:func:`auto_minimize` for a MIMO structure (a :class:`~hammerstein_ctrl.fit.MIMOCost`).

    The start comes from the data (:func:`~hammerstein_ctrl.fit._mimo_fit.mimo_starts`),
    with the user's ``x0`` (a whole beta, stabilised) as one more; each is
    refined by Levenberg-Marquardt on all outputs together, then seeded
    restarts around the best while it is unacceptable (unstable or no better
    than constants).  Parameters and return value as :func:`auto_minimize`.
    """
    from ._mimo_fit import completed, mimo_starts, noise_weights, spread_weighted, stabilized

    started = time.perf_counter()
    s = cost.structure
    if s.has_delay and x0 is None:
        return _auto_mimo_delayed(cost, maxfev=maxfev, seed=seed, allow_unstable=allow_unstable, callback=callback,
                                  started=started)
    budget, merged, rng = Budget(_total(maxfev)), _Merged(), as_rng(seed)
    try:
        starts = [stabilized(s, x) for x in mimo_starts(cost.data, s)]
    except ParameterError:
        if x0 is None:
            raise
        starts = []
    budget.charge(min(len(s.param_names), int(budget.remaining)))    # the starts' regressions, as one batch
    if x0 is not None:
        starts.append(stabilized(s, completed(cost, as_x0(x0))))
    restarts = []

    def next_restart(anchor):           # perturbations of the current best, at most MAX_RESTARTS
        if len(restarts) >= MAX_RESTARTS:
            return None
        restarts.append(stabilized(s, _perturbed(anchor, rng)))
        return restarts[-1]

    search = spread_weighted(cost)          # outputs in units far apart (mm beside m) searched scale-free
    best, runs = _search(search, starts, next_restart, budget, merged, allow_unstable, callback)
    if best is None:
        return _unrefined(cost, starts, len(starts), budget, merged, started)
    if search is not cost:          # the spread weights only guided the search: the estimate is the unweighted or
        if noise_weights(cost, best.x) is None and budget.remaining >= MIN_REFINE_BUDGET:
            best = _refine(cost, best.x, budget, int(budget.remaining), merged)
            runs += 1
        else:
            best.fun = float(cost(best.x))          # the noise-weighted one (_weighted_result)
    return _weighted_result(cost, best, budget, runs, len(starts), merged, allow_unstable, started)


def _weighted_result(cost, best, budget, runs, n_starts, merged, allow_unstable, started):
    """:func:`_result` of a MIMO fit, refined once more with each output weighted by the inverse of its noise
    level when the levels differ (:func:`~hammerstein_ctrl.fit._mimo_fit.noise_weights`); ``output_weights`` says which
    weights the estimate minimises (``None``: equal)."""
    from ._mimo_fit import noise_weights

    weights = noise_weights(cost, best.x) if np.all(np.isfinite(best.x)) and cost.weights is None else None
    if weights is not None and budget.remaining >= MIN_REFINE_BUDGET:
        weighted = cost.weighted(weights)
        again = _refine(weighted, best.x, budget, int(budget.remaining), merged)
        runs += 1
        if np.isfinite(again.fun):
            out = _result(weighted, again, budget, runs, n_starts, merged, allow_unstable, started)
            out.fun = float(cost(out.x))                       # the figures stay the unweighted sums of squares
            out.output_weights = weights
            out.message += "; outputs weighted by the inverse of their noise levels"
            return out
    out = _result(cost, best, budget, runs, n_starts, merged, allow_unstable, started)
    out.output_weights = cost.weights
    return out


def _auto_mimo_delayed(cost, *, maxfev, seed, allow_unstable, callback, started):
    """:func:`auto_mimo` with dead times: the structure without them fitted on the record with its inputs shifted
    by the whole samples :func:`~hammerstein_ctrl.fit._mimo_fit.delay_shifts` finds (the same model with those dead
    times), then everything refined with the dead times continuous."""
    from ._mimo_fit import MIMOCost, delay_shifts, shifted_inputs, with_delays

    s, data, total = cost.structure, cost.data, _total(maxfev)
    shifts = delay_shifts(data, s)
    joint_share = max(MIN_REFINE_BUDGET, int(config.get("auto.delay_joint_share") * total))
    part = auto_mimo(MIMOCost(shifted_inputs(data, shifts), s.without_delays(), reject_unstable=cost.reject_unstable),
                     maxfev=max(1, total - joint_share), seed=seed, allow_unstable=allow_unstable, callback=callback)
    budget, merged = Budget(total), _Merged()
    budget.charge(min(int(part.nfev), total))
    merged.add(part.history, 0)
    if not np.all(np.isfinite(part.x)) or budget.remaining < MIN_REFINE_BUDGET:
        return part
    weights = getattr(part, "output_weights", None)
    joint = cost if weights is None else cost.weighted(weights)
    best = _refine(joint, with_delays(s, part.x, shifts, data.dt), budget, int(budget.remaining), merged)
    result = _result(joint, best, budget, int(part.nit) + 1, int(part.starts), merged, allow_unstable, started)
    result.fun, result.output_weights = float(cost(result.x)), weights
    result.message += (f"; dead times started from {list(shifts)} sample(s), found by ARX fits input by input, then "
                       "refined continuously")
    return result
