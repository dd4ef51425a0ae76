"""Figures for judging identified models: time and error responses, spectra, Bode plots, the static map, convergence
and comparisons.

.. autosummary::
   :nosignatures:

   time_response
   error_response
   psd
   dominant_frequency
   input_signal
   bode
   convergence
   nonlinearity
   final_cost
   compare
   compare_fits
   result_figure
   study_figure_set
   study_figures
   residual_figure
"""

from ._figures import time_response, error_response
from ._spectra import psd, dominant_frequency, input_signal
from ._blocks import bode, nonlinearity
from ._runs import convergence, final_cost
from ._results import compare, compare_fits, result_figure, residual_figure
from ._studies import study_figure_set, study_figures

__all__ = [
    "time_response", "error_response", "psd", "dominant_frequency", "input_signal", "bode", "convergence",
    "nonlinearity", "final_cost", "compare", "compare_fits", "result_figure", "study_figure_set", "study_figures",
    "residual_figure"
]
