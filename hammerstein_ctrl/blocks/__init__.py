"""Block-oriented structures and models: static maps, Hammerstein, Wiener, Hammerstein-Wiener, MIMO, Lur'e loops
and Wiener-Hammerstein.

A *structure* maps a parameter vector to a *model*; a model simulates, linearises and exports to python-control.

.. autosummary::
   :nosignatures:

   Nonlinearity
   Tanh
   Coulomb
   Polynomial
   Saturation
   DeadZone
   PiecewiseLinear
   Sigmoid
   Friction
   CustomNonlinearity
   nonlinearity_from_name
   NONLINEARITIES
   LinearStructure
   BlockStructure
   HammersteinStructure
   WienerStructure
   HammersteinWienerStructure
   BlockModel
   HammersteinModel
   WienerModel
   HammersteinWienerModel
   MIMOStructure
   mimo_structure
   MIMOHammersteinStructure
   MIMOWienerStructure
   MIMOHammersteinWienerStructure
   MIMOModel
   LureStructure
   LureModel
   lure_structure
   WienerHammersteinStructure
   WienerHammersteinModel
   wiener_hammerstein_structure
   UnitGainBlock
"""

from ._nonlinearities import Nonlinearity
from ._families import (Tanh, Coulomb, Polynomial, Saturation, DeadZone, PiecewiseLinear, Sigmoid, Friction,
                        CustomNonlinearity, nonlinearity_from_name, NONLINEARITIES)
from ._structure import (LinearStructure, BlockStructure, HammersteinStructure, WienerStructure,
                         HammersteinWienerStructure)
from ._model import BlockModel, HammersteinModel, WienerModel, HammersteinWienerModel
from ._mimo import (MIMOStructure, mimo_structure, MIMOHammersteinStructure, MIMOWienerStructure,
                    MIMOHammersteinWienerStructure)
from ._mimo_model import MIMOModel
from ._lure import LureStructure, LureModel, lure_structure
from ._wiener_hammerstein import WienerHammersteinStructure, WienerHammersteinModel, wiener_hammerstein_structure
from ._unit_gain import UnitGainBlock

__all__ = [
    "Nonlinearity", "Tanh", "Coulomb", "Polynomial", "Saturation", "DeadZone", "PiecewiseLinear", "Sigmoid",
    "Friction", "CustomNonlinearity", "nonlinearity_from_name", "NONLINEARITIES", "LinearStructure",
    "BlockStructure", "HammersteinStructure", "WienerStructure", "HammersteinWienerStructure", "BlockModel",
    "HammersteinModel", "WienerModel", "HammersteinWienerModel", "MIMOStructure", "mimo_structure",
    "MIMOHammersteinStructure", "MIMOWienerStructure", "MIMOHammersteinWienerStructure", "MIMOModel",
    "LureStructure", "LureModel", "lure_structure", "WienerHammersteinStructure", "WienerHammersteinModel",
    "wiener_hammerstein_structure", "UnitGainBlock"
]
