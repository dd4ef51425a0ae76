"""Linear least squares over a long record in blocks of samples, without the ``N x p`` regression matrix.

The regressions of the automatic starts have a handful of columns (simulated
responses, a constant, free responses, lagged signals) but as many rows as the
record has samples; formed whole they took ``8 p`` bytes per sample, and the
LAPACK solvers copied them again.  Here the columns stay where they are (rows
of arrays the caller already holds, views of the record, or a broadcast
constant that takes no memory) and the regression is reduced block by block
to the triangular factor ``R`` of ``[X y]`` (a tall-skinny QR: each block of
:data:`BLOCK_SAMPLES` rows is factored, and the factors are merged pairwise
up a reduction tree).  ``R`` holds everything a least-squares solve needs: ``X = Q R_11``,
``Q^T y = z`` and the residual norm ``|R_pp|``, so the small solve on ``R``
gives the same coefficients as a solve on ``X`` itself, with the accuracy of
a QR factorisation (forming ``X^T X`` would square the condition number).
A regression small enough (:data:`WHOLE_FACTOR_BYTES`) is copied whole and
factored in one call instead, which is faster than its blocks.  The
factorisations are the compiled core's (Householder, LAPACK's
reflectors).

Columns are given as a sequence of arrays of shape ``(N,)`` or ``(p_i, N)``
(each row one column), in column order.

Examples
--------
>>> import numpy as np
>>> t = np.linspace(0.0, 1.0, 1000); y = 2.0 * t + 0.5 + 0.01 * np.sin(40 * t)
>>> columns = [t, np.broadcast_to(1.0, t.shape)]
>>> R = triangular_factor(columns, y)
>>> w = solve_scaled(R, t.size)
>>> ref = np.linalg.lstsq(np.column_stack([t, np.ones_like(t)]), y, rcond=None)[0]
>>> bool(np.allclose(w, ref, rtol=1e-12))
True
>>> r = residual(columns, w, y)
>>> bool(np.isclose(factor_sse(R, w), r @ r, rtol=1e-9))
True
"""

from __future__ import annotations

import functools

import numpy as np

from .. import _core
from ..exceptions import DataError

__all__ = ["BLOCK_SAMPLES", "triangular_factor", "factor_of_blocks", "rank_tolerance", "solve_scaled",
           "solve_minimum_norm", "factor_sse", "residual", "constant_column", "column_blocks",
           "factor_of_columns", "factor_of_rows", "held_whole", "residual_of_columns", "orthogonal_part",
           "column_scale", "independent"]

#: Samples per block of the streamed factorisation and residual (a block of
#: ``p + 1`` columns takes ``8 (p + 1) BLOCK_SAMPLES`` bytes).
BLOCK_SAMPLES = 8192
#: Size of ``[X y]`` (``8 (p + 1) N`` bytes) up to which :func:`triangular_factor` copies it whole and
#: factors it in one call: on the EMPS record (12 000 samples, 6 columns) that took 200 us where the blocks
#: and their merges took 430 us (with LAPACK's factorisation, when this was chosen), and the copy is small
#: beside the record.
WHOLE_FACTOR_BYTES = 1 << 22


@functools.lru_cache(maxsize=1)
def _lapack() -> dict:
    """scipy's LAPACK routines this module calls (scipy.linalg is imported when first needed: a sixth of a
    first fit's imports)."""
    import scipy.linalg

    trtri, gelsy, gelsy_lwork = scipy.linalg.get_lapack_funcs(("trtri", "gelsy", "gelsy_lwork"), dtype=np.float64)
    return {"trtri": trtri, "gelsy": gelsy, "gelsy_lwork": gelsy_lwork}



def constant_column(n_samples: int) -> np.ndarray:
    """A column of ones that takes no memory (a broadcast view).

    Examples
    --------
    >>> c = constant_column(5); c.tolist(), c.strides
    ([1.0, 1.0, 1.0, 1.0, 1.0], (0,))
    """
    return np.broadcast_to(np.float64(1.0), (n_samples,))


