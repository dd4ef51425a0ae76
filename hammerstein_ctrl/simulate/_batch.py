"""Batches of candidates simulated in one compiled pass: outputs, sums of squares, basis responses.

The simulator's second job: :func:`simulate_batch` and :func:`sse_batch`
(signals given) and :func:`sse_basis_batch` (signals formed from a basis in
the pass).  Public through :mod:`hammerstein_ctrl.simulate`.
"""

from __future__ import annotations

import numpy as np

from .._checks import check_intersample
from ..exceptions import DataError, ParameterError
from .._kernels import (LANE_MIN, get_coefficient_kernel, get_kernel, get_lane_kernel, has_basis_kernels,
                        has_output_maps)
from ._discretize import (COMPILED_EXPM_MAX_NORM, _coefficient_rows, _float_matrix, _offset_rows, _state_rows,
                          _tf_system, unstable)

__all__ = ["simulate_batch", "sse_batch", "sse_basis_batch", "output_terms"]


def _signals(V, batch: int) -> np.ndarray:
    V = np.atleast_2d(np.asarray(V, dtype=float))
    if V.ndim != 2 or V.shape[0] not in (1, batch):
        raise ParameterError(f"signals must be one row, or one row per transfer function ({batch}), "
                             f"got an array of shape {V.shape}")
    if V.shape[0] != batch:
        V = np.broadcast_to(V, (batch, V.shape[1]))
    return np.ascontiguousarray(V)


def _output_map(output_map, batch: int, n: int):
    """``(compiled map name or None, its kernel arguments, python fallback or None)``."""
    if output_map is None:
        return None, (), None
    nonlinearity, params = output_map
    m = nonlinearity.n_params
    if m == 0:                          # a map without parameters: one empty row per candidate
        HP = np.zeros((batch, 0))
    else:
        HP = np.ascontiguousarray(np.broadcast_to(nonlinearity.check_params(params).reshape(-1, m)
                                                  if np.ndim(params) else params, (batch, m)), dtype=float)
    if nonlinearity.compiled_map and has_output_maps(n):
        extra = np.ascontiguousarray(nonlinearity.map_extra(), dtype=float)
        return nonlinearity.compiled_map, (HP, extra), None
    return None, (), (nonlinearity, HP)


def _apply_python_map(Y, fallback, offsets):
    """Output map of a family without a compiled form, applied row by row after the recursion."""
    nonlinearity, HP = fallback
    with np.errstate(all="ignore"):
        for b in range(Y.shape[0]):
            Y[b] = nonlinearity._evaluate(Y[b], HP[b]) + offsets[b]
    return Y


def simulate_batch(num, den, V, dt: float, *, x0=None, offset=None, intersample: str = "foh",
                   output_map=None, out=None) -> np.ndarray:
    """Simulate a batch of linear blocks driven by a batch of intermediate signals.

    Parameters
    ----------
    num, den : array_like, shape (B, l+1) and (B, n+1)
        Transfer-function coefficients in descending powers, one row per candidate.
    V : array_like, shape (B, N) or (N,)
        The signals ``g(u)`` for each candidate (or one shared signal).
    dt : float
        Sampling interval.
    x0 : array_like, shape (B, n) or (n,), optional
        Initial states of the companion realisations; default 0.
    offset : array_like, shape (B,) or scalar, optional
        Output offsets; default 0.
    intersample : {"foh", "zoh"}, default "foh"
    output_map : (Nonlinearity, array_like of shape (B, m) or (m,)), optional
        A static output nonlinearity ``h`` and its parameters: the output is
        ``h(H v) + offset`` (Wiener and Hammerstein-Wiener models), applied in
        the compiled pass where the family has a compiled form.
    out : ndarray, shape (B, N), optional
        A C-ordered float array to write the outputs into (a caller's reused
        buffer: a fresh array of a long record costs its page faults on every call).

    Returns
    -------
    ndarray, shape (B, N)
        Outputs (``out`` when given); rows of candidates that cannot be simulated (non-finite
        coefficients, signals or overflow) contain NaN or inf.
    """
    hold = check_intersample(intersample)
    E, C, D, ok = _tf_system(num, den, dt)
    batch, n = E.shape[0], E.shape[1] - 2
    V = _signals(V, batch)
    if V.shape[1] == 0:
        raise DataError("the signals are empty")
    if out is not None and (out.shape != V.shape or out.dtype != np.float64 or not out.flags.c_contiguous
                            or not out.flags.writeable):
        raise ParameterError(f"out must be a writeable C-ordered float array of shape {V.shape}")
    Y = np.empty(V.shape) if out is None else out
    outmap, map_args, fallback = _output_map(output_map, batch, n)
    offsets = _offset_rows(offset, batch)
    get_kernel(n, "outputs", hold, outmap)(E, C, D, _state_rows(x0, batch, n),
                                           np.zeros(batch) if fallback else offsets, V, *map_args, Y)
    if fallback:
        Y = _apply_python_map(Y, fallback, offsets)
    Y[~ok] = np.nan
    return Y


