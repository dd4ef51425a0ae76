"""Exact sampled simulation: single systems, batches of candidates in one compiled pass, dead time, loops and the
python-control exports they agree with.

.. autosummary::
   :nosignatures:

   companion_realization
   discretize
   lsim
   simulate
   simulate_blocks
   simulate_batch
   sse_batch
   sse_basis_batch
   free_response
   response_blocks
   simulate_delayed
   linear_ss
   sampled_iosys
   simulate_loops
   simulate_controller_loop
   simulate_known_loop
   discrete_pid_iosys
"""

from ._simulate import (companion_realization, discretize, lsim, simulate, simulate_blocks, simulate_batch, sse_batch,
                        sse_basis_batch, free_response, response_blocks)
from ._delay import simulate_delayed
from ._export import linear_ss, sampled_iosys
from ._loop import simulate_loops, simulate_controller_loop, simulate_known_loop, discrete_pid_iosys

__all__ = [
    "companion_realization", "discretize", "lsim", "simulate", "simulate_blocks", "simulate_batch", "sse_batch",
    "sse_basis_batch", "free_response", "response_blocks", "simulate_delayed", "linear_ss", "sampled_iosys",
    "simulate_loops", "simulate_controller_loop", "simulate_known_loop", "discrete_pid_iosys"
]
