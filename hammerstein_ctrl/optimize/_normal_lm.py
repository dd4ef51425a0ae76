"""Levenberg-Marquardt on the normal equations, with the Jacobian formed in the same pass as the trial point.

Each step solves ``(G + lam D) delta = -g`` with ``G = J.T J`` and
``g = J.T r`` (:class:`~hammerstein_ctrl.optimize._normal_equations.NormalEquations`),
``D`` the squared column norms of ``J`` (the largest seen so far, as
MINPACK scales), and the damping ``lam`` updated by the gain ratio (Nielsen's
rule).  A trial point is evaluated together with its forward-difference
neighbours in one pass (``p + 1`` residual vectors): when the step is
accepted, as it mostly is, its Jacobian is already there, so an iteration
costs one pass.  After a rejected step the next trials are evaluated alone
(one residual vector) until one is accepted.

The normal equations square the Jacobian's condition number.  Where the
scaled Gram matrix is too ill-conditioned for them (:data:`ILL_CONDITIONED`;
typically far from the optimum, e.g. at an unstable start, or in a structure
with a nearly flat direction) the solver stops with code 8 and
:func:`~hammerstein_ctrl.optimize.levenberg_marquardt` continues from that
point with MINPACK's QR-based lmder, or (``factor``, for long records) goes
on itself with the Jacobian's QR factor streamed out of the compiled pass
(``normal_factor``), each step a small least-squares solve on it.

Termination follows MINPACK's tests and messages: ``ftol`` (actual and
predicted relative reductions of the sum of squares), ``xtol`` (scaled step
relative to the scaled point), ``gtol`` (largest cosine between the residual
and a Jacobian column).
"""

from __future__ import annotations

import math

import numpy as np

from .. import config
from .._linalg import positions_fit
from .. import _core
from .._kernels import normal_kernel_number
from ._normal_equations import FD_REL_STEP
from ._normal_equations import (NormalEquations, forward_steps, from_residuals, neighbours, normal_arrays)
from ._common import BudgetExhausted

__all__ = ["normal_equations_lm", "INITIAL_DAMPING", "MAX_DAMPING", "ILL_CONDITIONED", "MESSAGES",
           "CONVERGED", "ILL_CONDITIONED_CODE", "DAMPING_DECREASE_LIMIT", "HAND_BACK", "HAND_BACK_ALONE",
           "LOOP_MAX_WORK"]

#: First damping, relative to the largest diagonal entry of the scaled Gram matrix (Nielsen's tau).
INITIAL_DAMPING = 1e-3
#: Damping past which no step can lower the sum of squares any more.
MAX_DAMPING = 1e20
#: Condition number of the scaled Gram matrix past which the solver hands over to a QR-based one.
ILL_CONDITIONED = 1e10
#: Smallest fraction by which an accepted step lowers the damping (Nielsen's rule).
DAMPING_DECREASE_LIMIT = 1.0 / 3.0

#: Termination codes: MINPACK's (scipy's ``leastsq``) messages, and one for a damping that ran away.
MESSAGES = {
    1: "`ftol` termination condition is satisfied.",
    2: "`xtol` termination condition is satisfied.",
    3: "Both `ftol` and `xtol` termination conditions are satisfied.",
    4: "`gtol` termination condition is satisfied.",
    5: "the step limit was reached before convergence",
    6: "no step lowers the sum of squares any more (the damping exceeded 1e20)",
    7: "the sum of squares is not finite at the starting point (an overflowing simulation, or an unstable "
       "start where unstable candidates are rejected)",
    8: "the normal equations are too ill-conditioned here",
}
#: Codes that mean convergence.
CONVERGED = (1, 2, 3, 4)
#: The code for a point too ill-conditioned for the normal equations.
ILL_CONDITIONED_CODE = 8
#: Codes of the compiled loop (:func:`_loop`) for the Python loop to take the next iteration: at the
#: point returned, or alone (after a rejected step, the next trials are evaluated without their neighbours).
HAND_BACK, HAND_BACK_ALONE = 0, -1
#: Work of one call of the compiled loop at most, in samples x lanes x states of its passes (about 0.1 s
#: at 0.5-0.9 ns each): it then hands back, so a keyboard interrupt is seen within that time.
LOOP_MAX_WORK = 10**8


