"""How :func:`~hammerstein_ctrl.identify` fits each family of structures: the cost, its automatic method, the result.

:func:`route` dispatches on the structure's class (:func:`functools.singledispatch`), not on a chain of
``isinstance`` tests: a family of structures is one registered function that checks the records it can take and
names its :class:`Route`.  A new family registers its own (``route.register``) and :func:`identify` fits it without
being touched.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Tanh())
>>> data = hc.IOData([0.0, 1.0, 0.5, 0.2], [0.0, 0.1, 0.3, 0.2], dt=0.1)
>>> route(s, (data,)).cost.__name__, route(s, (data, data)).cost.__name__
('HammersteinCost', 'RecordsCost')
>>> try:
...     route("tanh", (data,))
... except hc.ParameterError as exc:
...     print(str(exc)[:60])
structure must be a structure of the package (HammersteinStr
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..blocks._lure import LureStructure
from ..blocks._mimo import MIMOStructure
from ..blocks._structure import BlockStructure
from ..blocks._wiener_hammerstein import WienerHammersteinStructure
from ..exceptions import ParameterError
from ._auto import auto_minimize
from ._auto_records import auto_delayed, auto_mimo, auto_records
from ._auto_whole import auto_lure, auto_wiener_hammerstein
from ._delay_fit import DelayedCost
from ._experiments import RecordsCost
from ._lure_fit import LureCost
from ._mimo_fit import MIMOCost
from ._objective import HammersteinCost
from ._wh_fit import WienerHammersteinCost

__all__ = ["Route", "route"]

STRUCTURES = ("HammersteinStructure, WienerStructure, HammersteinWienerStructure, a MIMO, Lur'e or "
              "Wiener-Hammerstein structure")


@dataclass(frozen=True)
class Route:
    """How one kind of fit runs.

    Attributes
    ----------
    cost : type
        The least-squares cost, called as ``cost(record, structure, reject_unstable=...)`` (``cost(records, ...)``
        when ``several``).
    auto : callable
        Its automatic method, ``auto(cost, x0, maxfev=, seed=, allow_unstable=, callback=)``.
    several : bool
        The cost takes every record (shared blocks, a nuisance set each).
    mimo : bool
        The result reports the fit of each output (its ``output_fits``).
    """

    cost: type
    auto: Callable
    several: bool = False
    mimo: bool = False

    def make(self, records, structure, reject_unstable: bool = False):
        """The cost of ``structure`` on ``records``, each record checked to determine its parameters first."""
        if not self.several:
            records[0].check_identifiable(structure.n_params)
            return self.cost(records[0], structure, reject_unstable=reject_unstable)
        cost = self.cost(records, structure, reject_unstable=reject_unstable)
        for rec in records:
            rec.check_identifiable(structure.n_params)
        cost.data.check_identifiable(cost.n_params)
        return cost


@functools.singledispatch
def route(structure, records) -> Route:
    """The :class:`Route` that fits ``structure`` to ``records`` (a tuple of records).

    Raises
    ------
    ParameterError
        ``structure`` is not a structure of the package, or the records are not what its family takes.
    """
    if isinstance(structure, str):
        raise ParameterError(f"structure must be a structure of the package ({STRUCTURES}), got the name "
                             f"{structure!r}; the paper's cases are hc.presets.trs() and hc.presets.emps() (their "
                             ".structure and .x0)")
    raise ParameterError(f"structure must be a structure of the package ({STRUCTURES}), got "
                         f"{type(structure).__name__}")


def _one_siso_record(records, structure, name: str) -> None:
    for rec in records:
        rec.require_siso(f"a {structure.kind} structure")
    if len(records) > 1:
        raise ParameterError(f"several records in one {name} fit are not supported yet: fit one record")


def _auto_block(cost, x0=None, **kwargs):
    """``auto`` on one record: an ``x0`` may leave out the offset and initial state, no other length is taken."""
    if x0 is not None:
        x = np.asarray(x0, dtype=float).reshape(-1)
        if x.size not in (cost.structure.n_core, cost.structure.n_params):
            cost.structure.check_beta(x)
    return auto_minimize(cost, x0, **kwargs)


@route.register
def _block(structure: BlockStructure, records) -> Route:
    for rec in records:
        rec.require_siso(f"a {structure.kind} structure")
    if len(records) > 1:
        return Route(RecordsCost, auto_records, several=True)
    if structure.linear.delay:
        return Route(DelayedCost, auto_delayed)
    return Route(HammersteinCost, _auto_block)


@route.register
def _mimo(structure: MIMOStructure, records) -> Route:
    if len(records) > 1:
        raise ParameterError("several records in one MIMO fit are not supported yet: fit one record, or join "
                             "records that follow each other")
    return Route(MIMOCost, auto_mimo, mimo=True)


@route.register
def _lure(structure: LureStructure, records) -> Route:
    _one_siso_record(records, structure, "Lur'e")
    return Route(LureCost, auto_lure)


@route.register
def _wiener_hammerstein(structure: WienerHammersteinStructure, records) -> Route:
    _one_siso_record(records, structure, "Wiener-Hammerstein")
    return Route(WienerHammersteinCost, auto_wiener_hammerstein)
