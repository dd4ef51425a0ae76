"""Machinery shared by the optimisers: counted evaluation, bounds, results."""

from __future__ import annotations

import time

import numpy as np

from .._checks import as_count, as_real_array
from ..exceptions import ParameterError

# Result status codes (``OptimizeResult.status``).
COMPLETED = 0  #: ran its full iteration/evaluation budget
CALLBACK_STOP = 1  #: the callback asked to stop
DIVERGED = 2  #: the iterates or objective blew up (SPSA's expected failure mode)
NO_FINITE_VALUE = 3  #: every evaluation was non-finite
SOLVER_FAILED = 4  #: a delegated scipy solver reported failure
BUDGET_EXHAUSTED = 5  #: a converging method (LM, scipy's) ran out of evaluations before its convergence test
#: Every status code, in order.
STATUS_CODES = (COMPLETED, CALLBACK_STOP, DIVERGED, NO_FINITE_VALUE, SOLVER_FAILED, BUDGET_EXHAUSTED)


class OptimizeResult(dict):
    """What every optimiser returns: a dict whose keys are also attributes, the interface of
    :class:`scipy.optimize.OptimizeResult` (``x``, ``fun``, ``nfev``, ``nit``, ``success``, ``status``,
    ``message``, ``history`` and each optimiser's own entries).

    The package's own class, so that a fit never imports :mod:`scipy.optimize` (a third of a first fit's time)
    unless one of scipy's methods is asked for.

    Examples
    --------
    >>> r = OptimizeResult(x=[1.0], fun=0.5, success=True)
    >>> r.fun, r["success"], sorted(r)
    (0.5, True, ['fun', 'success', 'x'])
    >>> print(r)
          x: [1.0]
        fun: 0.5
    success: True
    """

    __slots__ = ()

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None

    __setattr__ = dict.__setitem__
    __delattr__ = dict.__delitem__

    def __dir__(self):
        return list(self)

    def __repr__(self):
        if not self:
            return f"{type(self).__name__}()"
        width = max(map(len, self))
        return "\n".join(f"{key.rjust(width)}: {value!r}" for key, value in self.items())


def budget_exhausted_message(maxfev) -> str:
    """The message of a :data:`BUDGET_EXHAUSTED` result."""
    return f"evaluation budget of {maxfev} exhausted before convergence"


#: Arithmetic errors raised by an objective that are scored as ``inf`` instead
#: of aborting the search (e.g. Python-float overflow in ``x ** 3``).
_SCORED_AS_INF = (OverflowError, ZeroDivisionError, FloatingPointError)


class BudgetExhausted(RuntimeError):
    """Raised by :class:`CountedObjective` instead of exceeding ``maxfev``.

    ``nit`` is set by a solver that counts its iterations on the way out
    (``None`` otherwise).
    """

    nit: int | None = None


class ResidualsFault(RuntimeError):
    """A residual function returned something no least-squares solver can use (a failure status, not a crash)."""


def residual_array(r, size: int | None, *, batch: int | None = None) -> np.ndarray:
    """``r`` as a float vector (or, with ``batch``, ``batch`` rows) of ``size`` residuals (any size if None).

    Raises
    ------
    ResidualsFault
        For text or objects, the wrong number of dimensions, no residuals, or
        a length different from the one seen before (``size``).
    """
    try:
        with np.errstate(all="ignore"):
            a = np.asarray(r, dtype=float)
    except (TypeError, ValueError):
        raise ResidualsFault("the residual function must return an array of numbers of the same length at every "
                             f"point; got {type(r).__name__} {str(r)[:60]}") from None
    want = 1 if batch is None else 2
    if a.ndim != want or a.shape[-1] == 0 or (batch is not None and a.shape[0] != batch):
        raise ResidualsFault(f"the residual function must return a non-empty 1-D array (one residual per sample), "
                             f"got shape {np.shape(a) if batch is None else np.shape(a)[1:]}")
    if size is not None and a.shape[-1] != size:
        raise ResidualsFault(f"the residual vector changed length between evaluations, from {size} to "
                             f"{a.shape[-1]}; a residual function must return the same number of residuals at "
                             "every point")
    return a


class Budget:
    """An evaluation budget: ``maxfev`` candidates at most (``None``: no limit), ``nfev`` spent so far.

    The one budget of the package: every optimiser counts its objective with
    it (:class:`CountedObjective`), and the stages of an automatic fit share one.

    Examples
    --------
    >>> b = Budget(3); b.charge(2); b.remaining
    1
    >>> b.charge(2)
    Traceback (most recent call last):
    ...
    hammerstein_ctrl.optimize._common.BudgetExhausted: evaluation budget exhausted (2 + 2 > 3)
    """

    def __init__(self, maxfev: int | None = None):
        self.maxfev = maxfev
        self.nfev = 0

    @property
    def remaining(self) -> float:
        """Evaluations left (``inf`` without a limit)."""
        return np.inf if self.maxfev is None else self.maxfev - self.nfev

    def charge(self, count: int = 1):
        """Count ``count`` evaluations, or raise :class:`BudgetExhausted` (counting none) if they do not fit."""
        if self.maxfev is not None and self.nfev + count > self.maxfev:
            raise BudgetExhausted(f"evaluation budget exhausted ({self.nfev} + {count} > {self.maxfev})")
        self.nfev += int(count)

    _charge = charge


