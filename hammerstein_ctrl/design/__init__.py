"""Controller design on an identified model: PID tuning verified in the loop, robustness figures and operating points.

.. autosummary::
   :nosignatures:

   tune_pid
   PIDResult
   DiscretePID
   closed_loop
   analyze_loop
   approximate
   pid_controller
   TuningCost
   loop_figure
   RULES
   CRITERIA
   ms_constrained_pid
   loop_figures
   OperatingPoint
   operating_point
   small_signal
"""

from ._pid import PIDResult, DiscretePID, pid_controller, TuningCost, RULES, CRITERIA
from ._tune import tune_pid
from ._approximate import approximate
from ._loops import closed_loop, analyze_loop, loop_figure
from ._robust import ms_constrained_pid, loop_figures
from ._operating_point import OperatingPoint, operating_point, small_signal

__all__ = [
    "tune_pid", "PIDResult", "DiscretePID", "closed_loop", "analyze_loop", "approximate", "pid_controller",
    "TuningCost", "loop_figure", "RULES", "CRITERIA", "ms_constrained_pid", "loop_figures", "OperatingPoint",
    "operating_point", "small_signal"
]
