"""Automatic initial points for identification, from the data alone.

:func:`initial_points` returns candidate parameter vectors for a structure and
a record, best first, so that ``identify(data, structure)`` needs no ``x0``.
The construction uses that the output error is *linear* in many parameters
once the linear block ``H`` is fixed:

1. **Linear block.**  ``H`` is scanned over stable pole patterns spread over
   the record's bandwidth (from a few periods per record to a fraction of the
   Nyquist frequency): repeated real poles, a lightly damped pair, and poles
   spread by a decade.  For each candidate the output is fitted by linear least
   squares in the columns ``H phi_i(u)``, where ``phi_i`` is the
   nonlinearity's basis when ``g`` is linear in its parameters (Coulomb,
   polynomial, piecewise-linear: the fit is then exact) and ``[u, 1]``
   otherwise (an affine stand-in for ``g``), plus a constant column for an
   output offset and the free responses for an estimated initial state.  The
   best few candidates are refined by Levenberg-Marquardt on this reduced
   (variable-projection) residual, with Kaufman's Jacobian where the columns
   are held; a refinement that comes near an optimum an earlier one reached
   stops there and gives no second start.
2. **Nonlinearity.**  With ``H`` fixed, families linear in their parameters
   take the least-squares coefficients directly; families with a scale
   parameter (tanh, saturation, dead zone) scan their other parameters over
   the input's range (:meth:`~hammerstein_ctrl.blocks.Nonlinearity.shape_grid`)
   and fit the scale by least squares.
3. Offset and initial state come out of the same least-squares solve.

Every simulated signal (each column of a regression, each free response)
counts as one evaluation against the caller's budget (:class:`Budget`).
The regressions are solved block by block (:mod:`~hammerstein_ctrl.optimize._streamed_lstsq`):
on a long record they hold the simulated responses, never an ``N x p`` matrix.

Examples
--------
>>> import numpy as np, control as ct
>>> from hammerstein_ctrl import IOData, HammersteinStructure, LinearStructure, Coulomb
>>> t = np.arange(0, 20, 0.01); u = np.sin(0.7 * t) + 0.5 * np.sin(3.1 * t)
>>> g = 0.8 * u + 0.2 * np.sign(u) + 0.05
>>> y = ct.forced_response(ct.tf([1], [1, 2.0, 5.0]), t, g).outputs
>>> s = HammersteinStructure(LinearStructure(0, 2), Coulomb())
>>> x = initial_points(IOData(u, y, t), s, Budget(1000))[0]
>>> np.round(x, 3).tolist()     # a0, a1, d0, d1, d2
[5.0, 2.0, 0.8, 0.2, 0.05]
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ParameterError
from ..optimize import Budget, BudgetExhausted, lmder
from ..simulate._simulate import MAX_PASS_STATES, free_response, response_blocks, simulate_batch
from ..optimize import _streamed_lstsq as streamed_lstsq
from ..optimize._streamed_lstsq import (constant_column, factor_of_columns, factor_of_rows, factor_sse, held_whole,
                                        independent, orthogonal_part, residual, residual_of_columns, solve_scaled,
                                        triangular_factor)
from ._linear_starts import REFINED_CANDIDATES, _candidate_linear

__all__ = ["check_automatic", "initial_points", "points_for", "nuisance_estimate", "Budget"]

#: Residual evaluations allowed to each reduced refinement (each simulates every drive).
REFINE_EVALUATIONS = 60
#: Largest share of the remaining budget the starts may use.
INITIAL_SHARE = 0.5
#: Largest share of the starts' budget the scan may use, and of what is left
#: the share of the linear refinements (the rest fits the static blocks).
SCAN_SHARE = 0.4
REFINE_SHARE = 0.6
#: Relative tolerance of the reduced refinement.
REFINE_TOL = 1e-8
#: A reduced refinement whose best point comes within ``JOIN_TOL * max(|c|, JOIN_FLOOR)`` of an optimum an
#: earlier one converged to, in every coefficient ``c`` of it, stops there: it would return the same start.
JOIN_TOL = 1e-2
JOIN_FLOOR = 1e-6
#: Smallest singular value, relative to the largest, of a scan regression's column-scaled factor for which
#: its columns count as independent and ``R_pp^2`` as its sum of squared residuals (far above the rounding
#: level :func:`~hammerstein_ctrl.optimize._streamed_lstsq.rank_tolerance`).
CLEAR_RANK = 1e-8
#: Relative step of the forward differences of the reduced Jacobian (MINPACK's, ``sqrt(eps)``).
FORWARD_STEP = float(np.sqrt(np.finfo(float).eps))
#: Size of a regression's columns (``8 N`` bytes each) past which its driving signals and their
#: simulated responses are formed a block of samples at a time instead of held whole.
STREAMED_COLUMNS_BYTES = 1 << 24


# ---------------------------------------------------------------------------
# least squares with H fixed
# ---------------------------------------------------------------------------
class _Drives:
    """Signals that drive ``H`` in a regression (``count`` rows of ``n_samples``).

    Held whole (``array``), or, on a long record, formed from the input a
    block of samples at a time by ``part(begin, stop)`` (``array`` None).
    """

    def __init__(self, count: int, n_samples: int, array=None, part=None):
        self.count, self.n_samples, self.array = count, n_samples, array
        self._part = part if array is None else (lambda begin, stop: array[:, begin:stop])

    @classmethod
    def rows(cls, array) -> "_Drives":
        """Signals already held: an ``(count, N)`` array (or one signal)."""
        array = np.atleast_2d(np.asarray(array, dtype=float))
        return cls(array.shape[0], array.shape[1], array=array)

    @classmethod
    def basis_of(cls, nonlinearity, signal, reg) -> "_Drives | None":
        """The basis of ``nonlinearity`` on ``signal`` (``None`` if it has none); by blocks where ``reg`` streams it."""
        probe = None if nonlinearity is None else nonlinearity.checked_basis(signal[:1])
        if probe is None:
            return None
        if not reg.streams(np.shape(probe)[0]):
            return cls.rows(nonlinearity.checked_basis(signal))
        return cls(np.shape(probe)[0], signal.size,
                   part=lambda begin, stop: nonlinearity.checked_basis(signal[begin:stop]))

    @classmethod
    def signal_of(cls, nonlinearity, signal, params, reg) -> "_Drives":
        """The one signal ``nonlinearity(signal, params)``; by blocks where ``reg`` streams it."""
        if not reg.streams(1):
            return cls.rows(nonlinearity(signal, params)[None, :])
        return cls(1, signal.size, part=lambda begin, stop: nonlinearity(signal[begin:stop], params)[None, :])

    def part(self, begin: int, stop: int) -> np.ndarray:
        """Samples ``begin:stop`` of every signal, ``(count, stop - begin)``."""
        return self._part(begin, stop)

    def blocks(self):
        """Consecutive blocks of :data:`~hammerstein_ctrl.optimize._streamed_lstsq.BLOCK_SAMPLES` samples."""
        size = streamed_lstsq.BLOCK_SAMPLES
        for begin in range(0, self.n_samples, size):
            yield self.part(begin, min(begin + size, self.n_samples))


def _drives(nonlinearity, u, reg) -> _Drives:
    """Signals whose responses span the output with ``H`` fixed: the basis, else ``[u, 1]`` (by blocks where ``reg``
    streams them)."""
    basis = _Drives.basis_of(nonlinearity, u, reg)
    if basis is not None:
        return basis
    if not reg.streams(2):
        return _Drives.rows(np.stack([u, np.ones_like(u)]))
    return _Drives(2, u.size, part=lambda begin, stop: np.stack([u[begin:stop], np.ones(stop - begin)]))


class _StreamedColumns:
    """A regression's columns formed a block of samples at a time, never held whole.

    The responses of ``H(theta)`` to the drives (or, with ``theta`` None, the
    drives themselves), then a constant column and the free responses, as
    :meth:`_Regression.columns` holds them on a shorter record.
    """

    def __init__(self, reg, theta, drives: _Drives, constant: bool, free: bool):
        self.drives, self.constant, self.free = drives, constant, free
        self.dt, self.intersample = reg.data.dt, reg.data.intersample
        self.n_free = reg.structure.linear.den_order if free else 0
        self.width = drives.count + int(constant) + self.n_free
        self.block = None if theta is None else [r[0] for r in reg.structure.linear.coefficients(theta)]

    def _sources(self):
        """Blocks ``(L, count [+ n_free])`` of the simulated (or plain) drives."""
        if self.block is None:
            return (part.T for part in self.drives.blocks())
        return response_blocks(*self.block, self.dt, self.drives.blocks(), self.drives.count,
                               self.drives.n_samples, free=self.free, intersample=self.intersample)

    def blocks(self):
        """``(begin, X)``: the columns at the next block of samples (one reused buffer)."""
        k = self.drives.count
        buffer = np.empty((min(streamed_lstsq.BLOCK_SAMPLES, self.drives.n_samples), self.width))
        begin = 0
        for Y in self._sources():
            X = buffer[:Y.shape[0]]
            X[:, :k] = Y[:, :k]
            if self.constant:
                X[:, k] = 1.0
            X[:, k + int(self.constant):] = Y[:, k:]
            yield begin, X
            begin += Y.shape[0]

    def factor(self, y) -> np.ndarray:
        """The triangular factor of ``[X y]`` (:func:`~hammerstein_ctrl.optimize._streamed_lstsq.triangular_factor`);
        NaN if not finite."""
        try:
            return factor_of_columns(self.blocks(), y, self.width)
        except ParameterError:          # a block that cannot be simulated: no fit, as a non-finite column
            return np.full((self.width + 1, self.width + 1), np.nan)

    def residual(self, w, y) -> np.ndarray:
        """``y - X w``, formed block by block."""
        return residual_of_columns(self.blocks(), w, y)


class _Regression:
    """Least-squares fit of ``y`` by responses of one linear block (and nuisance columns).

    With ``affine_output`` (structures with an output nonlinearity, whose
    affine stand-in has a constant term) a constant column is always present.
    Columns are lists of ``(k, N)`` row arrays (:mod:`~hammerstein_ctrl.optimize._streamed_lstsq`):
    the regression matrix is never formed.
    """

    def __init__(self, structure, data, budget: Budget, *, affine_output: bool = False):
        self.structure, self.data, self.budget = structure, data, budget
        self.y = np.asarray(data.y, dtype=float)
        self.constant = structure.offset or affine_output

    def streams(self, count: int) -> bool:
        """Whether ``count`` drives and the columns of their regression are formed a block of samples at a time.

        The columns are the drives' responses and the free responses of an
        estimated initial state; blocks of more than
        :data:`~hammerstein_ctrl.simulate._simulate.MAX_PASS_STATES` states (which
        the compiled passes do not take) are held whole.
        """
        n = self.structure.linear.den_order
        columns = count + (n if self.free_columns else 0)
        return 1 <= n <= MAX_PASS_STATES and self.y.size * self.y.itemsize * columns > STREAMED_COLUMNS_BYTES

    def _responses(self, num, den, signals, out=None) -> np.ndarray:
        self.budget.charge(num.shape[0])
        return simulate_batch(num, den, signals, self.data.dt, intersample=self.data.intersample, out=out)

    def responses(self, thetas, v) -> np.ndarray:
        """Responses ``(k, N)`` of ``H(theta)`` to the one signal ``v`` for each of the ``k`` rows of ``thetas``
        (``k`` counted evaluations)."""
        num, den = zip(*(self.structure.linear.coefficients(theta) for theta in thetas))
        return self._responses(np.vstack(num), np.vstack(den), v)

    def simulate(self, theta, drives, out=None) -> np.ndarray:
        """Responses ``(k, N)`` of ``H(theta)`` to each drive (``k`` counted evaluations), in ``out`` if given."""
        num, den = self.structure.linear.coefficients(theta)
        k = drives.shape[0]
        return self._responses(np.repeat(num, k, 0), np.repeat(den, k, 0), drives, out)

    @property
    def free_columns(self) -> bool:
        """Whether :meth:`columns` adds the free responses of an estimated initial state."""
        return self.structure.initial_state == "estimate" and self.structure.output_nonlinearity is None

    def evaluations(self, drives: _Drives) -> int:
        """Simulated signals (budget charged) of one :meth:`columns` call."""
        return drives.count + (self.structure.linear.den_order if self.free_columns else 0)

    def columns(self, theta, drives):
        """Responses of ``H(theta)`` to each drive, then constant and free-response columns (:meth:`factor_at`
        writes the same rows in this order).

        A list of arrays, or, for drives formed by blocks, :class:`_StreamedColumns`.
        """
        drives = drives if isinstance(drives, _Drives) else _Drives.rows(drives)
        if drives.array is None:
            self.budget.charge(self.evaluations(drives))
            return _StreamedColumns(self, theta, drives, self.constant, self.free_columns)
        parts = [self.simulate(theta, drives.array)]
        if self.constant:
            parts.append(constant_column(self.y.size))
        if self.free_columns:
            parts.append(self._free_rows(theta))
        return parts

    def _free_rows(self, theta) -> np.ndarray:
        """The free responses of ``H(theta)`` (``(n, N)``, ``n`` counted evaluations): the estimated state's columns."""
        num, den = self.structure.linear.coefficients(theta)
        self.budget.charge(self.structure.linear.den_order)
        return free_response(num[0], den[0], self.data.dt, self.y.size).T

    def static_columns(self, signals):
        """The signals themselves (``(k, N)``, or :class:`_Drives`), then the offset column."""
        signals = signals if isinstance(signals, _Drives) else _Drives.rows(signals)
        if signals.array is None:
            return _StreamedColumns(self, None, signals, self.structure.offset, False)
        parts = [signals.array]
        if self.structure.offset:
            parts.append(constant_column(self.y.size))
        return parts

    def factor(self, columns) -> np.ndarray:
        """The triangular factor of ``[X y]`` (:func:`~hammerstein_ctrl.optimize._streamed_lstsq.triangular_factor`)."""
        return columns.factor(self.y) if isinstance(columns, _StreamedColumns) else triangular_factor(columns, self.y)

    def factor_at(self, theta, drives: _Drives) -> np.ndarray:
        """:meth:`factor` of :meth:`columns` at ``theta``, the same bits; a factor held whole has its responses
        simulated straight into the matrix that is factored (no copy of the columns)."""
        drives = drives if isinstance(drives, _Drives) else _Drives.rows(drives)
        width = self.evaluations(drives) + self.constant         # the columns of columns(), in its order
        if drives.array is None or not held_whole(width, self.y.size):
            return self.factor(self.columns(theta, drives))
        whole = np.empty((width + 1, self.y.size))
        self.simulate(theta, drives.array, out=whole[:drives.count])
        if self.constant:
            whole[drives.count] = 1.0
        if self.free_columns:
            whole[drives.count + self.constant:width] = self._free_rows(theta)
        whole[-1] = self.y
        return factor_of_rows(whole)

    def residual(self, columns, w) -> np.ndarray:
        """``y - X w``."""
        return columns.residual(w, self.y) if isinstance(columns, _StreamedColumns) else residual(columns, w, self.y)

    def fit_factor(self, R) -> tuple[np.ndarray | None, float]:
        """Coefficients and sum of squared residuals from the factor ``R`` of ``[X y]`` (``(None, inf)`` if not
        finite)."""
        w = solve_scaled(R, self.y.size)
        return (None, np.inf) if w is None else (w, factor_sse(R, w))

    def fit(self, columns) -> tuple[np.ndarray | None, float]:
        """Coefficients and sum of squared residuals of the least-squares fit (``(None, inf)`` if not finite)."""
        return self.fit_factor(self.factor(columns))


