"""Small dense linear algebra, in the package's compiled core.

The simulator needs one matrix exponential of a tiny matrix (``n + 2`` rows,
``n`` the order of the linear block) per candidate.  ``scipy.linalg.expm``
hands these to multi-threaded BLAS, whose threads spin against other work on a
busy machine (it made ``identify`` 12-90x slower there), and costs tens of
microseconds of call overhead.  :func:`expm_batch` is Higham's (2005)
scaling-and-squaring algorithm with the degree-13 Pade approximant, written as
plain loops: single-threaded, accurate to a few units of roundoff, and a few
microseconds for a 4x4 matrix.

These functions are C in the compiled core (``hammerstein_ctrl._core``, built
when the package is installed); the core's own kernels call the same C, so
both give the same bits.

Examples
--------
>>> import numpy as np, scipy.linalg
>>> M = np.array([[[0.0, 1.0], [-2.0, -3.0]]])
>>> bool(np.allclose(expm_batch(M), scipy.linalg.expm(M), rtol=1e-14, atol=1e-15))
True
"""

from __future__ import annotations

import contextlib
import functools
import threading

import numpy as np

from . import _core

__all__ = ["fill_coefficients", "filled_coefficients", "positions_fit", "expm_batch", "expm_into",
           "one_norm", "tf_augmented", "tf_discrete", "tf_discrete_into", "single_threaded_blas", "solve_in_place",
           "symmetric_eigenvalues"]


def _input(array, dtype=np.float64) -> np.ndarray:
    """``array`` as a C-ordered array of ``dtype`` the library reads (a copy only if need be)."""
    return np.ascontiguousarray(array, dtype=dtype)


def _square(M, what: str) -> np.ndarray:
    """``M`` as a C-ordered float square matrix, else a ``ValueError`` (the C code reads ``n x n`` values)."""
    M = _input(M)
    if M.ndim != 2 or M.shape[0] != M.shape[1]:
        raise ValueError(f"{what} must be a square matrix, not an array of shape {M.shape}")
    return M


def _rows(num, den):
    """``num``, ``den`` as C-ordered float rows, as many of each, ``den`` with a leading coefficient and no fewer
    than ``num``'s; else a ``ValueError``."""
    num, den = _input(num), _input(den)
    if num.ndim != 2 or den.ndim != 2 or num.shape[0] != den.shape[0] or not 1 <= num.shape[1] <= den.shape[1]:
        raise ValueError(f"num and den must be rows of coefficients, as many of each, den no shorter: shapes "
                         f"{num.shape} and {den.shape}")
    return num, den


def _shaped(array, shape: tuple, what: str):
    """``array`` itself if it has ``shape`` (the C code writes that many values), else a ``ValueError``."""
    if getattr(array, "shape", None) != shape:
        raise ValueError(f"{what} must have shape {shape}, not {getattr(array, 'shape', type(array).__name__)}")
    return array


def one_norm(M) -> float:
    """Largest absolute column sum of the square ``M`` (a NaN column is passed over, as Python's ``max`` does).

    Examples
    --------
    >>> one_norm(np.array([[1.0, -2.0], [3.0, 4.0]]))
    6.0
    """
    M = _square(M, "M")
    return _core.hc_one_norm(M, M.shape[0])


def solve_in_place(A, B) -> None:
    """Overwrite ``B`` (``n x m``) with ``A^-1 B``: Gaussian elimination with partial pivoting, ``A`` destroyed.

    A singular ``A`` leaves non-finite entries in ``B`` (no exception): NaN when
    elimination meets a zero pivot, else whatever the tiny pivots give.

    Examples
    --------
    >>> B = np.array([[1.0], [2.0]])
    >>> solve_in_place(np.array([[2.0, 0.0], [0.0, 4.0]]), B)
    >>> B.ravel().tolist()
    [0.5, 0.5]
    """
    if getattr(A, "ndim", 0) != 2 or A.shape[0] != A.shape[1]:
        raise ValueError(f"A must be a square matrix, not {getattr(A, 'shape', type(A).__name__)}")
    n = A.shape[0]
    if getattr(B, "ndim", 0) != 2 or B.shape[0] != n:
        raise ValueError(f"B must be a matrix of {n} rows, not {getattr(B, 'shape', type(B).__name__)}")
    _core.hc_solve_in_place(A, n, B, B.shape[1])


