"""Realisation and exact discretisation of batches of transfer functions (the simulator's first job).

:func:`companion_realization` gives the controllable canonical form the whole
package uses (an initial state means the same thing everywhere);
:func:`discretize` the exact sampled recursion under first- or zero-order hold
(the augmented matrix exponential of :mod:`hammerstein_ctrl.simulate`'s notes);
:func:`unstable` flags right-half-plane poles.  Public through
:mod:`hammerstein_ctrl.simulate`.
"""

from __future__ import annotations

import numpy as np

from .._checks import check_dt, check_intersample
from .._linalg import expm_batch, single_threaded_blas, tf_augmented, tf_discrete
from ..exceptions import ParameterError

__all__ = ["companion_realization", "discretize", "unstable", "COMPILED_EXPM_MAX_NORM"]


def companion_realization(num, den):
    """Controllable canonical realisation of ``num(p)/den(p)``, batched.

    Parameters
    ----------
    num, den : array_like, shape (l+1,) / (n+1,) or (B, l+1) / (B, n+1)
        Polynomial coefficients in descending powers (python-control's
        convention); ``den[..., 0]`` must be non-zero and ``l <= n``.

    Returns
    -------
    A : ndarray, shape (B, n, n)
    B : ndarray, shape (B, n)
    C : ndarray, shape (B, n)
    D : ndarray, shape (B,)

    Examples
    --------
    >>> A, B, C, D = companion_realization([1.0, 2.0], [1.0, 3.0, 4.0])
    >>> A[0]
    array([[-3., -4.],
           [ 1.,  0.]])
    >>> C[0], float(D[0])
    (array([1., 2.]), 0.0)
    """
    num = np.atleast_2d(np.asarray(num, dtype=float))
    den = np.atleast_2d(np.asarray(den, dtype=float))
    num, den = _broadcast_rows(num, den)
    n = den.shape[1] - 1
    M, C, D = tf_augmented(np.ascontiguousarray(num), np.ascontiguousarray(den), 1.0)
    return M[:, :n, :n].copy(), M[:, :n, n].copy(), C, D


def _broadcast_rows(num: np.ndarray, den: np.ndarray):
    """Check properness and give num and den the same number of rows."""
    if num.shape[1] > den.shape[1]:
        raise ParameterError(
            f"improper transfer function: numerator degree {num.shape[1] - 1} exceeds "
            f"denominator degree {den.shape[1] - 1}"
        )
    if num.shape[0] != den.shape[0]:
        batch = max(num.shape[0], den.shape[0])
        num = np.broadcast_to(num, (batch, num.shape[1]))
        den = np.broadcast_to(den, (batch, den.shape[1]))
    return num, den


def _augmented(A: np.ndarray, B: np.ndarray, dt: float) -> np.ndarray:
    """The matrix ``[[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]]`` for a batch of (A, B)."""
    batch, n = A.shape[0], A.shape[1]
    M = np.zeros((batch, n + 2, n + 2))
    M[:, :n, :n] = A * dt
    M[:, :n, n] = B * dt
    M[:, n, n + 1] = 1.0
    return M


#: Above this 1-norm the compiled Pade exponential would square too often to stay
#: accurate (ill-conditioned high-order or very fast blocks); scipy's expm,
#: with its sharper scaling, takes those rows (under a one-thread BLAS limit).
COMPILED_EXPM_MAX_NORM = 64.0


def _expm(M: np.ndarray) -> np.ndarray:
    E = expm_batch(M)
    with np.errstate(invalid="ignore"):
        big = np.abs(M).sum(axis=1).max(axis=1) > COMPILED_EXPM_MAX_NORM
    if big.any():
        import scipy.linalg

        with single_threaded_blas():
            E[big] = scipy.linalg.expm(M[big])
    return E


def discretize(A, B, dt: float, intersample: str = "foh"):
    """Exact sampled recursion ``x[k] = Ad x[k-1] + Bd0 v[k-1] + Bd1 v[k]`` of ``x' = A x + B v``.

    With ``intersample="foh"`` (``v`` linear between samples) this is the
    construction inside ``control.forced_response``; with ``"zoh"`` (``v``
    held) ``Bd0 = integral of exp(A s) B ds`` over one interval and ``Bd1 = 0``.

    Parameters
    ----------
    A : ndarray, shape (n, n) or (batch, n, n)
    B : ndarray, shape (n,) or (batch, n)
    dt : float
    intersample : {"foh", "zoh"}

    Returns
    -------
    Ad : ndarray, shape (batch, n, n)
    Bd0, Bd1 : ndarray, shape (batch, n)

    Examples
    --------
    >>> Ad, Bd0, Bd1 = discretize([[0.0]], [1.0], 0.5)   # an integrator, first-order hold
    >>> float(Ad[0, 0, 0]), float(Bd0[0, 0]), float(Bd1[0, 0])
    (1.0, 0.25, 0.25)
    >>> discretize([[0.0]], [1.0], 0.5, "zoh")[1:]
    (array([[0.5]]), array([[0.]]))
    """
    hold = check_intersample(intersample)
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim == 2:
        A, B = A[None], B.reshape(1, -1)
    n = A.shape[1]
    E = _expm(_augmented(A, B, dt))
    if hold == "zoh":
        return E[:, :n, :n].copy(), E[:, :n, n].copy(), np.zeros((E.shape[0], n))
    Bd1 = E[:, :n, n + 1]
    return E[:, :n, :n].copy(), E[:, :n, n] - Bd1, Bd1.copy()


