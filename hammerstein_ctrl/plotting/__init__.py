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

from ._figures import (time_response, error_response, psd, dominant_frequency, input_signal, bode, convergence,
                       nonlinearity, final_cost, compare, compare_fits, result_figure, study_figure_set, study_figures,
                       residual_figure)

__all__ = [
    "time_response", "error_response", "psd", "dominant_frequency", "input_signal", "bode", "convergence",
    "nonlinearity", "final_cost", "compare", "compare_fits", "result_figure", "study_figure_set", "study_figures",
    "residual_figure"
]
