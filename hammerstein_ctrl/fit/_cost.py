"""The contract every least-squares cost keeps (:class:`Cost`), and the sizes every cost reads off its structure
(:class:`StructureSized`)."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

__all__ = ["Cost", "StructureSized"]


class StructureSized:
    """``n_params`` and ``param_names`` of a cost: those of its ``structure``.

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Tanh())
    >>> data = hc.IOData([0.0, 1.0, 0.5, 0.2], [0.0, 0.1, 0.3, 0.2], dt=0.1)
    >>> cost = hc.HammersteinCost(data, s)
    >>> cost.n_params, cost.param_names == s.param_names
    (3, True)
    """

    @property
    def n_params(self) -> int:
        return self.structure.n_params

    @property
    def param_names(self) -> tuple[str, ...]:
        return self.structure.param_names


@runtime_checkable
class Cost(Protocol):
    """What every least-squares cost offers the optimisers, :func:`identify` and the verdicts.

    ``J(x) = sum of squared residuals`` of a structure on a record: one point (``cost(x)``, ``residuals(x)``,
    ``simulate(x)``) or a batch of candidates, one per row (``batch``, ``residuals_batch``).  The costs of the
    package (:class:`HammersteinCost`, :class:`DelayedCost`, :class:`RecordsCost`, :class:`MIMOCost`,
    :class:`LureCost`, :class:`WienerHammersteinCost`, :class:`KnownLoopCost`) all keep it.

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Tanh())
    >>> data = hc.IOData([0.0, 1.0, 0.5, 0.2], [0.0, 0.1, 0.3, 0.2], dt=0.1)
    >>> isinstance(hc.HammersteinCost(data, s), Cost)
    True
    """

    structure: object
    data: object
    reject_unstable: bool

    def __call__(self, x) -> float: ...

    def batch(self, X): ...

    def residuals(self, x): ...

    def residuals_batch(self, X): ...

    def simulate(self, x): ...