def _tf_system(num, den, dt: float):
    """(E, C, D, ok) for a batch of transfer functions; ``ok`` flags usable rows.

    Rows with non-finite coefficients or a zero leading denominator coefficient
    are replaced by a harmless system (their results are overwritten by the
    caller), so the matrix exponential never sees inf or NaN.
    """
    return _discretized(num, den, dt)[:4]


def _discretized(num, den, dt: float):
    """:func:`_tf_system` and ``clean``: every row usable (``ok`` all true, known without looking)."""
    num, den = _coefficient_rows(num, den)
    dt = dt if type(dt) is float and dt > 0 and dt != np.inf else check_dt(dt)
    E, C, D, ok, big, clean = tf_discrete(num, den, dt, COMPILED_EXPM_MAX_NORM)
    if not clean and big.any():
        import scipy.linalg

        M = tf_augmented(num[big], den[big], float(dt))[0]
        with single_threaded_blas(), np.errstate(all="ignore"):      # a fast unstable pole overflows: not finite
            E[big] = scipy.linalg.expm(M)
    return E, C, D, ok, clean


def _coefficient_rows(num, den):
    """``num``, ``den`` as C-contiguous, writeable float rows, as many of each (checked for properness).

    Writeable: the compiled discretisation takes them as such (one compiled
    version; a read-only record of coefficients is copied, a few numbers).
    """
    if (_float_matrix(num) and _float_matrix(den) and num.shape[0] == den.shape[0] and num.shape[1] <= den.shape[1]
            and num.flags.writeable and den.flags.writeable):
        return num, den
    num, den = _broadcast_rows(np.atleast_2d(np.asarray(num, dtype=float)),
                               np.atleast_2d(np.asarray(den, dtype=float)))
    return np.array(num, order="C"), np.array(den, order="C")


def unstable(den) -> np.ndarray:
    """Flag denominators (rows, descending powers) with a root strictly in the right half-plane.

    Examples
    --------
    >>> unstable([[1.0, 3.0, 0.0], [1.0, -1.0, 0.0]]).tolist()
    [False, True]
    """
    den = np.atleast_2d(np.asarray(den, dtype=float))
    if den.shape[1] < 2:
        return np.zeros(den.shape[0], dtype=bool)
    bad = ~np.isfinite(den).all(axis=1) | (den[:, 0] == 0)
    safe = np.where(bad[:, None], np.eye(1, den.shape[1]), den)
    A = companion_realization(np.ones((den.shape[0], 1)), safe)[0]
    with np.errstate(all="ignore"):
        poles = np.linalg.eigvals(A)
    return bad | np.any(poles.real > 1e-12 * np.maximum(1.0, np.abs(poles)), axis=1)


def _float_matrix(a, ndim: int = 2) -> bool:
    """Whether ``a`` is already a C-contiguous float64 array of ``ndim`` dimensions."""
    return type(a) is np.ndarray and a.ndim == ndim and a.dtype == np.float64 and a.flags.c_contiguous


def _state_rows(x0, batch: int, n: int) -> np.ndarray:
    """Initial states as a ``(batch, n)`` array (zeros for ``None``)."""
    if x0 is None:
        return np.zeros((batch, n))
    X = np.atleast_2d(np.asarray(x0, dtype=float))
    if X.shape[-1] != n or X.shape[0] not in (1, batch):
        raise ParameterError(f"initial state must have {n} entries per candidate, got shape {np.shape(x0)}")
    return np.ascontiguousarray(np.broadcast_to(X, (batch, n)))


def _offset_rows(offset, batch: int) -> np.ndarray:
    """Output offsets as a ``(batch,)`` array (zeros for ``None``)."""
    if offset is None:
        return np.zeros(batch)
    o = np.atleast_1d(np.asarray(offset, dtype=float)).reshape(-1)
    if o.size not in (1, batch):
        raise ParameterError(f"offset must be a scalar or one value per candidate, got shape {np.shape(offset)}")
    return np.ascontiguousarray(np.broadcast_to(o, (batch,)))
