"""Levenberg-Marquardt on the output error: the honest rival from outside the paper.

J(beta) is a sum of squared residuals, so a Gauss-Newton-type method that
works on the residual vector (not just on J) uses far more information per
evaluation than the SPSA family.  From the paper's EMPS initial point it reaches
the least-squares optimum J = 0.208517 in a few hundred evaluations, below every
value in the paper's Table 7.

Without bounds this runs :func:`~hammerstein_ctrl.optimize._normal_lm.normal_equations_lm`:
Levenberg-Marquardt on the normal equations ``J.T J``, ``J.T r`` of the
forward-difference Jacobian (scipy's ``"2-point"`` steps), which
:meth:`HammersteinCost.normal_equations
<hammerstein_ctrl.fit.HammersteinCost.normal_equations>` forms in one
compiled pass together with the trial point, with MINPACK's termination tests
and messages; where the normal equations are too ill-conditioned it goes on
from that point with MINPACK's QR-based ``lmder`` (:func:`~hammerstein_ctrl.optimize.lmder`,
the package's copy) or, on long records, on a streamed QR factor.  With
bounds it runs scipy's trust-region reflective method
(:func:`scipy.optimize.least_squares`, ``method="trf"``) with the batched
Jacobian.  Evaluation counting is exact: every residual vector computed,
including the Jacobian's, is one evaluation, and ``maxfev`` is never
exceeded.  It is deterministic (``seed`` is accepted and ignored).
"""

from __future__ import annotations

import contextlib
import time

import numpy as np

from .._linalg import single_threaded_blas
from ..exceptions import ParameterError
from ._normal_equations import NONFINITE_RESIDUAL, forward_steps
from ._common import (BUDGET_EXHAUSTED, COMPLETED, NO_FINITE_VALUE, SOLVER_FAILED, ResidualsFault, BudgetExhausted,
                      CountedObjective, History, as_bounds, as_x0, budget_exhausted_message, check_budget, make_result,
                      residual_array,)
from ._minpack import lmder
from ._normal_lm import CONVERGED, ILL_CONDITIONED_CODE, MESSAGES, normal_equations_lm

__all__ = ["levenberg_marquardt", "MINPACK_MAX_BYTES"]

#: Largest N x p Jacobian (bytes) handed to MINPACK's QR-based lmder where the normal equations are too
#: ill-conditioned.  Past it, an objective with ``normal_factor`` (a HammersteinCost) keeps to the
#: normal-equation solver on a streamed QR factor of the Jacobian instead, in memory bounded per sample;
#: below it, MINPACK's iterates and messages are kept.
MINPACK_MAX_BYTES = 1 << 24

#: The messages scipy's least_squares gives for MINPACK's exit codes.
_MINPACK_MESSAGES = {
    0: "Improper input parameters status returned from MINPACK",
    1: "`ftol` termination condition is satisfied.",
    2: "`xtol` termination condition is satisfied.",
    3: "Both `ftol` and `xtol` termination conditions are satisfied.",
    4: "`gtol` termination condition is satisfied.",
    5: "The maximum number of function evaluations is exceeded.",
}
#: MINPACK's own cap on residual evaluations per parameter (scipy's default for method "lm").
_MINPACK_MAXFEV_PER_PARAM = 100
#: Steps of the normal-equation solver per parameter before it gives up (MINPACK's cap, in steps).
_MAX_STEPS_PER_PARAM = 100


