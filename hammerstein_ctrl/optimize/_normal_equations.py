"""Gauss-Newton normal equations of a least-squares objective, formed without storing the Jacobian.

For residuals ``r(beta)`` (length N) and their Jacobian ``J = dr/dbeta``
(N x p), a Levenberg-Marquardt step needs only ``f = r @ r``, the gradient
half ``g = J.T @ r`` and the Gram matrix ``G = J.T @ J``: p(p+3)/2 + 1 numbers
instead of N(p+1).  :class:`NormalEquations` carries them together with the
forward-difference steps they were formed with.
:meth:`HammersteinCost.normal_equations
<hammerstein_ctrl.fit.HammersteinCost.normal_equations>` forms them in
one compiled pass over the record (the point and its p neighbours simulated
side by side); :func:`from_residuals` forms them from residual vectors, for
any other objective.

Examples
--------
>>> import numpy as np
>>> x = np.array([1.0, 2.0])
>>> t = np.linspace(0.0, 1.0, 5)
>>> residuals = lambda b: np.exp(-b[0] * t) - b[1] * t        # any residual function
>>> h = forward_steps(x)
>>> ne = from_residuals(np.array([residuals(b) for b in neighbours(x, h)]), h)
>>> J = np.column_stack([-t * np.exp(-t), -t])                 # its exact Jacobian at x
>>> bool(np.allclose(ne.gram, J.T @ J, rtol=1e-6)), bool(np.allclose(ne.gradient, J.T @ residuals(x), rtol=1e-6))
(True, True)
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._checks import as_real_array
from .. import _core
from ..exceptions import ParameterError

__all__ = ["NormalEquations", "from_residuals", "from_difference_sums", "from_factor", "scored_inf", "forward_steps",
           "point_and_steps", "neighbours", "normal_arrays", "FD_REL_STEP",
           "NONFINITE_RESIDUAL"]

#: Relative step of the forward-difference Jacobian (scipy's "2-point" default, sqrt(eps)).
FD_REL_STEP = float(np.sqrt(np.finfo(float).eps))

#: Value given to non-finite residuals, so that least-squares solvers back off instead of failing.
NONFINITE_RESIDUAL = 1e150


class NormalEquations(NamedTuple):
    """``f = r @ r``, ``gradient = J.T @ r`` and ``gram = J.T @ J`` at a point.

    ``steps`` are the forward-difference steps ``h`` of the Jacobian's columns.
    """

    fun: float
    gradient: np.ndarray
    gram: np.ndarray
    steps: np.ndarray
    #: ``(R, qtr)`` with ``J = Q R`` and ``qtr = Q.T r`` where the sums come from a QR factorisation
    #: (:func:`from_factor`), else ``None``.
    factor: tuple | None = None

    def neighbour_values(self) -> np.ndarray:
        """Sum of squares at each neighbour ``x + h_j e_j``: ``f + 2 h_j g_j + h_j**2 G_jj``.

        Exact up to rounding for forward differences, since the neighbour's
        residual is ``r + h_j J[:, j]``.
        """
        return _neighbour_values(self.fun, self.gradient, self.gram, self.steps)

    @property
    def finite(self) -> bool:
        """Whether every sum is finite."""
        return bool(_finite(self.fun, self.gradient, self.gram))


def normal_arrays(gradient, gram, *vectors):
    """``gradient``, ``gram`` and ``vectors`` as C-ordered float arrays of ``p``, ``p x p`` and ``p`` values (the C code
    reads that many), else a ``ValueError``.

    Examples
    --------
    >>> [a.shape for a in normal_arrays([1.0, 2.0], np.eye(2), [0.5, 0.5])]
    [(2,), (2, 2), (2,)]
    """
    arrays = [np.ascontiguousarray(a, dtype=float) for a in (gradient, gram, *vectors)]
    p = arrays[0].size
    if arrays[0].ndim != 1 or arrays[1].shape != (p, p) or any(a.shape != (p,) for a in arrays[2:]):
        raise ValueError(f"normal equations of {p} parameters need a {p} x {p} Gram matrix and {p}-vectors, "
                         f"not shapes {[a.shape for a in arrays]}")
    return arrays


def _finite(fun, gradient, gram) -> bool:
    """Whether ``fun``, ``gradient`` and ``gram`` are all finite."""
    gradient, gram = normal_arrays(gradient, gram)
    return _core.hc_finite_sums(float(fun), gradient, gram, gradient.size)


def _neighbour_values(fun, gradient, gram, steps) -> np.ndarray:
    gradient, gram, steps = normal_arrays(gradient, gram, steps)
    values = np.empty(steps.size)
    _core.hc_neighbour_values(float(fun), gradient, gram, steps, steps.size,
                                  values)
    return values


def forward_steps(x, upper=None, lower=None) -> np.ndarray:
    """scipy's ``"2-point"`` steps: ``sqrt(eps) max(1, |x|)`` with the sign of ``x``, kept inside ``[lower, upper]``.

    As scipy's ``approx_derivative`` does: a step that would leave the box is
    reversed if the reversed one fits, else it becomes the distance to the
    farther bound.  Returned as ``(x + h) - x`` so that the step is exactly
    representable.

    Examples
    --------
    >>> forward_steps([2.0, -1.0], upper=[2.0, 0.0], lower=[0.0, -1.0]) / 1.4901161193847656e-08
    array([-2.,  1.])
    """
    x = np.asarray(x, dtype=float)
    return _forward_steps(np.ascontiguousarray(x).ravel(), _bound(upper, x, np.inf),
                          _bound(lower, x, -np.inf)).reshape(x.shape)


def _bound(value, x, default):
    """A bound as a flat array: one value for every parameter if none is given, else one per entry of ``x``."""
    if value is None:
        return _NO_UPPER if default > 0 else _NO_LOWER
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=float), x.shape).ravel())


#: The bounds of unbounded forward steps (one value for every parameter; never written, and left writeable
#: like the bounds given).
_NO_UPPER, _NO_LOWER = np.array([np.inf]), np.array([-np.inf])


def _forward_steps(x, upper, lower) -> np.ndarray:
    """:func:`forward_steps` of a flat ``x`` in ``[lower, upper]`` (one value each, or one for all), in one call of
    the compiled core."""
    x, upper, lower = (np.ascontiguousarray(a, dtype=float).ravel() for a in (x, upper, lower))
    if upper.size not in (1, x.size) or lower.size not in (1, x.size):
        raise ValueError(f"bounds must hold one value or one per entry of x ({x.size}), not {upper.size} and "
                         f"{lower.size}")
    h = np.empty(x.size)
    _core.hc_forward_steps(x, x.size, upper, upper.size, lower, lower.size,
                               FD_REL_STEP, h)
    return h


def point_and_steps(structure, beta, steps=None, method: str = "normal_equations"):
    """``(b, h)``: one checked beta of ``structure`` and its forward-difference steps (:func:`forward_steps`
    by default; given ones must be one finite, non-zero number per parameter), else a :class:`ParameterError`.

    Examples
    --------
    >>> from hammerstein_ctrl import HammersteinStructure, LinearStructure, Tanh
    >>> s = HammersteinStructure(LinearStructure(0, 1), Tanh())
    >>> point_and_steps(s, [1.0, 2.0, 0.5], [0.1, 0.1, 0.1])[1].tolist()
    [0.1, 0.1, 0.1]
    >>> try:
    ...     point_and_steps(s, [1.0, 2.0, 0.5], [0.1, 0.0, 0.1])
    ... except ValueError as exc:
    ...     print(exc)
    steps must be 3 finite, non-zero numbers (one per parameter), got [0.1 0.  0.1]
    """
    b = structure.check_beta(beta)
    if b.ndim != 1:
        raise ParameterError(f"{method}(beta) takes one vector")
    if steps is None:
        return b, forward_steps(b)
    h = steps if type(steps) is np.ndarray and steps.dtype == np.float64 else as_real_array(steps, "steps")
    if h.shape != b.shape or not _usable_steps(h.ravel()):
        raise ParameterError(f"steps must be {b.size} finite, non-zero numbers (one per parameter), "
                             f"got {np.array2string(h, threshold=12)}")
    return b, h


def _usable_steps(h) -> bool:
    """Whether every step of the flat float array ``h`` is finite and non-zero."""
    h = np.ascontiguousarray(h, dtype=float)
    return _core.hc_usable_steps(h, h.size)


def neighbours(x, steps) -> np.ndarray:
    """The point ``x`` (row 0) and its forward-difference neighbours ``x + steps[j] e_j`` (row j+1).

    Examples
    --------
    >>> neighbours([1.0, 2.0], [0.5, 0.25])
    array([[1.  , 2.  ],
           [1.5 , 2.  ],
           [1.  , 2.25]])
    """
    x = np.asarray(x, dtype=float)
    steps = np.asarray(steps, dtype=float)
    if x.ndim != 1 or steps.shape != x.shape:
        raise ValueError(f"neighbours needs a point and one step per entry, got shapes {x.shape} and {steps.shape}")
    return _neighbours(np.ascontiguousarray(x), np.ascontiguousarray(steps))


def _neighbours(x, steps) -> np.ndarray:
    x, steps = np.ascontiguousarray(x, dtype=float).ravel(), np.ascontiguousarray(steps, dtype=float).ravel()
    if steps.size != x.size:
        raise ValueError(f"neighbours need one step per entry of x ({x.size}), not {steps.size}")
    X = np.empty((x.size + 1, x.size))
    _core.hc_neighbours(x, x.size, steps, X)
    return X


def from_difference_sums(sums, steps) -> NormalEquations:
    """Normal equations from ``[r @ r, D.T @ r, D.T @ D]`` (flattened), ``D[:, j] = h_j J[:, j]`` the neighbours'
    differences.

    A pass that sums the differences ``r_{j+1} - r_0`` of the neighbours'
    residuals (as :func:`~hammerstein_ctrl._kernels.get_normal_kernel` does)
    divides by the steps once here instead of at every sample.

    Parameters
    ----------
    sums : array_like, shape (1 + p + p*p,)
        ``r @ r``, then ``D.T @ r``, then ``D.T @ D`` row by row.
    steps : array_like, shape (p,)
        The forward-difference steps ``h``.

    Returns
    -------
    NormalEquations

    Raises
    ------
    ValueError
        If the sizes of ``sums`` and ``steps`` do not fit each other.

    Examples
    --------
    >>> ne = from_difference_sums([13.0, 3.25, 0.8125], [0.25])
    >>> ne.fun, ne.gradient, ne.gram
    (13.0, array([13.]), array([[13.]]))
    """
    sums, steps = np.ascontiguousarray(sums, dtype=float), np.ascontiguousarray(steps, dtype=float)
    if steps.ndim != 1 or sums.shape != (1 + steps.size * (steps.size + 1),):
        raise ValueError(f"sums of shape {sums.shape} do not fit {steps.size} steps (1 + p + p*p values expected)")
    gradient, gram = _divide_by_steps(sums, steps)
    return NormalEquations(float(sums[0]), gradient, gram, steps)


def _divide_by_steps(sums, steps):
    """``(gradient, gram)``: the pass's sums over the neighbours' differences divided by the steps."""
    sums, steps = np.ascontiguousarray(sums, dtype=float).ravel(), np.ascontiguousarray(steps, dtype=float).ravel()
    p = steps.size
    if sums.size != 1 + p + p * p:
        raise ValueError(f"sums of {sums.size} values do not fit {p} steps (1 + p + p*p values expected)")
    gradient, gram = np.empty(p), np.empty((p, p))
    _core.hc_divide_by_steps(sums, steps, p, gradient, gram)
    return gradient, gram


def from_factor(R, steps) -> NormalEquations:
    """Normal equations from the triangular factor ``R`` of ``[D r]``, ``D[:, j] = h_j J[:, j]``, keeping the factor.

    Examples
    --------
    >>> import numpy as np
    >>> D = np.array([[0.5], [1.0]]); r = np.array([1.0, 2.0])        # h = 0.5: J = [[1], [2]]
    >>> R = np.linalg.qr(np.column_stack([D, r]), mode="r")
    >>> ne = from_factor(R, [0.5])
    >>> round(ne.fun, 12), ne.gradient.round(12).tolist(), ne.gram.round(12).tolist()
    (5.0, [5.0], [[5.0]])
    """
    R, steps = np.asarray(R, dtype=float), np.asarray(steps, dtype=float)
    p = steps.size
    if R.shape != (p + 1, p + 1):
        raise ValueError(f"a factor of shape {R.shape} does not fit {p} steps")
    qtr = R[:p, p].copy()
    with np.errstate(all="ignore"):
        RJ = R[:p, :p] / steps
        fun = float(R[:, p] @ R[:, p])
        return NormalEquations(fun, RJ.T @ qtr, RJ.T @ RJ, steps, (RJ, qtr))


def scored_inf(steps) -> NormalEquations:
    """Normal equations of a point scored ``inf`` (it cannot be simulated, or is rejected): no solver can use it.

    The sums are left at zero: nothing was simulated to form them.

    Examples
    --------
    >>> ne = scored_inf([0.5, 0.25])
    >>> ne.fun, ne.finite, ne.neighbour_values().tolist()
    (inf, False, [inf, inf])
    """
    steps = np.ascontiguousarray(steps, dtype=float)
    return NormalEquations(np.inf, np.zeros(steps.size), np.zeros((steps.size, steps.size)), steps)


def from_residuals(R, steps) -> NormalEquations:
    """Normal equations from residual vectors at a point (row 0) and its neighbours ``x + h_j e_j`` (row j+1).

    Non-finite residuals are replaced by :data:`NONFINITE_RESIDUAL` first.
    """
    R = np.array(R, dtype=float)
    with np.errstate(all="ignore"):
        R[~np.isfinite(R)] = NONFINITE_RESIDUAL
        r = R[0]
        J = (R[1:] - r) / np.asarray(steps, dtype=float)[:, None]
        return NormalEquations(float(r @ r), J @ r, J @ J.T, np.asarray(steps, dtype=float))