def sse_batch(num, den, V, dt: float, y, *, x0=None, offset=None, intersample: str = "foh",
              output_map=None, reject_unstable: bool = False) -> np.ndarray:
    """Sum of squared output errors ``J`` (the paper's equation 13) for a batch of candidates.

    Never raises or warns for hostile candidates: a candidate whose
    coefficients, signal or simulated output are non-finite (or, with
    ``reject_unstable=True``, that has a pole with positive real part) gets
    ``J = inf``.

    Parameters
    ----------
    num, den, V, dt, x0, offset, intersample, output_map
        As for :func:`simulate_batch`.
    y : ndarray, shape (N,)
        Measured output.
    reject_unstable : bool, default False
        Give unstable candidates ``inf`` instead of simulating them.

    Returns
    -------
    ndarray, shape (B,)
    """
    hold = check_intersample(intersample)
    E, C, D, ok = _tf_system(num, den, dt)
    if reject_unstable:
        ok &= ~unstable(den)
    batch, n = E.shape[0], E.shape[1] - 2
    outmap, map_args, fallback = _output_map(output_map, batch, n)
    y = _measured(y, np.shape(V)[-1])
    if fallback:
        Y = simulate_batch(num, den, V, dt, x0=x0, offset=offset, intersample=hold, output_map=output_map)
        with np.errstate(all="ignore"):
            J = np.sum((y - Y) ** 2, axis=1)
        J[~np.isfinite(J)] = np.inf
    else:
        V = _signals(V, batch)
        J = np.empty(batch)
        get_kernel(n, "sse", hold, outmap)(E, C, D, _state_rows(x0, batch, n), _offset_rows(offset, batch), V,
                                           *map_args, y, J)
    J[~ok] = np.inf
    return J


