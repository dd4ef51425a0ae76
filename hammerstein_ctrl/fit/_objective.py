"""The identification objective J(beta) (the paper's equation 13) on a record.

:class:`HammersteinCost` is what the optimisers minimise.  It is a plain
callable ``cost(beta) -> float`` with a vectorised ``cost.batch(betas)``, and
it never raises or warns for a hostile candidate: a candidate whose
simulation is non-finite (overflow, NaN parameters) scores ``inf``.  A wrong
*length* of beta is a programming error and raises
:class:`~hammerstein_ctrl.exceptions.ParameterError`.

Memory stays bounded on long records.  Where ``g`` is linear in its
parameters (or absent) and the basis is stored, the values of J come from one
compiled pass that forms each candidate's signal sample by sample
(:func:`~hammerstein_ctrl.simulate.sse_basis_batch`), so no ``B x N`` array
exists.  Otherwise (and for simulated outputs and residuals) a batch is formed
a chunk of candidates at a time (:data:`CHUNK_BYTES` of signals), and past
:data:`BASIS_MAX_BYTES` the basis of ``g`` is recomputed in blocks instead of
stored.  The public methods do not enter a BLAS thread limit themselves (it
would cost ~7 us, a seventh of an EMPS evaluation, and the evaluation calls no
BLAS: the matrix exponential and the signal combination are compiled loops);
the entry points that drive them (``identify``, ``minimize``, ``run_study``) hold it.

Unstable candidates are simulated like any other by default, because that is
what the paper does: EMPS's initial point (Table 5, ``a1 = -1``) is unstable
and has the finite cost 3.82e11 that the SPSA family starts from.  Pass
``reject_unstable=True`` to score every candidate with a right-half-plane pole
as ``inf`` instead.

Examples
--------
>>> from hammerstein_ctrl import presets
>>> p = presets.trs()
>>> round(p.cost(p.true_beta), 6)
178.5
"""

from __future__ import annotations

import functools
import threading
from typing import NamedTuple

import numpy as np

from .._linalg import single_threaded_blas, tf_discrete
from .. import _core
from ..exceptions import ParameterError
from .._kernels import MAX_LANE_BASIS, MAX_NORMAL_LANES, get_coefficient_kernel, get_normal_kernel, has_basis_kernels
from ..optimize._normal_equations import (NONFINITE_RESIDUAL, NormalEquations, from_difference_sums, from_factor,
                                          from_residuals, neighbours, point_and_steps, scored_inf)
from ..simulate._simulate import (COMPILED_EXPM_MAX_NORM, GROUPS_MIN_BYTES, normal_factor, normal_pass, output_terms,
                                  simulate_batch, sse_basis_batch, sse_batch, unstable)
from ..blocks._structure import BlockStructure
from ._cost import StructureSized

__all__ = ["HammersteinCost", "DirectPass", "EVALUATING_METHODS", "CHUNK_BYTES", "BASIS_MAX_BYTES", "BASIS_BLOCK",
           "EVAL_BLOCK", "NONFINITE_RESIDUAL"]


#: Largest block of per-candidate signals ``g(u)`` (and simulated outputs) formed
#: at once, in bytes, where signals are formed at all (not in the compiled basis
#: pass).  A batch whose ``B x N`` signals would exceed it is
#: evaluated a chunk of candidates at a time, so that memory per sample stays
#: bounded on long records (one candidate at a time from 2 million samples up);
#: records of ordinary length take the whole batch in one chunk.
CHUNK_BYTES = 1 << 24


#: Largest basis of ``g`` (``p x N`` regressors) kept in memory.  Longer records
#: recompute it in blocks of :data:`BASIS_BLOCK` samples whenever signals are
#: formed, trading a little time for ``8 p`` bytes per sample.
BASIS_MAX_BYTES = 1 << 26

#: Samples per block of a recomputed basis.
BASIS_BLOCK = 1 << 16

