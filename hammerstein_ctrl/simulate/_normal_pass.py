"""Normal equations of a point and its forward-difference neighbours, in one compiled pass (the third job).

:func:`normal_pass` returns ``r @ r``, ``J.T r`` and ``J.T J`` of a candidate
and its neighbours without forming the Jacobian; :func:`normal_factor` the
Jacobian's triangular factor streamed out of the pass.  Candidates run in the
SIMD lanes of one loop, in groups when they do not fit one pass.  The same
lane passes give the responses the initial-point regressions use a block of
samples at a time (:func:`response_blocks`, :func:`free_response`).  Public
through :mod:`hammerstein_ctrl.simulate`.
"""

from __future__ import annotations

import numpy as np

from .._checks import check_intersample, check_transfer_function
from .._linalg import single_threaded_blas
from ..exceptions import DataError, ParameterError
from .._kernels import (MAX_LANE_BASIS, MAX_NORMAL_LANES, MAX_PASS_STATES, get_normal_kernel)
from ..optimize._normal_equations import NormalEquations, from_difference_sums, from_factor
from ._discretize import (_coefficient_rows, _discretized, _offset_rows, _state_rows)
from ._batch import (_apply_python_map, _measured, _output_map, output_terms, simulate_batch)

__all__ = ["normal_pass", "normal_factor", "response_blocks", "free_response", "GROUPS_MIN_BYTES"]


def normal_pass(num, den, dt: float, y, P, blocks, steps, *, x0=None, offset=None,
                intersample: str = "foh", output_map=None) -> NormalEquations | None:
    """Normal equations of a point and its forward-difference neighbours, in one compiled pass.

    Row 0 of the candidates is the point, row ``j + 1`` the point with
    parameter ``j`` moved by ``steps[j]``; candidate ``g``'s intermediate
    signal is ``P[g] @ Phi``, with the basis ``Phi`` (``K x N``) given as
    consecutive blocks of samples, so a long record's basis never has to be
    held whole.  No ``p x N`` Jacobian is formed.

    Parameters
    ----------
    num, den : array_like, shape (L, l+1) and (L, n+1), 1 <= L <= p+1
        The candidates' linear blocks; candidates past the first ``L`` share
        row 0's (neighbours that move only the signal, the offset or the
        initial state: one discretisation serves them all).
    dt : float
    y : ndarray, shape (N,)
        Measured output.
    P : array_like, shape (p+1, K)
        Each candidate's coefficients of the basis.
    blocks : iterable of ndarray, shape (K, L_i)
        The basis, in blocks of samples that together span the record.
    steps : array_like, shape (p,)
        The forward-difference steps.
    x0, offset, intersample, output_map
        As for :func:`simulate_batch` (an output map's parameters: one row per candidate).

    Returns
    -------
    NormalEquations or None
        ``None`` if the pass does not apply (no state or more than
        :data:`MAX_PASS_STATES` states, a candidate whose coefficients
        cannot be discretised, or, past one pass, a candidate whose signal
        needs more than :data:`~hammerstein_ctrl._kernels.MAX_LANE_BASIS`
        basis rows).  More than :data:`~hammerstein_ctrl._kernels.MAX_NORMAL_LANES`
        candidates or :data:`~hammerstein_ctrl._kernels.MAX_LANE_BASIS`
        basis signals run in groups of passes side by side, and an output
        map without a compiled form is applied in numpy; either way the
        lanes' outputs leave the pass a block of samples at a time.  The
        sums may be non-finite if a simulation overflows.

    Raises
    ------
    ParameterError
        If the shapes of ``steps``, ``P`` and ``den`` do not fit each other.
    DataError
        If the record is empty or the blocks do not cover it.
    """
    steps = _pass_steps(steps, P, den)
    lane_pass = _lane_pass(num, den, dt, y, P, x0, offset, intersample, output_map, outputs=False)
    if lane_pass is None:
        return None
    acc = np.zeros(1 + (lane_pass.lanes - 1) * lane_pass.lanes)
    if lane_pass.streams_outputs:       # the lanes' outputs leave the pass (mapped in numpy, or lane groups)
        with single_threaded_blas():    # small products of each block: threads would only spin
            _sum_blocks(lane_pass.difference_blocks(blocks), lane_pass.lanes - 1, acc)
        if not lane_pass.signals_finite():
            acc[0] = np.nan
    else:
        for begin, Phi, y_block in lane_pass.blocks(blocks):
            lane_pass.run(Phi, y_block, begin, acc)
    return from_difference_sums(acc, steps)


