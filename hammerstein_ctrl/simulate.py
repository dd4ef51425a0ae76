"""Exact, fast sampled simulation of Hammerstein models.

The semantics (DESIGN.md section 1) are those of
``control.forced_response(H, t, g(u)).outputs``: the nonlinearity is applied to
the sampled input, the intermediate signal ``v = g(u)`` is interpolated
linearly between samples (first-order hold), and ``H`` is simulated exactly
from a zero initial state.  With the augmented matrix exponential

.. math::

    \\exp\\left(\\begin{bmatrix} A\\,dt & B\\,dt & 0 \\\\ 0 & 0 & 1 \\\\ 0 & 0 & 0
    \\end{bmatrix}\\right) =
    \\begin{bmatrix} A_d & B_{d0} + B_{d1} & B_{d1} \\\\ \\cdot & \\cdot & \\cdot
    \\end{bmatrix}

the state obeys ``x[k] = Ad x[k-1] + Bd0 v[k-1] + Bd1 v[k]`` and
``y[k] = C x[k] + D v[k]``.  Here the matrix exponential is computed once per
candidate (stacked over a batch) and the recursion, including the sum of
squared residuals, runs in compiled code (numba).  It agrees with
python-control to about 1e-13 relative on the EMPS and TRS cases while costing
tens of microseconds instead of tens of milliseconds.

The realisation used for a transfer function is the controllable canonical
form, the same one python-control obtains through ``scipy.signal.tf2ss``.

Examples
--------
>>> import numpy as np, control as ct
>>> from hammerstein_ctrl.simulate import lsim
>>> H = ct.tf([1.0], [1.0, 3.0, 0.0])
>>> t = np.arange(0, 1.0, 1e-3); v = np.sin(5 * t)
>>> y = lsim(H, t, v)
>>> bool(np.allclose(y, ct.forced_response(H, t, v).outputs, rtol=1e-12, atol=0))
True
"""

from __future__ import annotations

import functools

import numba
import numpy as np
import scipy.linalg

from ._checks import as_signal, check_transfer_function, uniform_grid
from .exceptions import DataError, ParameterError

__all__ = [
    "companion_realization",
    "foh_discretize",
    "lsim",
    "simulate",
    "simulate_batch",
    "sse_batch",
]


# ---------------------------------------------------------------------------
# realisation and discretisation (vectorised over a batch of candidates)
# ---------------------------------------------------------------------------
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
    M, C, D = _tf_augmented(np.ascontiguousarray(num), np.ascontiguousarray(den), 1.0)
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


def _expm(M: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):
        return scipy.linalg.expm(M)


def foh_discretize(A, B, dt: float):
    """First-order-hold discretisation ``(Ad, Bd0, Bd1)`` of ``x' = A x + B v``.

    Identical to the construction inside ``control.forced_response``:
    ``x[k] = Ad x[k-1] + Bd0 v[k-1] + Bd1 v[k]``.

    Parameters
    ----------
    A : ndarray, shape (n, n) or (batch, n, n)
    B : ndarray, shape (n,) or (batch, n)
    dt : float

    Returns
    -------
    Ad : ndarray, shape (batch, n, n)
    Bd0, Bd1 : ndarray, shape (batch, n)

    Examples
    --------
    >>> Ad, Bd0, Bd1 = foh_discretize([[0.0]], [1.0], 0.5)   # an integrator
    >>> float(Ad[0, 0, 0]), float(Bd0[0, 0]), float(Bd1[0, 0])
    (1.0, 0.25, 0.25)
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim == 2:
        A, B = A[None], B.reshape(1, -1)
    n = A.shape[1]
    E = _expm(_augmented(A, B, dt))
    Bd1 = E[:, :n, n + 1]
    return E[:, :n, :n].copy(), E[:, :n, n] - Bd1, Bd1.copy()


@numba.njit(cache=True, nogil=True)
def _tf_augmented(num, den, dt):  # pragma: no cover - compiled
    """Augmented FOH matrices of the companion realisations of a batch of num/den."""
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


# ---------------------------------------------------------------------------
# compiled recursions
# ---------------------------------------------------------------------------
#: State dimensions up to this get a generated kernel that keeps the state in
#: registers (about 3x faster than the generic loop); larger ones use the loop.
MAX_UNROLLED_STATES = 8

#: Candidates simulated side by side in one loop of a generated kernel.  The
#: recursion is latency-bound (each step waits for the previous one); two
#: independent chains keep the CPU busy (~24 instead of ~38 us per EMPS candidate).
INTERLEAVE = 2

_KERNEL_TEMPLATE = """
def kernel(E, C, D, V, {args}):
    batch, N = V.shape
    b0 = 0
    while b0 + {group} <= batch:
{block_group}
        b0 += {group}
    while b0 < batch:
{block_single}
        b0 += 1
