"""Optimisers for Hammerstein identification: SPSA, NL-SPSA, N-SPSA and AMVO-SCA.

Use :func:`minimize` (``scipy.optimize.minimize`` style) or the individual
functions; each returns an :class:`OptimizeResult` (scipy's interface).  Every
routine takes a ``seed`` (int or ``numpy.random.Generator``), counts every
objective evaluation in ``nfev`` and never exceeds ``maxfev``.
:func:`lmder` is MINPACK's Levenberg-Marquardt on a residual vector, the
package's own copy (scipy 1.15-1.17's reads past a Jacobian column), which the
``"lm"`` method and the start search hand ill-conditioned problems to.

Result status (``OptimizeResult.status``; ``success`` is true for the first two
with a finite ``fun``):

=====================  ==  =====================================================
``COMPLETED``           0  ran its budget (SPSA family, AMVO-SCA) or converged
``CALLBACK_STOP``       1  the callback asked to stop
``DIVERGED``            2  the iterates or J blew up (SPSA's failure mode)
``NO_FINITE_VALUE``     3  every evaluation was non-finite
``SOLVER_FAILED``       4  a solver stopped without converging (scipy's message)
``BUDGET_EXHAUSTED``    5  LM or a scipy method ran out of ``maxfev`` first
=====================  ==  =====================================================

.. autosummary::
   :nosignatures:

   minimize
   spsa
   nlspsa
   nspsa
   amvo_sca
   levenberg_marquardt
   lmder
   OptimizeResult
   Budget
   History
   StepGain
   PerturbationGain
   GainSequence
"""

from ._common import (BUDGET_EXHAUSTED, CALLBACK_STOP, COMPLETED, DIVERGED, NO_FINITE_VALUE, SOLVER_FAILED,
                      STATUS_CODES, Budget, BudgetExhausted, History, OptimizeResult, as_rng, as_x0)
from ._minpack import MinpackResult, lmder
from ._amvo_sca import amvo_sca
from ._least_squares import levenberg_marquardt
from ._gains import SPALL_ALPHA, SPALL_GAMMA, GainSequence, PerturbationGain, StepGain
from ._minimize import METHODS, SCIPY_METHODS, canonical_method, minimize
from ._spsa import nlspsa, normalized_difference, nspsa, spsa

__all__ = [
    "Budget", "BudgetExhausted", "OptimizeResult",
    "minimize", "canonical_method", "METHODS", "SCIPY_METHODS",
    "spsa", "nlspsa", "nspsa", "amvo_sca", "levenberg_marquardt", "normalized_difference",
    "GainSequence", "StepGain", "PerturbationGain", "SPALL_ALPHA", "SPALL_GAMMA",
    "COMPLETED", "CALLBACK_STOP", "DIVERGED", "NO_FINITE_VALUE", "SOLVER_FAILED", "BUDGET_EXHAUSTED", "STATUS_CODES",
    "History", "lmder", "MinpackResult",
    "as_rng", "as_x0",
]


def __getattr__(name):
    """The flat layout's sub-modules ``gains``, ``least_squares`` and ``normal_lm`` as attributes, for one release
    (their old paths import with a DeprecationWarning)."""
    if name in ("gains", "least_squares", "normal_lm"):
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