def _reduced_sse(reg: _Regression, theta, drives) -> float:
    """The sum of squared residuals of ``H(theta)``'s regression (inf if not finite).

    Where the columns are independent well above the rounding level
    (:func:`~hammerstein_ctrl.optimize._streamed_lstsq.independent` at
    :data:`CLEAR_RANK`) it is ``R_pp^2``, which needs no solve; columns
    dependent but for rounding (a constant drive's response beside an offset
    and free responses) take the solve, which drops those directions.
    """
    R = reg.factor_at(theta, drives)
    if independent(R, CLEAR_RANK):         # False where R is not finite
        return float(R[-1, -1] ** 2)
    return reg.fit_factor(R)[1]


class _Joined(Exception):
    """A refinement came within :data:`JOIN_TOL` of an optimum an earlier refinement reached."""


class _Fit:
    """One evaluation of the reduced residual: the point, its coefficients (``None``: no finite fit), and (for
    Kaufman's Jacobian) the columns and their factor."""

    def __init__(self, theta, w, columns=None, R=None):
        self.theta, self.w, self.columns, self.R = np.array(theta, dtype=float), w, columns, R


class _ReducedProblem:
    """The variable-projection residual over the linear coefficients, within a budget of simulated signals.

    Its Jacobian (:meth:`jacobian`) is Kaufman's: the simulated response to
    the fitted drive ``v = sum w_i d_i``, differentiated by forward
    differences in one batch (with ``H(theta) v`` itself, so that the
    differences see one rounding), less its fit by the columns.  One Jacobian
    simulates ``p + 1`` signals where forward differences of the whole
    reduced residual re-ran every drive's response and the regression ``p``
    times.  It needs the columns held and no free responses; otherwise
    :attr:`kaufman` is False and MINPACK differentiates.

    The search stops (:class:`_Joined`) when a new best point comes within
    :data:`JOIN_TOL` of one of the ``known`` optima.
    """

    def __init__(self, reg: _Regression, drives: _Drives, evaluations: int, known=()):
        self.reg, self.drives, self.known = reg, drives, [np.asarray(k, dtype=float) for k in known]
        self.left = evaluations * reg.evaluations(drives)         # simulated signals this refinement may use
        self.kaufman = drives.array is not None and not reg.free_columns
        self.big = np.sqrt(np.finfo(float).max) / max(reg.y.size, 1)
        self.best_sse = np.inf
        self.last = self.kept = None        # the last evaluation, and the best finite one (its sse: best_sse)

    def _spend(self, signals: int):
        if signals > self.left:
            raise BudgetExhausted("refinement budget spent")
        self.left -= signals

    def _evaluate(self, theta) -> tuple[_Fit | None, np.ndarray]:
        self._spend(self.reg.evaluations(self.drives))
        columns = self.reg.columns(theta, self.drives)
        R = self.reg.factor(columns)
        w = solve_scaled(R, self.reg.y.size)
        if w is None:
            self.last = _Fit(theta, None)
            return self.last, np.full(self.reg.y.size, self.big)
        r = self.reg.residual(columns, w)
        self.last = _Fit(theta, w, *((columns, R) if self.kaufman else ()))
        sse = float(r @ r)
        if sse < self.best_sse:
            self.best_sse, self.kept = sse, self.last
            self._check_joined(self.kept.theta)
        return self.last, r

    def _check_joined(self, theta):
        if any(np.all(np.abs(theta - k) <= JOIN_TOL * np.maximum(np.abs(k), JOIN_FLOOR)) for k in self.known):
            raise _Joined

    def residual(self, theta) -> np.ndarray:
        """The reduced residual at ``theta``."""
        return self._evaluate(theta)[1]

    def _fit_at(self, theta) -> _Fit:
        for fit in (self.last, self.kept):
            if fit is not None and np.array_equal(fit.theta, theta):
                return fit
        return self._evaluate(theta)[0]

    def jacobian(self, theta) -> np.ndarray:
        """Kaufman's Jacobian of :meth:`residual` at ``theta``, as rows (``(p, N)``; zero rows where the fit or
        a difference is not finite)."""
        fit = self._fit_at(theta)
        theta = np.asarray(theta, dtype=float)
        if fit.w is None:
            return np.zeros((theta.size, self.reg.y.size))
        self._spend(theta.size + 1)
        v = fit.w[:self.drives.count] @ self.drives.array
        h = FORWARD_STEP * np.where(theta == 0, 1.0, np.abs(theta))
        Y = self.reg.responses(np.vstack([theta, theta + np.diag(h)]), v)
        with np.errstate(all="ignore"):
            D = (Y[1:] - Y[0]) / h[:, None]
        bad = ~np.all(np.isfinite(D), axis=1)
        D[bad] = 0.0
        J = -orthogonal_part(fit.columns, fit.R, D)
        J[bad] = 0.0
        return J


