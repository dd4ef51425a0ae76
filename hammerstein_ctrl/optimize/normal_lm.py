"""Levenberg-Marquardt on the normal equations, with the Jacobian formed in the same pass as the trial point.

Each step solves ``(G + lam D) delta = -g`` with ``G = J.T J`` and
``g = J.T r`` (:class:`~hammerstein_ctrl.normal_equations.NormalEquations`),
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
import os
import subprocess
import sys

import numba.extending
import numpy as np

from .. import config
from .._jit import _digest, cached_njit, machine_cache_dir
from .._linalg import _copy, copy_vector, fill_coefficients
from .._native import DEPENDS as NATIVE_DEPENDS, c_call, library
from ..kernels import call_normal_kernel, discretised, normal_kernel_address
from ..normal_equations import (NormalEquations, compiled_neighbourhood, compiled_sums, forward_steps,
                                from_residuals, neighbours, normal_arrays)
from ._common import BudgetExhausted

__all__ = ["normal_equations_lm", "INITIAL_DAMPING", "MAX_DAMPING", "ILL_CONDITIONED", "MESSAGES",
           "CONVERGED", "ILL_CONDITIONED_CODE", "DAMPING_DECREASE_LIMIT", "HAND_BACK", "HAND_BACK_ALONE",
           "LOOP_MAX_WORK", "LOOP_DEPENDS"]

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
#: Codes of the compiled loop (:func:`_compiled_loop`) for the Python loop to take the next iteration: at the
#: point returned, or alone (after a rejected step, the next trials are evaluated without their neighbours).
HAND_BACK, HAND_BACK_ALONE = 0, -1
#: The compiled loop's code for "go on".
GO_ON = -2
#: Work of one call of the compiled loop at most, in samples x lanes x states of its passes (about 0.1 s
#: at 0.5-0.9 ns each): it then hands back, so a keyboard interrupt is seen within that time.
LOOP_MAX_WORK = 10**8


class _Passes:
    """Counted evaluations for the solver: a point with its neighbours, or a point alone.

    ``counted`` is a :class:`~hammerstein_ctrl.optimize.least_squares._CountedResiduals`-like
    object (``charge``, ``record_value``, ``record_neighbourhood``, ``record_passes``, ``remaining``); ``fun`` supplies
    ``normal_equations(x, steps)``, or residuals from which they are formed.
    """

    def __init__(self, fun, counted):
        self.counted = counted
        self.steps = 0                  # steps tried by the solver (its iterations)
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
        if self.counted.remaining < h.size + 1:
            # spend what is left on the point and the neighbours that fit, as separate differences would
            for row in neighbours(x, h)[:int(self.counted.remaining)]:
                self.value(row)
            raise BudgetExhausted("evaluation budget exhausted")
        self.counted.charge(h.size + 1)
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
        """Steps of the compiled loop (:func:`_compiled_loop`) from ``x``: ``(x, ne, scale, code)``.

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
        address = normal_kernel_address(d.n, d.hold, p + 1, d.K, d.direct)
        x = np.array(x, dtype=float)
        if start:
            fun, gradient, gram, steps, scale = np.nan, np.empty(p), np.empty((p, p)), np.empty(p), np.empty(p)
        else:
            fun = ne.fun
            gradient, gram, steps, scale = (np.array(a, dtype=float) for a in (ne.gradient, ne.gram, ne.steps, scale))
        lam_nu = np.array([damping.lam, damping.nu])
        counts = np.array([self.steps, max_steps, rows * (p + 1), 0], dtype=np.int64)
        logs = np.empty((rows, p)), np.empty((rows, p)), np.empty((rows, p + 1))
        code, fun = _compiled_loop(address, x, fun, gradient, gram, steps, scale, lam_nu,
                                  counts, np.array([*tolerances, ILL_CONDITIONED]), start, d.num0, d.den0, d.num_pos,
                                  d.den_pos, d.has_g, d.dt, d.max_norm, d.direct, d.basis, d.y, *logs)
        passes = int(counts[3])
        if passes:
            self.counted.record_passes(*(log[:passes] for log in logs))
        elif start:
            return x, None, None, HAND_BACK
        self.steps = int(counts[0])
        damping.lam, damping.nu = float(lam_nu[0]), float(lam_nu[1])
        return x, NormalEquations(float(fun), gradient, gram, steps), scale, int(code)

    @property
    def can_factor(self) -> bool:
        """Whether the objective gives the Jacobian's QR factor (``normal_factor``)."""
        return self._factor is not None