#: Samples of one candidate's signal ``g(u)`` evaluated at once by a nonlinearity without a
#: basis (8 KiB samples: numpy's temporaries stay below the allocator's 128 KiB mmap threshold).
EVAL_BLOCK = 1 << 13


def _combine(P, basis, out, start: int) -> None:
    """``out[:B, start:start + n] = P @ basis`` single-threaded (BLAS threads would compete with the simulation), in
    the compiled core: the products added term by term.  ``P``, ``basis`` and the writeable ``out`` are C-ordered float
    arrays (the core's wrapper checks that), ``out`` wide enough and apart from the others (checked here)."""
    B, p = P.shape
    n = basis.shape[1]
    if not (basis.shape[0] == p and out.ndim == 2 and out.shape[0] >= B and out.shape[1] >= start + n and start >= 0
            and not np.may_share_memory(out, P) and not np.may_share_memory(out, basis)):
        raise TypeError(f"_combine takes arrays of fitting shapes, out apart from the others, not "
                        f"{P.shape}, {basis.shape}, {out.shape}")
    _core.hc_combine(P, B, p, basis, n, out, out.shape[1], start)


#: Methods of :class:`HammersteinCost` that evaluate it: a subclass redefining one gets no compiled LM loop.
EVALUATING_METHODS = ("__call__", "batch", "residuals", "residuals_batch", "normal_equations", "normal_factor")


class DirectPass(NamedTuple):
    """A plain cost's normal-equation pass, as compiled code runs it from the parameters
    (:meth:`HammersteinCost.direct_pass`).

    The linear block's coefficients are ``num0``/``den0`` with the free ones
    written at ``num_pos``/``den_pos`` (:meth:`~hammerstein_ctrl.blocks.LinearStructure.coefficient_template`),
    the signal is ``P @ basis`` with ``P`` the parameters of ``g`` that follow
    them (``has_g``; else ``basis`` is ``u``), and the pass kernel is
    :func:`~hammerstein_ctrl._kernels.get_normal_kernel`'s for ``n`` states,
    ``hold``, ``K`` basis signals and a ``direct`` term or not.
    """

    n: int
    hold: str
    K: int
    direct: bool
    num0: np.ndarray
    den0: np.ndarray
    num_pos: np.ndarray
    den_pos: np.ndarray
    has_g: bool
    dt: float
    max_norm: float
    basis: np.ndarray
    y: np.ndarray

    @property
    def n_params(self) -> int:
        """Length of the parameter vectors the pass takes: the free coefficients, then the ``K`` of ``g``."""
        return self.num_pos.size + self.den_pos.size + (self.K if self.has_g else 0)