def _refine_linear(reg: _Regression, theta, drives, limit: int = REFINE_EVALUATIONS,
                   known=()) -> tuple[np.ndarray, float, bool] | None:
    """Levenberg-Marquardt on the variable-projection residual over the linear coefficients.

    MINPACK's lmder (:func:`~hammerstein_ctrl.optimize.lmder`) with Kaufman's Jacobian
    (:class:`_ReducedProblem`) where the columns are held, else with its own
    forward differences.  At most :data:`REFINE_EVALUATIONS` residuals' worth
    of signals are simulated.  Returns ``(theta, sse, converged)``: the
    best point seen, and whether MINPACK reported convergence; ``None`` when
    the search comes within :data:`JOIN_TOL` of one of the optima ``known``
    (it would only reach that start again).
    """
    problem = _ReducedProblem(reg, drives, int(min(REFINE_EVALUATIONS, limit,
                                                   reg.budget.remaining // reg.evaluations(drives))), known)
    if theta.size == 0 or problem.left <= (theta.size + 1) * reg.evaluations(drives):
        return theta, _reduced_sse(reg, theta, drives), False
    jacobian = problem.jacobian if problem.kaufman else None
    try:
        res = lmder(problem.residual, jacobian, theta, xtol=REFINE_TOL, ftol=REFINE_TOL, gtol=REFINE_TOL)
        if problem.kept is None:                # no finite fit anywhere: nothing converged
            return theta, np.inf, False
        return res.x, float(res.fvec @ res.fvec), res.converged
    except BudgetExhausted:
        return (theta if problem.kept is None else problem.kept.theta), problem.best_sse, False
    except _Joined:
        return None


def _fit_static(reg: _Regression, nl, signal, columns) -> tuple[np.ndarray, np.ndarray] | None:
    """``(parameters of nl, remaining coefficients)`` fitting ``y`` by ``columns(nl's regressors)``.

    Families linear in their parameters are solved directly; families with a
    scale parameter scan their shape (:meth:`~Nonlinearity.shape_grid`) over the
    range of ``signal`` and fit the scale.
    """
    basis = _Drives.basis_of(nl, signal, reg)
    if basis is not None:
        w, _ = reg.fit(columns(basis))
        return None if w is None else (w[:nl.n_params], w[nl.n_params:])
    best = None
    for p in nl.shape_grid(signal):
        w, sse = reg.fit(columns(_Drives.signal_of(nl, signal, p, reg)))
        if w is not None and (best is None or sse < best[0]):
            q = p.copy()
            q[nl.scale_index] = w[0]
            best = (sse, q, w[1:])
    return None if best is None else (best[1], best[2])


def _input_candidates(reg: _Regression, theta, u):
    """Candidate full parameter vectors of ``g``: its least-squares fit through ``H``, then
    (with an output nonlinearity, where ``g`` has unit gain) every shape of its scan."""
    g = reg.structure.input_nonlinearity
    fitted = _fit_static(reg, g, u, lambda d: reg.columns(theta, d))
    if fitted is None:
        return []
    first = (np.array(fitted[0], dtype=float), fitted[1])
    if reg.structure.output_nonlinearity is None:
        return [first]
    grid = g.shape_grid(u)
    shapes = [first[0]] + ([] if grid is None else list(grid))
    for p in shapes:
        p[g.gain_index] = 1.0
    return [(p, np.empty(0)) for p in shapes]


def _output_fit(reg: _Regression, theta, v):
    """``(h parameters, offset coefficients, sse)`` of ``h`` fitted to ``z = H v``, or ``None``."""
    z = reg.simulate(theta, np.asarray(v, dtype=float)[None, :])[0]
    fitted = _fit_static(reg, reg.structure.output_nonlinearity, z, reg.static_columns)
    if fitted is None:
        return None
    h, offset = fitted
    with np.errstate(all="ignore"):
        r = reg.y - (reg.structure.output_nonlinearity(z, h) + (offset[0] if offset.size else 0.0))
    return h, offset, float(r @ r) if np.all(np.isfinite(r)) else np.inf


def _static_blocks(reg: _Regression, theta, u):
    """``(free g parameters, h parameters, nuisance)`` with ``H(theta)`` fixed, or ``None``.

    Input block: fitted through ``H``.  Output block: fitted to ``z = H g(u)``
    for each candidate ``g`` (unit gain in a Hammerstein-Wiener structure, ``h``
    then carries the gain).  The initial state of a structure with an output
    nonlinearity starts at zero (it enters nonlinearly).
    """
    s = reg.structure
    if s.output_nonlinearity is None:
        candidates = _input_candidates(reg, theta, u)
        return None if not candidates else (candidates[0][0], np.empty(0), candidates[0][1])
    inputs = [(None, u)] if s.input_nonlinearity is None else (  # one signal at a time
        (p, s.input_nonlinearity(u, p)) for p, _ in _input_candidates(reg, theta, u))
    best = None
    for p, v in inputs:
        fitted = _output_fit(reg, theta, v)
        if fitted is not None and (best is None or fitted[2] < best[2][2]):
            best = (p, v, fitted)
    if best is None:
        return None
    p, _, (h, offset, _) = best
    g_free = np.empty(0) if p is None else np.delete(p, s.input_nonlinearity.gain_index)
    state = np.zeros(s.linear.den_order if s.initial_state == "estimate" else 0)
    return g_free, h, np.concatenate([offset, state])


def _static_evaluations(reg: _Regression, u) -> int:
    """Evaluations one :func:`_static_blocks` call charges: the fit (or scan) of ``g``, then one simulation per
    candidate signal of an output nonlinearity."""
    s = reg.structure
    free = s.linear.den_order if reg.free_columns else 0
    g, evaluations, candidates = s.input_nonlinearity, 0, 1
    if g is not None:
        basis = g.checked_basis(u[:1])
        grid = g.shape_grid(u) if basis is None or s.output_nonlinearity is not None else None
        shapes = 0 if grid is None else len(grid)
        evaluations = np.shape(basis)[0] + free if basis is not None else shapes * (1 + free)
        candidates = 1 + shapes
    return evaluations + (candidates if s.output_nonlinearity is not None else 0)


def _assemble(structure, theta, g_params, h_params, nuisance) -> np.ndarray:
    return structure.normalize(np.concatenate([theta, g_params, h_params, nuisance]))


def _nuisance_words(structure) -> list[str]:
    return (["offset"] if structure.offset else []) + (["initial state"] if structure.initial_state == "estimate"
                                                       else [])


def check_automatic(structure, u) -> None:
    """Refuse, naming the whole x0 to give, a structure whose maps have neither a basis nor a scan."""
    for nl in (structure.input_nonlinearity, structure.output_nonlinearity):
        # whether there is a basis shows on one sample (the whole basis of a long record takes 8 p bytes per sample)
        if nl is not None and nl.checked_basis(u[:1]) is None and (nl.shape_grid(u) is None or nl.scale_index is None):
            raise ParameterError(
                f"no automatic initial point for the {nl.name!r} nonlinearity (it has neither a basis nor a "
                f"scan); give x0 = [{', '.join(structure.param_names[:structure.n_core])}]"
                + (f" (the {' and '.join(_nuisance_words(structure))} then follow by least squares; or the whole "
                   f"[{', '.join(structure.param_names)}])" if structure.n_params > structure.n_core else ""))


def _ranked_starts(reg: _Regression, groups: dict, drives: _Drives, count: int) -> list:
    """``(theta, reduced sse)`` of the best ``count`` scan candidates of each group, interleaved by rank.

    Each group's best comes first, then each group's second, and so on.  A
    small budget thins the scan (every ``stride``-th candidate) rather than losing it.
    """
    total = sum(len(rows) for rows in groups.values()) * reg.evaluations(drives)
    stride = max(1, int(np.ceil(total / max(reg.budget.remaining * SCAN_SHARE, 1.0))))
    ranked = []
    for rows in groups.values():
        rows = rows[::stride]
        scored = sorted(((_reduced_sse(reg, theta, drives), i) for i, theta in enumerate(rows)))
        ranked.append([(rows[i], sse) for sse, i in scored[:count]])
    return [group[rank] for rank in range(count) for group in ranked if rank < len(group)]


def _refine_in_turn(reg: _Regression, starts: list, drives: _Drives, reserve: int = 0) -> list:
    """``(theta, sse)`` of each start refined in turn, best first, each with up to :data:`REFINE_EVALUATIONS`.

    The refinements share :data:`REFINE_SHARE` of what is left, less
    ``reserve`` (the static fits that follow); a start that needs many
    steps to converge (a scan candidate far from the optimum) gets them,
    where an even split of the share left each a few steps and none
    converged.  Starts past the share keep their scan value.  A refinement
    that joins an optimum an earlier one converged to is dropped (it would
    give the same start again).
    """
    remaining = reg.budget.remaining
    pool, begin = min(REFINE_SHARE * remaining, remaining - reserve), reg.budget.nfev
    refined, reached = [], []
    for theta, sse in starts:
        left = (REFINE_EVALUATIONS if pool == np.inf
                else int((pool - (reg.budget.nfev - begin)) // reg.evaluations(drives)))
        if left <= theta.size + 1:          # no step fits: the scan's value stands
            refined.append((theta, sse))
            continue
        out = _refine_linear(reg, theta, drives, min(REFINE_EVALUATIONS, left), reached)
        if out is not None:
            refined.append(out[:2])
            if out[2]:
                reached.append(out[0])
    return sorted(refined, key=lambda item: item[1])


def initial_points(data, structure, budget: Budget, *, count: int = REFINED_CANDIDATES) -> list[np.ndarray]:
    """Candidate starting betas for ``structure`` on ``data``, best first.

    Parameters
    ----------
    data : IOData
    structure : HammersteinStructure, WienerStructure or HammersteinWienerStructure
    budget : Budget
        Shared evaluation counter; every simulated candidate costs one.
    count : int
        How many scan candidates to refine and return (at most).

    Returns
    -------
    list of ndarray
        Full beta vectors (with offset and initial state where the structure
        estimates them).  Empty if the budget runs out first.

    Raises
    ------
    ParameterError
        For a nonlinearity with neither a basis nor a scan (e.g. a
        :class:`~hammerstein_ctrl.blocks.CustomNonlinearity`): give ``x0``.
    """
    u = np.asarray(data.u, dtype=float)
    check_automatic(structure, u)
    # the starts may use a share of what is left; the refinements need the rest
    own = Budget(int(INITIAL_SHARE * budget.remaining) if np.isfinite(budget.remaining) else None)
    reg = _Regression(structure, data, own, affine_output=structure.output_nonlinearity is not None)
    drives = _drives(structure.input_nonlinearity, u, reg)
    points = []
    try:
        starts = _ranked_starts(reg, _candidate_linear(structure.linear, data, drives), drives, count)
        refined = _refine_in_turn(reg, starts, drives, _static_evaluations(reg, u))    # the best start's static fit
        del drives  # the static fits form their own basis
        reg.constant = structure.offset
        for theta, _ in refined[:count]:
            fitted = _static_blocks(reg, theta, u)
            if fitted is not None:
                points.append(_assemble(structure, theta, *fitted))
    except BudgetExhausted:
        pass  # the points completed so far
    budget.charge(own.nfev)
    return points


def points_for(data, structure, thetas, budget: Budget) -> list[np.ndarray]:
    """Starting betas with the linear block at each of ``thetas`` (its parameters) and the static blocks (and
    nuisances) fitted to it, as :func:`initial_points` completes its own candidates; those that fail are left
    out, and so is what the budget cannot pay for."""
    u = np.asarray(data.u, dtype=float)
    check_automatic(structure, u)
    own = Budget(int(budget.remaining) if np.isfinite(budget.remaining) else None)
    reg = _Regression(structure, data, own, affine_output=structure.output_nonlinearity is not None)
    reg.constant = structure.offset
    points = []
    try:
        for theta in thetas:
            fitted = _static_blocks(reg, np.asarray(theta, dtype=float), u)
            if fitted is not None:
                points.append(_assemble(structure, np.asarray(theta, dtype=float), *fitted))
    except BudgetExhausted:
        pass
    budget.charge(own.nfev)
    return points


def nuisance_estimate(data, structure, core, budget: Budget) -> np.ndarray:
    """Least-squares offset and initial state for given block parameters ``core``.

    Returns the full beta (``core`` followed by the estimates); ``core`` itself
    when the structure estimates neither.
    """
    core = np.asarray(core, dtype=float)
    if structure.n_params == core.size:
        return core.copy()
    extra = np.zeros(structure.n_params - core.size)
    if structure.output_nonlinearity is not None:  # enters nonlinearly: start at zero
        return np.concatenate([core, extra])
    k = structure.linear.n_params
    reg = _Regression(structure, data, budget)
    v = structure.input_nonlinearity(np.asarray(data.u, dtype=float), core[k:])
    w, _ = reg.fit(reg.columns(core[:k], v[None, :]))
    return np.concatenate([core, extra if w is None else w[1:]])
