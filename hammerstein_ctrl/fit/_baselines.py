"""The least-squares baselines every fit is measured against (a constant, the static affine gain y = k u + c) and
the initial state of a given model on a record."""

from __future__ import annotations

import numpy as np
from ..optimize import lmder
from ..optimize._streamed_lstsq import constant_column, factor_sse, solve_minimum_norm, triangular_factor

__all__ = ["estimate_initial_state", "static_affine_sse", "static_affine_sse_columns", "affine_coefficients"]


def static_affine_sse(data) -> float:
    """Sum of squared errors of the best static affine model ``y = k u + c``.

    A dynamic model that does no better than this has found nothing.

    Examples
    --------
    >>> import numpy as np
    >>> from hammerstein_ctrl import IOData
    >>> static_affine_sse(IOData(np.arange(5.0), 2 * np.arange(5.0) + 1, dt=1.0)) < 1e-20
    True
    """
    u, y = np.asarray(data.u, dtype=float), np.asarray(data.y, dtype=float)
    if u.ndim == 2 or y.ndim == 2:          # several channels: each output's best affine map of all the inputs
        return float(sum(static_affine_sse_columns(data.inputs, y) for y in data.outputs.T))
    R = triangular_factor([u, constant_column(u.size)], y)
    return factor_sse(R, solve_minimum_norm(R, u.size))


def affine_coefficients(u, y) -> tuple[float, float]:
    """``(k, c)`` of the best static affine model ``y = k u + c`` (the one :func:`static_affine_sse` scores).

    Examples
    --------
    >>> [round(v, 6) for v in affine_coefficients(np.arange(4.0), np.array([1.0, 3.0, 5.0, 8.0]))]
    [2.3, 0.8]
    """
    u, y = np.asarray(u, dtype=float).reshape(-1), np.asarray(y, dtype=float).reshape(-1)
    k, c = solve_minimum_norm(triangular_factor([u, constant_column(u.size)], y), u.size)
    return float(k), float(c)


def static_affine_sse_columns(inputs, y) -> float:
    """Sum of squared errors of ``y = K u + c`` over the input columns ``inputs`` ``(N, m)``."""
    R = triangular_factor([np.ascontiguousarray(c) for c in np.asarray(inputs, dtype=float).T]
                          + [constant_column(len(y))], np.asarray(y, dtype=float))
    return factor_sse(R, solve_minimum_norm(R, len(y)))


def estimate_initial_state(model, data, *, offset: bool = False):
    """Least-squares initial state of ``model`` on ``data`` (its other parameters fixed), through the whole model.

    The state enters the output linearly when the model has no output map and
    no feedback: then the columns ``simulate(e_i) - simulate(0)`` give it by
    linear least squares.  Through an output map ``h`` or a Lur'e loop it does
    not: that solution, the model's own initial state and rest are the starts,
    and Levenberg-Marquardt (forward differences of the model's own
    simulation) refines the best of them.  The result is never worse than any
    of the starts.

    Parameters
    ----------
    model : model with ``order``, ``offset`` and ``simulate(data, initial_state=...)``
    data : IOData
    offset : bool, default False
        Also re-estimate the additive output offset (a new experiment's
        operating point): returns ``(x0, offset)``.

    Returns
    -------
    ndarray, or (ndarray, float) with ``offset``

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Coulomb, IOData
    >>> m = HammersteinModel(ct.tf([1], [1, 1.0, 4.0]), Coulomb(), [1.0, 0.0, 0.0], initial_state=[0.5, -1.0])
    >>> t = np.arange(0, 10, 0.01); d = IOData(np.sin(t), m.simulate(t, np.sin(t)) + 0.3, t)
    >>> x0, c = estimate_initial_state(m, d, offset=True)
    >>> x0.round(6).tolist(), round(c, 6)
    ([0.5, -1.0], 0.3)
    """
    fit = _StateFit(model, data, offset)
    with np.errstate(all="ignore"):
        starts = [fit.linear_start(), np.zeros(fit.size)]
        own = getattr(model, "initial_state", None)
        if own is not None:
            own = np.concatenate([np.ravel(x) for x in own]) if isinstance(own, tuple) else own   # blocks' states
            starts.append(np.append(own, [fit.own_offset] if offset else []))
        best = min(starts, key=fit.sse)
        if not fit.linear:
            best = fit.refine(best)
    return (best[:-1], float(best[-1])) if offset else best


class _StateFit:
    """The residuals of ``model`` on ``data`` as a function of its initial state (and offset)."""

    def __init__(self, model, data, offset: bool):
        self.model, self.data, self.offset = model, data, bool(offset)
        self.y = np.asarray(data.y, dtype=float).reshape(-1)
        self.n = model.order
        self.size = self.n + self.offset
        self.own_offset = float(getattr(model, "offset", 0.0) or 0.0)
        self.linear = getattr(model, "state_enters_linearly",
                              getattr(model, "output_nonlinearity", None) is None and not hasattr(model, "feedback"))

    def simulate(self, beta) -> np.ndarray:
        y = self.model.simulate(self.data, initial_state=beta[:self.n])
        return y + (beta[-1] - self.own_offset) if self.offset else y

    def residual(self, beta) -> np.ndarray:
        return self.y - self.simulate(np.asarray(beta, dtype=float))

    def sse(self, beta) -> float:
        r = self.residual(beta)
        return float(r @ r) if np.all(np.isfinite(r)) else np.inf

    def linear_start(self) -> np.ndarray:
        """The least-squares solution of the model linearised in the state at rest (exact when it is linear)."""
        zero = np.zeros(self.size)
        rest = self.simulate(zero)
        columns = [self.simulate(np.eye(self.size)[i]) - rest for i in range(self.n)]
        if self.offset:
            columns.append(constant_column(self.y.size))
        if not columns:
            return zero
        R = triangular_factor(columns, self.y - rest)
        return solve_minimum_norm(R, self.y.size) if np.all(np.isfinite(R)) else zero

    def refine(self, start) -> np.ndarray:
        """Levenberg-Marquardt from ``start`` (kept if it does not improve)."""
        if self.size == 0 or not np.isfinite(self.sse(start)):
            return start
        try:
            res = lmder(self.residual, None, start, maxfev=30 * (self.size + 1))
        except ValueError:   # a non-finite trial where MINPACK would go on with NaN
            return start
        return res.x if self.sse(res.x) < self.sse(start) else start