class HammersteinCost(StructureSized):
    """Sum of squared output errors of a Hammerstein structure on a record.

    Parameters
    ----------
    data : IOData
        The estimation record (uniform time grid).
    structure : HammersteinStructure, WienerStructure or HammersteinWienerStructure
        Maps beta to a model.
    reject_unstable : bool, default False
        Score candidates with a pole in the open right half-plane as ``inf``.

    Attributes
    ----------
    n_params : int
    param_names : tuple of str

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Polynomial(1))
    >>> t = np.arange(100) * 0.1
    >>> data = hc.IOData(np.sin(t), s.model([2.0, 3.0]).simulate(t, np.sin(t)), dt=0.1)
    >>> cost = HammersteinCost(data, s)
    >>> float(cost([2.0, 3.0])), cost.batch([[2.0, 3.0], [2.0, 3.5]])[1] > 0
    (0.0, np.True_)
    """

    def __init__(self, data, structure: BlockStructure, *, reject_unstable: bool = False):
        from ..data._iodata import IOData

        if not isinstance(data, IOData):
            raise ParameterError(f"data must be an IOData record, got {type(data).__name__}")
        if not isinstance(structure, BlockStructure):
            raise ParameterError(
                "structure must be a HammersteinStructure, WienerStructure or HammersteinWienerStructure, "
                f"got {type(structure).__name__}"
            )
        if structure.linear.delay:
            raise ParameterError("this structure has a dead time, which HammersteinCost does not simulate: use "
                                 "hammerstein_ctrl.fit.DelayedCost (identify chooses it)")
        self.data = data.require_siso(f"a {structure.kind} structure")
        self.structure = structure
        self.reject_unstable = bool(reject_unstable)
        self._y = np.ascontiguousarray(data.y, dtype=float)
        self._u = np.ascontiguousarray(data.u, dtype=float)
        self._n_linear = structure.linear.n_params
        # g(u; d) = d @ basis for nonlinearities linear in their parameters: a
        # batch of signals is then one matrix product (7x cheaper than the formula).
        g = structure.input_nonlinearity
        probe = None if g is None else g.checked_basis(self._u[:1])
        self._linear_in_params = probe is not None
        self._basis = None
        self._local = threading.local()     # each thread's signal buffer (see _signal_buffer)
        if self._linear_in_params and probe.size * self._u.size * self._u.itemsize <= BASIS_MAX_BYTES:
            self._basis = np.ascontiguousarray(g.checked_basis(self._u), dtype=float)
        self._direct = self._direct_pass()

    @property
    def n_samples(self) -> int:
        """Length of the record."""
        return self._y.size

    def _chunks(self, batch: int):
        """Slices of at most ``CHUNK_BYTES`` worth of signals covering ``range(batch)``."""
        rows = max(1, CHUNK_BYTES // (self._y.itemsize * max(1, self._y.size)))
        return [slice(i, min(i + rows, batch)) for i in range(0, batch, rows)]

    def _pieces(self, b: np.ndarray, buffer=None):
        """Coefficients, signals and simulation options for a validated ``(B, n_params)`` array.

        ``buffer`` (at least ``B`` rows of ``N``) receives the signals, so
        chunks (and calls) reuse one block of memory.
        """
        s = self.structure
        num, den = s.linear._coefficients(b[:, :self._n_linear])
        g_params = s.input_params(b)
        with np.errstate(all="ignore"):
            if g_params is None:
                V = self._u
            elif self._linear_in_params:
                V = self._combined(np.ascontiguousarray(g_params), buffer)
            else:
                V = self._evaluated(np.atleast_2d(g_params), buffer)
        offset, x0 = s.nuisance(b)
        h_params = s.output_params(b)
        opts = {"offset": offset, "x0": x0, "intersample": self.data.intersample,
                "output_map": None if h_params is None else (s.output_nonlinearity, h_params)}
        return num, den, V, opts

    def _combined(self, P, buffer):
        """Signals ``P @ basis`` in (the first rows of) ``buffer``, from the stored or a recomputed basis."""
        if buffer is None:
            buffer = np.empty((P.shape[0], self._u.size))
        if self._basis is not None:
            _combine(P, self._basis, buffer, 0)
        else:
            for start in range(0, self._u.size, BASIS_BLOCK):
                block = self.structure.input_nonlinearity.checked_basis(self._u[start:start + BASIS_BLOCK])
                _combine(P, np.ascontiguousarray(block, dtype=float), buffer, start)
        return buffer[:P.shape[0]]

    def _evaluated(self, params, buffer):
        """Signals ``g(u; params[b])`` in (the first rows of) ``buffer``, a row and :data:`EVAL_BLOCK` samples at a
        time.

        Evaluating the whole ``B x N`` array at once has numpy allocate
        ``B x N`` temporaries in every call, which the C allocator serves from
        fresh pages once they pass its threshold (a page fault per 4 KiB on
        every call: 2.5x the time of a TRS batch, depending on what the
        process allocated before); blocks this size reuse the same memory.
        """
        if buffer is None:
            buffer = np.empty((params.shape[0], self._u.size))
        g = self.structure.input_nonlinearity
        for row, p in zip(buffer, params):
            for start in range(0, self._u.size, EVAL_BLOCK):
                row[start:start + EVAL_BLOCK] = g._evaluate(self._u[start:start + EVAL_BLOCK], p)
        return buffer[:params.shape[0]]

    def _signal_buffer(self, chunks):
        """One block of signals reused by every chunk, kept for this thread's next call of the same size or less."""
        rows = chunks[0].stop - chunks[0].start if chunks else 0
        buffer = getattr(self._local, "buffer", None)
        if buffer is None or buffer.shape[0] < rows:
            buffer = self._local.buffer = np.empty((rows, self._u.size))
        return buffer

    def __getstate__(self):
        state = self.__dict__.copy()
        del state["_local"]                 # buffers are per process and thread, not part of the cost
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._local = threading.local()

    def __call__(self, beta) -> float:
        """J at one beta (``inf`` if the candidate cannot be simulated)."""
        b = self.structure.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("cost(beta) takes one vector; use cost.batch for a batch")
        b = np.ascontiguousarray(b)[None, :]             # a strided view (a column of an array) too
        form = None if self._direct is None or self.reject_unstable else self._basis_form(b, evaluate=True)
        if form is not None and form[0].shape[1] <= MAX_LANE_BASIS:
            n, X0, Y0 = self._direct
            P, basis = form
            num, den = self.structure.linear._coefficients(b[:, :self._n_linear])
            J = np.empty(1)
            # discretisation and pass in one compiled call; False sends the candidate the general way
            if get_coefficient_kernel(n, self.data.intersample, P.shape[1])(
                    num, den, self.data.dt, COMPILED_EXPM_MAX_NORM, X0, Y0, P, basis, self._y, J):
                return float(J[0])
        return float(self._sse(b)[0])

    def _direct_pass(self):
        """``(n, X0, Y0)`` for single evaluations in one compiled call
        (:func:`~hammerstein_ctrl._kernels.get_coefficient_kernel`).

        ``None`` unless the structure is a plain Hammerstein one (or a linear
        block alone) of at most :data:`~hammerstein_ctrl._kernels.MAX_UNROLLED_STATES`
        states with no estimated offset or initial state; :meth:`__call__`
        uses it where the signal has a basis form (:meth:`_basis_form`) and
        unstable candidates are not rejected, and it gives the bits
        :meth:`batch` gives.
        """
        s, n = self.structure, self.structure.linear.den_order
        if s.output_nonlinearity is not None or s.n_params != s.n_core or not has_basis_kernels(n):
            return None
        return n, np.zeros((1, n)), np.zeros(1)

    def _basis_form(self, b: np.ndarray, evaluate: bool = False):
        """``(P, basis)`` with each candidate's signal ``P[i] @ basis``, or ``None`` where it is not formed that way.

        Without ``g`` the basis is ``u`` (weight 1); with a stored basis, the
        coefficients of ``g``.  With ``evaluate``, a single candidate of a
        ``g`` without a basis has its evaluated signal as the basis (weight 1).
        """
        g_params = self.structure.input_params(b)
        if g_params is None:
            return np.ones((b.shape[0], 1)), self._u[None, :]
        if self._basis is not None:
            return g_params, self._basis
        if evaluate and not self._linear_in_params and b.shape[0] == 1:
            with np.errstate(all="ignore"):
                return np.ones((1, 1)), self._evaluated(np.atleast_2d(g_params), None)
        return None

    def batch(self, betas) -> np.ndarray:
        """J for each row of ``betas`` (shape ``(B, n_params)``), in one compiled pass."""
        b = self.structure.check_beta(betas)
        return self._sse(b.reshape(-1, b.shape[-1]))

    def _sse(self, b: np.ndarray) -> np.ndarray:
        J = self._basis_sse(b)
        if J is not None:
            return J
        J = np.empty(b.shape[0])
        chunks = self._chunks(b.shape[0])
        buffer = self._signal_buffer(chunks)
        for rows in chunks:
            num, den, V, opts = self._pieces(b[rows], buffer)
            J[rows] = sse_batch(num, den, V, self.data.dt, self._y, reject_unstable=self.reject_unstable,
                                **opts)
        return J

    def _basis_sse(self, b: np.ndarray) -> np.ndarray | None:
        """J of a batch with the signals formed inside the compiled pass (``None`` where it does not apply).

        A single candidate of a ``g`` without a basis passes its evaluated signal
        as a basis of one (weight 1: the same bits as the signal read as it is),
        so its structure needs no pass of its own for signals read whole (up to
        :data:`~hammerstein_ctrl._kernels.MAX_UNROLLED_STATES` states, the orders with a basis pass).
        """
        s = self.structure
        evaluate = has_basis_kernels(s.linear.den_order)       # as sse_basis_batch takes it (else read whole)
        form = None if s.output_nonlinearity is not None else self._basis_form(b, evaluate=evaluate)
        if form is None:
            return None
        P, basis = form
        num, den = s.linear._coefficients(b[:, :self._n_linear])
        offset, x0 = s.nuisance(b)
        # compiled throughout: no numpy floating-point warnings to silence
        return sse_basis_batch(num, den, P, basis, self.data.dt, self._y, x0=x0, offset=offset,
                               intersample=self.data.intersample, reject_unstable=self.reject_unstable)

    def simulate(self, beta) -> np.ndarray:
        """Simulated output ŷ for one beta (NaN where the simulation fails)."""
        return self.simulate_batch(beta)[0]

    def simulate_batch(self, betas) -> np.ndarray:
        """Simulated outputs for each row of ``betas``, shape ``(B, N)`` (NaN rows where it fails)."""
        b = self.structure.check_beta(betas)
        b = b.reshape(-1, b.shape[-1])
        chunks = self._chunks(b.shape[0])
        if len(chunks) == 1:
            return self._simulate_chunk(b, None)
        Y = np.empty((b.shape[0], self._y.size))
        for rows in chunks:
            # a chunk's signals go to its own rows of the output: the simulation reads them whole
            # before its outputs are copied over them
            Y[rows] = self._simulate_chunk(b[rows], Y[rows] if self._linear_in_params else None)
        return Y

    def _simulate_chunk(self, b, buffer):
        num, den, V, opts = self._pieces(b, buffer)
        with np.errstate(all="ignore"):
            return simulate_batch(num, den, V, self.data.dt, **opts)

    def residuals(self, beta) -> np.ndarray:
        """``y - ŷ`` for one beta, for least-squares solvers (``J = sum(residuals**2)``).

        Non-finite residuals are replaced by a large finite value
        (:data:`NONFINITE_RESIDUAL`) so that trust-region solvers back off
        instead of failing; with ``reject_unstable`` an unstable candidate's
        residuals are all that value (the cost scores it ``inf``).
        """
        b = self.structure.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("residuals(beta) takes one vector; use residuals_batch for a batch")
        return self.residuals_batch(b)[0]

    def residuals_batch(self, betas) -> np.ndarray:
        """:meth:`residuals` for each row of ``betas``, shape ``(B, N)``, in one compiled pass.

        Finite-difference Jacobians evaluate all their columns with it.

        Examples
        --------
        >>> from hammerstein_ctrl import presets
        >>> p = presets.trs()
        >>> R = p.cost.residuals_batch([p.true_beta, p.x0])
        >>> R.shape == (2, len(p.data)), round(float(R[0] @ R[0]), 6)
        (True, 178.5)
        """
        R = self.simulate_batch(betas)
        with np.errstate(all="ignore"):
            np.subtract(self._y, R, out=R)
            for r in R:  # a finite sum proves a finite row without an N-long mask
                if not np.isfinite(r.sum()):
                    r[~np.isfinite(r)] = NONFINITE_RESIDUAL
        if self.reject_unstable:
            R[self._unstable(betas)] = NONFINITE_RESIDUAL   # what the cost scores inf, least squares sees huge
        return R

    def _unstable(self, betas) -> np.ndarray:
        """Which rows of ``betas`` have a linear block with a pole in the open right half-plane."""
        b = self.structure.check_beta(betas)
        return unstable(self.structure.linear._coefficients(b.reshape(-1, b.shape[-1])[:, :self._n_linear])[1])

    def normal_equations(self, beta, steps=None) -> NormalEquations:
        """``r @ r``, ``J.T @ r`` and ``J.T @ J`` at ``beta``, ``J`` the forward-difference Jacobian of the residuals.

        The point and its neighbours are simulated side by side in one
        compiled pass that accumulates the sums, with no ``N x p`` Jacobian
        in memory (the signals of ``g`` formed from its basis, or evaluated a
        block at a time; an output map applied in the pass).  Structures with
        more than :data:`~hammerstein_ctrl._kernels.MAX_NORMAL_LANES` - 1
        parameters or more than :data:`~hammerstein_ctrl._kernels.MAX_LANE_BASIS`
        distinct signals run in groups of passes side by side, and an output
        map without a compiled form is applied in numpy, the lanes' outputs
        leaving the pass a block of samples at a time.  Either way the ``p + 1``
        residual vectors are those of ``beta`` and ``beta + steps[j] e_j``.

        Parameters
        ----------
        beta : array_like, shape (n_params,)
        steps : array_like, shape (n_params,), optional
            Forward-difference steps; default scipy's ``"2-point"`` steps
            (:func:`~hammerstein_ctrl.optimize._normal_equations.forward_steps`).

        Returns
        -------
        NormalEquations

        Examples
        --------
        >>> import numpy as np
        >>> from hammerstein_ctrl import presets
        >>> from hammerstein_ctrl.optimize._normal_equations import from_residuals, neighbours
        >>> p = presets.emps()
        >>> x = np.asarray(p.paper["nspsa"]["beta"])
        >>> ne = p.cost.normal_equations(x)
        >>> slow = from_residuals(p.cost.residuals_batch(neighbours(x, ne.steps)),
        ...                       ne.steps)    # the N x p Jacobian, stored
        >>> bool(np.allclose(ne.gram, slow.gram, rtol=1e-6)), round(ne.fun, 6) == round(p.cost(x), 6)
        (True, True)
        """
        b, h, X = self._neighbourhood(beta, steps, "normal_equations")
        if self.reject_unstable:
            bad = self._unstable(X)
            if bad[0]:          # the cost scores the point inf: so do its normal equations (a solver cannot
                                # start there)
                return scored_inf(h)
            if bad.any():       # an unstable neighbour: its huge residuals keep the solver from stepping that way
                return from_residuals(self.residuals_batch(X), h)
        ne = self._fused_normal_equations(X, h)
        if ne is not None and ne.finite:
            return ne
        if self._point_scored_inf(ne, X, b):    # no p + 1 stored residual vectors for a point no solver can use
            return scored_inf(h)
        return from_residuals(self.residuals_batch(X), h)

    def _point_scored_inf(self, ne, X, b) -> bool:
        """Whether the cost scores the point ``b`` itself inf, asked where the pass ``ne`` gave no finite sums.

        A pass that came out non-finite cannot tell which lane failed: a
        finite point with a non-finite neighbour (a parameter at inf) takes the
        residuals' route.  Without a pass (``ne`` None) the point is checked
        only where its neighbourhood's residual vectors ``X`` would be large
        (past :data:`~hammerstein_ctrl.simulate._simulate.GROUPS_MIN_BYTES`): the point
        alone is one evaluation.
        """
        if ne is None and X.shape[0] * self._y.size * self._y.itemsize <= GROUPS_MIN_BYTES:
            return False
        return (ne is None or not np.isfinite(ne.fun)) and not np.isfinite(self(b))

    def normal_factor(self, beta, steps=None) -> NormalEquations:
        """:meth:`normal_equations` with the Jacobian's QR factor (``factor = (R, Q.T r)``) instead of ``J.T J``.

        Where :meth:`normal_equations` takes its compiled pass, the lanes'
        outputs leave it a block of samples at a time and the differences are
        reduced by a streamed QR (:func:`~hammerstein_ctrl.simulate._simulate.normal_factor`):
        memory stays bounded per sample, and the factor keeps the accuracy the
        Gram matrix loses on an ill-conditioned Jacobian.  Elsewhere the
        factor comes from the stored residual vectors.

        Examples
        --------
        >>> import numpy as np
        >>> from hammerstein_ctrl import presets
        >>> p = presets.emps()
        >>> x = np.asarray(p.paper["nspsa"]["beta"])
        >>> qr, ne = p.cost.normal_factor(x), p.cost.normal_equations(x)
        >>> bool(np.allclose(qr.gram, ne.gram, rtol=1e-6)), round(qr.fun, 6) == round(ne.fun, 6)
        (True, True)
        """
        b, h, X = self._neighbourhood(beta, steps, "normal_factor")
        if self.reject_unstable and self._unstable(X).any():
            return self.normal_equations(b, steps)       # its rules for rejected points
        ne = self._fused_normal_equations(X, h, normal_factor)
        if ne is not None and ne.finite:
            return ne
        if self._point_scored_inf(ne, X, b):
            return scored_inf(h)
        from ..optimize._streamed_lstsq import factor_of_blocks    # scipy.linalg's LAPACK: imported on first use

        R = self.residuals_batch(X)                      # non-finite entries already NONFINITE_RESIDUAL
        if not np.isfinite(h).all():
            return from_residuals(R, h)
        with np.errstate(all="ignore"):
            D = np.column_stack([(R[1:] - R[0]).T, R[0]])
            fun = float(R[0] @ R[0])
        # a record shorter than p + 1 samples: the factor is padded with zero rows
        with single_threaded_blas():
            R = factor_of_blocks([D], h.size + 1)
        return from_factor(R, h)._replace(fun=fun)

    def _neighbourhood(self, beta, steps, method: str):
        """``(b, h, X)``: the checked point, its forward-difference steps and the point with its neighbours."""
        b, h = point_and_steps(self.structure, beta, steps, method)
        return b, h, neighbours(b, h)

    def _fused_normal_equations(self, X, h, driver=normal_pass):
        """The compiled pass of :func:`~hammerstein_ctrl.simulate._simulate.normal_pass` (or ``driver``), or ``None``
        where it does not apply."""
        s = self.structure
        form = self._basis_form(X)
        if form is not None and driver is normal_pass and self._direct is not None:
            ne = self._direct_normal_equations(X, h, *form)
            if ne is not None:
                return ne
        if form is not None:
            P, blocks = form[0], [form[1]]
        elif self._linear_in_params:
            P, blocks = s.input_params(X), self._basis_blocks()
        else:
            P, blocks = self._signal_selection(s.input_params(X))
        # rows past 1 + n_linear move no parameter of the linear block: they share row 0's
        num, den = s.linear._coefficients(X[:1 + self._n_linear, :self._n_linear])
        offset, x0 = s.nuisance(X)
        h_params = s.output_params(X)
        return driver(num, den, self.data.dt, self._y, P, blocks, h, x0=x0, offset=offset,
                      intersample=self.data.intersample,
                      output_map=None if h_params is None else (s.output_nonlinearity, h_params))

    def _direct_normal_equations(self, X, h, P, basis):
        """:meth:`_fused_normal_equations` of a plain structure (:attr:`_direct`): the compiled pass run straight from
        the coefficients.

        No offset, initial state or output map, and the basis whole: the
        checks and lane set-up of :func:`~hammerstein_ctrl.simulate._simulate.normal_pass`
        have nothing to do.  ``None`` where the candidates do not fit one
        pass or a row needs scipy's exponential; the general pass then takes
        them, with the same kernel, and so gives the same sums.
        """
        lanes, K = P.shape
        if not 2 <= lanes <= MAX_NORMAL_LANES or K > MAX_LANE_BASIS:
            return None
        num, den = self.structure.linear._coefficients(X[:1 + self._n_linear, :self._n_linear])
        E, C, D, _, _, clean = tf_discrete(num, den, self.data.dt, COMPILED_EXPM_MAX_NORM)
        if not clean:
            return None
        n = self._direct[0]
        direct, _ = output_terms(num, den, D, None, None)      # as the general pass decides (same kernel, same bits)
        kernel = get_normal_kernel(n, self.data.intersample, lanes, K, direct, False)
        acc = np.zeros(1 + (lanes - 1) * lanes)
        kernel(E, C, D, np.zeros((lanes, n)), np.zeros(lanes), np.zeros(lanes), np.ascontiguousarray(P), basis,
               np.zeros((lanes, 0)), np.zeros(0), self._y, 0, acc)
        return from_difference_sums(acc, h)

    def direct_pass(self) -> DirectPass | None:
        """The normal-equation pass as compiled code runs it from the parameters, or ``None`` where the cost has none.

        For the compiled Levenberg-Marquardt loop of :mod:`~hammerstein_ctrl.optimize._normal_lm`:
        a plain structure (as :meth:`_direct_normal_equations` takes) whose
        signal has a stored basis, unstable candidates not rejected, and a
        pass of at most :data:`~hammerstein_ctrl._kernels.MAX_NORMAL_LANES` lanes.
        ``None`` also for a subclass that redefines how the cost is evaluated
        (:data:`EVALUATING_METHODS`): the compiled loop would bypass it.

        Examples
        --------
        >>> from hammerstein_ctrl import presets
        >>> d = presets.emps().cost.direct_pass()
        >>> d.n, d.hold, d.K, d.direct, d.basis.shape
        (2, 'foh', 3, False, (3, 12000))
        """
        cls = type(self)
        if self.reject_unstable or any(getattr(cls, m) is not getattr(HammersteinCost, m) for m in EVALUATING_METHODS):
            return None
        return self._plain_pass

    @functools.cached_property
    def _plain_pass(self) -> DirectPass | None:
        """:meth:`direct_pass`, whether or not unstable candidates are rejected (formed once)."""
        if self._direct is None:
            return None
        form = self._basis_form(np.zeros((1, self.n_params)))
        if form is None or not self.n_params + 1 <= MAX_NORMAL_LANES or form[0].shape[1] > MAX_LANE_BASIS:
            return None
        num0, den0, num_pos, den_pos = self.structure.linear.coefficient_template()
        direct = num0.size == den0.size and (0 in num_pos or num0[0] != 0)      # b_n free, or fixed off zero
        basis, y = np.ascontiguousarray(form[1]), np.ascontiguousarray(self._y)
        return DirectPass(self._direct[0], self.data.intersample, form[0].shape[1], bool(direct), num0, den0,
                          num_pos, den_pos, self.structure.input_nonlinearity is not None, float(self.data.dt),
                          COMPILED_EXPM_MAX_NORM, basis, y)

    def _signal_selection(self, params):
        """``(P, blocks)`` for a ``g`` without a basis: its distinct signals as the basis, each lane selecting one.

        The point and the neighbours that move no parameter of ``g`` share
        one signal; each neighbour that moves one has its own.  The signals
        are evaluated :data:`EVAL_BLOCK` samples at a time, so memory stays
        bounded.
        """
        rows = [0] + [int(i) for i in np.flatnonzero(np.any(params != params[0], axis=1))]
        P = np.zeros((params.shape[0], len(rows)))
        P[:, 0] = 1.0                             # the point's signal, for every lane but those moving g
        P[rows[1:], 0] = 0.0
        P[rows[1:], np.arange(1, len(rows))] = 1.0
        g, u = self.structure.input_nonlinearity, self._u

        def blocks():
            with np.errstate(all="ignore"):
                for start in range(0, u.size, EVAL_BLOCK):
                    part = u[start:start + EVAL_BLOCK]
                    yield np.array([g._evaluate(part, params[r]) for r in rows])
        return P, blocks()

    def _basis_blocks(self):
        """The basis of ``g``, recomputed a block of samples at a time (for records too long to store it)."""
        g = self.structure.input_nonlinearity
        return (g.checked_basis(self._u[start:start + BASIS_BLOCK]) for start in range(0, self._u.size, BASIS_BLOCK))

    def __repr__(self):
        return f"HammersteinCost({self.data.name!r}, {self.structure.describe()})"