def _sum_blocks(parts, p: int, acc):
    """Add ``[r @ r, D.T @ r, D.T @ D]`` of each block ``[D r]`` to ``acc`` (the layout of the compiled sums)."""
    with np.errstate(all="ignore"):
        for part in parts:
            D, r = part[:, :p], part[:, p]
            acc[0] += r @ r
            acc[1:1 + p] += D.T @ r
            acc[1 + p:] += (D.T @ D).ravel()


def normal_factor(num, den, dt: float, y, P, blocks, steps, *, x0=None, offset=None,
                  intersample: str = "foh", output_map=None) -> NormalEquations | None:
    """:func:`normal_pass` with the Jacobian reduced by a streamed QR instead of summed into ``J.T J``.

    The lanes' outputs come out of the compiled pass :data:`~hammerstein_ctrl.optimize._streamed_lstsq.BLOCK_SAMPLES`
    samples at a time; each block of ``[D r]`` (the neighbours' differences
    and the residual) is factored and merged up a tree
    (:func:`~hammerstein_ctrl.optimize._streamed_lstsq.factor_of_blocks`), so the
    result keeps a QR factorisation's accuracy where ``J.T J`` would square
    the condition number, in memory bounded per sample.

    Returns
    -------
    NormalEquations or None
        With ``factor = (R, qtr)``: ``J = Q R`` and ``qtr = Q.T r``
        (``gram = R.T R``, ``gradient = R.T qtr``); ``None`` where
        :func:`normal_pass` gives ``None``, and NaN sums if a simulation
        overflows.
    """
    from ..optimize._streamed_lstsq import factor_of_blocks     # imports scipy.linalg (its LAPACK): on first use

    steps = _pass_steps(steps, P, den)
    lane_pass = _lane_pass(num, den, dt, y, P, x0, offset, intersample, output_map, outputs=True)
    if lane_pass is None:
        return None
    p = lane_pass.lanes - 1
    with single_threaded_blas():        # the blocks' products (the QR is the compiled core's): threads would only spin
        R = factor_of_blocks(lane_pass.difference_blocks(blocks), p + 1)
    if not lane_pass.signals_finite():   # a signal sample that reached no output
        R[:] = np.nan
    return from_factor(R, steps)


#: Size of the candidates' outputs (``8 (p + 1) N`` bytes) past which normal equations that do not fit
#: one compiled pass run as lane groups; below it stored residual vectors are quicker (17 lanes at
#: 4 000 samples: 0.6 ms against 1.6 ms) and take no more than this.
GROUPS_MIN_BYTES = 1 << 24


def _pass_steps(steps, P, den) -> np.ndarray:
    """The forward-difference steps of a pass, checked against the candidates' basis coefficients and blocks."""
    steps = np.ascontiguousarray(steps, dtype=float)
    lanes = steps.size + 1
    if steps.ndim != 1 or np.ndim(P) != 2 or np.shape(P)[0] != lanes or not 1 <= np.shape(den)[0] <= lanes:
        raise ParameterError(f"a normal-equation pass needs one row of basis coefficients per candidate "
                             f"(p + 1 = {lanes}) and at most as many linear blocks, got steps {steps.shape}, "
                             f"P {np.shape(P)}, den {np.shape(den)}")
    return steps