class CountedObjective(Budget):
    """Wrap ``fun`` to count evaluations, track the best point, and tame values.

    * Every call counts; a batch of ``B`` points counts ``B``.  An evaluation
      that would exceed ``maxfev`` raises :class:`BudgetExhausted` instead.
    * Arithmetic errors (overflow, division by zero) score ``inf``.
    * If ``fun`` has a ``batch`` method (like
      :class:`~hammerstein_ctrl.fit.HammersteinCost`) batches use it.
    """

    def __init__(self, fun, args=(), maxfev: int | None = None):
        if not callable(fun):
            raise ParameterError(f"fun must be callable, got {type(fun).__name__}")
        self.fun = fun
        self.args = tuple(args)
        self._batch = getattr(fun, "batch", None) if not self.args else None
        super().__init__(maxfev)
        self.best_x: np.ndarray | None = None
        self.best_fun = np.inf
        self.nfev_monitor = 0

    def _scalar(self, x) -> float:
        try:
            val = self.fun(x, *self.args)
        except _SCORED_AS_INF:
            return np.inf
        try:
            val = float(np.asarray(val, dtype=float).reshape(()))
        except (TypeError, ValueError):
            raise ParameterError(
                f"the objective must return a scalar, got {type(val).__name__} {np.shape(val)}"
            ) from None
        return val

    def _track(self, X, F):
        with np.errstate(invalid="ignore"):
            i = int(np.argmin(np.where(np.isnan(F), np.inf, F)))
        if F[i] < self.best_fun:
            self.best_fun = float(F[i])
            self.best_x = np.array(X[i], dtype=float)

    def __call__(self, x) -> float:
        self._charge(1)
        f = self._scalar(x)
        self._track([x], np.array([f]))
        return f

    def peek(self, x) -> float:
        """Evaluate for monitoring only: not counted in ``nfev``, not tracked as best.

        Counted separately in ``nfev_monitor``; the search never sees the value.
        """
        self.nfev_monitor += 1
        return self._scalar(x)

    def many(self, X) -> np.ndarray:
        """Evaluate each row of ``X``."""
        X = np.asarray(X, dtype=float)
        self._charge(X.shape[0])
        if self._batch is not None:
            F = np.asarray(self._batch(X), dtype=float).reshape(X.shape[0])
        else:
            F = np.array([self._scalar(x) for x in X])
        self._track(X, F)
        return F


def check_budget(maxfev, maxiter=None) -> tuple[int | None, int | None]:
    """Validate an evaluation budget and an iteration limit; return them as ints (or None).

    ``maxfev`` must be a positive integer and ``maxiter`` a non-negative one;
    NaN, infinities, fractions and booleans are rejected rather than ignored.

    Examples
    --------
    >>> check_budget(100, None)
    (100, None)
    >>> check_budget(float("nan"))
    Traceback (most recent call last):
    ...
    hammerstein_ctrl.exceptions.ParameterError: maxfev must be a positive integer, got nan
    """
    return _as_count(maxfev, "maxfev", 1), _as_count(maxiter, "maxiter", 0)


def _as_count(value, name: str, least: int) -> int | None:
    return None if value is None else as_count(value, name, minimum=least)


def as_rng(seed) -> np.random.Generator:
    """A :class:`numpy.random.Generator` from a seed, a Generator, or None."""
    if isinstance(seed, np.random.Generator):
        return seed
    if isinstance(seed, (bool, np.bool_)):
        raise ParameterError(f"seed must be None, a non-negative integer or a numpy.random.Generator, got {seed!r}")
    if isinstance(seed, np.random.RandomState):
        raise ParameterError("pass an int seed or a numpy.random.Generator, not a RandomState")
    try:
        return np.random.default_rng(seed)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"seed must be None, a non-negative integer (or a sequence of them) or a "
                             f"numpy.random.Generator, got {seed!r} ({exc})") from None


def as_x0(x0) -> np.ndarray:
    """A starting point as a new, flat float array: real, finite and not empty, else a :class:`ParameterError`.

    Examples
    --------
    >>> as_x0([[1, 2], [3, 4]]).tolist()
    [1.0, 2.0, 3.0, 4.0]
    """
    x = np.array(as_real_array(x0, "x0")).reshape(-1)
    if x.size == 0:
        raise ParameterError("x0 is empty")
    if not np.all(np.isfinite(x)):
        raise ParameterError(f"x0 must be finite, got {x.tolist()}")
    return x


