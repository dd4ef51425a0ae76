"""How far to trust a fit: parameter covariance and its propagation, verdicts, residual analysis and tests
against nested models.

.. autosummary::
   :nosignatures:

   ParameterUncertainty
   NoiseModel
   UncertainParameters
   Propagated
   CharacteristicsTable
   estimate_uncertainty
   propagate
   parameter_covariance
   linear_characteristics
   Verdict
   ResidualAnalysis
   residual_analysis
   NestedTest
   nested_f_test
"""

from ._uncertainty import ParameterUncertainty, NoiseModel, Propagated, estimate_uncertainty, parameter_covariance
from ._propagation import UncertainParameters, CharacteristicsTable, propagate, linear_characteristics
from ._diagnostics import Verdict
from ._residuals import ResidualAnalysis, residual_analysis
from ._significance import NestedTest, nested_f_test

__all__ = [
    "ParameterUncertainty", "NoiseModel", "UncertainParameters", "Propagated", "CharacteristicsTable",
    "estimate_uncertainty", "propagate", "parameter_covariance", "linear_characteristics", "Verdict",
    "ResidualAnalysis", "residual_analysis", "NestedTest", "nested_f_test"
]