def _lane_pass(num, den, dt, y, P, x0, offset, intersample, output_map, outputs: bool):
    """One compiled pass over every candidate, or lane groups where they do not fit one (``None``: neither applies).

    One pass takes up to :data:`~hammerstein_ctrl._kernels.MAX_NORMAL_LANES`
    candidates and :data:`~hammerstein_ctrl._kernels.MAX_LANE_BASIS` basis
    signals; past either, :class:`_LaneGroups` runs several passes side by
    side over each block of samples, their outputs leaving them, on records
    whose candidates' outputs would take more than :data:`GROUPS_MIN_BYTES`
    (shorter ones are quicker from stored residual vectors: ``None``).
    """
    lanes, K = np.shape(P)
    if not _fits_one_pass(lanes, K) and lanes * np.size(y) * np.dtype(float).itemsize <= GROUPS_MIN_BYTES:
        return None
    return _lane_pass_or_groups(num, den, dt, y, P, x0, offset, intersample, output_map, np.size(y), outputs)


def _fits_one_pass(lanes: int, K: int) -> bool:
    """Whether ``lanes`` candidates on ``K`` basis signals fit one compiled pass."""
    return lanes <= MAX_NORMAL_LANES and 1 <= K <= MAX_LANE_BASIS


def _lane_pass_or_groups(num, den, dt, y, P, x0, offset, intersample, output_map, n_samples: int,
                         outputs: bool = True):
    """One :class:`_LanePass` where the candidates fit one, else :class:`_LaneGroups` (``None`` if neither applies)."""
    lanes, K = np.shape(P)
    if _fits_one_pass(lanes, K):
        return _LanePass.prepare(num, den, dt, y, P, x0, offset, intersample, output_map, outputs, n_samples)
    if K == 0:
        return None
    return _LaneGroups.prepare(num, den, dt, y, np.ascontiguousarray(P, dtype=float), x0, offset, intersample,
                               output_map, n_samples)


class _LanePass:
    """The checked arguments of a compiled pass over a point and its neighbours, and its running state."""

    @classmethod
    def prepare(cls, num, den, dt, y, P, x0, offset, intersample, output_map, outputs: bool, n_samples=None):
        """The pass over the candidates (rows of ``P``), or ``None`` where it does not apply (see :func:`normal_pass`).

        ``y`` is the measured output, or ``None`` for outputs only (``outputs``) over ``n_samples``.
        """
        hold = check_intersample(intersample)
        P = np.ascontiguousarray(P, dtype=float)
        lanes, n, K = P.shape[0], np.shape(den)[-1] - 1, P.shape[-1]
        if not 2 <= lanes <= MAX_NORMAL_LANES or not 1 <= n <= MAX_PASS_STATES or not 1 <= K <= MAX_LANE_BASIS:
            return None
        E, C, D, ok, clean = _discretized(num, den, dt)
        if not clean and not ok.all():
            return None
        outmap, map_args, fallback = _output_map(output_map, lanes, n)
        self = cls()
        self.lanes, self.K, self.P = lanes, K, P
        self.X, self.Y0 = np.array(_state_rows(x0, lanes, n)), _offset_rows(offset, lanes)  # X is written: a copy
        direct, has_offset = output_terms(num, den, D, offset, self.Y0)
        # an output map without a compiled form: the lanes' linear outputs leave the pass, and the map
        # (then the offset) is applied to them a block at a time (python_map)
        self.python_map = fallback
        # whether the lanes' outputs leave the pass (difference_blocks) instead of being summed in it
        self.streams_outputs = fallback is not None
        self.kernel = get_normal_kernel(n, hold, lanes, K, direct, has_offset and not fallback, outmap,
                                        outputs or bool(fallback))
        self.E, self.C, self.D = E, C, D
        self.HP, self.HX = map_args or (np.zeros((lanes, 0)), np.zeros(0))
        self.VP = np.zeros(lanes)
        self.y = None if y is None else _measured(y, np.size(y))
        self.n_samples = n_samples if y is None else self.y.size
        return self

    def signals_finite(self) -> bool:
        """Whether every lane's last signal sample is finite (one that reached no output yet may not be)."""
        return bool(np.isfinite(self.VP).all())

    def run(self, Phi, y_block, begin: int, acc):
        """One block of samples through the compiled pass (the lanes' state carried over)."""
        self.kernel(self.E, self.C, self.D, self.X, self.Y0, self.VP, self.P, Phi, self.HP, self.HX, y_block,
                    begin, acc)

    def blocks(self, blocks):
        """``(begin, Phi, y)`` of each block of the basis, checked against the record, which they must cover."""
        return _checked_blocks(blocks, self.K, self.y, self.n_samples)

    def output_blocks(self, blocks):
        """``(y, Yh)``: the lanes' outputs (``Yh[i, lane]``) a block of at most ``BLOCK_SAMPLES`` samples at a time."""
        from ..optimize._streamed_lstsq import BLOCK_SAMPLES

        outputs = np.empty((BLOCK_SAMPLES, self.lanes))
        for begin, Phi, y_block in self.blocks(blocks):
            for a in range(0, Phi.shape[1], BLOCK_SAMPLES):
                b = min(a + BLOCK_SAMPLES, Phi.shape[1])
                Yh = outputs[:b - a]
                self.run(np.ascontiguousarray(Phi[:, a:b]), y_block[a:b], begin + a, Yh)
                if self.python_map is not None:
                    _apply_python_map(Yh.T, self.python_map, self.Y0)     # writes through the view
                yield y_block[a:b], Yh

    def difference_blocks(self, blocks):
        """``[D r]`` a block of at most ``BLOCK_SAMPLES`` samples at a time (one reused buffer)."""
        return _differences(self.output_blocks(blocks), self.lanes)


