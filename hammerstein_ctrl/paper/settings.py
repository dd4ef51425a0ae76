"""The paper's optimiser settings (Tables 2 and 6) and the Section 4.1 example.

Table 6 (EMPS) is garbled in the source text: it prints ``c(k) = 0.2/(k+1)^(1/3)``
and no norm limit.  With the exponent 1/3 N-SPSA's mean J over 25 runs is about
37 and NL-SPSA's about 18, against the paper's 0.536 and 1.855; with 1/6 (the
TRS value of Table 2 for SPSA and NL-SPSA) they are 0.57 and 1.90.  The EMPS
presets therefore use ``gamma = 1/6`` and ``delta = 0.01``.

The paper scores a run by its last iterate, so the SPSA family's presets ask
for ``estimate="last"`` (the library's default returns the best point evaluated).

The paper gives iteration counts through NFE = 2 x iterations (2 000 for TRS,
2 500 for EMPS); the presets set ``maxiter = k_max`` accordingly.  Scoring the
final iterate costs one evaluation more, so a run reports ``nfev = 2 k_max + 1``.

``"lm"`` (Levenberg-Marquardt, not in the paper) gets the SPSA family's
budget.

AMVO-SCA's search box is not given in the paper.  The boxes below contain the
paper's initial point and every best estimate it reports (Tables 4 and 8), with
room to spare; they are our choice, documented here and in the closing notes.
"""

from __future__ import annotations

import numpy as np

from ..optimize._gains import PerturbationGain, StepGain

__all__ = ["trs_methods", "emps_methods", "eq8_objective", "eq8_methods", "TRS_BOUNDS", "EMPS_BOUNDS"]

#: The paper scores a run by its last iterate (section 4.3, step 3), not the best point evaluated.
LAST = {"estimate": "last"}

#: AMVO-SCA box for the TRS, beta = [b0, a0, a1, d0, d1].
TRS_BOUNDS = ((-5.0, 0.0), (0.0, 10.0), (0.0, 10.0), (-10.0, 0.0), (0.0, 1.0))
#: AMVO-SCA box for the EMPS, beta = [a1, d0, d1, d2].
EMPS_BOUNDS = ((0.0, 10.0), (0.0, 2.0), (-2.0, 2.0), (-0.5, 0.5))


def trs_methods() -> dict:
    """Keyword arguments for :func:`~hammerstein_ctrl.optimize._minimize`, TRS (Table 2)."""
    return {
        "spsa": {"method": "spsa", "maxiter": 1000,
                 "options": {"a": StepGain(0.02, 10, 0.9), "c": PerturbationGain(0.1, 1 / 6), **LAST}},
        "nlspsa": {"method": "nlspsa", "maxiter": 1000,
                   "options": {"a": StepGain(800, 10, 0.9), "c": PerturbationGain(0.1, 1 / 6),
                               "norm_limit": 0.01, **LAST}},
        "nspsa": {"method": "nspsa", "maxiter": 1000,
                  "options": {"a": StepGain(0.025, 11, 0.3), "c": PerturbationGain(0.2, 1 / 3), **LAST}},
        "amvo-sca": {"method": "amvo-sca", "maxfev": 5000, "options": {"pop_size": 50},
                     "bounds": TRS_BOUNDS},
        "lm": {"method": "lm", "maxfev": 2001},
    }


def emps_methods() -> dict:
    """Keyword arguments for :func:`~hammerstein_ctrl.optimize._minimize`, EMPS (Table 6, fixed)."""
    c = PerturbationGain(0.2, 1 / 6)
    return {
        "spsa": {"method": "spsa", "maxiter": 1250, "options": {"a": StepGain(2e-4, 24, 0.9), "c": c, **LAST}},
        "nlspsa": {"method": "nlspsa", "maxiter": 1250,
                   "options": {"a": StepGain(9e-4, 24, 0.9), "c": c, "norm_limit": 0.01, **LAST}},
        "nspsa": {"method": "nspsa", "maxiter": 1250, "options": {"a": StepGain(0.66, 24, 0.9), "c": c, **LAST}},
        "amvo-sca": {"method": "amvo-sca", "maxfev": 5000, "options": {"pop_size": 50},
                     "bounds": EMPS_BOUNDS},
        "lm": {"method": "lm", "maxfev": 2501},
    }


def eq8_objective(theta) -> float:
    """The Section 4.1 test function ``f(theta) = ((theta - 1)^T (theta - 1))^3`` (equation 8).

    Its minimum is 0 at ``theta = 1``; ``f(0) = 1000`` for ``n = 10``.
    """
    d = np.asarray(theta, dtype=float) - 1.0
    return float(np.dot(d, d) ** 3)


def eq8_methods() -> dict:
    """Section 4.1 settings: ``theta(0) = 0`` (n = 10); SPSA and N-SPSA gains."""
    c = PerturbationGain(0.01, 0.101)
    return {
        "spsa": {"method": "spsa", "options": {"a": StepGain(0.05, 200, 0.602), "c": c, **LAST}},
        "nspsa": {"method": "nspsa", "options": {"a": StepGain(1.2, 200, 0.602), "c": c, **LAST}},
    }