"""


def _block(n: int, group: int, mode: str, ind: str) -> str:
    """Source simulating rows ``b0 .. b0+group-1`` with ``n`` states held in scalars.

    Every kernel reads ``E = expm([[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]])``
    directly: ``Ad = E[:n, :n]``, ``Bd1 = E[:n, n+1]``, ``Bd0 = E[:n, n] - Bd1``,
    exactly as ``control.forced_response`` forms them.
    """
    lines = []
    for g in range(group):
        row = f"b0 + {g}"
        lines += [f"{ind}a{g}_{r}_{c} = E[{row}, {r}, {c}]" for r in range(n) for c in range(n)]
        for r in range(n):
            lines += [f"{ind}q{g}_{r} = E[{row}, {r}, {n + 1}]",
                      f"{ind}p{g}_{r} = E[{row}, {r}, {n}] - q{g}_{r}",
                      f"{ind}c{g}_{r} = C[{row}, {r}]", f"{ind}x{g}_{r} = 0.0"]
        lines += [f"{ind}d{g} = D[{row}]", f"{ind}vp{g} = V[{row}, 0]", f"{ind}yh{g} = d{g} * vp{g}"]
        if mode == "sse":
            lines += [f"{ind}e{g} = y[0] - yh{g}", f"{ind}J{g} = e{g} * e{g}"]
        else:
            lines.append(f"{ind}out[{row}, 0] = yh{g}")
    lines.append(f"{ind}for i in range(1, N):")
    body = ind + "    "
    if mode == "sse":
        lines.append(f"{body}yi = y[i]")
    for g in range(group):
        lines.append(f"{body}vi{g} = V[b0 + {g}, i]")
        for r in range(n):
            dyn = " + ".join(f"a{g}_{r}_{c} * x{g}_{c}" for c in range(n))
            lines.append(f"{body}n{g}_{r} = ({dyn}) + (p{g}_{r} * vp{g} + q{g}_{r} * vi{g})")
        lines += [f"{body}x{g}_{r} = n{g}_{r}" for r in range(n)]
        output = " + ".join(f"c{g}_{r} * x{g}_{r}" for r in range(n)) or "0.0"
        lines.append(f"{body}yh{g} = ({output}) + d{g} * vi{g}")
        if mode == "sse":
            lines += [f"{body}e{g} = yi - yh{g}", f"{body}J{g} += e{g} * e{g}"]
        else:
            lines.append(f"{body}out[b0 + {g}, i] = yh{g}")
        lines.append(f"{body}vp{g} = vi{g}")
    if mode == "sse":
        # stop early only when every interleaved sum has overflowed (or is NaN)
        alive = " or ".join(f"J{g} <= 1.7e308" for g in range(group))
        lines += [f"{body}if (i & 1023) == 0 and not ({alive}):", f"{body}    break"]
        lines += [f"{ind}out[b0 + {g}] = J{g} if J{g} <= 1.7e308 else np.inf" for g in range(group)]
    return "\n".join(lines)


def _generate_kernel(n: int, mode: str):
    """Compile a recursion for exactly ``n`` states (``mode`` 'sse' or 'outputs')."""
    ind = " " * 8
    src = _KERNEL_TEMPLATE.format(
        args="y, out" if mode == "sse" else "out", group=INTERLEAVE,
        block_group=_block(n, INTERLEAVE, mode, ind), block_single=_block(n, 1, mode, ind),
    )
    namespace = {"np": np}
    exec(compile(src, f"<hammerstein_ctrl kernel n={n} {mode}>", "exec"), namespace)
    return numba.njit(nogil=True)(namespace["kernel"])


@functools.lru_cache(maxsize=None)
def _kernel(n: int, mode: str):
    """The compiled recursion for ``n`` states: generated (small n) or generic."""
    if n <= MAX_UNROLLED_STATES:
        return _generate_kernel(n, mode)
    return _foh_sse_generic if mode == "sse" else _foh_outputs_generic


@numba.njit(cache=True, nogil=True)
def _foh_step(E, b, n, x, xn, vp, vi):  # pragma: no cover - compiled
    for r in range(n):
        s = 0.0
        for c in range(n):
            s += E[b, r, c] * x[c]
        bd1 = E[b, r, n + 1]
        xn[r] = s + ((E[b, r, n] - bd1) * vp + bd1 * vi)
    for r in range(n):
        x[r] = xn[r]


@numba.njit(cache=True, nogil=True)
def _foh_outputs_generic(E, C, D, V, Y):  # pragma: no cover - compiled
    batch, N = V.shape
    n = E.shape[1] - 2
    x = np.zeros(n)
    xn = np.zeros(n)
    for b in range(batch):
        x[:] = 0.0
        for i in range(N):
            if i > 0:
                _foh_step(E, b, n, x, xn, V[b, i - 1], V[b, i])
            Y[b, i] = np.dot(C[b], x) + D[b] * V[b, i]


@numba.njit(cache=True, nogil=True)
def _foh_sse_generic(E, C, D, V, y, out):  # pragma: no cover - compiled
    batch, N = V.shape
    n = E.shape[1] - 2
    x = np.zeros(n)
    xn = np.zeros(n)
    for b in range(batch):
        x[:] = 0.0
        J = 0.0
        for i in range(N):
            if i > 0:
                _foh_step(E, b, n, x, xn, V[b, i - 1], V[b, i])
            e = y[i] - (np.dot(C[b], x) + D[b] * V[b, i])
            J += e * e
            if (i & 1023) == 0 and not J <= 1.7e308:
                break
        out[b] = J if J <= 1.7e308 else np.inf


# ---------------------------------------------------------------------------
# public simulation entry points
# ---------------------------------------------------------------------------
def _lti_system(linear, dt: float):
    """(E, C, D) batch-of-one arrays for a SISO LTI system or a (num, den) pair."""
    import control

    if isinstance(linear, tuple) and len(linear) == 2:
        E, C, D, _ = _tf_system(*check_transfer_function(*linear, name="linear block"), dt)
        return E, C, D
    if not isinstance(linear, (control.TransferFunction, control.StateSpace)):
        raise ParameterError(
            f"linear block must be a control.TransferFunction, control.StateSpace or (num, den), "
            f"got {type(linear).__name__}"
        )
    if linear.ninputs != 1 or linear.noutputs != 1:
        raise ParameterError("only SISO linear blocks are supported")
    if linear.isdtime(strict=True):
        raise ParameterError("the linear block must be a continuous-time system (dt=0)")
    if isinstance(linear, control.TransferFunction):
        E, C, D, _ = _tf_system(*check_transfer_function(linear.num[0][0], linear.den[0][0],
                                                         name="linear block"), dt)
        return E, C, D
    n = linear.nstates
    A = np.asarray(linear.A, dtype=float).reshape(1, n, n)
    B = np.asarray(linear.B, dtype=float).reshape(1, n)
    C = np.asarray(linear.C, dtype=float).reshape(1, n)
    D = np.asarray(linear.D, dtype=float).reshape(1)
    return _expm(_augmented(A, B, dt)), C, D


def _check_pair(t, v, vname="v"):
    t_grid, dt = uniform_grid(t)
    v = as_signal(v, vname)
    if v.size != t_grid.size:
        raise DataError(f"length mismatch: t has {t_grid.size} samples but {vname} has {v.size}")
    return dt, v


def lsim(linear, t, v) -> np.ndarray:
    """Response of a SISO LTI block to ``v`` with first-order hold, ``x(0) = 0``.

    Equal (to rounding) to ``control.forced_response(linear, t, v).outputs``.

    Parameters
    ----------
    linear : control.TransferFunction, control.StateSpace or (num, den)
    t : array_like, shape (N,)
        Uniform time grid.
    v : array_like, shape (N,)
        Input samples.

    Returns
    -------
    ndarray, shape (N,)
    """
    dt, v = _check_pair(t, v)
    return _response(linear, dt, v)


def _response(linear, dt: float, v: np.ndarray) -> np.ndarray:
    """:func:`lsim` for an already validated sampling interval and signal."""
    E, C, D = _lti_system(linear, dt)
    Y = np.empty((1, v.size))
    _kernel(E.shape[1] - 2, "outputs")(E, C, D, v[None, :], Y)
    return Y[0]


def simulate(linear, nonlinearity, params, t, u) -> np.ndarray:
    """Simulate the Hammerstein model ``y = H(p) g(u)`` with the sampled semantics.

    Parameters
    ----------
    linear : control.TransferFunction, control.StateSpace or (num, den)
    nonlinearity : Nonlinearity
    params : array_like
        Parameters of the nonlinearity.
    t, u : array_like, shape (N,)
        Uniform time grid and input samples.

    Returns
    -------
    ndarray, shape (N,)

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> from hammerstein_ctrl.nonlinearities import Tanh
    >>> t = np.arange(0, 5, 0.1); u = np.ones_like(t)
    >>> y = simulate(ct.tf([1], [1, 1]), Tanh(), [2.0, 1.0], t, u)
    >>> round(float(y[-1]), 4)  # 2*tanh(1)*(1 - exp(-4.9))
    1.5118
    """
    dt, u = _check_pair(t, u, "u")
    return _response(linear, dt, as_signal(nonlinearity(u, params), "g(u)"))


def _tf_system(num, den, dt: float):
    """(E, C, D, ok) for a batch of transfer functions; ``ok`` flags usable rows.

    Rows with non-finite coefficients or a zero leading denominator coefficient
    are replaced by a harmless system (their results are overwritten by the
    caller), so the matrix exponential never sees inf or NaN.
    """
    num, den = _broadcast_rows(np.atleast_2d(np.asarray(num, dtype=float)),
                               np.atleast_2d(np.asarray(den, dtype=float)))
    ok = np.isfinite(num).all(axis=1) & np.isfinite(den).all(axis=1) & (den[:, 0] != 0)
    if not ok.all():
        num = np.where(ok[:, None], num, 0.0)
        den = np.where(ok[:, None], den, np.eye(1, den.shape[1]))
    M, C, D = _tf_augmented(np.ascontiguousarray(num), np.ascontiguousarray(den), float(dt))
    return _expm(M), C, D, ok


def _unstable(den: np.ndarray) -> np.ndarray:
    """Flag denominators with a root strictly in the right half-plane."""
    den = np.atleast_2d(den)
    if den.shape[1] < 2:
        return np.zeros(den.shape[0], dtype=bool)
    A = companion_realization(np.ones((den.shape[0], 1)), den)[0]
    with np.errstate(all="ignore"):
        poles = np.linalg.eigvals(A)
    return np.any(poles.real > 1e-12 * np.maximum(1.0, np.abs(poles)), axis=1)


def _signals(V, batch: int) -> np.ndarray:
    V = np.atleast_2d(np.asarray(V, dtype=float))
    if V.shape[0] != batch:
        V = np.broadcast_to(V, (batch, V.shape[1]))
    return np.ascontiguousarray(V)


def simulate_batch(num, den, V, dt: float) -> np.ndarray:
    """Simulate a batch of linear blocks driven by a batch of intermediate signals.

    Parameters
    ----------
    num, den : array_like, shape (B, l+1) and (B, n+1)
        Transfer-function coefficients in descending powers, one row per candidate.
    V : array_like, shape (B, N) or (N,)
        The signals ``g(u)`` for each candidate (or one shared signal).
    dt : float
        Sampling interval.

    Returns
    -------
    ndarray, shape (B, N)
        Outputs; rows of candidates that cannot be simulated (non-finite
        coefficients, signals or overflow) contain NaN or inf.
    """
    E, C, D, ok = _tf_system(num, den, dt)
    V = _signals(V, E.shape[0])
    Y = np.empty(V.shape)
    _kernel(E.shape[1] - 2, "outputs")(E, C, D, V, Y)
    Y[~ok] = np.nan
    return Y


def sse_batch(num, den, V, dt: float, y, *, reject_unstable: bool = False) -> np.ndarray:
    """Sum of squared output errors ``J`` (paper Eq. 13) for a batch of candidates.

    Never raises or warns for hostile candidates: a candidate whose
    coefficients, signal or simulated output are non-finite (or, with
    ``reject_unstable=True``, that has a pole with positive real part) gets
    ``J = inf``.

    Parameters
    ----------
    num, den, V, dt
        As for :func:`simulate_batch`.
    y : ndarray, shape (N,)
        Measured output.
    reject_unstable : bool, default False
        Give unstable candidates ``inf`` instead of simulating them.

    Returns
    -------
    ndarray, shape (B,)
    """
    E, C, D, ok = _tf_system(num, den, dt)
    if reject_unstable:
        ok &= ~_unstable(den)
    V = _signals(V, E.shape[0])
    J = np.empty(V.shape[0])
    _kernel(E.shape[1] - 2, "sse")(E, C, D, V, np.ascontiguousarray(y, dtype=float), J)
    J[~ok] = np.inf
    return J