def _checked_blocks(blocks, K: int, y, n_samples: int):
    """``(begin, Phi, y)`` of each block of a ``K``-signal basis, checked against the record, which they must cover.

    Without a measured output (``y`` None) the block's ``y`` is zeros (a pass that only hands out outputs).
    """
    begin = 0
    for Phi in blocks:
        Phi = np.ascontiguousarray(Phi, dtype=float)
        if Phi.ndim != 2 or Phi.shape[0] != K or begin + Phi.shape[1] > n_samples:
            raise DataError(f"a block of the basis of shape {Phi.shape} does not fit {K} basis signals "
                            f"and a record of {n_samples} samples (at sample {begin})")
        stop = begin + Phi.shape[1]
        yield begin, Phi, np.zeros(Phi.shape[1]) if y is None else y[begin:stop]
        begin = stop
    if begin != n_samples:
        raise DataError(f"the blocks of the basis cover {begin} samples of a record of {n_samples}")


def _differences(output_blocks, lanes: int):
    """``[D r]`` of each block of lane outputs: ``D[:, j] = y_0 - y_{j+1}`` and ``r = y - y_0`` (one reused buffer)."""
    from ..optimize._streamed_lstsq import BLOCK_SAMPLES

    F = np.empty((BLOCK_SAMPLES, lanes), order="F")
    for y_part, Yh in output_blocks:
        part = F[:Yh.shape[0]]
        with np.errstate(all="ignore"):
            np.subtract(Yh[:, :1], Yh[:, 1:], out=part[:, :-1])
            np.subtract(y_part, Yh[:, 0], out=part[:, -1])
        yield part


