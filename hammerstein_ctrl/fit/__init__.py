"""Identification: :func:`identify` and its one result type, the least-squares costs of every structure, structure
selection and fits inside a known control loop.

.. autosummary::
   :nosignatures:

   identify
   IdentificationResult
   identify_in_loop
   KnownLoop
   KnownLoopCost
   select_structure
   candidate_structures
   SelectionResult
   information_criterion
   HammersteinCost
   DelayedCost
   RecordsStructure
   RecordsCost
   MIMOCost
   LureCost
   WienerHammersteinCost
   Cost
   route
   Route
"""

from ._identify import identify
from ._result import IdentificationResult
from ._in_loop import identify_in_loop, KnownLoop, KnownLoopCost
from ._selection import select_structure, candidate_structures, SelectionResult, information_criterion
from ._objective import HammersteinCost
from ._delay_fit import DelayedCost
from ._experiments import RecordsStructure, RecordsCost
from ._mimo_fit import MIMOCost
from ._lure_fit import LureCost
from ._wh_fit import WienerHammersteinCost
from ._cost import Cost
from ._routes import Route, route

__all__ = [
    "identify", "IdentificationResult", "identify_in_loop", "KnownLoop", "KnownLoopCost", "select_structure",
    "candidate_structures", "SelectionResult", "information_criterion", "HammersteinCost", "DelayedCost",
    "RecordsStructure", "RecordsCost", "MIMOCost", "LureCost", "WienerHammersteinCost", "Cost", "route", "Route",
]
