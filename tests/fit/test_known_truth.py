"""Known-truth bench: `identify(data, structure)` with no x0 recovers systems made by independent code.

Every record is generated without the package's simulator: the nonlinearity is
plain numpy, the linear block is simulated by ``control.forced_response``
(first-order hold) or ``scipy.signal.lsim(..., interp=False)`` (zero-order
hold) on a state-space realisation written out here.  Tolerances come from
the noise: each parameter must lie within ``K_SIGMA`` standard errors
(Gauss-Newton covariance ``s^2 (J^T J)^-1`` at the estimate) of the truth, and
the fit must be at least as good as the truth's (J <= J(truth)).
"""

from __future__ import annotations

import numpy as np
import pytest
from _truths import J_SLACK, K_SIGMA, SYSTEMS, make_case, standard_errors

from hammerstein_ctrl import identify
from hammerstein_ctrl.fit import HammersteinCost


@pytest.mark.parametrize("name", sorted(SYSTEMS))
def test_identify_recovers_known_truth_without_x0(name):
    data, structure, truth, _ = make_case(name)
    res = identify(data, structure, maxfev=3000)
    cost = HammersteinCost(data, structure)
    j_truth = cost(truth)
    assert res.success, res.message
    assert res.fun <= j_truth * (1 + J_SLACK), (res.fun, j_truth)
    se = standard_errors(cost, res.x)
    err = np.abs(res.x - structure.normalize(truth))
    assert np.all(err <= K_SIGMA * se + 1e-9), dict(zip(structure.param_names, (err / se).round(2)))
