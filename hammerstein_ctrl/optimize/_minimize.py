"""One entry point for every optimiser, in the style of :func:`scipy.optimize.minimize`.

Examples
--------
>>> import numpy as np
>>> from hammerstein_ctrl.optimize import minimize, StepGain, PerturbationGain
>>> f = lambda x: float(np.sum((x - 1.0) ** 2))
>>> r = minimize(f, np.zeros(2), method="nspsa", maxfev=1001, seed=0,
...              options={"a": StepGain(0.5, 10), "c": PerturbationGain(0.1)})
>>> r.nfev, r.success        # the start, 499 iterations of two evaluations, the last iterate
(1000, True)
"""

from __future__ import annotations

import time

import numpy as np

from .._linalg import single_threaded_blas
from ..exceptions import ParameterError, UnknownNameError
from ._common import (BUDGET_EXHAUSTED, COMPLETED, SOLVER_FAILED, BudgetExhausted, CountedObjective, History,
                      OptimizeResult, as_x0, budget_exhausted_message, check_budget, check_options, make_result,)
from ._amvo_sca import amvo_sca
from ._least_squares import levenberg_marquardt
from ._spsa import nlspsa, nspsa, spsa

__all__ = ["minimize", "canonical_method", "METHODS", "SCIPY_METHODS"]

#: The paper's methods and the least-squares rival, by canonical name.
METHODS = {"spsa": spsa, "nlspsa": nlspsa, "nspsa": nspsa, "amvo-sca": amvo_sca,
           "lm": levenberg_marquardt}

#: Local methods of :func:`scipy.optimize.minimize` that can be used through
#: :func:`minimize` with the same counting and budget rules.
SCIPY_METHODS = ("nelder-mead", "powell", "l-bfgs-b", "bfgs", "tnc", "slsqp", "cobyla", "trust-constr")

#: scipy methods handed ``maxfev`` (they stop on it themselves), and the status they then report.
_OWN_MAXFEV = ("nelder-mead", "powell")
_SCIPY_MAXFEV_STATUS = 1

_ALIASES = {
    "nl-spsa": "nlspsa", "n-spsa": "nspsa", "amvosca": "amvo-sca", "amvo_sca": "amvo-sca",
    "mvo-sca": "amvo-sca", "neldermead": "nelder-mead", "nelder_mead": "nelder-mead",
    "levenberg-marquardt": "lm", "least-squares": "lm", "least_squares": "lm",
}

_OPTIONS = {
    "spsa": {"a", "c", "scale", "divergence_factor", "monitor", "estimate"},
    "nlspsa": {"a", "c", "scale", "norm_limit", "divergence_factor", "monitor", "estimate"},
    "nspsa": {"a", "c", "scale", "divergence_factor", "monitor", "estimate"},
    "amvo-sca": {"pop_size", "wep_min", "wep_max", "include_x0"},
    "lm": {"ftol", "xtol", "gtol"},
}


def canonical_method(method: str) -> str:
    """Canonical lower-case name of a method (``"N-SPSA"`` -> ``"nspsa"``).

    Raises
    ------
    UnknownNameError
        Listing the known methods.
    """
    key = str(method).strip().lower()
    key = _ALIASES.get(key, key)
    if key not in METHODS and key not in SCIPY_METHODS:
        raise UnknownNameError(
            f"unknown method {method!r}; known: {', '.join(METHODS)} "
            f"(and scipy's {', '.join(SCIPY_METHODS)})"
        )
    return key