class _LaneGroups:
    """Candidates past one compiled pass (lanes or basis signals), in groups of passes run side by side.

    Each group is a :class:`_LanePass` of at most
    :data:`~hammerstein_ctrl._kernels.MAX_NORMAL_LANES` candidates whose
    signals take at most :data:`~hammerstein_ctrl._kernels.MAX_LANE_BASIS`
    rows: the basis rows its candidates use, or (``relative``) row 0's
    signal ``P[0] @ Phi`` and the rows in which they differ from it, as a
    forward-difference neighbour differs in one.  Over each block of samples
    every group runs on its own signals, carrying its lanes' state, and the
    outputs of all candidates leave together: memory stays bounded per sample.
    """

    streams_outputs = True

    @classmethod
    def prepare(cls, num, den, dt, y, P, x0, offset, intersample, output_map, n_samples=None):
        """The groups, or ``None`` where a candidate fits no group or a pass does not apply (``y``: as
        :class:`_LanePass`)."""
        plan = _lane_groups(P)
        num, den = _coefficient_rows(num, den)
        if plan is None or not 1 <= den.shape[1] - 1 <= MAX_PASS_STATES:
            return None
        lanes, n = P.shape[0], den.shape[1] - 1
        X, Y0 = _state_rows(x0, lanes, n), _offset_rows(offset, lanes)
        HP = None if output_map is None else np.broadcast_to(
            np.atleast_2d(np.asarray(output_map[1], dtype=float)), (lanes, output_map[0].n_params))
        self = cls()
        self.lanes, self.K, self.P, self.groups = lanes, P.shape[1], P, []
        self.y = None if y is None else _measured(y, np.size(y))
        self.n_samples = n_samples if y is None else self.y.size
        for rows, cols, relative in plan:
            lane_rows = rows if len(rows) > 1 else rows * 2       # a pass has two lanes at least
            Pg = P[lane_rows][:, cols]
            if relative:
                with np.errstate(all="ignore"):         # a parameter at inf: its lanes' signals are not finite
                    Pg = np.column_stack([np.ones(len(lane_rows)), Pg - P[0, cols]])
            linear = [r if r < den.shape[0] else 0 for r in lane_rows]    # past the given blocks: row 0's
            group = _LanePass.prepare(num[linear], den[linear], dt, self.y, Pg, X[lane_rows], Y0[lane_rows],
                                      intersample, None if HP is None else (output_map[0], HP[lane_rows]),
                                      outputs=True, n_samples=self.n_samples)
            if group is None:
                return None
            self.groups.append((rows, cols, relative, group))
        return self

    def signals_finite(self) -> bool:
        """Whether every group's lanes have a finite last signal sample (see :meth:`_LanePass.signals_finite`)."""
        return all(group.signals_finite() for *_, group in self.groups)

    def output_blocks(self, blocks):
        """``(y, Yh)``: every candidate's output, a block of at most ``BLOCK_SAMPLES`` samples at a time."""
        from ..optimize._streamed_lstsq import BLOCK_SAMPLES

        outputs = np.empty((BLOCK_SAMPLES, self.lanes))
        buffers = [np.empty((BLOCK_SAMPLES, group.lanes)) for *_, group in self.groups]
        for begin, Phi, y_block in _checked_blocks(blocks, self.K, self.y, self.n_samples):
            for a in range(0, Phi.shape[1], BLOCK_SAMPLES):
                b = min(a + BLOCK_SAMPLES, Phi.shape[1])
                part, reference = Phi[:, a:b], None
                for (rows, cols, relative, group), buffer in zip(self.groups, buffers):
                    if relative and reference is None:
                        with np.errstate(all="ignore"):     # an overflowing signal: its sums are not finite
                            reference = self.P[0] @ part
                    signals = np.vstack([reference, part[cols]]) if relative else np.ascontiguousarray(part[cols])
                    Yg = buffer[:b - a]
                    group.run(signals, y_block[a:b], begin + a, Yg)
                    if group.python_map is not None:
                        _apply_python_map(Yg.T, group.python_map, group.Y0)
                    outputs[:b - a, rows] = Yg[:, :len(rows)]
                yield y_block[a:b], outputs[:b - a]

    def difference_blocks(self, blocks):
        """``[D r]`` a block of at most ``BLOCK_SAMPLES`` samples at a time (one reused buffer)."""
        return _differences(self.output_blocks(blocks), self.lanes)


def _group_signals(P, rows):
    """``(cols, relative)``: the fewest basis rows that give the candidates ``rows`` their signals, or ``None``."""
    direct = np.flatnonzero(np.any(P[rows] != 0.0, axis=0))
    moved = np.flatnonzero(np.any(P[rows] != P[0], axis=0))
    if direct.size <= moved.size + 1 and direct.size <= MAX_LANE_BASIS:
        return (direct if direct.size else np.arange(1)), False
    if moved.size + 1 <= MAX_LANE_BASIS:
        return moved, True
    return None


def _lane_groups(P):
    """``[(rows, cols, relative)]``: consecutive candidates in groups that fit one pass each (``None`` if one fits
    none)."""
    plan, rows = [], []
    for b in range(P.shape[0]):
        if rows and len(rows) < MAX_NORMAL_LANES and _group_signals(P, rows + [b]) is not None:
            rows.append(b)
            continue
        if rows:
            plan.append((rows, *_group_signals(P, rows)))
        if _group_signals(P, [b]) is None:
            return None
        rows = [b]
    plan.append((rows, *_group_signals(P, rows)))
    return plan