@numba.extending.intrinsic
def _c_iteration(typingctx, gram, gradient, p, fun, scale, lam, x, check, limit, xtol, work, delta, out):
    return c_call("hc_lm_iteration", (gram, gradient, p, fun, scale, lam, x, check, limit, xtol, work, delta, out))


@numba.extending.intrinsic
def _c_norms(typingctx, gram, p, floor, norms):
    return c_call("hc_lm_norms", (gram, p, floor, norms))


def _iteration(gram, gradient, fun, scale, lam, x, check, limit, xtol):
    """One iteration's linear algebra: ``(cosine, ill, solved, delta, small, predicted)`` (the C library's).

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
    library().hc_lm_iteration(gram, gradient, p, float(fun), scale, float(lam),
                              x, int(bool(check)), float(limit), float(xtol), work,
                              delta, out)
    return out[0], bool(out[1]), bool(out[2]), delta, bool(out[3]), out[4]


@numba.extending.overload(_iteration)
def _iteration_compiled(gram, gradient, fun, scale, lam, x, check, limit, xtol):
    def impl(gram, gradient, fun, scale, lam, x, check, limit, xtol):
        p = scale.size
        work, delta, out = np.empty(2 * p * p + 2 * p), np.empty(p), np.empty(5)
        _c_iteration(gram, gradient, p, fun, scale, lam, x, 1 if check else 0, limit, xtol, work, delta, out)
        return out[0], out[1] != 0.0, out[2] != 0.0, delta, out[3] != 0.0, out[4]
    return impl


def _step_measures(gram, gradient, scale, delta, x, xtol):
    """MINPACK's xtol test on the step ``delta`` and the reduction of the sum of squares its linear model predicts."""
    gradient, gram, scale, delta, x = normal_arrays(gradient, gram, scale, delta, x)
    out = np.empty(2)
    library().hc_lm_step_measures(gram, gradient, scale, delta,
                                  x, scale.size, float(xtol), out)
    return bool(out[0]), out[1]


def _cosine(gram, gradient, fun):
    """Largest cosine between the residual vector and a Jacobian column (MINPACK's ``gtol`` measure; NaN wins)."""
    gradient, gram = normal_arrays(gradient, gram)
    return library().hc_lm_cosine(gram, gradient, gradient.size, float(fun))


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
    library().hc_lm_norms(gram, floor.size, floor, norms)
    return norms


@numba.extending.overload(_norms)
def _norms_compiled(gram, floor):
    def impl(gram, floor):
        norms = np.empty(floor.size)
        _c_norms(gram, floor.size, floor, norms)
        return norms
    return impl


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


@numba.extending.intrinsic
def _c_lowered_damping(typingctx, lam, rho, limit):
    return c_call("hc_lm_lowered_damping", (lam, rho, limit))


@numba.extending.intrinsic
def _c_accepted_code(typingctx, actual, predicted, f_old, ftol, small):
    return c_call("hc_lm_accepted_code", (actual, predicted, f_old, ftol, small))


def _lowered_damping(lam, rho) -> float:
    """Nielsen's rule: the damping ``lam`` after an accepted step of gain ratio ``rho`` (both loops use it):
    ``lam max(1/3, 1 - (2 rho - 1)^3)``.

    Examples
    --------
    >>> _lowered_damping(1.0, 1.0), _lowered_damping(1.0, 0.5)
    (0.3333333333333333, 1.0)
    """
    return library().hc_lm_lowered_damping(lam, rho, DAMPING_DECREASE_LIMIT)


@numba.extending.overload(_lowered_damping)
def _lowered_damping_compiled(lam, rho):
    return lambda lam, rho: _c_lowered_damping(lam, rho, DAMPING_DECREASE_LIMIT)