def as_bounds(bounds, n: int):
    """Return ``(lower, upper)`` arrays of length ``n`` or ``None``.

    Accepts :class:`scipy.optimize.Bounds` or a sequence of ``(low, high)``
    pairs (``None`` for an open side), like :func:`scipy.optimize.minimize`.
    """
    if bounds is None:
        return None
    from scipy.optimize import Bounds    # scipy.optimize's import is a third of a first fit's: made when needed

    if isinstance(bounds, Bounds):
        lo = np.broadcast_to(np.asarray(bounds.lb, dtype=float), (n,)).copy()
        hi = np.broadcast_to(np.asarray(bounds.ub, dtype=float), (n,)).copy()
    else:
        pairs = list(bounds)
        if len(pairs) != n:
            raise ParameterError(f"bounds has {len(pairs)} pairs but x0 has {n} entries")
        try:
            lo = np.array([-np.inf if p[0] is None else p[0] for p in pairs], dtype=float)
            hi = np.array([np.inf if p[1] is None else p[1] for p in pairs], dtype=float)
        except (TypeError, IndexError, ValueError):
            raise ParameterError("bounds must be a sequence of (low, high) pairs or a scipy Bounds") from None
    if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo > hi):
        raise ParameterError(f"invalid bounds: lower {lo.tolist()} upper {hi.tolist()}")
    return lo, hi


class History:
    """Per-iteration record.

    Columns: ``nit``, ``nfev`` (evaluations so far), ``fun`` (the iteration's
    value: the better of f+ and f- for the SPSA family, the best universe of
    the iteration for AMVO-SCA), ``best`` (best value evaluated so far) and
    ``estimate`` (the objective at the method's current estimate: theta(k) for
    the SPSA family where monitored, NaN elsewhere; the best point for the
    other methods).
    """

    #: Columns per row.
    WIDTH = 5

    def __init__(self):
        self._values: list = []         # the rows' values one after another (a flat list converts fastest)

    def append(self, nit: int, nfev: int, fun: float, best: float, estimate: float = np.nan):
        self._values.extend((nit, nfev, float(fun), float(best), float(estimate)))

    def extend(self, values):
        """Append whole rows given as their values one after another: ``nit, nfev, fun, best, estimate, nit, ...``."""
        if len(values) % self.WIDTH:
            raise ValueError(f"history rows have {self.WIDTH} values, got {len(values)} in all")
        self._values.extend(values)

    def set_last_estimate(self, estimate: float):
        """Record the objective at the final estimate on the last row."""
        if self._values:
            self._values[-1] = float(estimate)

    def as_dict(self) -> dict:
        a = np.array(self._values, dtype=float).reshape(-1, self.WIDTH)
        return {"nit": a[:, 0].astype(int), "nfev": a[:, 1].astype(int), "fun": a[:, 2], "best": a[:, 3],
                "estimate": a[:, 4]}


def call_back(callback, x, fun, nit, nfev) -> bool:
    """Call a user callback with an :class:`OptimizeResult`; True means stop."""
    if callback is None:
        return False
    try:
        return bool(callback(OptimizeResult(x=np.array(x, copy=True), fun=fun, nit=nit, nfev=nfev)))
    except StopIteration:
        return True


def make_result(*, x, fun, obj: CountedObjective, nit, status, message, history: History,
                method: str, started: float, keep_last: bool = False, **extra) -> OptimizeResult:
    """Assemble the :class:`OptimizeResult` every optimiser returns.

    The contract of every optimiser: the point returned is never worse than
    the best one it evaluated (``obj.best_x``, which replaces ``x`` when
    better, or when ``fun`` is NaN), unless ``keep_last`` asks for the given
    point (the paper's last-iterate estimate).
    """
    if not keep_last and obj.best_x is not None and (obj.best_fun < fun or (np.isnan(fun) and
                                                                            np.isfinite(obj.best_fun))):
        x, fun = obj.best_x, obj.best_fun
    if status in (COMPLETED, DIVERGED) and obj.nfev and not np.isfinite(obj.best_fun):
        status, message = NO_FINITE_VALUE, f"every evaluation was non-finite ({message})"
    res = OptimizeResult(
        x=np.asarray(x, dtype=float),
        fun=float(fun),
        nfev=obj.nfev,
        nit=int(nit),
        success=bool(status in (COMPLETED, CALLBACK_STOP) and np.isfinite(fun)),
        status=int(status),
        message=message,
        history=history.as_dict(),
        best_x=None if obj.best_x is None else obj.best_x.copy(),
        best_fun=float(obj.best_fun),
        nfev_monitor=int(getattr(obj, "nfev_monitor", 0)),
        method=method,
        elapsed=time.perf_counter() - started,
    )
    res.update(extra)
    return res


def check_options(method: str, options: dict, allowed: set):
    unknown = set(options) - allowed
    if unknown:
        raise ParameterError(
            f"unknown option(s) {sorted(unknown)} for method {method!r}; valid: {sorted(allowed)}"
        )