def symmetric_eigenvalues(S) -> np.ndarray:
    """Eigenvalues of the symmetric, finite ``S`` in ascending order (cyclic Jacobi, at most 60 sweeps; ``S``
    unchanged).

    Each rotation is skipped once ``|a_pq| <= eps sqrt(|a_pp a_qq|)``, the
    test that gives small eigenvalues of definite matrices to high relative
    accuracy (Demmel and Veselic 1992).

    Examples
    --------
    >>> symmetric_eigenvalues(np.array([[2.0, 1.0], [1.0, 2.0]])).round(12).tolist()
    [1.0, 3.0]
    """
    A = np.array(_square(S, "S"), order="C")
    w = np.empty(A.shape[0])
    _core.hc_symmetric_eigenvalues(A, A.shape[0], w)
    return w


def expm_into(M, out) -> None:
    """``out[:, :] = expm(M)`` for one square matrix (NaN if ``M`` is not finite); ``out`` may be ``M`` itself.

    Examples
    --------
    >>> out = np.empty((1, 1))
    >>> expm_into(np.array([[1.0]]), out)
    >>> bool(np.isclose(out[0, 0], np.e))
    True
    """
    M = _square(M, "M")
    _core.hc_expm(M, M.shape[0], _shaped(out, M.shape, "out"))


def tf_augmented(num, den, dt):
    """Augmented matrices ``[[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]]`` of the companion realisations of num/den rows.

    Parameters
    ----------
    num, den : ndarray, shape (B, l+1) and (B, n+1)
        Descending powers, ``l <= n``, ``den[:, 0] != 0``.
    dt : float

    Returns
    -------
    M : ndarray, shape (B, n+2, n+2)
    C : ndarray, shape (B, n)
    D : ndarray, shape (B,)

    Examples
    --------
    >>> M, C, D = tf_augmented(np.array([[1.0]]), np.array([[1.0, 2.0]]), 0.5)   # 1/(p + 2)
    >>> M[0]
    array([[-1. ,  0.5,  0. ],
           [ 0. ,  0. ,  1. ],
           [ 0. ,  0. ,  0. ]])
    >>> C[0], D[0]
    (array([1.]), np.float64(0.0))
    """
    num, den = _rows(num, den)
    batch, n = den.shape[0], den.shape[1] - 1
    M, C, D = np.empty((batch, n + 2, n + 2)), np.empty((batch, n)), np.empty(batch)
    _core.hc_tf_augmented(num, den, batch, num.shape[1], den.shape[1], float(dt),
                             M, C, D)
    return M, C, D


def tf_discrete_into(num, den, dt, max_norm, E, C, D, ok, big) -> bool:
    """:func:`tf_discrete` into the caller's arrays ``E`` (B, n+2, n+2), ``C`` (B, n), ``D``, ``ok`` and ``big`` (B,);
    returns ``clean``.

    The C code checks no index, so this door checks every shape it passes
    (a ``ValueError`` naming the array).

    Examples
    --------
    >>> E, C, D = np.empty((1, 3, 3)), np.empty((1, 1)), np.empty(1)
    >>> ok, big = np.empty(1, dtype=bool), np.empty(1, dtype=bool)
    >>> tf_discrete_into(np.array([[1.0]]), np.array([[1.0, 2.0]]), 0.5, 64.0, E, C, D, ok, big)
    True
    >>> bool(np.isclose(E[0, 0, 0], np.exp(-1.0))), C[0, 0], D[0]
    (True, np.float64(1.0), np.float64(0.0))
    """
    num, den = _rows(num, den)
    batch, n = den.shape[0], den.shape[1] - 1
    for array, shape, what in ((E, (batch, n + 2, n + 2), "E"), (C, (batch, n), "C"), (D, (batch,), "D"),
                               (ok, (batch,), "ok"), (big, (batch,), "big")):
        _shaped(array, shape, what)
    return _core.hc_tf_discrete(num, den, den.shape[0], num.shape[1], den.shape[1],
                                   float(dt), float(max_norm), E, C, D,
                                   ok, big)


