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
from .._deprecation import moved_names
from ._loop import simulate_loops, simulate_controller_loop, simulate_known_loop, discrete_pid_iosys

__all__ = [
    "companion_realization", "discretize", "lsim", "simulate", "simulate_blocks", "simulate_batch", "sse_batch",
    "sse_basis_batch", "free_response", "response_blocks", "simulate_delayed", "linear_ss", "sampled_iosys",
    "simulate_loops", "simulate_controller_loop", "simulate_known_loop", "discrete_pid_iosys"
]

#: Names of the flat layout's ``simulate`` module that are internals now: one release with a DeprecationWarning.
__getattr__ = moved_names(__name__, {
    **{name: (f"{__name__}._normal_pass", "internal: the normal-equation pass has no public replacement")
       for name in ("normal_pass", "normal_factor", "GROUPS_MIN_BYTES")},
    "output_terms": (f"{__name__}._batch", "internal: no public replacement"),
    "unstable": (f"{__name__}._simulate", "internal: use a model's or structure's own stability checks"),
    "COMPILED_EXPM_MAX_NORM": (f"{__name__}._discretize", "internal: no public replacement"),
    **{name: ("hammerstein_ctrl._kernels", "internal: no public replacement")
       for name in ("MAX_UNROLLED_STATES", "MAX_PASS_STATES")},
})
