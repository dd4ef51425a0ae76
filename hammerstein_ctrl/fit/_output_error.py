"""The output-error cost protocol of the structures simulated as a whole (Lur'e loops, Wiener-Hammerstein models).

:class:`OutputErrorCost` holds one SISO record and gives ``cost(beta)``,
``batch``, ``residuals``, ``residuals_batch`` and ``simulate`` from one hook,
``simulate_batch(betas)`` (a subclass's simulation of a batch of candidates).
A candidate that cannot be simulated scores ``inf`` and gets residuals
:data:`~hammerstein_ctrl.optimize._normal_equations.NONFINITE_RESIDUAL`; with
``reject_unstable`` so does one whose structure says it is unstable
(``structure.unstable(betas)``).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ParameterError
from ..optimize._normal_equations import NONFINITE_RESIDUAL
from ._cost import StructureSized

__all__ = ["OutputErrorCost"]


class OutputErrorCost(StructureSized):
    """``J(beta) = sum (y - y_hat(beta))^2`` on one SISO record; subclasses define :meth:`simulate_batch`."""

    #: Words naming the structure in a refusal (``"a Lur'e structure"``).
    what = "this structure"

    def __init__(self, data, structure, *, reject_unstable: bool = False):
        data.require_siso(self.what)
        self.data, self.structure, self.reject_unstable = data, structure, bool(reject_unstable)
        self._u = np.ascontiguousarray(np.asarray(data.u, dtype=float).reshape(-1))
        self._y = np.ascontiguousarray(np.asarray(data.y, dtype=float).reshape(-1))
        self._dt, self._hold = float(data.dt), data.intersample

    @property
    def n_samples(self) -> int:
        return self._u.size

    def _rows(self, betas) -> np.ndarray:
        return np.atleast_2d(self.structure.check_beta(betas))

    def _rejected(self, B: np.ndarray) -> np.ndarray:
        if not self.reject_unstable:
            return np.zeros(B.shape[0], dtype=bool)
        return self.structure.unstable(B)

    def simulate_batch(self, betas) -> np.ndarray:
        """Simulated outputs ``(B, N)`` of the rows of ``betas``."""
        raise NotImplementedError

    def simulate(self, beta) -> np.ndarray:
        return self.simulate_batch(beta)[0]

    def residuals_batch(self, betas) -> np.ndarray:
        """``y - y_hat`` for each row, non-finite values (and rejected rows) replaced by :data:`NONFINITE_RESIDUAL`."""
        B = self._rows(betas)
        R = self.simulate_batch(B)
        with np.errstate(all="ignore"):
            np.subtract(self._y, R, out=R)
        R[~np.isfinite(R)] = NONFINITE_RESIDUAL
        R[self._rejected(B)] = NONFINITE_RESIDUAL
        return R

    def residuals(self, beta) -> np.ndarray:
        b = self.structure.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("residuals(beta) takes one vector; use residuals_batch for a batch")
        return self.residuals_batch(b)[0]

    def batch(self, betas) -> np.ndarray:
        """``J`` of each row of ``betas``."""
        B = self._rows(betas)
        J = self._sse_batch(B)
        J[~np.isfinite(J) | self._rejected(B)] = np.inf
        return J

    def _sse_batch(self, B: np.ndarray) -> np.ndarray:
        """Sums of squared errors of the rows (a subclass with a faster pass overrides it)."""
        R = self.simulate_batch(B)
        with np.errstate(all="ignore"):
            np.subtract(self._y, R, out=R)
            return np.einsum("ij,ij->i", R, R)

    def __call__(self, beta) -> float:
        b = self.structure.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("cost(beta) takes one vector; use cost.batch for a batch")
        return float(self.batch(b)[0])

    def __repr__(self):
        return f"{type(self).__name__}({self.structure!r}, N={self.n_samples})"