def sse_basis_batch(num, den, P, basis, dt: float, y, *, x0=None, offset=None, intersample: str = "foh",
                    reject_unstable: bool = False) -> np.ndarray | None:
    """:func:`sse_batch` for candidates whose intermediate signal is ``P[b] @ basis``, formed in the pass.

    The signals are formed sample by sample inside the compiled pass (from
    :data:`~hammerstein_ctrl._kernels.LANE_MIN` candidates on across SIMD
    lanes, :func:`~hammerstein_ctrl._kernels.get_lane_kernel`), so no
    ``B x N`` array is made, and the sums are bit-identical to
    :func:`sse_batch` on the signals ``P @ basis`` summed basis row by basis row.

    Parameters
    ----------
    num, den : array_like, shape (B, l+1) and (B, n+1)
    P : array_like, shape (B, K) or (K,)
        Each candidate's coefficients of the basis (one row: shared by all).
    basis : ndarray, shape (K, N)
    dt, y, x0, offset, intersample, reject_unstable
        As for :func:`sse_batch`.

    Returns
    -------
    ndarray, shape (B,) or None
        ``None`` where no compiled pass applies (no state, more than
        :data:`~hammerstein_ctrl._kernels.MAX_UNROLLED_STATES` states or more than
        :data:`~hammerstein_ctrl._kernels.MAX_LANE_BASIS` basis signals).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(0, 2, 0.01); u = np.sin(3 * t); y = np.cos(t)
    >>> basis = np.vstack([u, u ** 3]); P = np.array([[1.0, 0.5], [2.0, -1.0], [0.0, 1.0]])
    >>> num, den = np.ones((3, 1)), np.tile([1.0, 2.0], (3, 1))
    >>> V = P[:, :1] * basis[0] + P[:, 1:] * basis[1]          # summed basis row by basis row
    >>> bool(np.array_equal(sse_basis_batch(num, den, P, basis, 0.01, y), sse_batch(num, den, V, 0.01, y)))
    True
    """
    hold = check_intersample(intersample)
    num, den, P, basis, y = _basis_arguments(num, den, P, basis, y)
    batch, n, K = den.shape[0], den.shape[1] - 1, P.shape[1]
    if not has_basis_kernels(n, K):
        return None
    X0, Y0 = _state_rows(x0, batch, n), _offset_rows(offset, batch)
    if batch < LANE_MIN:
        J = np.empty(batch)
        # discretisation and pass in one compiled call, unless a row needs the general path
        if get_coefficient_kernel(n, hold, K)(num, den, float(dt), COMPILED_EXPM_MAX_NORM, X0, Y0, P, basis, y, J):
            if reject_unstable:
                J[unstable(den)] = np.inf
            return J
    E, C, D, ok = _tf_system(num, den, dt)
    if reject_unstable:
        ok &= ~unstable(den)
    J = np.empty(batch)
    if batch < LANE_MIN:
        kernel = get_kernel(n, "sse", hold, None, K)     # positional: the cached lookup is quicker
    else:
        kernel = get_lane_kernel(n, hold, K, *output_terms(num, den, D, offset, Y0))
    kernel(E, C, D, X0, Y0, P, basis, y, J)
    if not ok.all():
        J[~ok] = np.inf
    return J


def output_terms(num, den, D, offset, Y0) -> tuple[bool, bool]:
    """Whether the outputs have a direct term and an offset (a strictly proper block, or no offset given, needs no
    look)."""
    return np.shape(num)[-1] == np.shape(den)[-1] and bool(D.any()), offset is not None and bool(Y0.any())


def _basis_arguments(num, den, P, basis, y):
    """Coefficient rows, basis coefficients (one row per candidate), basis and output, checked against each other."""
    num, den = _coefficient_rows(num, den)
    if _float_matrix(P) and _float_matrix(basis) and P.shape[0] == den.shape[0] and P.shape[1] == basis.shape[0]:
        return num, den, P, basis, _measured(y, basis.shape[1])        # the cost's own arrays: nothing to do
    P = np.atleast_2d(np.asarray(P, dtype=float))
    basis = np.atleast_2d(np.asarray(basis, dtype=float))
    if P.ndim != 2 or basis.ndim != 2 or P.shape[1] != basis.shape[0]:
        raise ParameterError(f"basis coefficients of shape {P.shape} do not match a basis of shape {basis.shape}")
    if P.shape[0] != den.shape[0]:
        if 1 not in (P.shape[0], den.shape[0]):
            raise ParameterError(f"{P.shape[0]} rows of basis coefficients for {den.shape[0]} transfer functions")
        rows = max(P.shape[0], den.shape[0])
        num, den = (np.array(np.broadcast_to(a, (rows, a.shape[1])), order="C") for a in (num, den))  # writeable
        P = np.broadcast_to(P, (rows, P.shape[1]))
    return num, den, np.ascontiguousarray(P), np.ascontiguousarray(basis), _measured(y, basis.shape[1])


def _measured(y, n_samples: int) -> np.ndarray:
    """The measured output as a contiguous float array, as long as the signals (else a :class:`DataError`)."""
    if _float_matrix(y, 1) and y.size == n_samples > 0:
        return y                                # the cost's own array: nothing to do
    y = np.ascontiguousarray(y, dtype=float)
    if y.ndim != 1 or y.size != n_samples or n_samples == 0:
        raise DataError(f"the measured output has shape {y.shape}, the signals {n_samples} samples "
                        "(both must have the same, non-zero, length)")
    return y