def _rows(columns) -> list[np.ndarray]:
    """Each source of columns as a 2-D ``(p_i, N)`` array (views, no copies)."""
    return [a[None, :] if a.ndim == 1 else a for a in (np.asarray(c, dtype=float) for c in columns)]


def _fill(rows, begin: int, stop: int, out: np.ndarray):
    """Write samples ``begin:stop`` of every column into ``out`` (``(stop - begin, p)``)."""
    j = 0
    for a in rows:
        out[:, j:j + a.shape[0]] = a[:, begin:stop].T
        j += a.shape[0]


def _triangle(a: np.ndarray) -> np.ndarray:
    """The ``R`` of a QR factorisation of ``a`` (at least as many rows as columns; overwritten where it is a
    writeable, Fortran-ordered float array, else factored in such a copy).

    The compiled core's Householder factorisation of the columns where they lie
    (a Fortran-ordered array's columns are the rows of its C-ordered
    transpose): LAPACK's reflectors, its sums in a fixed order of vector
    lanes, 1.43-1.49x faster than LAPACK's ``dgeqrf`` (through scipy) on a
    regression of 12 000 samples and 6 columns, the same ``R`` to a few units
    of rounding.
    """
    a = np.require(a, np.float64, ["F_CONTIGUOUS", "WRITEABLE"])     # a copy only if it is not one already
    rows = a.T
    if a.ndim != 2 or rows.shape[1] < rows.shape[0]:
        raise ValueError(f"a must be a matrix of at least as many rows as columns, not of shape {a.shape}")
    R = np.empty((rows.shape[0], rows.shape[0]))
    _core.hc_qr_rows(rows, rows.shape[0], rows.shape[1], R)
    return R