def _accepted_code(actual, predicted, f_old, ftol, small) -> int:
    """MINPACK's code after an accepted step: 1 (``ftol``), 2 (``xtol``: ``small``), 3 (both), or 0 (go on).

    Examples
    --------
    >>> _accepted_code(1e-9, 1e-9, 1.0, 1e-8, False), _accepted_code(0.5, 0.5, 1.0, 1e-8, True)
    (1, 2)
    """
    return library().hc_lm_accepted_code(actual, predicted, f_old, ftol, bool(small))


@numba.extending.overload(_accepted_code)
def _accepted_code_compiled(actual, predicted, f_old, ftol, small):
    return lambda actual, predicted, f_old, ftol, small: _c_accepted_code(actual, predicted, f_old, ftol,
                                                                        1 if small else 0)


#: Package files holding compiled code that :func:`_compiled_loop` calls or inlines (the pass kernel's signature
#: among them): numba's cache of it is keyed on them too (a stale copy would call the kernel unchecked).
LOOP_DEPENDS = ("kernels.py", "_kernel_source.py", "normal_equations.py", "structure.py", "_linalg.py",
                "_simd.py") + NATIVE_DEPENDS
_WARMING: list = []              # the background process compiling the loop, once per process


def loop_marker():
    """The file that says the compiled loop of these sources is in the machine's cache (``None``: no cache)."""
    import numba

    root = machine_cache_dir()
    if root is None:
        return None
    digest = _digest(LOOP_DEPENDS + ("optimize/normal_lm.py",))[:16]
    return root / f"lm-loop-{digest}-numba-{numba.__version__}.ready"


def compiled_loop_wanted() -> bool:
    """Whether :func:`normal_equations_lm` runs its compiled loop (``config.defaults["lm.compiled_loop"]``).

    ``"auto"``: once the loop is compiled on this machine (:func:`loop_marker`);
    until then the Python loop runs (the same steps, a few microseconds more
    per iteration) while a background process compiles the loop, so a first
    use does not wait about 5 s of CPU for it.
    """
    mode = config.get("lm.compiled_loop")
    if mode != "auto":
        return mode == "always"
    marker = loop_marker()
    if marker is None:
        return False                     # nowhere to keep it: every process would compile it again
    if marker.is_file():
        return True
    if not _WARMING and not marker.with_suffix(".failed").is_file():     # a failed attempt is not repeated
        try:
            _WARMING.append(subprocess.Popen([sys.executable, "-m", "hammerstein_ctrl._warm"],
                                             stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                             stderr=subprocess.DEVNULL, start_new_session=True,
                                             env={**os.environ, "HAMMERSTEIN_CTRL_COMPILED_LOOP": "always"}))
        except OSError:
            _WARMING.append(None)
    return False