def response_blocks(num, den, dt: float, signals, n_signals: int, n_samples: int, *, free: bool = False,
                    intersample: str = "foh"):
    """Responses of one linear block to several signals, handed out a block of samples at a time.

    The responses are never held whole: the compiled passes of the
    normal equations (in outputs mode, several side by side past one)
    carry their state from block to block, so a long record's regression
    columns take memory bounded per sample.

    Parameters
    ----------
    num, den : array_like, shape (l+1,) and (n+1,)
        One transfer function (descending powers).
    dt : float
    signals : iterable of ndarray, shape (n_signals, L_i)
        The driving signals, in consecutive blocks of samples that together span the record.
    n_signals, n_samples : int
    free : bool, default False
        Also hand out the free responses from each unit initial state
        (:func:`free_response`), after the driven ones.
    intersample : {"foh", "zoh"}, default "foh"

    Yields
    ------
    ndarray, shape (L, n_signals [+ n])
        The responses at the next ``L <= BLOCK_SAMPLES`` samples, one column
        each (a reused buffer: copy what you keep).

    Raises
    ------
    ParameterError
        If the block cannot be simulated in a compiled pass (no state, more
        than :data:`MAX_PASS_STATES` states, coefficients that cannot be
        discretised).

    Examples
    --------
    >>> t = np.arange(5.0)
    >>> parts = response_blocks([1.0], [1.0, 1.0], 1.0, [np.ones((1, 5))], 1, 5, free=True)
    >>> Y = np.vstack([part.copy() for part in parts])
    >>> bool(np.allclose(Y[:, 0], simulate_batch([[1.0]], [[1.0, 1.0]], np.ones(5), 1.0)[0]))
    True
    >>> bool(np.allclose(Y[:, 1], free_response([1.0], [1.0, 1.0], 1.0, 5)[:, 0]))
    True
    """
    num, den = check_transfer_function(num, den, name="linear block")
    n = den.size - 1
    extra = n if free else 0
    K = max(n_signals, 1)               # no signal (free responses alone): one zero signal drives no lane
    if n_signals == 0:
        signals = (np.zeros((1, np.shape(block)[-1])) for block in signals)
    lanes = max(n_signals + extra, 2)                   # a pass has two lanes at least
    P = np.zeros((lanes, K))
    P[np.arange(n_signals), np.arange(n_signals)] = 1.0
    X = np.zeros((lanes, n))
    X[n_signals:n_signals + extra] = np.eye(n)[:extra]
    passes = _lane_pass_or_groups(num[None, :], den[None, :], dt, None, P, X, None, intersample, None,
                                  n_samples) if 1 <= n <= MAX_PASS_STATES else None
    if passes is None:
        raise ParameterError(f"the linear block {num} / {den} cannot be simulated a block at a time "
                             f"(1 to {MAX_PASS_STATES} states and finite coefficients)")
    for _, Y in passes.output_blocks(signals):
        yield Y[:, :n_signals + extra]


def free_response(num, den, dt: float, n_samples: int) -> np.ndarray:
    """Output of each transfer function from each unit initial state, with zero input.

    The columns span every output an initial state can add (``y = Phi @ x0``),
    which makes the initial state a linear least-squares problem once the
    transfer function is fixed.

    Parameters
    ----------
    num, den : array_like, shape (l+1,) and (n+1,)
        One transfer function (descending powers).
    dt : float
    n_samples : int

    Returns
    -------
    ndarray, shape (n_samples, n)

    Examples
    --------
    >>> free_response([1.0], [1.0, 1.0], 1.0, 3).ravel().round(4)   # exp(-k)
    array([1.    , 0.3679, 0.1353])
    """
    num = np.atleast_2d(np.asarray(num, dtype=float))
    den = np.atleast_2d(np.asarray(den, dtype=float))
    n = den.shape[1] - 1
    eye = np.eye(n)
    Y = simulate_batch(np.repeat(num, n, 0), np.repeat(den, n, 0), np.zeros(n_samples), dt, x0=eye)
    return Y.T
