"""Fitting Lur'e loops: the least-squares cost and the data-driven starts.

:class:`LureCost` is the output-error objective ``J = sum (y - y_hat)^2`` of a
:class:`~hammerstein_ctrl.lure.LureStructure` on a record, with the protocol
the optimisers and :func:`~hammerstein_ctrl.identify` use (``cost(beta)``,
``batch``, ``residuals``, ``residuals_batch``, ``simulate``).

:func:`hammerstein_start` turns a Hammerstein fit of the same record (friction
approximated on the input force, ``d0 u + d1 sign(u) + d2``) into a loop:
gain ``b = d0 B_monic``, Coulomb level ``|d1 / d0|``, constant ``-d2 / d0``.
"""

from __future__ import annotations

import numpy as np

from .exceptions import ParameterError
from .lure import LureStructure, simulate_parts
from .nonlinearities import Coulomb, Friction
from .normal_equations import NONFINITE_RESIDUAL
from .simulate import unstable
from .structure import HammersteinStructure, LinearStructure

__all__ = ["LureCost", "hammerstein_structure_of", "hammerstein_start"]


class LureCost:
    """``J(beta) = sum (y - y_hat(beta))^2`` of a Lur'e loop on one SISO record.

    Never raises for a hostile candidate: one that cannot be simulated scores
    ``inf`` (its residuals :data:`NONFINITE_RESIDUAL`).

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> from hammerstein_ctrl.lure import lure_structure
    >>> s = lure_structure(); truth = [0.4, 2.0, 0.5, 0.05]
    >>> t = np.arange(3000) * 0.01; u = 2 * np.sin(0.7 * t) + np.sin(2.3 * t)
    >>> data = hc.IOData(u, s.model(truth).simulate(t, u), dt=0.01)
    >>> float(LureCost(data, s)(truth))
    0.0
    """

    def __init__(self, data, structure: LureStructure, *, reject_unstable: bool = False):
        if not isinstance(structure, LureStructure):
            raise ParameterError(f"structure must be a LureStructure, got {type(structure).__name__}")
        data.require_siso("a Lur'e structure")
        self.data, self.structure, self.reject_unstable = data, structure, bool(reject_unstable)
        self._u = np.ascontiguousarray(np.asarray(data.u, dtype=float).reshape(-1))
        self._y = np.ascontiguousarray(np.asarray(data.y, dtype=float).reshape(-1))
        self._dt, self._hold = float(data.dt), data.intersample

    @property
    def n_params(self) -> int:
        return self.structure.n_params

    @property
    def param_names(self) -> tuple[str, ...]:
        return self.structure.param_names

    @property
    def n_samples(self) -> int:
        return self._u.size

    def _rejected(self, B: np.ndarray) -> np.ndarray:
        if not self.reject_unstable:
            return np.zeros(B.shape[0], dtype=bool)
        return unstable(self.structure.linear.coefficients(B[:, :self.structure.linear.n_params])[1])

    def batch(self, betas) -> np.ndarray:
        """``J`` of each row of ``betas``."""
        B = np.atleast_2d(self.structure.check_beta(betas))
        J = simulate_parts(self.structure.parts(B), self._u, self._dt, self._hold, y=self._y)
        J[~np.isfinite(J) | self._rejected(B)] = np.inf
        return J

    def __call__(self, beta) -> float:
        b = self.structure.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("cost(beta) takes one vector; use cost.batch for a batch")
        return float(self.batch(b)[0])

    def simulate_batch(self, betas) -> np.ndarray:
        """Simulated outputs ``(B, N)``."""
        B = np.atleast_2d(self.structure.check_beta(betas))
        return simulate_parts(self.structure.parts(B), self._u, self._dt, self._hold)

    def simulate(self, beta) -> np.ndarray:
        return self.simulate_batch(beta)[0]

    def residuals_batch(self, betas) -> np.ndarray:
        """``y - y_hat`` for each row, non-finite values (and rejected rows) replaced by :data:`NONFINITE_RESIDUAL`."""
        B = np.atleast_2d(self.structure.check_beta(betas))
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

    def __repr__(self):
        return f"LureCost({self.structure!r}, N={self.n_samples})"


def hammerstein_structure_of(structure: LureStructure) -> HammersteinStructure:
    """The Hammerstein structure whose fit starts a Lur'e one: the same poles, a monic numerator, and
    ``Coulomb`` on the input (the friction's sign taken on the force instead of the feedback signal)."""
    lin = structure.linear
    fixed = {k: v for k, v in lin.fixed.items() if k != f"b{lin.num_order}"}
    monic = LinearStructure(lin.num_order, lin.den_order, fixed=fixed)
    return HammersteinStructure(monic, Coulomb(), offset=structure.offset, initial_state=structure.initial_state)


def hammerstein_start(structure: LureStructure, hammerstein: HammersteinStructure, beta) -> np.ndarray:
    """The Lur'e parameters that :func:`hammerstein_structure_of`'s fit ``beta`` suggests."""
    beta = np.asarray(beta, dtype=float)
    k = hammerstein.linear.n_params
    num, den = hammerstein.linear.coefficients(beta[:k])
    d0, d1, d2 = beta[k:k + 3]
    gain = d0 if abs(d0) > 0 else 1.0
    lin = structure.linear
    linear = lin.free_parameters(num[0] * gain, den[0])
    fc, c = abs(d1 / gain), -d2 / gain
    nl = [fc, c] if isinstance(structure.nonlinearity, Friction) else [0.0, fc, c]
    rest = beta[hammerstein.n_core:].copy()
    if structure.initial_state == "estimate":     # the loop's states carry the gain the map had
        rest[int(structure.offset):] /= gain
    return np.concatenate([linear, nl, rest])