@cached_njit(depends=LOOP_DEPENDS)
def _compiled_loop(address, x, fun, gradient, gram, steps, scale, damping, counts, tolerances, start,
                  num0, den0, num_pos, den_pos, has_g, dt, max_norm, direct, Phi, y, log_x, log_steps,
                  log_values):  # pragma: no cover - compiled
    """The Levenberg-Marquardt loop of :func:`normal_equations_lm`, compiled around the pass of a plain cost.

    For a cost's :meth:`~hammerstein_ctrl.objective.HammersteinCost.direct_pass`
    (no offset, initial state or output map; the signal ``P @ Phi`` with ``P``
    the parameters of ``g``), whose pass kernel is at ``address``
    (:func:`~hammerstein_ctrl.kernels.normal_kernel_address`).  The loop takes
    the steps of the Python loop one after another while each trial point is
    accepted, with the same compiled helpers in the same order (so the same
    bits), and returns where the Python loop must take the next iteration: a
    rejected step, an ill-conditioned or unsolvable system, a pass that is not
    finite or needs scipy's exponential, or a budget short of a whole pass.
    In Python a step costs about 25 µs around the pass; here about 5.

    ``x``, ``gradient``, ``gram``, ``steps`` (the current point's normal
    equations), ``scale``, ``damping = [lam, nu]`` and ``counts = [steps taken,
    step limit, evaluations left, passes logged]`` are updated in place; with
    ``start`` the loop begins with the pass at ``x`` and fills them (if that
    pass is left to the general one, nothing is logged).  Row ``i`` of the
    logs holds pass ``i``'s point, steps and the sums of squares of the point
    and its neighbours.  Returns ``(code, fun)``, ``code`` a key of
    :data:`MESSAGES`, :data:`HAND_BACK` or :data:`HAND_BACK_ALONE`.
    """
    lanes, n = x.size + 1, den0.size - 1
    begin = counts[3] - counts[3]       # 0 at run time (the kernel's type for it is int64, not a literal)
    while True:
        code, trial, small, predicted, h, E, C, D, P = _loop_prepare(
            x, fun, gradient, gram, scale, damping, counts, tolerances, start, num0, den0, num_pos, den_pos, has_g,
            dt, max_norm, direct)
        if code != GO_ON:
            return code, fun
        sums = np.zeros(1 + x.size * lanes)
        call_normal_kernel(address, E, C, D, np.zeros((lanes, n)), np.zeros(lanes), np.zeros(lanes), P, Phi,
                           np.zeros((lanes, 0)), np.zeros(0), y, begin, sums)
        code, fun = _loop_absorb(x, trial, fun, sums, h, gradient, gram, steps, scale, damping, counts, small,
                                predicted, tolerances, start, log_x, log_steps, log_values)
        start = False
        if code != GO_ON:
            return code, fun


@cached_njit(inline="always")
def _loop_prepare(x, fun, gradient, gram, scale, damping, counts, tolerances, start, num0, den0, num_pos, den_pos,
                 has_g, dt, max_norm, direct):  # pragma: no cover - compiled
    """Before a pass of the compiled loop: ``(code, trial, small, predicted, h, E, C, D, P)``.

    With ``start`` the pass is at ``x`` itself, else at the step of
    :func:`_loop_trial`; ``code`` is :data:`GO_ON` with the pass's inputs
    (:func:`_loop_pass_inputs`), a termination code, or :data:`HAND_BACK`
    where the Python loop must take the iteration.
    """
    code, trial, small, predicted = GO_ON, x.copy(), False, 0.0
    if not start:
        code, delta, small, predicted = _loop_trial(gram, gradient, fun, scale, damping, x, counts, tolerances)
        trial = x + delta
    if code != GO_ON:
        return code, trial, small, predicted, np.empty(0), np.empty((0, 0, 0)), np.empty((0, 0)), np.empty(0), \
            np.empty((0, 0))
    ok, h, E, C, D, P = _loop_pass_inputs(trial, num0, den0, num_pos, den_pos, has_g, dt, max_norm, direct)
    return GO_ON if ok else HAND_BACK, trial, small, predicted, h, E, C, D, P


@cached_njit(inline="always")
def _loop_absorb(x, trial, fun, sums, h, gradient, gram, steps, scale, damping, counts, small, predicted, tolerances,
                start, log_x, log_steps, log_values):  # pragma: no cover - compiled
    """After a pass of the compiled loop: its sums logged and charged, the state updated in place; ``(code, fun)``.

    The first pass (``start``) sets the point's normal equations and column
    scales; a trial's is accepted or rejected (:func:`_loop_outcome`).  A pass
    that is not finite is not logged: :data:`HAND_BACK`.
    """
    finite, new_fun, new_gradient, new_gram, values = compiled_sums(sums, h)
    if not finite:
        return HAND_BACK, fun
    row = counts[3]
    copy_vector(trial, log_x[row])
    copy_vector(h, log_steps[row])
    copy_vector(values, log_values[row])
    counts[2] -= values.size
    counts[3] += 1
    if start:
        copy_vector(new_gradient, gradient)
        _copy(new_gram, gram)
        copy_vector(h, steps)
        copy_vector(_norms(gram, np.zeros(gram.shape[0])), scale)
        return GO_ON, new_fun
    counts[0] += 1
    return _loop_outcome(x, trial, fun, new_fun, new_gradient, new_gram, h, gradient, gram, steps, scale, damping,
                        small, predicted, tolerances)


