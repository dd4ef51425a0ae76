"""Fitting Lur'e loops: the least-squares cost and the data-driven starts.

:class:`LureCost` is the output-error objective ``J = sum (y - y_hat)^2`` of a
:class:`~hammerstein_ctrl.blocks.LureStructure` on a record, with the protocol
the optimisers and :func:`~hammerstein_ctrl.fit` use (``cost(beta)``,
``batch``, ``residuals``, ``residuals_batch``, ``simulate``).

:func:`hammerstein_start` turns a Hammerstein fit of the same record (friction
approximated on the input force, ``d0 u + d1 sign(u) + d2``) into a loop:
gain ``b = d0 B_monic``, Coulomb level ``|d1 / d0|``, constant ``-d2 / d0``.
"""

from __future__ import annotations

import numpy as np

from ._output_error import OutputErrorCost
from ..exceptions import ParameterError
from ..blocks._lure import DERIVATIVES, LureStructure
from ..blocks._families import Coulomb, Friction, Polynomial
from ..blocks._structure import HammersteinStructure, LinearStructure

__all__ = ["LureCost", "hammerstein_structure_of", "hammerstein_start", "linear_structure_of", "map_starts",
           "MAP_SHARE"]


class LureCost(OutputErrorCost):
    """``J(beta) = sum (y - y_hat(beta))^2`` of a Lur'e loop on one SISO record.

    Never raises for a hostile candidate: one that cannot be simulated scores
    ``inf`` (its residuals :data:`NONFINITE_RESIDUAL`).

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> from hammerstein_ctrl.blocks import lure_structure
    >>> s = lure_structure(); truth = [0.4, 2.0, 0.5, 0.05]
    >>> t = np.arange(3000) * 0.01; u = 2 * np.sin(0.7 * t) + np.sin(2.3 * t)
    >>> data = hc.IOData(u, s.model(truth).simulate(t, u), dt=0.01)
    >>> float(LureCost(data, s)(truth))
    0.0
    """

    what = "a Lur'e structure"

    def __init__(self, data, structure: LureStructure, *, reject_unstable: bool = False):
        if not isinstance(structure, LureStructure):
            raise ParameterError(f"structure must be a LureStructure, got {type(structure).__name__}")
        super().__init__(data, structure, reject_unstable=reject_unstable)

    def _sse_batch(self, B: np.ndarray) -> np.ndarray:
        return self.structure.simulate_rows(B, self._u, self._dt, self._hold, y=self._y)

    def simulate_batch(self, betas) -> np.ndarray:
        """Simulated outputs ``(B, N)``."""
        return self.structure.simulate_rows(self._rows(betas), self._u, self._dt, self._hold)


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


#: Share of the feedback's linear term a linear fit's start gives the map when no fixed coefficient decides it.
MAP_SHARE = 0.5


def linear_structure_of(structure: LureStructure) -> HammersteinStructure:
    """The linear model whose fit starts a Lur'e loop with a map that is not sign-type: the same orders, a monic
    numerator (the gain on a ``Polynomial(1)`` input map), the same offset and initial-state option."""
    lin = structure.linear
    return HammersteinStructure(LinearStructure(lin.num_order, lin.den_order), Polynomial(1), offset=structure.offset,
                                initial_state=structure.initial_state)


def _slope_and_blocks(structure: LureStructure, num, den):
    """``(s, B, A)``: the Lur'e block ``B/A`` and the map's slope ``s`` whose loop is the linear model ``num/den``
    (``A = den - s p^k num``): ``s`` keeps a fixed coefficient of ``A`` at the feedback's power ``k``, else gives
    the map :data:`MAP_SHARE` of that term."""
    k = DERIVATIVES[structure.feedback]
    lead = np.trim_zeros(np.asarray(num, dtype=float), "f")
    low = lead[-1] if lead.size else 0.0
    den = np.asarray(den, dtype=float)
    term = den[den.size - 1 - k]
    fixed = structure.linear.fixed.get(f"a{k}")
    if low == 0.0 or not np.isfinite(low):
        return None
    s = (term - fixed) / low if fixed is not None else MAP_SHARE * term / low
    shifted = np.polymul(num, np.eye(k + 1)[0])
    return s, np.asarray(num, dtype=float), np.polysub(den, s * np.concatenate(
        [np.zeros(den.size - shifted.size), shifted]))


def _map_candidates(nl, z, s) -> list[np.ndarray]:
    """Parameter vectors of ``nl`` whose map is closest to the line ``s z`` over the signal ``z``: the least-squares
    fit of a family linear in its parameters, or each shape of its scan with the scale fitted."""
    z = np.asarray(z, dtype=float)
    grid = np.quantile(z, np.linspace(0.0, 1.0, 201))
    target = s * grid
    basis = nl.basis(grid)
    if basis is not None:
        w, *_ = np.linalg.lstsq(np.atleast_2d(basis).T, target, rcond=None)
        return [w]
    shapes = nl.shape_grid(z) if nl.scale_index is not None else None
    out = []
    for p in ([] if shapes is None else np.atleast_2d(shapes)):
        with np.errstate(all="ignore"):
            col = nl(grid, p)
        if np.all(np.isfinite(col)) and col @ col > 0:
            q = np.array(p, dtype=float)
            q[nl.scale_index] = float(col @ target / (col @ col))
            out.append(q)
    return out


def map_starts(structure: LureStructure, linear: HammersteinStructure, beta, data) -> list[np.ndarray]:
    """Lur'e parameters that the linear fit ``beta`` (of :func:`linear_structure_of`) suggests, one per candidate of
    the map (:func:`_map_candidates`); empty for a map with no automatic start (a custom one)."""
    from ..simulate._batch import simulate_batch

    beta = np.asarray(beta, dtype=float)
    num, den = linear.linear.coefficients(beta[:linear.linear.n_params])
    gain = beta[linear.linear.n_params]
    found = _slope_and_blocks(structure, num[0] * gain, den[0])
    if found is None:
        return []
    s, B, A = found
    k = DERIVATIVES[structure.feedback]
    with np.errstate(all="ignore"):
        z = simulate_batch(np.polymul(num[0] * gain, np.eye(k + 1)[0])[None, :], den, np.asarray(data.u, float),
                           float(data.dt), intersample=data.intersample)[0]
    if not np.all(np.isfinite(z)):
        return []
    theta = structure.linear.free_parameters(B, A)
    rest = beta[linear.n_core:].copy()
    if structure.initial_state == "estimate":     # the loop's states carry the gain the input map had
        rest[int(structure.offset):] /= gain
    return [np.concatenate([theta, p, rest]) for p in _map_candidates(structure.nonlinearity, z, s)]