class _CountedResiduals(CountedObjective):
    """:class:`CountedObjective` for a residual vector: counts, budgets and tracks J = r @ r.

    Remembers the last residual vector: asked again for the same point (as
    MINPACK and the Jacobian are), it returns it without a new evaluation,
    as scipy's least_squares does.
    """

    def __init__(self, residuals, maxfev):
        super().__init__(residuals, (), maxfev)
        self.history = History()
        self._last = (None, None)
        self.calls = 0          # charged residual vectors the solver asked for (its trial points), not Jacobian columns
        self.size = None        # the number of residuals, fixed by the first evaluation

    def check(self, r, batch: int | None = None) -> np.ndarray:
        """``r`` as residuals of the one length every evaluation must have (:func:`residual_array`)."""
        a = residual_array(r, self.size, batch=batch)
        self.size = a.shape[-1]
        return a

    def record(self, x, r):
        """Book one charged evaluation of the residual vector ``r``."""
        with np.errstate(over="ignore"):        # huge residuals (1e150 stand-ins) sum to inf, without a warning
            self.record_value(x, float(r @ r))

    def record_value(self, x, f: float):
        """Book one charged evaluation with sum of squares ``f``: best point (NaN never wins) and history row."""
        if f < self.best_fun:
            self.best_fun, self.best_x = f, np.array(x, dtype=float)
        self.history.append(self.nfev, self.nfev, f, self.best_fun, self.best_fun)

    def record_neighbourhood(self, x, steps, values):
        """Book charged evaluations of ``x`` and its neighbours ``x + steps[j] e_j`` with sums of squares ``values``.

        As :meth:`record_value` point by point (``values[0]`` is ``x``'s); the
        best neighbour's row is formed only if it becomes the best point.
        """
        self._book_passes(np.asarray(x)[None], np.asarray(steps)[None], [list(values)])

    def record_passes(self, xs, steps, values):
        """Book whole passes in their order: :meth:`record_neighbourhood` of the rows of ``xs``, ``steps``, ``values``,
        each charged first."""
        self._charge(values.size)
        self._book_passes(xs, steps, values.tolist())

    def _book_passes(self, xs, steps, values: list):
        """History rows and best point of charged passes (``values[i]``: point ``xs[i]``, then its neighbours).

        The best point's row is formed once, at the end, bit for bit the row of ``neighbours(xs[i], steps[i])``.
        """
        nfev = self.nfev - sum(len(row) for row in values)
        best, where, rows = self.best_fun, None, []
        for i, row in enumerate(values):
            nfev += len(row)
            for j, f in enumerate(row):
                if f < best:
                    best, where = f, (i, j)
                rows += (nfev, nfev, f, best, best)
        self.history.extend(rows)
        if where is not None:
            i, j = where
            self.best_fun, self.best_x = best, np.array(xs[i], dtype=float)
            if j > 0:
                self.best_x[j - 1] += steps[i][j - 1]

    def __call__(self, x):
        last_x, last_r = self._last
        if last_x is not None and np.array_equal(last_x, x):
            return last_r
        self._charge(1)
        self.calls += 1
        with np.errstate(all="ignore"):
            r = self.check(self.fun(x))
        self.record(x, r)
        if not np.isfinite(r).all():        # as the Jacobian's passes do: solvers back off from a stand-in
            r = np.where(np.isfinite(r), r, NONFINITE_RESIDUAL)
        self._last = (np.array(x, dtype=float), r)
        return r

    charge = CountedObjective._charge


class _BatchedJacobian:
    """Forward-difference Jacobian of the residuals, all columns in one batched call.

    The same steps as scipy's ``"2-point"`` scheme (``h = sqrt(eps) max(1, |x|)``,
    sign of ``x``, flipped to stay inside ``bounds``), and every column counts
    as one evaluation against the budget, as with scipy's own differences.  If
    fewer evaluations than columns remain, the columns that fit are evaluated
    (and count, and can become the best point) before the budget stops the run.
    Without ``residuals_batch`` the columns are evaluated one by one.
    """

    def __init__(self, counted: _CountedResiduals, residuals_batch, box):
        self.counted = counted
        self.residuals_batch = residuals_batch or (lambda X: [counted.check(counted.fun(x)) for x in X])
        self.lower, self.upper = (None, None) if box is None else box

    def steps(self, x):
        return forward_steps(x, self.upper, self.lower)

    def columns(self, x):
        """The Jacobian's columns as the rows of an ``(n, N)`` array (the residual at ``x`` from the
        counted objective's last value where it is the same point)."""
        x = np.asarray(x, dtype=float)
        r0 = self.counted(x)
        h = self.steps(x)
        X = x + np.diag(h)
        fit = int(min(x.size, self.counted.remaining))
        with np.errstate(all="ignore"):
            R = self.counted.check(self.residuals_batch(X[:fit]), batch=fit)
        for xk, rk in zip(X[:fit], R):  # one by one, as scipy's differences would have
            self.counted.charge(1)
            self.counted.record(xk, rk)
        if fit < x.size:
            self.counted.charge(x.size - fit)  # raises BudgetExhausted
        with np.errstate(all="ignore"):
            R[~np.isfinite(R)] = NONFINITE_RESIDUAL
            R -= r0
            R /= h[:, None]
        return R

    def __call__(self, x):
        return self.columns(x).T


