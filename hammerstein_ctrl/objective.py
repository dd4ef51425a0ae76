"""The identification objective J(beta) (paper Eq. 13) on a record.

:class:`HammersteinCost` is what the optimisers minimise.  It is a plain
callable ``cost(beta) -> float`` with a vectorised ``cost.batch(betas)``, and
it never raises or warns for a hostile candidate: a candidate whose
simulation is non-finite (overflow, NaN parameters) scores ``inf``.  A wrong
*length* of beta is a programming error and raises
:class:`~hammerstein_ctrl.exceptions.ParameterError`.

Unstable candidates are simulated like any other by default, because that is
what the paper does: EMPS's initial point (Table 5, ``a1 = -1``) is unstable
and has the finite cost 3.82e11 that the SPSA family starts from.  Pass
``reject_unstable=True`` to score every candidate with a right-half-plane pole
as ``inf`` instead.

Examples
--------
>>> from hammerstein_ctrl import presets
>>> p = presets.trs()
>>> round(p.cost(p.true_beta), 6)
178.5
"""

from __future__ import annotations

import numba
import numpy as np

from .exceptions import ParameterError
from .simulate import simulate_batch, sse_batch
from .structure import HammersteinStructure

__all__ = ["HammersteinCost"]


@numba.njit(cache=True, nogil=True)
def _combine(P, basis):  # pragma: no cover - compiled
    """``P @ basis`` single-threaded (BLAS threads would compete with the simulation)."""
    batch, p = P.shape
    V = np.empty((batch, basis.shape[1]))
    for b in range(batch):
        V[b, :] = P[b, 0] * basis[0]
        for j in range(1, p):
            V[b, :] += P[b, j] * basis[j]
    return V


class HammersteinCost:
    """Sum of squared output errors of a Hammerstein structure on a record.

    Parameters
    ----------
    data : IOData
        The estimation record (uniform time grid).
    structure : HammersteinStructure
        Maps beta to a model.
    reject_unstable : bool, default False
        Score candidates with a pole in the open right half-plane as ``inf``.

    Attributes
    ----------
    n_params : int
    param_names : tuple of str
    """

    def __init__(self, data, structure: HammersteinStructure, *, reject_unstable: bool = False):
        from .datasets import IOData

        if not isinstance(data, IOData):
            raise ParameterError(f"data must be an IOData record, got {type(data).__name__}")
        if not isinstance(structure, HammersteinStructure):
            raise ParameterError(
                f"structure must be a HammersteinStructure, got {type(structure).__name__}"
            )
        self.data = data
        self.structure = structure
        self.reject_unstable = bool(reject_unstable)
        self._y = np.ascontiguousarray(data.y, dtype=float)
        self._u = np.ascontiguousarray(data.u, dtype=float)
        self._n_linear = structure.linear.n_params
        # g(u; d) = d @ basis for nonlinearities linear in their parameters: a
        # batch of signals is then one matrix product (7x cheaper than the formula).
        basis = structure.nonlinearity.basis(self._u)
        self._basis = None if basis is None else np.ascontiguousarray(basis, dtype=float)

    @property
    def n_params(self) -> int:
        return self.structure.n_params

    @property
    def param_names(self) -> tuple[str, ...]:
        return self.structure.param_names

    def _pieces(self, b: np.ndarray):
        """Coefficients, signals and simulation options for a validated ``(B, n_params)`` array."""
        k, m = self._n_linear, self.structure.n_core
        num, den = self.structure.linear._coefficients(b[:, :k])
        with np.errstate(all="ignore"):
            if self._basis is not None:
                V = _combine(np.ascontiguousarray(b[:, k:m]), self._basis)
            else:
                V = self.structure.nonlinearity._evaluate(self._u, b[:, k:m])
        offset, x0 = self.structure.nuisance(b)
        opts = {"offset": offset, "x0": x0, "intersample": self.data.intersample}
        return num, den, V, opts

    def __call__(self, beta) -> float:
        """J at one beta (``inf`` if the candidate cannot be simulated)."""
        b = self.structure.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("cost(beta) takes one vector; use cost.batch for a batch")
        return float(self._sse(b[None, :])[0])

    def batch(self, betas) -> np.ndarray:
        """J for each row of ``betas`` (shape ``(B, n_params)``), in one compiled pass."""
        b = self.structure.check_beta(betas)
        return self._sse(b.reshape(-1, b.shape[-1]))

    def _sse(self, b: np.ndarray) -> np.ndarray:
        num, den, V, opts = self._pieces(b)
        return sse_batch(num, den, V, self.data.dt, self._y, reject_unstable=self.reject_unstable, **opts)

    def simulate(self, beta) -> np.ndarray:
        """Simulated output ŷ for one beta (NaN where the simulation fails)."""
        return self.simulate_batch(beta)[0]

    def simulate_batch(self, betas) -> np.ndarray:
        """Simulated outputs for each row of ``betas``, shape ``(B, N)`` (NaN rows where it fails)."""
        b = self.structure.check_beta(betas)
        num, den, V, opts = self._pieces(b.reshape(-1, b.shape[-1]))
        with np.errstate(all="ignore"):
            return simulate_batch(num, den, V, self.data.dt, **opts)

    def residuals(self, beta) -> np.ndarray:
        """``y - ŷ`` for one beta, for least-squares solvers (``J = sum(residuals**2)``).

        Non-finite residuals are replaced by a large finite value so that
        trust-region solvers back off instead of failing.
        """
        with np.errstate(all="ignore"):
            r = self._y - self.simulate(beta)
        bad = ~np.isfinite(r)
        if bad.any():
            r[bad] = 1e150
        return r

    def __repr__(self):
        return f"HammersteinCost({self.data.name!r}, {self.structure.describe()})"