@cached_njit(inline="always")
def _loop_trial(gram, gradient, fun, scale, damping, x, counts, tolerances):  # pragma: no cover - compiled
    """The top of an iteration of the compiled loop: ``(code, delta, small, predicted)``.

    ``code`` is a termination code, :data:`HAND_BACK` (an ill-conditioned or
    unsolvable system, a budget short of a whole pass) or :data:`GO_ON` with
    the step ``delta`` to try; ``tolerances`` are ``[ftol, xtol, gtol, ILL_CONDITIONED]``.
    """
    if fun == 0.0:
        return 1, np.zeros(x.size), False, 0.0
    check = tolerances[3] > 0       # True at run time: a literal True would have _iteration compiled again
    cosine, ill, solved, delta, small, predicted = _iteration(gram, gradient, fun, scale, damping[0], x, check,
                                                              tolerances[3], tolerances[1])
    if cosine <= tolerances[2]:
        return 4, delta, small, predicted
    if ill or not solved:
        return HAND_BACK, delta, small, predicted
    if counts[0] >= counts[1]:
        return 5, delta, small, predicted
    if counts[2] < x.size + 1:
        return HAND_BACK, delta, small, predicted
    return GO_ON, delta, small, predicted


@cached_njit(inline="always")
def _loop_pass_inputs(trial, num0, den0, num_pos, den_pos, has_g, dt, max_norm,
                      direct):  # pragma: no cover - compiled
    """What the pass at ``trial`` needs: ``(ok, h, E, C, D, P)``, as ``HammersteinCost.normal_equations`` forms them.

    Not ``ok`` where the general pass must take the point: a row for scipy's
    exponential, or a direct term other than the kernel's (``direct``).
    """
    h, X = compiled_neighbourhood(trial)
    n_linear = num_pos.size + den_pos.size
    num, den = fill_coefficients(X[:1 + n_linear, :n_linear].copy(), num0, den0, num_pos, den_pos)
    E, C, D, clean = discretised(num, den, dt, max_norm)
    P = X[:, n_linear:].copy() if has_g else np.ones((X.shape[0], 1))
    return clean and (num.shape[1] == den.shape[1] and D.any()) == direct, h, E, C, D, P


@cached_njit(inline="always")
def _loop_outcome(x, trial, fun, f_trial, new_gradient, new_gram, new_steps, gradient, gram, steps, scale, damping,
                 small, predicted, tolerances):  # pragma: no cover - compiled
    """The evaluated trial accepted or rejected as :func:`normal_equations_lm` does: ``(code, fun)``, the state updated
    in place."""
    if f_trial < fun and predicted > 0:
        actual = fun - f_trial
        damping[0] = _lowered_damping(damping[0], actual / predicted)
        damping[1] = 2.0
        copy_vector(trial, x)
        copy_vector(new_gradient, gradient)
        _copy(new_gram, gram)
        copy_vector(new_steps, steps)
        copy_vector(_norms(gram, scale), scale)
        code = _accepted_code(actual, predicted, fun, tolerances[0], small)
        return (code if code else GO_ON), f_trial
    damping[0] *= damping[1]
    damping[1] *= 2.0
    if small:
        return 2, fun
    if damping[0] > MAX_DAMPING:
        return 6, fun
    return HAND_BACK_ALONE, fun


def normal_equations_lm(fun, counted, x0, *, ftol, xtol, gtol, max_steps: int, factor: bool = False):
    """Run the solver from ``x0``; ``(x, f, code, iterations)`` with ``code`` a key of :data:`MESSAGES`.

    Code 8 (:data:`ILL_CONDITIONED_CODE`) returns the current point as soon
    as the scaled Gram matrix is :data:`ILL_CONDITIONED`, for the caller to
    continue from it with a QR-based solver.  With ``factor`` (and an
    objective with ``normal_factor``) the solver goes on itself instead:
    from then on each pass reduces the Jacobian by a streamed QR
    (:func:`~hammerstein_ctrl.simulate.normal_factor`) and each step is a
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