class _Passes:
    """Counted evaluations for the solver: a point with its neighbours, or a point alone.

    ``counted`` is a :class:`~hammerstein_ctrl.optimize._least_squares._CountedResiduals`-like
    object (``charge``, ``record_value``, ``record_neighbourhood``, ``record_passes``, ``remaining``); ``fun`` supplies
    ``normal_equations(x, steps)``, or residuals from which they are formed.
    """

    def __init__(self, fun, counted):
        self.counted = counted
        self.steps = 0                  # steps tried by the solver (its iterations)
        self._fun = fun
        self._normal = getattr(fun, "normal_equations", None)
        self._factor = getattr(fun, "normal_factor", None)
        self.factored = False           # True: passes give the Jacobian's QR factor (normal_factor)
        self._batch = getattr(fun, "residuals_batch", None)
        self._residuals = fun.residuals
        # the bound __call__ itself is kept (not a callability test, so not callable(fun))
        self._value = getattr(fun, "__call__", None) if self._normal is not None else None  # noqa: B004
        direct_pass = getattr(fun, "direct_pass", None)
        self.direct = None if direct_pass is None else direct_pass()    # the compiled loop's pass, or None
        if self.direct is not None and not compiled_loop_wanted():
            self.direct = None

    def _pass_cost(self, n: int) -> int:
        """Evaluations a pass of ``n`` differences costs: ``n + 1``, or what the objective says one costs when its
        differences each touch part of the data (several records: a record's pass involves the shared blocks and
        its own nuisances only, so a pass over all of them costs as many evaluations as one record's)."""
        own = getattr(self._fun, "pass_evaluations", None)
        return int(own()) if own is not None else n + 1

    def value(self, x) -> float:
        """Sum of squares at ``x`` alone (one evaluation)."""
        self.counted.charge(1)
        with np.errstate(all="ignore"):
            if self._value is not None:
                f = float(self._value(x))
            else:
                r = self.counted.check(self._residuals(x))
                f = float(r @ r)
        f = f if np.isfinite(f) else np.inf
        self.counted.record_value(x, f)
        return f

    def full(self, x) -> NormalEquations:
        """Normal equations at ``x`` (``p + 1`` evaluations); a partial budget is spent on ``x`` and the neighbours that
        fit."""
        h = forward_steps(x)
        cost = self._pass_cost(h.size)
        if self.counted.remaining < cost:
            # spend what is left on the point and the neighbours that fit, as separate differences would
            for row in neighbours(x, h)[:int(self.counted.remaining)]:
                self.value(row)
            raise BudgetExhausted("evaluation budget exhausted")
        self.counted.charge(cost)
        if self.factored:
            ne = self._factor(x, h)
        elif self._normal is not None:
            ne = self._normal(x, h)
        else:
            X = neighbours(x, h)
            with np.errstate(all="ignore"):
                R = self._batch(X) if self._batch is not None else [self.counted.check(self._residuals(row))
                                                                     for row in X]
                ne = from_residuals(self.counted.check(R, batch=len(X)), h)
        values = [f if math.isfinite(f) else math.inf for f in [ne.fun, *ne.neighbour_values().tolist()]]
        self.counted.record_neighbourhood(x, h, values)
        return ne if values[0] == ne.fun else ne._replace(fun=values[0])

    def loop(self, x, ne, scale, damping, max_steps: int, tolerances):
        """Steps of the compiled loop (:func:`_loop`) from ``x``: ``(x, ne, scale, code)``.

        Without ``ne`` (and ``scale``) the loop begins with the pass at ``x``;
        ``ne`` is returned ``None`` if that pass is left to the general one.
        ``code`` is a key of :data:`MESSAGES`, or :data:`HAND_BACK` /
        :data:`HAND_BACK_ALONE` for the Python loop to take the next iteration;
        the loop's passes are booked afterwards, in their order.
        """
        p, d, start = x.size, self.direct, ne is None
        rows = int(min(max_steps - self.steps + start, self.counted.remaining // (p + 1),
                       max(1, LOOP_MAX_WORK // (d.y.size * (p + 1) * d.n))))
        if rows < 1 or p != d.n_params:     # a point of another length: the general pass refuses it
            return x, ne, scale, HAND_BACK
        number = normal_kernel_number(d.n, d.hold, p + 1, d.K, d.direct)
        x = np.array(x, dtype=float)
        if start:
            fun, gradient, gram, steps, scale = np.nan, np.empty(p), np.empty((p, p)), np.empty(p), np.empty(p)
        else:
            fun = ne.fun
            gradient, gram, steps, scale = (np.array(a, dtype=float) for a in (ne.gradient, ne.gram, ne.steps, scale))
        state = np.array([fun, damping.lam, damping.nu])
        counts = np.array([self.steps, max_steps, rows * (p + 1), 0], dtype=np.int64)
        logs = np.empty((rows, p)), np.empty((rows, p)), np.empty((rows, p + 1))
        settings = np.array([*tolerances, ILL_CONDITIONED, d.dt, d.max_norm, FD_REL_STEP, MAX_DAMPING,
                             DAMPING_DECREASE_LIMIT])
        code = _loop(number, x, state, gradient, gram, steps, scale, counts, settings, start, d, logs)
        fun = state[0]
        passes = int(counts[3])
        if passes:
            self.counted.record_passes(*(log[:passes] for log in logs))
        elif start:
            return x, None, None, HAND_BACK
        self.steps = int(counts[0])
        damping.lam, damping.nu = float(state[1]), float(state[2])
        return x, NormalEquations(float(fun), gradient, gram, steps), scale, int(code)

    @property
    def can_factor(self) -> bool:
        """Whether the objective gives the Jacobian's QR factor (``normal_factor``)."""
        return self._factor is not None


def _iteration(gram, gradient, fun, scale, lam, x, check, limit, xtol):
    """One iteration's linear algebra: ``(cosine, ill, solved, delta, small, predicted)`` (the compiled core's).

    ``cosine`` is MINPACK's gtol measure; ``ill`` whether the scaled Gram
    matrix has a non-finite entry or a condition number of ``limit`` or more
    (only if ``check``); ``delta`` the damped Gauss-Newton step
    ``-(G + mu diag(scale**2))^-1 g`` with ``mu`` relative to the largest
    scaled curvature (``solved`` False if it cannot be formed; a singular
    damped matrix gives a non-finite step, and the caller raises the damping);
    ``small`` MINPACK's xtol test on it and ``predicted`` the reduction of
    the sum of squares its linear model predicts.

    Examples
    --------
    >>> cosine, ill, solved, delta, small, predicted = _iteration(
    ...     np.array([[4.0]]), np.array([2.0]), 1.0, np.array([2.0]), 0.0, np.array([0.0]), True, 1e10, 1e-8)
    >>> float(cosine), ill, solved, delta.tolist(), small, float(predicted)
    (1.0, False, True, [-0.5], False, 1.0)
    """
    gradient, gram, scale, x = normal_arrays(gradient, gram, scale, x)
    p = scale.size
    work, delta, out = np.empty(2 * p * p + 2 * p), np.empty(p), np.empty(5)
    _core.hc_lm_iteration(gram, gradient, p, float(fun), scale, float(lam),
                              x, int(bool(check)), float(limit), float(xtol), work,
                              delta, out)
    return out[0], bool(out[1]), bool(out[2]), delta, bool(out[3]), out[4]


def _step_measures(gram, gradient, scale, delta, x, xtol):
    """MINPACK's xtol test on the step ``delta`` and the reduction of the sum of squares its linear model predicts."""
    gradient, gram, scale, delta, x = normal_arrays(gradient, gram, scale, delta, x)
    out = np.empty(2)
    _core.hc_lm_step_measures(gram, gradient, scale, delta,
                                  x, scale.size, float(xtol), out)
    return bool(out[0]), out[1]


def _cosine(gram, gradient, fun):
    """Largest cosine between the residual vector and a Jacobian column (MINPACK's ``gtol`` measure; NaN wins)."""
    gradient, gram = normal_arrays(gradient, gram)
    return _core.hc_lm_cosine(gram, gradient, gradient.size, float(fun))


def _factor_iteration(ne, scale, lam, x, xtol):
    """:func:`_iteration` from the Jacobian's QR factor (``ne.factor``): the damped step by least squares.

    ``min |R delta + Q.T r|^2 + mu |diag(scale) delta|^2`` is solved as the
    stacked least-squares problem, with a QR factorisation's accuracy where
    the normal equations would square the condition number; nothing is ill-conditioned here.
    """
    RJ, qtr = ne.factor
    p = scale.size
    A = RJ / scale
    top = max(float(np.max(np.einsum("ij,ij->j", A, A))), np.finfo(np.float64).tiny)
    stacked = np.vstack([A, np.sqrt(lam * top) * np.eye(p)])
    with np.errstate(all="ignore"):
        finite = np.isfinite(stacked).all() and np.isfinite(qtr).all()
        z = np.linalg.lstsq(stacked, np.concatenate([-qtr, np.zeros(p)]), rcond=None)[0] if finite else np.zeros(p)
    delta = z / scale
    solved = bool(finite and np.isfinite(delta).all())
    small, predicted = _step_measures(ne.gram, ne.gradient, scale, delta, x, xtol)
    return _cosine(ne.gram, ne.gradient, ne.fun), False, solved, delta, small, predicted


def _column_norms(gram, previous=None):
    """Column norms of J from the Gram matrix (1 for a zero column), never below ``previous``."""
    return _norms(gram, np.zeros(gram.shape[0]) if previous is None else previous)


def _norms(gram, floor):
    """Column norms of J from the Gram matrix (1 for a zero or non-finite one), never below ``floor``."""
    floor, gram = normal_arrays(floor, gram)
    norms = np.empty(floor.size)
    _core.hc_lm_norms(gram, floor.size, floor, norms)
    return norms


class _Damping:
    """Nielsen's damping: lowered after a good step by the gain ratio, raised geometrically after a bad one.

    ``lam`` is relative to the largest diagonal entry of the scaled Gram
    matrix, so a Jacobian that shrinks by orders of magnitude on the way in
    from a poor start does not leave the steps over-damped.
    """

    def __init__(self):
        self.lam = INITIAL_DAMPING
        self.nu = 2.0

    def accept(self, rho):
        self.lam = _lowered_damping(self.lam, rho)
        self.nu = 2.0

    def reject(self):
        self.lam *= self.nu
        self.nu *= 2.0


def _lowered_damping(lam, rho) -> float:
    """Nielsen's rule: the damping ``lam`` after an accepted step of gain ratio ``rho`` (both loops use it):
    ``lam max(1/3, 1 - (2 rho - 1)^3)``.

    Examples
    --------
    >>> _lowered_damping(1.0, 1.0), _lowered_damping(1.0, 0.5)
    (0.3333333333333333, 1.0)
    """
    return _core.hc_lm_lowered_damping(lam, rho, DAMPING_DECREASE_LIMIT)


def _accepted_code(actual, predicted, f_old, ftol, small) -> int:
    """MINPACK's code after an accepted step: 1 (``ftol``), 2 (``xtol``: ``small``), 3 (both), or 0 (go on).

    Examples
    --------
    >>> _accepted_code(1e-9, 1e-9, 1.0, 1e-8, False), _accepted_code(0.5, 0.5, 1.0, 1e-8, True)
    (1, 2)
    """
    return _core.hc_lm_accepted_code(actual, predicted, f_old, ftol, bool(small))


def compiled_loop_wanted() -> bool:
    """Whether :func:`normal_equations_lm` runs its compiled loop (``config.defaults["lm.compiled_loop"]``):
    ``"auto"`` and ``"always"`` run it, ``"never"`` runs the same steps in Python.

    The loop is C in the package's compiled core (:func:`_loop`), built when the package is installed.
    """
    return config.get("lm.compiled_loop") != "never"


def _loop_fits(p, K, N, gradient, gram, steps, scale, state, counts, settings, d, logs) -> bool:
    """Whether :func:`_loop`'s arrays fit one another: the point's, the pass's (its basis, record and linear
    block) and the logs' (a row for every pass the evaluations left allow, none written yet)."""
    n_linear = d.num_pos.size + d.den_pos.size
    rows = min(log.shape[0] for log in logs)
    return (p >= 1 and gradient.size == steps.size == scale.size == p and gram.size == p * p and state.size == 3
            and counts.size == 4 and settings.size == 9 and d.y.size >= N
            and all(log.ndim == 2 for log in logs) and logs[0].shape[1] == logs[1].shape[1] == p
            and logs[2].shape[1] == p + 1 and counts[3] == 0 and p + 1 <= counts[2] <= rows * (p + 1)
            and d.n == d.den0.size - 1 and n_linear <= p and d.num0.size <= d.den0.size
            and positions_fit(d.num0, d.den0, d.num_pos, d.den_pos)
            and K == (p - n_linear if d.has_g else 1) and K >= 1)


def _loop(number, x, state, gradient, gram, steps, scale, counts, settings, start, d, logs) -> int:
    """The compiled core's Levenberg-Marquardt loop around the pass kernel ``number`` (``hc_lm_loop``), for a
    cost's :meth:`~hammerstein_ctrl.fit.HammersteinCost.direct_pass` ``d`` (no offset, initial state or
    output map; the signal ``P @ Phi`` with ``P`` the parameters of ``g``).

    The loop takes the steps of the Python loop one after another while each
    trial point is accepted, with the same library functions in the same
    order (so the same bits), and returns where the Python loop must take the
    next iteration: a rejected step, an ill-conditioned or unsolvable system,
    a pass that is not finite or needs scipy's exponential, or a budget short
    of a whole pass.  In Python a step costs about 25 us around the pass;
    here about 5.

    ``x``, ``gradient``, ``gram``, ``steps`` (the current point's normal
    equations), ``scale``, ``state = [fun, lam, nu]`` and ``counts = [steps
    taken, step limit, evaluations left, passes logged]`` are updated in
    place; with ``start`` the loop begins with the pass at ``x`` and fills
    them (if that pass is left to the general one, nothing is logged).  Row
    ``i`` of ``logs`` (point, steps, sums of squares of the point and its
    neighbours) holds pass ``i``.  ``settings`` are ``[ftol, xtol, gtol,
    ILL_CONDITIONED, dt, max_norm, FD_REL_STEP, MAX_DAMPING,
    DAMPING_DECREASE_LIMIT]``.  Returns a key of :data:`MESSAGES`,
    :data:`HAND_BACK` or :data:`HAND_BACK_ALONE`.
    """
    p, (K, N) = x.size, d.basis.shape
    if not _loop_fits(p, K, N, gradient, gram, steps, scale, state, counts, settings, d, logs):
        raise ValueError("the compiled loop's arrays do not fit its point, its pass or its logs")
    log_x, log_steps, log_values = logs
    return _core.hc_lm_loop(
        number, x, p, state, gradient, gram, steps, scale, counts, settings, int(bool(start)), d.num0, d.num0.size,
        d.den0, d.den0.size, d.num_pos, d.num_pos.size, d.den_pos, d.den_pos.size, int(bool(d.has_g)),
        int(bool(d.direct)), d.basis, K, N, d.y, log_x, log_steps, log_values)


def normal_equations_lm(fun, counted, x0, *, ftol, xtol, gtol, max_steps: int, factor: bool = False):
    """Run the solver from ``x0``; ``(x, f, code, iterations)`` with ``code`` a key of :data:`MESSAGES`.

    Code 8 (:data:`ILL_CONDITIONED_CODE`) returns the current point as soon
    as the scaled Gram matrix is :data:`ILL_CONDITIONED`, for the caller to
    continue from it with a QR-based solver.  With ``factor`` (and an
    objective with ``normal_factor``) the solver goes on itself instead:
    from then on each pass reduces the Jacobian by a streamed QR
    (:func:`~hammerstein_ctrl.simulate._simulate.normal_factor`) and each step is a
    small least-squares solve on the factor, in memory bounded per sample.

    Raises :class:`~hammerstein_ctrl.optimize._common.BudgetExhausted` when
    the budget ends first (the counted object then holds the best point).
    """
    passes = _Passes(fun, counted)
    try:
        return _iterate(passes, np.array(x0, dtype=float), ftol, xtol, gtol, max_steps, factor)
    except BudgetExhausted as exc:
        exc.nit = passes.steps
        raise


def _start(passes, x, damping, max_steps: int, tolerances):
    """The first pass, and the compiled loop's steps after it where the objective has one: ``(x, ne, scale, code)``.

    ``code`` is ``None`` after the first pass alone, else as :meth:`_Passes.loop` returns it
    (7 if the sum of squares at ``x`` is not finite).
    """
    if passes.direct is not None:
        x, ne, scale, code = passes.loop(x, None, None, damping, max_steps, tolerances)
        if ne is not None:
            return x, ne, scale, code
    ne = passes.full(x)
    if not np.isfinite(ne.fun):
        return x, ne, None, 7
    return x, ne, _column_norms(ne.gram), None


def _iterate(passes, x, ftol, xtol, gtol, max_steps: int, factor: bool):
    """The loop of :func:`normal_equations_lm`; ``passes.steps`` counts the steps tried.

    Where the objective has a :meth:`_Passes.loop`, the steps run there from
    the start, and after each hand-back this loop takes one iteration.
    """
    damping = _Damping()
    x, ne, scale, code = _start(passes, x, damping, max_steps, (ftol, xtol, gtol))
    if code not in (None, HAND_BACK, HAND_BACK_ALONE):
        return x, ne.fun, code, passes.steps
    alone, python = code == HAND_BACK_ALONE, code is not None     # python: the next iteration in Python
    while True:
        if ne.fun == 0.0:
            return x, ne.fun, 1, passes.steps
        if passes.direct is not None and not (alone or python) and ne.factor is None:
            x, ne, scale, code = passes.loop(x, ne, scale, damping, max_steps, (ftol, xtol, gtol))
            if code not in (HAND_BACK, HAND_BACK_ALONE):
                return x, ne.fun, code, passes.steps
            alone, python = code == HAND_BACK_ALONE, True
            continue
        python = False
        if ne.factor is not None:
            cosine, ill, solved, delta, small, predicted = _factor_iteration(ne, scale, damping.lam, x, xtol)
        else:
            cosine, ill, solved, delta, small, predicted = _iteration(
                ne.gram, ne.gradient, ne.fun, scale, damping.lam, x, not alone, ILL_CONDITIONED, xtol)
        if cosine <= gtol:
            return x, ne.fun, 4, passes.steps
        if ill and not (factor and passes.can_factor):
            return x, ne.fun, ILL_CONDITIONED_CODE, passes.steps
        if ill:                                 # from here on, the QR factor of each pass
            passes.factored = True
            ne, alone = passes.full(x), False
            continue
        if not solved:
            damping.reject()
            if damping.lam > MAX_DAMPING:
                return x, ne.fun, 6, passes.steps
            continue
        if passes.steps >= max_steps:
            return x, ne.fun, 5, passes.steps
        trial = x + delta
        if passes.counted.remaining >= 1:       # a step counts once its trial point (a pass's row 0) is evaluated,
            passes.steps += 1                   # also by a pass the budget cuts short
        trial_ne = None if alone else passes.full(trial)
        f_trial = passes.value(trial) if alone else trial_ne.fun
        if f_trial < ne.fun and predicted > 0:
            actual, f_old = ne.fun - f_trial, ne.fun
            damping.accept(actual / predicted)
            ne = trial_ne if trial_ne is not None else passes.full(trial)
            x, alone = trial, False
            scale = _column_norms(ne.gram, scale)
            code = _accepted_code(actual, predicted, f_old, ftol, small)
            if code:
                return x, ne.fun, code, passes.steps
        else:
            damping.reject()
            alone = True
            if small:
                return x, ne.fun, 2, passes.steps
            if damping.lam > MAX_DAMPING:
                return x, ne.fun, 6, passes.steps