def minimize(fun, x0, method: str | None = None, *, args=(), maxfev: int | None = None,
             maxiter: int | None = None, seed=None, options: dict | None = None,
             callback=None, bounds=None):
    """Minimise ``fun`` from ``x0`` with one of the paper's methods (or scipy's).

    Parameters
    ----------
    fun : callable
        ``fun(x, *args) -> float``.  Objects with a ``batch(X)`` method (such
        as :class:`~hammerstein_ctrl.fit.HammersteinCost`) are evaluated a
        population at a time by AMVO-SCA and a pair at a time by the SPSA family.
    x0 : array_like
        Initial point.
    method : str, optional
        Default: ``"lm"`` for a least-squares objective (one with a
        ``residuals`` method), else scipy's choice (``"bfgs"``, or
        ``"l-bfgs-b"`` with bounds).  ``"spsa"``, ``"nlspsa"``, ``"nspsa"``, ``"amvo-sca"``, ``"lm"``
        (Levenberg-Marquardt on the residuals; needs an objective with a
        ``residuals`` method such as :class:`~hammerstein_ctrl.fit.HammersteinCost`),
        or one of :data:`SCIPY_METHODS` (delegated to :func:`scipy.optimize.minimize`).
    args : tuple
        Extra arguments for ``fun``.
    maxfev : int, optional
        Evaluation budget; never exceeded.
    maxiter : int, optional
        Iteration limit (``k_max`` for the SPSA family).
    seed : int or numpy.random.Generator, optional
        Every random choice comes from it; the same seed gives the same result
        bit for bit.
    options : dict or "auto", optional
        Method options: ``a``, ``c`` (gain sequences, or ``"auto"``: calibrated
        from the problem by Spall's guidelines, also the default when neither is
        given), ``scale`` (per-parameter scales, or ``"auto"``), ``norm_limit``
        (NL-SPSA's delta), ``divergence_factor`` and ``monitor`` for the SPSA family;
        ``pop_size``, ``wep_min``, ``wep_max``, ``include_x0`` for AMVO-SCA;
        scipy's own options for scipy methods.
    callback : callable, optional
        Called after each iteration with an ``OptimizeResult(x, fun, nit, nfev)``;
        returning True or raising StopIteration stops the run.
    bounds : scipy.optimize.Bounds or sequence of (low, high), optional
        Box constraints (required by AMVO-SCA).

    Returns
    -------
    hammerstein_ctrl.optimize.OptimizeResult
        With ``x, fun, nfev, nit, success, status, message``, ``history`` (a dict
        of per-iteration arrays ``nit, nfev, fun, best``), ``best_x``,
        ``best_fun``, ``method`` and ``elapsed`` (seconds).

    Raises
    ------
    UnknownNameError
        For an unknown method.
    ParameterError
        For unknown options or invalid settings.

    Notes
    -----
    BLAS and OpenMP thread pools are held to one thread while it runs: the
    objectives here do small dense linear algebra, for which threads only spin
    against other work (entering the limit costs a few microseconds per call
    of ``minimize``, not per evaluation).

    Examples
    --------
    >>> import numpy as np
    >>> r = minimize(lambda x: float(np.sum((x - 3.0) ** 2)), [0.0, 0.0], method="nelder-mead", maxfev=400)
    >>> r.success, np.round(r.x, 3).tolist()
    (True, [3.0, 3.0])
    """
    if method is None:
        method = "lm" if callable(getattr(fun, "residuals", None)) else ("l-bfgs-b" if bounds is not None else "bfgs")
    key = canonical_method(method)
    maxfev, maxiter = check_budget(maxfev, maxiter)
    if isinstance(options, str):
        if options != "auto" or key not in ("spsa", "nlspsa", "nspsa"):
            raise ParameterError(f"options={options!r}: only 'auto' (gains calibrated from the problem) "
                                 "is understood, and only by the SPSA family")
        options = {"a": "auto", "c": "auto", "scale": "auto"}
    options = dict(options or {})
    if key in METHODS:
        check_options(key, options, _OPTIONS[key])
    # the objectives here do tiny dense linear algebra: BLAS threads only spin against other work
    with single_threaded_blas():
        if key in METHODS:
            return METHODS[key](fun, x0, args=args, maxfev=maxfev, maxiter=maxiter, seed=seed,
                                bounds=bounds, callback=callback, **options)
        return _scipy_minimize(key, fun, x0, args=args, maxfev=maxfev, maxiter=maxiter,
                               options=options, callback=callback, bounds=bounds)


def _scipy_minimize(method, fun, x0, *, args, maxfev, maxiter, options, callback, bounds):
    import scipy.optimize        # a third of a first fit's time: imported where scipy's methods are asked for

    started = time.perf_counter()
    x0 = as_x0(x0)
    obj = CountedObjective(fun, args, maxfev=maxfev)
    history = History()
    nit = 0

    def wrapped(x):
        with np.errstate(all="ignore"):
            return obj(x)

    def step(intermediate_result):
        nonlocal nit
        nit += 1
        if not isinstance(intermediate_result, scipy.optimize.OptimizeResult):
            # tnc (and scipy's legacy callbacks) pass only the current point
            intermediate_result = OptimizeResult(x=np.array(intermediate_result, dtype=float), fun=obj.best_fun)
        history.append(nit, obj.nfev, float(intermediate_result.fun), obj.best_fun, obj.best_fun)
        if callback is not None and callback(intermediate_result):
            raise StopIteration

    opts = dict(options)
    if maxfev is not None and method in _OWN_MAXFEV:
        opts.setdefault("maxfev", maxfev)
    if maxiter is not None:
        opts.setdefault("maxiter", maxiter)
    try:
        with np.errstate(all="ignore"):     # scipy's finite differences of an objective scored inf: inf - inf
            res = scipy.optimize.minimize(wrapped, x0, method=method, bounds=bounds, options=opts,
                                          callback=step)
        x, fun_x, message = res.x, float(res.fun), str(res.message)
        status = COMPLETED if res.success else SOLVER_FAILED
        if _stopped_by_budget(method, res, obj):     # scipy's own stop on our maxfev
            status, message = BUDGET_EXHAUSTED, budget_exhausted_message(maxfev)
    except BudgetExhausted:
        x, fun_x = obj.best_x, obj.best_fun
        status, message = BUDGET_EXHAUSTED, budget_exhausted_message(maxfev)
    if x is None:  # budget exhausted before any evaluation
        x, fun_x = x0, np.nan
    return make_result(x=x, fun=fun_x, obj=obj, nit=nit, status=status, message=message,
                       history=history, method=method, started=started)


def _stopped_by_budget(method, res, obj: CountedObjective) -> bool:
    """Whether a method of :data:`_OWN_MAXFEV` stopped on its maxfev with the whole budget spent."""
    return (method in _OWN_MAXFEV and not res.success and res.status == _SCIPY_MAXFEV_STATUS
            and obj.maxfev is not None and obj.nfev >= obj.maxfev)
