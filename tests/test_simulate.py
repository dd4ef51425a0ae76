"""The fast path must equal control.forced_response (DESIGN.md section 1)."""

import warnings

import control as ct
import numpy as np
import pytest

from hammerstein_ctrl import DataError, ParameterError
from hammerstein_ctrl.simulate import MAX_UNROLLED_STATES, lsim, simulate_batch, sse_batch

EMPS_BETAS = [
    [3.2870, 0.59130, -0.4448, 0.0486],
    [3.1626, 0.5485, -0.4019, 0.0457],
    [3.1102, 0.6361, -0.5352, 0.0552],
    [3.138764, 0.544501, -0.398365, 0.045066],
    [-1.0, 0.5, -0.4, 0.0],  # unstable initial point of Table 5
]


def rel_max_err(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


def reference(case, beta):
    model = case.structure.model(beta)
    return ct.forced_response(model.linear, case.data.t, model.g(case.data.u)).outputs


@pytest.mark.parametrize("beta", EMPS_BETAS)
def test_emps_matches_forced_response(emps_case, beta):
    ref = reference(emps_case, beta)
    assert rel_max_err(emps_case.cost.simulate(beta), ref) <= 1e-9
    assert rel_max_err(emps_case.structure.model(beta).simulate(emps_case.data), ref) <= 1e-9
    # the cost is the sum of squares of exactly that output
    J = np.sum((emps_case.data.y - ref) ** 2)
    assert emps_case.cost(beta) == pytest.approx(J, rel=1e-9)


@pytest.mark.parametrize("beta", [[-1.816, 0.118, 4.7681, -4.7132, 0.1229], [-2.0, 0.0, 5.0, -5.0, 0.3],
                                  [-1.9078, 4.7607, 0.1085, -9.8045, 0.0574]])
def test_trs_matches_forced_response(trs_case, beta):
    ref = reference(trs_case, beta)
    assert rel_max_err(trs_case.cost.simulate(beta), ref) <= 1e-9


@pytest.mark.parametrize("order", [1, 2, 3, 4, MAX_UNROLLED_STATES + 1])
def test_random_stable_systems_match_forced_response(order, rng):
    t = np.arange(3000) * 0.01
    for _ in range(5):
        poles = -rng.uniform(0.2, 20.0, order).astype(complex)
        if order >= 2 and rng.random() < 0.5:  # a complex pair
            w = rng.uniform(0.5, 10.0)
            poles[0], poles[1] = poles[0] + 1j * w, poles[0] - 1j * w
        den = np.real(np.poly(poles))
        num = rng.standard_normal(rng.integers(1, order + 2))
        H = ct.tf(num, den)
        v = np.cumsum(rng.standard_normal(t.size)) * 0.1
        ref = ct.forced_response(H, t, v).outputs
        assert rel_max_err(lsim(H, t, v), ref) <= 1e-9
        assert rel_max_err(lsim(ct.ss(H), t, v), ref) <= 1e-9


def test_batch_equals_single(rng):
    t = np.arange(500) * 0.05
    dens = np.column_stack([np.ones(6), rng.uniform(1, 3, 6), rng.uniform(1, 3, 6)])
    nums = np.column_stack([np.ones(6), rng.standard_normal(6)])
    V = rng.standard_normal((6, t.size))
    Y = simulate_batch(nums, dens, V, 0.05)
    for k in range(6):
        np.testing.assert_allclose(Y[k], lsim((nums[k], dens[k]), t, V[k]), rtol=1e-13, atol=1e-15)
    y = rng.standard_normal(t.size)
    J = sse_batch(nums, dens, V, 0.05, y)
    np.testing.assert_allclose(J, np.sum((Y - y) ** 2, axis=1), rtol=1e-12)


def test_hostile_candidates_score_inf_without_warnings(emps_case):
    cost = emps_case.cost
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        J = cost.batch(np.array([
            [np.nan, 0.5, -0.4, 0.0],      # NaN parameter
            [-1e4, 0.5, -0.4, 0.0],        # violently unstable: overflows
            [1e300, 1e300, -1e300, 1e300],  # absurd magnitudes
            [np.inf, 0.5, 0.0, 0.0],
            [3.138764, 0.544501, -0.398365, 0.045066],
        ]))
        assert np.all(np.isinf(J[:4])) and np.all(J[:4] > 0)
        assert J[4] == pytest.approx(0.208517, abs=2e-6)
        assert cost([-1e4, 0.5, -0.4, 0.0]) == np.inf


def test_reject_unstable_option(emps_dir):
    from hammerstein_ctrl import presets

    strict = presets.emps(path=emps_dir, reject_unstable=True)
    assert strict.cost(strict.x0) == np.inf  # a1 = -1: pole at +1
    assert np.isfinite(strict.cost([3.1, 0.5, -0.4, 0.04]))  # the integrator pole at 0 is allowed


def test_reject_unstable_reaches_least_squares(emps_dir):
    """Residuals and normal equations see an unstable candidate as the cost does (huge, not a fit)."""
    from hammerstein_ctrl import identify, presets
    from hammerstein_ctrl.normal_equations import NONFINITE_RESIDUAL, neighbours

    strict, plain = presets.emps(path=emps_dir, reject_unstable=True), presets.emps(path=emps_dir)
    bad, good = np.asarray(strict.x0, float), np.array([3.1, 0.5, -0.4, 0.04])
    R = strict.cost.residuals_batch([bad, good])
    assert np.all(R[0] == NONFINITE_RESIDUAL)
    np.testing.assert_array_equal(R[1], plain.cost.residuals(good))
    ne = strict.cost.normal_equations(bad)
    assert ne.fun == np.inf == strict.cost(bad)          # a solver cannot start there
    # a stable point whose neighbours are stable: the fused pass, as without the option
    assert strict.cost.normal_equations(good).fun == plain.cost.normal_equations(good).fun
    # a stable point with an unstable neighbour (a1 just below 0 after a forward step of the other sign)
    edge = np.array([0.0, 0.5, -0.4, 0.04])
    h = np.array([-1e-8, 1e-8, 1e-8, 1e-8])
    assert strict.cost._unstable(neighbours(edge, h)).tolist() == [False, True, False, False, False]
    assert strict.cost.normal_equations(edge, h).gram[0, 0] > 1e290
    res = identify(strict.data, strict.structure, method="lm", x0=bad, reject_unstable=True)
    assert not res.success and "unstable" in res.message and "not finite at the starting point" in res.message


def test_lsim_input_errors():
    H = ct.tf([1], [1, 1])
    with pytest.raises(DataError, match="length mismatch: t has 10 samples but v has 9"):
        lsim(H, np.arange(10.0), np.zeros(9))
    with pytest.raises(DataError, match="irregular time grid"):
        lsim(H, np.array([0, 1, 2, 3.5, 4, 5.0]), np.zeros(6))
    with pytest.raises(DataError, match="NaN at sample 2"):
        lsim(H, np.arange(4.0), [0, 1, np.nan, 0])
    with pytest.raises(ParameterError, match="continuous-time"):
        lsim(ct.tf([1], [1, 0.5], dt=0.1), np.arange(4.0), np.zeros(4))
