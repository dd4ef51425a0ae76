"""Exact, fast sampled simulation of Hammerstein models.

The semantics are those of
``control.forced_response(H, t, g(u)).outputs``: the nonlinearity is applied to
the sampled input, the intermediate signal ``v = g(u)`` is interpolated
linearly between samples (first-order hold), and ``H`` is simulated exactly
from a zero initial state.  Two real-data extensions keep the simulation
exact: an input held constant between samples (``intersample="zoh"``, as
MATLAB's ``iddata`` ``InterSample``) and a non-zero initial state ``x0`` of
the realisation below, plus a constant output ``offset``.  With the augmented matrix exponential

.. math::

    \\exp\\left(\\begin{bmatrix} A\\,dt & B\\,dt & 0 \\\\ 0 & 0 & 1 \\\\ 0 & 0 & 0
    \\end{bmatrix}\\right) =
    \\begin{bmatrix} A_d & B_{d0} + B_{d1} & B_{d1} \\\\ \\cdot & \\cdot & \\cdot
    \\end{bmatrix}

the state obeys ``x[k] = Ad x[k-1] + Bd0 v[k-1] + Bd1 v[k]`` (first-order
hold; with zero-order hold ``x[k] = Ad x[k-1] + (Bd0 + Bd1) v[k-1]``) and
``y[k] = C x[k] + D v[k] + offset``.  Here the realisation and the matrix
exponential are computed once per candidate in compiled code without BLAS
(:func:`hammerstein_ctrl._linalg.tf_discrete`) and the recursion, including the
sum of squared residuals, runs in generated compiled code
(:mod:`hammerstein_ctrl._kernels`); a signal that is a combination of basis
signals is formed inside that pass (:func:`sse_basis_batch`).  It agrees with
python-control to about 1e-13 relative on the EMPS and TRS cases while costing
tens of microseconds instead of tens of milliseconds.

The realisation used for a transfer function is the controllable canonical
form, the same one python-control obtains through ``scipy.signal.tf2ss``.

The module is the public face of three private ones, one per job:
:mod:`~hammerstein_ctrl.simulate._discretize` (realisation and discretisation),
:mod:`~hammerstein_ctrl.simulate._batch` (batches of candidates in one compiled pass)
and :mod:`~hammerstein_ctrl.simulate._normal_pass` (normal equations in one pass); it
holds the entry points for single systems itself.

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

import warnings

import numpy as np

from .._checks import as_signal, check_intersample, check_transfer_function, uniform_grid
from ..exceptions import DataError, ParameterError, SimulationWarning
from .._kernels import MAX_PASS_STATES, MAX_UNROLLED_STATES, get_kernel
from ._batch import output_terms, simulate_batch, sse_basis_batch, sse_batch
from ._discretize import (COMPILED_EXPM_MAX_NORM, _augmented, _expm, _offset_rows, _state_rows, _tf_system,
                          companion_realization, discretize, unstable)
from ._normal_pass import GROUPS_MIN_BYTES, free_response, normal_factor, normal_pass, response_blocks

__all__ = [
    "companion_realization",
    "discretize",
    "lsim",
    "simulate",
    "simulate_blocks",
    "simulate_batch",
    "sse_batch",
    "sse_basis_batch",
    "free_response",
    "response_blocks",
    "normal_pass",
    "normal_factor",
    "output_terms",
    "unstable",
    "COMPILED_EXPM_MAX_NORM",
    "GROUPS_MIN_BYTES",
    "MAX_UNROLLED_STATES",
    "MAX_PASS_STATES",
]

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


def lsim(linear, t, v, *, x0=None, intersample: str = "foh") -> np.ndarray:
    """Response of a SISO LTI block to ``v`` (exact for the given intersample behaviour).

    With the defaults equal (to rounding) to
    ``control.forced_response(linear, t, v).outputs``; with
    ``intersample="zoh"`` to ``scipy.signal.lsim(..., interp=False)``.

    Parameters
    ----------
    linear : control.TransferFunction, control.StateSpace or (num, den)
    t : array_like, shape (N,)
        Uniform time grid.
    v : array_like, shape (N,)
        Input samples.
    x0 : array_like, shape (n,), optional
        Initial state (of the controllable canonical realisation for transfer
        functions, of the given realisation for state-space blocks); default 0.
    intersample : {"foh", "zoh"}, default "foh"
        Input linear between samples, or held.

    Returns
    -------
    ndarray, shape (N,)
    """
    dt, v = _check_pair(t, v)
    return warn_diverged(_response(linear, dt, v, x0=x0, intersample=intersample), dt, "lsim")


def warn_diverged(y: np.ndarray, dt: float, name: str, why: str | None = None, *, t0: float = 0.0,
                  stacklevel: int = 3) -> np.ndarray:
    """``y``, after a :class:`~hammerstein_ctrl.exceptions.SimulationWarning` naming the first sample where it is
    not finite (``why``: the cause, when the caller knows it; ``stacklevel`` as :func:`warnings.warn`'s)."""
    bad = ~np.isfinite(y)
    if bad.any():
        k = int(np.flatnonzero(bad.reshape(len(y), -1).any(axis=1))[0])
        why = why or "the linear block is unstable, or its state overflowed"
        warnings.warn(f"{name}: the simulated output is not finite from sample {k} (t = {t0 + k * dt:.6g} s): "
                      f"{why}; do not use this output", SimulationWarning, stacklevel=stacklevel)
    return y


def _response(linear, dt: float, v: np.ndarray, *, x0=None, offset=None, intersample="foh") -> np.ndarray:
    """:func:`lsim` for an already validated sampling interval and signal."""
    hold = check_intersample(intersample)
    E, C, D = _lti_system(linear, dt)
    X0 = _state_rows(x0, 1, E.shape[1] - 2)
    Y = np.empty((1, v.size))
    V = np.ascontiguousarray(v)[None, :]                # a strided view of the caller's too
    get_kernel(E.shape[1] - 2, "outputs", hold)(E, C, D, X0, _offset_rows(offset, 1), V, Y)
    return Y[0]


def simulate(linear, nonlinearity, params, t, u, *, x0=None, offset=0.0, intersample: str = "foh") -> np.ndarray:
    """Simulate the Hammerstein model ``y = H(p) g(u) + offset`` with the sampled semantics.

    Parameters
    ----------
    linear : control.TransferFunction, control.StateSpace or (num, den)
    nonlinearity : Nonlinearity
    params : array_like
        Parameters of the nonlinearity.
    t, u : array_like, shape (N,)
        Uniform time grid and input samples.
    x0 : array_like, optional
        Initial state of the linear block (see :func:`lsim`); default 0.
    offset : float, default 0
        Constant added to the output.
    intersample : {"foh", "zoh"}, default "foh"

    Returns
    -------
    ndarray, shape (N,)

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> from hammerstein_ctrl.blocks import Tanh
    >>> t = np.arange(0, 5, 0.1); u = np.ones_like(t)
    >>> y = simulate(ct.tf([1], [1, 1]), Tanh(), [2.0, 1.0], t, u)
    >>> round(float(y[-1]), 4)  # 2*tanh(1)*(1 - exp(-4.9))
    1.5118
    """
    dt, u = _check_pair(t, u, "u")
    v = as_signal(nonlinearity(u, params), "g(u)")
    return warn_diverged(_response(linear, dt, v, x0=x0, offset=offset, intersample=intersample), dt, "simulate")


def simulate_blocks(model, t, u, *, x0=None, intersample: str = "foh") -> np.ndarray:
    """Simulate a block-oriented model ``y = h(H g(u)) + offset`` (Hammerstein, Wiener or both).

    ``g`` acts on the input samples, the linear block is simulated exactly
    with the given intersample behaviour, and ``h`` acts on its output samples
    in the same compiled pass.

    Parameters
    ----------
    model : BlockModel
    t, u : array_like, shape (N,)
    x0 : array_like, optional
        Initial state of the linear block; default 0.
    intersample : {"foh", "zoh"}, default "foh"

    Returns
    -------
    ndarray, shape (N,)
    """
    dt, u = _check_pair(t, u, "u")
    num, den = check_transfer_function(*model.coefficients(), name="linear block")
    v = as_signal(model.g(u), "g(u)")
    h = None if model.output_nonlinearity is None else (model.output_nonlinearity, model.output_params)
    return simulate_batch(num[None, :], den[None, :], v, dt, x0=x0, offset=model.offset,
                          intersample=intersample, output_map=h)[0]