def tf_discrete(num, den, dt, max_norm):
    """:func:`tf_augmented` and the exponential in one call.

    Returns ``(E, C, D, ok, big, clean)``: unusable rows (``~ok``) are
    replaced by ``1/p`` before the exponential; rows whose augmented matrix
    has a 1-norm above ``max_norm`` (``big``) are left for scipy's expm
    (their ``E`` is not set); ``clean`` says that every row is usable and done.

    Examples
    --------
    >>> E, C, D, ok, big, clean = tf_discrete(np.array([[1.0]]), np.array([[1.0, 2.0]]), 0.5, 64.0)
    >>> bool(np.isclose(E[0, 0, 0], np.exp(-1.0))), bool(clean)
    (True, True)
    """
    batch, m = den.shape[0], den.shape[1] + 1
    E, C, D = np.empty((batch, m, m)), np.empty((batch, m - 2)), np.empty(batch)
    ok, big = np.empty(batch, dtype=np.bool_), np.empty(batch, dtype=np.bool_)
    clean = tf_discrete_into(num, den, dt, max_norm, E, C, D, ok, big)
    return E, C, D, ok, big, clean


def expm_batch(M) -> np.ndarray:
    """Matrix exponential of each matrix in a ``(B, m, m)`` stack.

    Non-finite matrices give NaN results instead of raising.

    Parameters
    ----------
    M : array_like, shape (B, m, m)

    Returns
    -------
    ndarray, shape (B, m, m)
    """
    M = _input(M)
    if M.ndim != 3 or M.shape[1] != M.shape[2]:
        raise ValueError(f"M must be a stack of square matrices, not an array of shape {M.shape}")
    E = np.empty_like(M)
    m = M.shape[1]
    for k in range(M.shape[0]):
        _core.hc_expm(M[k], m, E[k])
    return E


@functools.lru_cache(maxsize=1)
def _controller():
    import scipy.linalg  # noqa: F401  (scipy's OpenBLAS, a library apart from numpy's, must be loaded to be found)
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


#: How many :func:`single_threaded_blas` blocks are open in the process, and the pools the first one
#: limited, with the thread counts to restore.
_BLAS_LIMIT = {"depth": 0, "saved": []}
_BLAS_LOCK = threading.Lock()


def single_threaded_blas():
    """Context manager holding BLAS and OpenMP thread pools to one thread.

    Small dense linear algebra gains nothing from threads, and on a busy
    machine the spinning worker threads of OpenBLAS made each call tens of
    times slower.  The controller is built once per process (inspecting the
    loaded libraries is the expensive part; numpy's and scipy's BLAS are both
    among them).  The limits are process-wide, so blocks are counted across
    threads: the first to open sets each pool that has more than one thread
    (a few microseconds), the last to close restores them, and blocks nested
    in those (``identify`` calls ``minimize``, which calls its solver) cost nothing.  The
    manager is a class rather than a generator: about 8 µs to enter and leave the outermost block instead of 11.
    It also decorates a function (``@single_threaded_blas()``), which then runs whole under the limit.

    Examples
    --------
    >>> import numpy as np
    >>> with single_threaded_blas():
    ...     float(np.linalg.det(np.eye(3)))
    1.0
    """
    return _SINGLE_THREADED_BLAS


class _SingleThreadedBlas(contextlib.ContextDecorator):
    """The context manager of :func:`single_threaded_blas` (one for the process: its state is process-wide)."""

    __slots__ = ()

    def __enter__(self):
        with _BLAS_LOCK:
            if _BLAS_LIMIT["depth"] == 0:
                with _CONTROLLING_THIS_THREAD:
                    _BLAS_LIMIT["saved"] = _limit_pools(_controller().lib_controllers)
            _BLAS_LIMIT["depth"] += 1
        return self

    def __exit__(self, *exc_info):
        with _BLAS_LOCK:
            _BLAS_LIMIT["depth"] -= 1
            if _BLAS_LIMIT["depth"] == 0:
                with _CONTROLLING_THIS_THREAD:
                    for pool, threads in _BLAS_LIMIT["saved"]:
                        pool.set_num_threads(threads)
                _BLAS_LIMIT["saved"] = []
        return False


