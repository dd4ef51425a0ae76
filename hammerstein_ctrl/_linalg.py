"""Small dense linear algebra in compiled code, without BLAS.

The simulator needs one matrix exponential of a tiny matrix (``n + 2`` rows,
``n`` the order of the linear block) per candidate.  ``scipy.linalg.expm``
hands these to multi-threaded BLAS, whose threads spin against other work on a
busy machine (it made ``identify`` 12-90x slower there), and costs tens of
microseconds of call overhead.  :func:`expm_batch` is Higham's (2005)
scaling-and-squaring algorithm with the degree-13 Pade approximant, written as
plain loops: single-threaded, accurate to a few units of roundoff, and a few
microseconds for a 4x4 matrix.

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

from ._attributes import never_inline
from ._jit import cached_njit

__all__ = ["copy_vector", "fill_coefficients", "expm_batch", "expm_into", "tf_augmented", "tf_discrete",
           "tf_discrete_into", "single_threaded_blas", "solve_in_place", "symmetric_eigenvalues", "PADE13_THETA",
           "JACOBI_MAX_SWEEPS"]

#: Largest 1-norm for which the degree-13 Pade approximant is accurate to unit
#: roundoff without scaling (Higham 2005, Table 2.3).
PADE13_THETA = 5.371920351148152

#: Coefficients b_0 .. b_13 of the degree-13 Pade approximant (Higham 2005).
_B13 = np.array([
    64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
    129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
    40840800.0, 960960.0, 16380.0, 182.0, 1.0,
])


@cached_njit()
def _matmul(X, Y, out):  # pragma: no cover - compiled
    never_inline()                      # six calls in the exponential: one copy of its loops, not six
    n = X.shape[0]
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                s += X[i, k] * Y[k, j]
            out[i, j] = s


@cached_njit()
def solve_in_place(A, B):  # pragma: no cover - compiled
    """Overwrite ``B`` (``n x m``) with ``A^-1 B``: Gaussian elimination with partial pivoting, ``A`` destroyed.

    A singular ``A`` leaves non-finite entries in ``B`` (no exception): NaN when
    elimination meets a zero pivot, else whatever the tiny pivots give.

    Examples
    --------
    >>> import numpy as np
    >>> B = np.array([[1.0], [2.0]])
    >>> solve_in_place(np.array([[2.0, 0.0], [0.0, 4.0]]), B)
    >>> B.ravel().tolist()
    [0.5, 0.5]
    """
    n, m = A.shape[0], B.shape[1]
    for col in range(n):
        piv = col
        best = abs(A[col, col])
        for r in range(col + 1, n):
            if abs(A[r, col]) > best:
                best, piv = abs(A[r, col]), r
        if piv != col:
            for c in range(n):
                A[col, c], A[piv, c] = A[piv, c], A[col, c]
            for c in range(m):
                B[col, c], B[piv, c] = B[piv, c], B[col, c]
        d = A[col, col]
        if d == 0.0:                    # a zero column below the diagonal: A is singular
            for r in range(n):
                for c in range(m):
                    B[r, c] = np.nan
            return
        for r in range(col + 1, n):
            f = A[r, col] / d
            if f != 0.0:
                for c in range(col, n):
                    A[r, c] -= f * A[col, c]
                for c in range(m):
                    B[r, c] -= f * B[col, c]
    for col in range(n - 1, -1, -1):
        d = A[col, col]
        for c in range(m):
            s = B[col, c]
            for k in range(col + 1, n):
                s -= A[col, k] * B[k, c]
            B[col, c] = s / d


#: Most sweeps of the Jacobi eigenvalue method (it converges quadratically: a few sweeps suffice).
JACOBI_MAX_SWEEPS = 60


@cached_njit()
def _rotate(A, p, q):  # pragma: no cover - compiled
    """One Jacobi rotation of the symmetric ``A`` zeroing ``A[p, q]``; False if it is already negligible."""
    apq = A[p, q]
    app, aqq = A[p, p], A[q, q]
    if abs(apq) <= np.finfo(np.float64).eps * (np.sqrt(abs(app)) * np.sqrt(abs(aqq))) or apq == 0.0:
        return False
    theta = (aqq - app) / (2.0 * apq)
    t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
    if theta < 0.0:
        t = -t
    c = 1.0 / np.sqrt(t * t + 1.0)
    s = t * c
    n = A.shape[0]
    for k in range(n):
        akp, akq = A[k, p], A[k, q]
        A[k, p] = c * akp - s * akq
        A[k, q] = s * akp + c * akq
    for k in range(n):
        apk, aqk = A[p, k], A[q, k]
        A[p, k] = c * apk - s * aqk
        A[q, k] = s * apk + c * aqk
    return True


@cached_njit()
def symmetric_eigenvalues(S):  # pragma: no cover - compiled
    """Eigenvalues of the symmetric, finite ``S`` in ascending order (cyclic Jacobi; ``S`` unchanged).

    Each rotation is skipped once ``|a_pq| <= eps sqrt(|a_pp a_qq|)``, the
    test that gives small eigenvalues of definite matrices to high relative
    accuracy (Demmel and Veselic 1992).

    Examples
    --------
    >>> import numpy as np
    >>> symmetric_eigenvalues(np.array([[2.0, 1.0], [1.0, 2.0]])).round(12).tolist()
    [1.0, 3.0]
    """
    n = S.shape[0]
    A = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            A[i, j] = S[i, j]
    for _ in range(JACOBI_MAX_SWEEPS):
        rotated = False
        for p in range(n - 1):
            for q in range(p + 1, n):
                rotated = _rotate(A, p, q) or rotated
        if not rotated:
            break
    w = np.empty(n)
    for i in range(n):                  # insertion sort of the diagonal (n is small; np.sort compiles for seconds)
        v = A[i, i]
        j = i
        while j > 0 and w[j - 1] > v:
            w[j] = w[j - 1]
            j -= 1
        w[j] = v
    return w


@cached_njit(inline="always")
def copy_vector(src, dst):  # pragma: no cover - compiled
    """``dst[:] = src`` for vectors of one length, element by element, in compiled code: an array assigned to a
    slice makes numba compile its shape-mismatch reporting (string formatting, about 5 s on a first use).
    The lengths are not checked (``dst``'s is used): the caller makes them equal.

    Examples
    --------
    >>> import numpy as np
    >>> dst = np.zeros(2); copy_vector(np.array([1.0, 2.0]), dst); dst
    array([1., 2.])
    """
    for i in range(dst.shape[0]):
        dst[i] = src[i]


@cached_njit()
def _one_norm(M):  # pragma: no cover - compiled
    """Largest absolute column sum of the square ``M``."""
    n = M.shape[0]
    norm = 0.0
    for j in range(n):
        s = 0.0
        for i in range(n):
            s += abs(M[i, j])
        norm = max(norm, s)
    return norm


@cached_njit()
def _combine3(X, cx, Y, cy, Z, cz, out, add):  # pragma: no cover - compiled
    """``out = cx X + cy Y + cz Z``, or ``out + cx X + ...`` with ``add``, summed left to right as numpy would."""
    n = X.shape[0]
    for i in range(n):
        for j in range(n):
            s = cx * X[i, j]
            if add:
                s = out[i, j] + s
            out[i, j] = (s + cy * Y[i, j]) + cz * Z[i, j]


@cached_njit()
def _copy(src, dst):  # pragma: no cover - compiled
    n = src.shape[0]
    for i in range(n):
        for j in range(n):
            dst[i, j] = src[i, j]


#: Square work matrices of one exponential: A, A^2, A^4, A^6, W, T, U, V, Q.
_EXPM_WORK = 9


@cached_njit()
def _expm_one(M, out, b):  # pragma: no cover - compiled
    """``out = expm(M)``: degree-13 Pade with scaling and squaring, in one block of work memory.

    Written as loops (no array expressions): the compiled code stays small,
    which keeps loading it from the cache quick, and nothing is allocated but
    the work block.
    """
    never_inline()                      # one copy per caller's module, however many times it calls
    n = M.shape[0]
    norm = _one_norm(M)
    if not np.isfinite(norm):
        for i in range(n):
            for j in range(n):
                out[i, j] = np.nan
        return
    s = 0
    if norm > PADE13_THETA:
        s = int(np.ceil(np.log2(norm / PADE13_THETA)))
    work = np.empty((_EXPM_WORK, n, n))
    A, A2, A4, A6, W, T, U, V, Q = (work[0], work[1], work[2], work[3], work[4], work[5], work[6], work[7],
                                    work[8])
    scale = 0.5 ** s
    for i in range(n):
        for j in range(n):
            A[i, j] = M[i, j] * scale
    _matmul(A, A, A2)
    _matmul(A2, A2, A4)
    _matmul(A4, A2, A6)
    _combine3(A6, b[13], A4, b[11], A2, b[9], W, False)
    _matmul(A6, W, T)
    _combine3(A6, b[7], A4, b[5], A2, b[3], T, True)
    for i in range(n):
        T[i, i] += b[1]
    _matmul(A, T, U)
    _combine3(A6, b[12], A4, b[10], A2, b[8], W, False)
    _matmul(A6, W, T)
    _combine3(A6, b[6], A4, b[4], A2, b[2], T, True)
    for i in range(n):
        T[i, i] += b[0]
    for i in range(n):                  # P = V + U (in T), Q = V - U
        for j in range(n):
            Q[i, j] = T[i, j] - U[i, j]
            T[i, j] = T[i, j] + U[i, j]
    solve_in_place(Q, T)
    for _ in range(s):
        _matmul(T, T, V)
        _copy(V, T)
    _copy(T, out)


@cached_njit()
def _expm_batch(M, b):  # pragma: no cover - compiled
    E = np.empty_like(M)
    for k in range(M.shape[0]):
        _expm_one(M[k], E[k], b)
    return E


@cached_njit()
def expm_into(M, out):  # pragma: no cover - compiled
    """``out[:, :] = expm(M)`` for one square matrix, callable from compiled code (NaN if ``M`` is not finite).

    Examples
    --------
    >>> import numpy as np
    >>> out = np.empty((1, 1))
    >>> expm_into(np.array([[1.0]]), out)
    >>> bool(np.isclose(out[0, 0], np.e))
    True
    """
    _expm_one(M, out, _B13)


@cached_njit()
def tf_augmented(num, den, dt):  # pragma: no cover - compiled
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
    >>> import numpy as np
    >>> M, C, D = tf_augmented(np.array([[1.0]]), np.array([[1.0, 2.0]]), 0.5)   # 1/(p + 2)
    >>> M[0]
    array([[-1. ,  0.5,  0. ],
           [ 0. ,  0. ,  1. ],
           [ 0. ,  0. ,  0. ]])
    >>> C[0], D[0]
    (array([1.]), np.float64(0.0))
    """
    batch = den.shape[0]
    n = den.shape[1] - 1
    shift = n - (num.shape[1] - 1)
    M = np.zeros((batch, n + 2, n + 2))
    C = np.zeros((batch, n))
    D = np.zeros(batch)
    for b in range(batch):
        lead = den[b, 0]
        d = num[b, 0] / lead if shift == 0 else 0.0
        D[b] = d
        for r in range(n):
            a = den[b, r + 1] / lead
            M[b, 0, r] = -a * dt
            if r > 0:
                M[b, r, r - 1] = dt
            j = r + 1 - shift
            C[b, r] = (num[b, j] / lead if j >= 0 else 0.0) - d * a
        if n > 0:
            M[b, 0, n] = dt
        M[b, n, n + 1] = 1.0
    return M, C, D


@cached_njit()
def tf_discrete_into(num, den, dt, max_norm, E, C, D, ok, big):  # pragma: no cover - compiled
    """:func:`tf_discrete` into the caller's arrays ``E`` (B, n+2, n+2), ``C`` (B, n), ``D``, ``ok`` and ``big`` (B,);
    returns ``clean``.

    Compiled code calls it through its address
    (:func:`hammerstein_ctrl.kernels.discretisation_address`), so its code is
    compiled once, not again inside every compiled caller.  The arrays'
    shapes are not checked (compiled code checks no index): the caller sizes
    them, as :func:`tf_discrete` and :func:`hammerstein_ctrl.kernels.discretised` do.

    Examples
    --------
    >>> import numpy as np
    >>> E, C, D = np.empty((1, 3, 3)), np.empty((1, 1)), np.empty(1)
    >>> ok, big = np.empty(1, dtype=bool), np.empty(1, dtype=bool)
    >>> tf_discrete_into(np.array([[1.0]]), np.array([[1.0, 2.0]]), 0.5, 64.0, E, C, D, ok, big)
    True
    >>> bool(np.isclose(E[0, 0, 0], np.exp(-1.0))), C[0, 0], D[0]
    (True, np.float64(1.0), np.float64(0.0))
    """
    batch = den.shape[0]
    for b in range(batch):
        good = den[b, 0] != 0
        for j in range(num.shape[1]):
            good = good and np.isfinite(num[b, j])
        for j in range(den.shape[1]):
            good = good and np.isfinite(den[b, j])
        ok[b] = good
    if not ok.all():
        num, den = num.copy(), den.copy()
        for b in range(batch):
            if not ok[b]:
                num[b, :] = 0.0
                den[b, :] = 0.0
                den[b, 0] = 1.0
    M, C_new, D_new = tf_augmented(num, den, dt)
    copy_vector(D_new, D)
    for b in range(batch):
        copy_vector(C_new[b], C[b])
        big[b] = _one_norm(M[b]) > max_norm
        if not big[b]:
            _expm_one(M[b], E[b], _B13)  # not through expm_into: one level less to compile on a first fit
    return ok.all() and not big.any()


def tf_discrete(num, den, dt, max_norm):
    """:func:`tf_augmented` and the compiled exponential in one call.

    Returns ``(E, C, D, ok, big, clean)``: unusable rows (``~ok``) are
    replaced by ``1/p`` before the exponential; rows whose augmented matrix
    has a 1-norm above ``max_norm`` (``big``) are left for scipy's expm
    (their ``E`` is not set); ``clean`` says that every row is usable and done.

    Examples
    --------
    >>> import numpy as np
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
    M = np.ascontiguousarray(M, dtype=float)
    return _expm_batch(M, _B13)


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


@cached_njit()
def fill_coefficients(theta, num0, den0, num_pos, den_pos):  # pragma: no cover - compiled
    """Rows of ``num0``/``den0`` with the free coefficients of each row of ``theta`` written in (one call per batch)."""
    batch, k = theta.shape[0], num_pos.size
    num = np.empty((batch, num0.size))
    den = np.empty((batch, den0.size))
    for b in range(batch):
        for j in range(num0.size):      # element loops: a slice assignment pulls in numpy's shape-error machinery,
            num[b, j] = num0[j]         # seconds of compilation on a machine's first fit
        for j in range(den0.size):
            den[b, j] = den0[j]
        for j in range(k):
            num[b, num_pos[j]] = theta[b, j]
        for j in range(den_pos.size):
            den[b, den_pos[j]] = theta[b, k + j]
    return num, den