def _merge(upper: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """``R`` of two stacked triangular factors."""
    return _triangle(np.vstack([upper, lower]))


def triangular_factor(columns, y) -> np.ndarray:
    """Upper-triangular factor ``R`` (``(p + 1, p + 1)``) of the QR factorisation of ``[X y]``.

    Up to :data:`WHOLE_FACTOR_BYTES`, ``[X y]`` is copied whole and factored
    in one call.  Past it, each block of samples is factored on its own and the factors are merged
    pairwise as in a binary counter (a reduction tree: every sample passes
    through about ``log2(N / BLOCK_SAMPLES)`` merges, so rounding errors grow
    far more slowly than when each block is stacked under one running factor).

    Parameters
    ----------
    columns : sequence of array_like, shape (N,) or (p_i, N)
        The columns of ``X``.
    y : array_like, shape (N,)
        The fitted signal.

    Returns
    -------
    ndarray
        ``R``; all NaN if a column or ``y`` holds a non-finite value (or, held whole, if the factorisation
        overflows).
    """
    y = np.asarray(y, dtype=float)
    rows = _rows(columns)
    for a in rows:
        _check_length(a, y.shape[0])
    width = sum(a.shape[0] for a in rows)
    if not held_whole(width, y.shape[0]):
        return factor_of_columns(column_blocks(rows, y.shape[0]), y, width)
    whole = np.empty((width + 1, y.shape[0]))
    j = 0
    for a in rows:
        whole[j:j + a.shape[0]] = a
        j += a.shape[0]
    whole[-1] = y
    return factor_of_rows(whole)


def held_whole(width: int, n_samples: int) -> bool:
    """Whether :func:`triangular_factor` factors ``[X y]`` of ``width`` columns held whole (in one call).

    Examples
    --------
    >>> held_whole(5, 12_000), held_whole(5, 1_000_000), held_whole(5, 5)
    (True, False, False)
    """
    return 8 * (width + 1) * n_samples <= WHOLE_FACTOR_BYTES and n_samples > width


def factor_of_rows(whole: np.ndarray) -> np.ndarray:
    """:func:`triangular_factor` of ``[X y]`` held whole as C-ordered rows ``(p + 1, N)`` (overwritten), ``y`` last.

    The rows' transpose is ``[X y]`` in Fortran order, which is factored
    where it lies, so a caller may simulate its columns straight into
    ``whole``.  All NaN if a value is not finite (or the factorisation overflows).

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 20)
    >>> bool(np.array_equal(factor_of_rows(np.vstack([t, 3.0 * t])), triangular_factor([t], 3.0 * t)))
    True
    """
    R = _triangle(whole.T)
    # a NaN or inf anywhere reaches R (a column's norm, then every reflector after it): checking the small R
    # instead of the whole copy saves a pass over it
    return R if np.all(np.isfinite(R)) else np.full(R.shape, np.nan)


def _check_length(a: np.ndarray, n_samples: int):
    """Raise unless the columns ``a`` (``(p_i, N)``) have as many samples as ``y``."""
    if a.shape[1] != n_samples:
        raise DataError(f"a column has {a.shape[1]} samples where y has {n_samples}")


def column_blocks(columns, n_samples: int):
    """``(begin, X)``: the columns at consecutive blocks of :data:`BLOCK_SAMPLES` samples.

    ``X`` (``(L, p)``) is one reused buffer: use each block before asking
    for the next.  This is the form :func:`factor_of_columns` and
    :func:`residual_of_columns` take; a caller whose columns are computed a
    block at a time (never held whole) yields it itself.

    Examples
    --------
    >>> [(begin, X.shape) for begin, X in column_blocks([np.arange(3.0), np.ones((2, 3))], 3)]
    [(0, (3, 3))]
    """
    rows = _rows(columns)
    buffer = np.empty((min(BLOCK_SAMPLES, n_samples), sum(a.shape[0] for a in rows)))
    for begin in range(0, n_samples, BLOCK_SAMPLES):
        stop = min(begin + BLOCK_SAMPLES, n_samples)
        X = buffer[:stop - begin]
        _fill(rows, begin, stop, X)
        yield begin, X


def factor_of_columns(blocks, y, width: int) -> np.ndarray:
    """:func:`triangular_factor` of ``[X y]`` from ``(begin, X)`` blocks of ``width`` columns (:func:`column_blocks`).

    Examples
    --------
    >>> t = np.arange(5.0)
    >>> R = factor_of_columns(column_blocks([t], 5), 2.0 * t, 1)
    >>> solve_scaled(R, 5).round(12).tolist()
    [2.0]
    """
    y = np.asarray(y, dtype=float)

    def parts():
        buffer = np.empty((min(BLOCK_SAMPLES, y.shape[0]), width + 1), order="F")
        done = 0
        for begin, X in blocks:
            done = _next_block(begin, X, done, width, y.shape[0])
            if X.shape[0] > buffer.shape[0]:
                buffer = np.empty((X.shape[0], width + 1), order="F")
            part = buffer[:X.shape[0]]
            part[:, :-1] = X
            part[:, -1] = y[begin:done]
            yield part
        _check_covered(done, y.shape[0])
    return factor_of_blocks(parts(), width + 1)


def _next_block(begin: int, X: np.ndarray, done: int, width: int, n_samples: int) -> int:
    """The samples covered after block ``(begin, X)``; raise unless it has ``width`` columns and follows ``0:done``."""
    if X.ndim != 2 or X.shape[1] != width:
        raise DataError(f"a block of columns has shape {X.shape}: expected (samples, {width}) for {width} columns")
    if begin != done or begin + X.shape[0] > n_samples:
        raise DataError(f"blocks must cover the {n_samples} samples of y in order: a block of {X.shape[0]} samples "
                        f"starts at sample {begin}, expected {done}")
    return done + X.shape[0]


def _check_covered(done: int, n_samples: int):
    """Raise unless the blocks covered all ``n_samples`` samples of ``y``."""
    if done != n_samples:
        raise DataError(f"the blocks cover {done} of the {n_samples} samples of y")


def factor_of_blocks(blocks, width: int) -> np.ndarray:
    """Upper-triangular ``R`` (``width x width``) of the rows of consecutive blocks, reduced as a tree.

    Parameters
    ----------
    blocks : iterable of ndarray, shape (L_i, width)
        The matrix, a block of rows at a time (each may be overwritten).
    width : int

    Returns
    -------
    ndarray
        ``R`` with ``R^T R`` the Gram matrix of all the rows; all NaN if a
        block holds a non-finite value.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.random.default_rng(0).normal(size=(50, 3))
    >>> R = factor_of_blocks((A[i:i + 7].copy() for i in range(0, 50, 7)), 3)
    >>> bool(np.allclose(R.T @ R, A.T @ A))
    True
    """
    pending: list[tuple[int, np.ndarray]] = []  # (level, R) with strictly decreasing levels
    for part in blocks:
        if not np.all(np.isfinite(part)):
            return np.full((width, width), np.nan)
        if np.ndim(part) != 2 or np.shape(part)[1] != width:
            raise ValueError(f"a block of shape {np.shape(part)} does not have the {width} columns of the factor")
        if part.shape[0] < width:  # a block shorter than the triangle: zero rows
            part = np.vstack([part, np.zeros((width - part.shape[0], width))])
        level, R = 0, _triangle(part)
        while pending and pending[-1][0] == level:
            R = _merge(pending.pop()[1], R)
            level += 1
        pending.append((level, R))
    R = pending.pop()[1] if pending else np.zeros((width, width))
    while pending:
        R = _merge(pending.pop()[1], R)
    return R


def rank_tolerance(n_samples: int) -> float:
    """Relative singular value below which a direction of unit-norm columns is rounding: ``eps sqrt(N)``.

    The rounding errors of a factorisation of ``N`` rows accumulate to about
    this much in each unit-norm column, so a column closer than that to the
    span of the others is treated as dependent whichever way ``R`` was
    accumulated.  Columns that are dependent but for the simulation's rounding
    (an offset and the free response of a pole at the origin; a step response,
    a constant and the free responses) show relative singular values of
    ``1e-16`` to ``1e-14``: a cut at ``eps`` kept some of them and fitted the
    rounding with coefficients of ``1e13``.

    Examples
    --------
    >>> float(rank_tolerance(10**4) / np.finfo(float).eps)
    100.0
    """
    return float(np.finfo(float).eps * np.sqrt(max(n_samples, 1)))


def solve_scaled(R: np.ndarray, n_samples: int) -> np.ndarray | None:
    """Least-squares coefficients from ``R``, columns scaled to unit norm (``gelsy``, rank-revealing).

    Directions below :func:`rank_tolerance` are dropped.  Returns ``None``
    when ``R`` or a column norm is not finite.
    """
    scaled = _scaled_factor(R)
    if scaled is None:
        return None
    T, scale = scaled
    p, cond = T.shape[1], rank_tolerance(n_samples)
    if p == 0:
        return np.zeros(0)
    # LAPACK's gelsy as scipy.linalg.lstsq calls it (the same bits), without its checks and workspace query
    w = _lapack()["gelsy"](T, R[:-1, -1].copy(), np.zeros((p, 1), dtype=np.int32), cond, _gelsy_work(p), True, True)[1]
    return w / scale


def column_scale(R11: np.ndarray) -> np.ndarray:
    """The norms of the columns of ``X`` from its factor ``R11`` (columns of ``R11``), a zero norm taken as 1.

    Examples
    --------
    >>> column_scale(np.array([[3.0, 1.0], [0.0, 0.0]])).tolist()
    [3.0, 1.0]
    >>> column_scale(np.zeros((2, 2))).tolist()
    [1.0, 1.0]
    """
    with np.errstate(all="ignore"):
        scale = np.sqrt(np.sum(R11 * R11, axis=0))
    scale[scale == 0] = 1.0
    return scale


def _scaled_factor(R: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(R_11 / scale, scale)``: the factor of ``X`` (``R`` of ``[X y]``) with its columns scaled to unit norm,
    and the scale (:func:`column_scale`); ``None`` when ``R`` or a column norm is not finite."""
    R11 = R[:-1, :-1]
    scale = column_scale(R11)
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(scale))):
        return None
    return R11 / scale, scale


def _clear_of_rank_loss(T: np.ndarray, cut: float) -> bool:
    """Whether the smallest singular value of ``T`` (upper triangular, unit-norm columns) exceeds ``cut`` times the
    largest.

    Mostly decided without the SVD: the largest is at most ``sqrt(p)`` (the
    Frobenius norm of ``p`` unit columns) and the smallest at least
    ``1 / |T^-1|_F``, so ``2 sqrt(p) cut |T^-1|_F < 1`` (the factor 2 for the
    rounding of an inverse whose condition is then below ``1 / cut``) proves
    it, in a microsecond of the compiled core's back substitution; the SVD
    (27 us through numpy) decides the rest.
    """
    p = T.shape[0]
    if p == 0:
        return True
    T = np.ascontiguousarray(T, dtype=float)
    bound = _core.hc_triangular_inverse_norm(T, p) if T.shape == (p, p) else np.inf
    if 2.0 * np.sqrt(p) * cut * bound < 1.0:
        return True
    sigma = np.linalg.svd(T, compute_uv=False)
    return bool(sigma[-1] > cut * sigma[0])


@functools.lru_cache(maxsize=64)
def _gelsy_work(p: int) -> int:
    """Workspace size of LAPACK's gelsy for a ``p x p`` system and one right-hand side (whatever the cut)."""
    work, info = _lapack()["gelsy_lwork"](p, p, 1, np.finfo(float).eps)
    if info != 0:  # pragma: no cover - only for invalid arguments
        raise RuntimeError(f"gelsy's workspace query failed (info = {info})")
    return int(work)


def solve_minimum_norm(R: np.ndarray, n_samples: int) -> np.ndarray:
    """Minimum-norm least-squares coefficients from ``R`` (SVD), cut as ``numpy.linalg.lstsq`` on ``X``.

    Singular values below ``eps max(N, p)`` times the largest are treated as
    zero, the default of ``numpy.linalg.lstsq(X, y, rcond=None)``.
    """
    p = R.shape[0] - 1
    rcond = np.finfo(float).eps * max(n_samples, p)
    return np.linalg.lstsq(R[:-1, :-1], R[:-1, -1], rcond=rcond)[0]


def factor_sse(R: np.ndarray, w) -> float:
    """Sum of squared residuals ``|y - X w|^2`` from ``R``: ``|R_11 w - z|^2 + R_pp^2``."""
    d = R[:-1, :-1] @ np.asarray(w, dtype=float) - R[:-1, -1]
    return float(d @ d + R[-1, -1] ** 2)


def residual(columns, w, y) -> np.ndarray:
    """The residual vector ``y - X w``.

    The columns are held (rows of arrays), so each source's rows are combined
    with their coefficients in one product: no block of ``X`` is formed.

    Examples
    --------
    >>> residual([np.arange(3.0)], [2.0], np.array([1.0, 2.0, 3.0])).tolist()
    [1.0, 0.0, -1.0]
    """
    y = np.asarray(y, dtype=float)
    w = np.asarray(w, dtype=float).reshape(-1)
    rows = _rows(columns)
    for a in rows:
        _check_length(a, y.shape[0])
    width = sum(a.shape[0] for a in rows)
    if w.size != width:
        raise DataError(f"{w.size} coefficients for {width} columns")
    return y.copy() if width == 0 else y - _combination(rows, w[:, None])[0]


def _combination(rows, C: np.ndarray) -> np.ndarray:
    """``C^T X^T``: each column of ``C`` (``(p, m)``) combines the columns of ``X`` (``(m, N)``)."""
    out, j = None, 0
    for a in rows:
        part = C[j:j + a.shape[0]].T @ a
        out = part if out is None else np.add(out, part, out=out)
        j += a.shape[0]
    return out


def _products(rows, Z: np.ndarray) -> np.ndarray:
    """``X^T Z^T`` (``(p, m)``) for the rows ``Z`` (``(m, N)``) of other signals."""
    return np.vstack([a @ Z.T for a in rows])


def independent(R: np.ndarray, cut: float) -> bool:
    """Whether the columns of ``X`` are independent above ``cut``: the smallest singular value of its factor
    ``R_11`` (``R`` of ``[X y]``), columns scaled to unit norm, exceeds ``cut`` times the largest.

    The diagonal of a factor without pivoting cannot say so: it bounds the
    smallest singular value from above only (three columns each within
    ``3e-8`` of the next span a plane to ``1e-15``).

    False when ``R`` or a column norm is not finite.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 50)
    >>> independent(triangular_factor([t, 2.0 * t], t), 1e-8), independent(triangular_factor([t, t * t], t), 1e-8)
    (False, True)
    """
    scaled = _scaled_factor(R)
    return scaled is not None and _clear_of_rank_loss(scaled[0], cut)


def _inverse_factor(T: np.ndarray, cut: float) -> np.ndarray:
    """``T^+`` of an upper-triangular ``T`` with unit-norm columns, singular values below ``cut`` times the largest
    dropped: LAPACK's triangular inverse where none is, else the pseudo-inverse."""
    if T.size and _clear_of_rank_loss(T, cut):
        inverse, info = _lapack()["trtri"](T, lower=0)
        if info == 0 and np.all(np.isfinite(inverse)):
            return inverse
    return np.linalg.pinv(T, rcond=cut)


def orthogonal_part(columns, R: np.ndarray, Z) -> np.ndarray:
    """The rows of ``Z`` less their least-squares fit by the columns: ``(I - P_X) Z^T``, as rows.

    ``R`` is the :func:`triangular_factor` of ``[X y]``.  The coefficients
    come from ``R`` by the semi-normal equations ``R^T R C = X^T Z^T``, with
    the columns scaled to unit norm and directions below
    :func:`rank_tolerance` dropped as in :func:`solve_scaled`: their error
    grows with the square of the condition number, but what is left of ``Z``
    (the part along the columns removed) errs by about ``cond(X) eps``
    (measured: 4e-10 of ``Z`` at a condition number of 1e6, 1e-6 at 1e10),
    ample for a variable-projection Jacobian, which uses it: how a change of
    the simulated columns moves the residual once the linear coefficients follow.

    Parameters
    ----------
    columns : sequence of array_like, shape (N,) or (p_i, N)
        The columns of ``X``, held.
    R : ndarray, shape (p + 1, p + 1)
    Z : array_like, shape (m, N)

    Returns
    -------
    ndarray, shape (m, N)
        ``Z`` itself without columns; all NaN if ``R`` or a column norm is not finite.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 5)
    >>> columns = [np.ones(5)]
    >>> R = triangular_factor(columns, t)
    >>> orthogonal_part(columns, R, t[None, :]).round(12).tolist()     # t less its mean
    [[-0.5, -0.25, 0.0, 0.25, 0.5]]
    """
    rows = _rows(columns)
    Z = np.atleast_2d(np.asarray(Z, dtype=float))
    for a in rows:
        _check_length(a, Z.shape[1])
    if not rows:
        return Z.copy()
    scaled = _scaled_factor(R)
    if scaled is None:
        return np.full(Z.shape, np.nan)
    T, scale = scaled
    inverse = _inverse_factor(T, rank_tolerance(Z.shape[1]))
    coefficients = (inverse @ (inverse.T @ (_products(rows, Z) / scale[:, None]))) / scale[:, None]
    return Z - _combination(rows, coefficients)


def residual_of_columns(blocks, w, y) -> np.ndarray:
    """:func:`residual` ``y - X w`` from ``(begin, X)`` blocks (:func:`column_blocks`).

    Examples
    --------
    >>> residual_of_columns(column_blocks([np.ones(3)], 3), [0.5], np.arange(3.0)).tolist()
    [-0.5, 0.5, 1.5]
    """
    y = np.asarray(y, dtype=float)
    w = np.asarray(w, dtype=float)
    out = np.empty(y.shape[0])
    done = 0
    for begin, X in blocks:
        done = _next_block(begin, X, done, w.size, y.shape[0])
        np.subtract(y[begin:done], X @ w, out=out[begin:done])
    _check_covered(done, y.shape[0])
    return out