def _solve(fun, counted, jac, x0, box, tolerances):
    """Run the normal-equation solver (no bounds) or scipy's trust-region reflective method.

    Returns ``(x, J, success, message, iterations)``.
    """
    if box is not None:
        import scipy.optimize    # a third of a first fit's time: imported where bounds ask for scipy's solver

        with _steps_on_exhaustion(counted, 0), _solver_refusal(), np.errstate(all="ignore"):
            res = scipy.optimize.least_squares(counted, x0, jac=jac, method="trf", bounds=box, **tolerances)
        return res.x, float(2.0 * res.cost), bool(res.success), str(res.message), int(res.nfev)
    # past MINPACK_MAX_BYTES of Jacobian the solver goes on with a streamed QR factor instead of MINPACK
    factor = getattr(fun, "n_samples", 0) * x0.size * np.dtype(float).itemsize > MINPACK_MAX_BYTES
    x, f, code, iterations = normal_equations_lm(fun, counted, x0, max_steps=_MAX_STEPS_PER_PARAM * x0.size,
                                                 factor=factor, **tolerances)
    if code != ILL_CONDITIONED_CODE:
        return x, f, code in CONVERGED, MESSAGES[code], iterations
    x0 = x
    # MINPACK's lmder (this package's port: scipy's reads past a Jacobian column), the Jacobian as rows
    with _steps_on_exhaustion(counted, iterations), _solver_refusal(), np.errstate(all="ignore"):
        res = lmder(counted, jac.columns, x0, maxfev=_MINPACK_MAXFEV_PER_PARAM * x0.size, **tolerances)
    x, f, ier = res.x, res.fvec, res.info
    message = _MINPACK_MESSAGES.get(ier, f"MINPACK exit code {ier}")
    return x, float(f @ f), res.converged, message, iterations + res.nfev


@contextlib.contextmanager
def _solver_refusal():
    """A solver (lmder, scipy's trf) refusing non-finite values it formed from the residuals, as a
    :class:`ResidualsFault`."""
    try:
        yield
    except (ValueError, FloatingPointError) as exc:
        raise ResidualsFault(f"the least-squares solver stopped: {exc} (residuals too large to square?)") from None


@contextlib.contextmanager
def _steps_on_exhaustion(counted: _CountedResiduals, before: int):
    """On :class:`BudgetExhausted` inside a solver (lmder, scipy's trf), set its ``nit``: ``before`` plus
    the trial points asked for.

    Counted as on a normal return (the solver's ``nfev``: residual vectors, not Jacobian columns).
    """
    calls = counted.calls
    try:
        yield
    except BudgetExhausted as exc:
        exc.nit = before + counted.calls - calls
        raise


def _trf_box(bounds, x0):
    """``as_bounds`` plus what scipy's trust-region-reflective solver needs: lo < hi, x0 inside."""
    box = as_bounds(bounds, x0.size)
    if box is None:
        return None
    lo, hi = box
    same = np.flatnonzero(lo >= hi)
    if same.size:
        raise ParameterError(
            f"method 'lm' needs low < high for every bound; parameter {int(same[0])} has low = high = "
            f"{lo[same[0]]:g} (fix that parameter in the structure instead of bounding it)"
        )
    out = np.flatnonzero((x0 < lo) | (x0 > hi))
    if out.size:
        i = int(out[0])
        raise ParameterError(f"x0[{i}] = {x0[i]:g} lies outside its bounds [{lo[i]:g}, {hi[i]:g}]")
    return box