def _limit_pools(pools) -> list:
    """Set each of threadpoolctl's library controllers ``pools`` to one thread; ``[(pool, threads before)]`` of those
    changed."""
    saved = []
    for pool in pools:
        threads = pool.get_num_threads()
        if threads is not None and threads != 1:
            pool.set_num_threads(1)
            saved.append((pool, threads))
    return saved


class _ControllingThisThread:
    """Let this thread set OpenBLAS's process-wide pool, then let any thread do so again.

    threadpoolctl (3.8) lets only the first thread that set a limit change it
    again; the block that closes last may run in another thread.
    """

    __slots__ = ()

    def __enter__(self):
        _release_control()
        return self

    def __exit__(self, *exc_info):
        _release_control()
        return False


def _release_control():
    clear = _clear_controlling_thread()
    if clear is not None:
        clear(force=True)


@functools.lru_cache(maxsize=1)
def _clear_controlling_thread():
    """threadpoolctl's ``OpenBLASController.clear_controlling_thread``, or ``None`` in versions without it."""
    import threadpoolctl

    return getattr(getattr(threadpoolctl, "OpenBLASController", None), "clear_controlling_thread", None)


_SINGLE_THREADED_BLAS, _CONTROLLING_THIS_THREAD = _SingleThreadedBlas(), _ControllingThisThread()


def fill_coefficients(theta, num0, den0, num_pos, den_pos):
    """Rows of ``num0``/``den0`` with the free coefficients of each row of ``theta`` written in (one call per batch):
    the first ``num_pos.size`` at ``num_pos``, the next ``den_pos.size`` at ``den_pos``.

    Examples
    --------
    >>> num, den = fill_coefficients(np.array([[5.0, 7.0]]), np.array([0.0]), np.array([1.0, 0.0]),
    ...                              np.array([0]), np.array([1]))
    >>> num.tolist(), den.tolist()
    ([[5.0]], [[1.0, 7.0]])
    """
    theta, num0, den0 = _input(theta), _input(num0), _input(den0)
    num_pos, den_pos = _input(num_pos, np.int64), _input(den_pos, np.int64)
    if theta.ndim != 2 or theta.shape[1] < num_pos.size + den_pos.size:
        raise ValueError(f"theta must have rows of at least {num_pos.size + den_pos.size} values, not shape "
                         f"{theta.shape}")
    if not positions_fit(num0, den0, num_pos, den_pos):
        raise ValueError(f"positions {num_pos.tolist()} and {den_pos.tolist()} must index num0 ({num0.size} values) "
                         f"and den0 ({den0.size})")
    return filled_coefficients(theta, num0, den0, num_pos, den_pos)


def positions_fit(num0, den0, num_pos, den_pos) -> bool:
    """Whether the positions ``num_pos``/``den_pos`` index ``num0``/``den0`` (what the compiled core writes at).

    Examples
    --------
    >>> positions_fit(np.zeros(1), np.zeros(3), np.array([0]), np.array([1, 2])), positions_fit(
    ...     np.zeros(1), np.zeros(3), np.array([1]), np.array([1]))
    (True, False)
    """
    return bool(np.all((0 <= num_pos) & (num_pos < np.size(num0)))
                and np.all((0 <= den_pos) & (den_pos < np.size(den0))))


def filled_coefficients(theta, num0, den0, num_pos, den_pos):
    """:func:`fill_coefficients` for arrays a caller has checked once (C-ordered, of the core's types, positions
    within ``num0``/``den0``, rows of ``theta`` long enough): a structure's template, on every evaluation."""
    num, den = np.empty((theta.shape[0], num0.size)), np.empty((theta.shape[0], den0.size))
    _core.hc_fill_coefficients(theta, theta.shape[0], theta.shape[1], num0, num0.size,
                                  den0, den0.size, num_pos, num_pos.size,
                                  den_pos, den_pos.size, num, den)
    return num, den