def levenberg_marquardt(fun, x0, *, maxfev: int | None = None, maxiter=None, seed=None, args=(),
                        bounds=None, callback=None, ftol=1e-10, xtol=1e-10, gtol=1e-10):
    """Minimise ``sum(fun.residuals(x)**2)`` with Levenberg-Marquardt.

    Parameters
    ----------
    fun : object with a ``residuals(x)`` method
        Such as :class:`~hammerstein_ctrl.fit.HammersteinCost`.  If it
        has ``normal_equations(x, steps)``, each step's point and its
        forward-difference Jacobian come from that one call; else, if it has
        ``residuals_batch(X)`` (rows of ``X`` to residual vectors), the
        Jacobian's columns are evaluated in one batched call.
    x0 : array_like

    maxfev : int, optional
        Budget of residual evaluations (Jacobian columns included).
    bounds : optional
        Box constraints; switches to scipy's trust-region-reflective method.
    maxiter, seed, args, callback
        Accepted for a uniform interface; ``maxiter`` and ``callback`` are not
        supported by scipy's least-squares solvers and must be None.
    ftol, xtol, gtol : float
        Termination tolerances, with MINPACK's meaning (see
        :mod:`~hammerstein_ctrl.optimize._normal_lm`).

    Returns
    -------
    hammerstein_ctrl.optimize.OptimizeResult
        ``fun`` is J at ``x`` (the sum of squared residuals); ``nit`` counts
        the steps tried (for ``"trf"``, scipy's evaluation count) and
        ``history`` has one row per evaluation.

    Examples
    --------
    >>> from hammerstein_ctrl import presets
    >>> p = presets.emps()
    >>> r = levenberg_marquardt(p.cost, p.x0, maxfev=2500)
    >>> r.success, round(r.fun, 6)
    (True, 0.208517)
    """
    started = time.perf_counter()
    residuals = getattr(fun, "residuals", None)
    if residuals is None:
        raise ParameterError(
            "method 'lm' needs a least-squares objective: an object with a residuals(x) method "
            "such as HammersteinCost"
        )
    if args:
        raise ParameterError("method 'lm' does not take args")
    if maxiter is not None or callback is not None:
        raise ParameterError("method 'lm' supports neither maxiter nor callback; use maxfev")
    maxfev, _ = check_budget(maxfev)
    x0 = as_x0(x0)
    box = _trf_box(bounds, x0)
    counted = _CountedResiduals(residuals, maxfev)
    jac = _BatchedJacobian(counted, getattr(fun, "residuals_batch", None), box)
    fault = False
    try:
        # The residual vectors are long enough for OpenBLAS to thread its dot
        # products; handing off to those threads between compiled simulations
        # made each evaluation ~50x slower on a 2-core machine.
        with single_threaded_blas():
            x, fun_x, success, message, nit = _solve(fun, counted, jac, x0, box,
                                                     dict(ftol=ftol, xtol=xtol, gtol=gtol))
        status = COMPLETED if success else SOLVER_FAILED
    except BudgetExhausted as exc:    # nit: the steps tried before it (see _steps_on_exhaustion)
        x, fun_x, nit = counted.best_x, counted.best_fun, counted.calls if exc.nit is None else exc.nit
        status, message = BUDGET_EXHAUSTED, budget_exhausted_message(maxfev)
    except ResidualsFault as exc:
        x, fun_x, nit, status, message = counted.best_x, counted.best_fun, counted.calls, SOLVER_FAILED, str(exc)
        fault = True
    if x is None:
        x, fun_x = x0, np.nan
    res = make_result(x=x, fun=fun_x, obj=counted, nit=nit, status=status,
                      message=message, history=counted.history, method="lm", started=started)
    if not fault and not res.fun < NONFINITE_RESIDUAL ** 2:   # every residual vector had non-finite entries
        res.update(status=NO_FINITE_VALUE, success=False,
                   message=f"no evaluated point had finite residuals (J = {res.fun:.4g}); {res.message}")
    return res
