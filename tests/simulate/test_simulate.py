"""The fast path must equal control.forced_response (the sampled first-order-hold semantics)."""

import warnings

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import DataError, ParameterError
from hammerstein_ctrl._checks import MAX_ORDER
from hammerstein_ctrl.exceptions import HammersteinError
from hammerstein_ctrl.simulate._simulate import (MAX_UNROLLED_STATES, free_response, lsim, response_blocks,
                                                 simulate_batch, simulate, sse_batch)

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
    from hammerstein_ctrl import presets
    from hammerstein_ctrl import identify
    from hammerstein_ctrl.optimize._normal_equations import NONFINITE_RESIDUAL, neighbours

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


@pytest.mark.parametrize("dt", [0.0, -0.1])
def test_public_simulation_rejects_a_non_positive_sampling_interval(dt):
    """sse_batch / simulate_batch are public and documented with dt the sampling interval;
    dt <= 0 returns numbers (a simulation backwards in time for dt < 0) instead of an error."""
    t = 0.1 * np.arange(100)
    u, y = np.sin(t), np.cos(t)
    with pytest.raises(HammersteinError):
        sse_batch([[1.0]], [[1.0, 2.0]], u, dt, y)
    with pytest.raises(HammersteinError):
        simulate_batch([[1.0]], [[1.0, 2.0]], u, dt)


def test_simulate_batch_checks_the_rows_of_its_signals():
    """Three signals for two transfer functions: numpy's broadcast ValueError instead of a clear error."""
    u = np.sin(0.1 * np.arange(100))
    with pytest.raises(HammersteinError):
        simulate_batch([[1.0], [1.0]], [[1.0, 2.0], [1.0, 3.0]], np.vstack([u, u, u]), 0.1)


DT = 0.01


def test_simulating_a_fast_unstable_block_leaks_no_scipy_warning():
    """A candidate with a fast right-half-plane pole (1e5 rad/s at dt = 0.01) goes to scipy's
    expm in _discretized outside any errstate; scipy's 'overflow encountered in matmul' reaches the user.
    Met in identify(data, structure) on a 1e5-sample record of a (0, 4) resonant plant (the LM
    refinement's normal_pass at a trial point), printed on the console.  The project's filter only
    catches warnings attributed to hammerstein_ctrl modules, so its tests do not see it."""
    u = np.sin(DT * np.arange(1000))[None, :]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        y = simulate_batch([[1.0]], [[1.0, -1e5]], u, DT)
    assert not np.all(np.isfinite(y))


def test_response_blocks_refuses_a_block_of_the_wrong_shape_clearly():
    """A block given as one 1-D signal (n_signals = 1) fails deep in _checked_blocks with numpy's
    'IndexError: tuple index out of range' instead of the DataError that names a block of the wrong shape
    (as a block with the wrong number of rows gets)."""
    with pytest.raises(HammersteinError, match="block"):
        list(response_blocks([1.0], [1.0, 1.0], DT, [np.ones(50)], 1, 50))


def test_response_blocks_gives_the_free_responses_alone():
    """n_signals = 0 with free=True (the free responses alone, as estimate_initial_state needs) raises
    'the linear block [1.] / [1. 1.] cannot be simulated a block at a time', which is not so: the same
    block is simulated with one signal.  It should hand out free_response's numbers, or name n_signals."""
    num, den, n = [1.0, 2.0], [1.0, 3.0, 2.0], 40
    try:
        Y = np.vstack([part.copy() for part in response_blocks(num, den, DT, [np.zeros((0, n))], 0, n,
                                                               free=True)])
    except HammersteinError as e:
        assert "n_signals" in str(e) or "signal" in str(e)
    else:
        np.testing.assert_allclose(Y, free_response(num, den, DT, n), rtol=1e-12, atol=1e-15)


def test_lsim_trims_a_leading_zero_of_the_denominator():
    t = np.arange(0.0, 5.0 + 1e-9, 0.01)
    v = np.ones_like(t)
    y = lsim(([1.0], [0.0, 1.0, 1.0]), t, v)
    ref = ct.forced_response(ct.tf([1.0], [1.0, 1.0]), t, v).outputs
    assert ref[-1] == pytest.approx(0.9933, abs=1e-4)
    np.testing.assert_allclose(y, ref, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("num, den, message", [
    ([1.0], [np.nan, 1.0], "non-finite"),
    ([1.0], [1.0, np.inf], "non-finite"),
    ([np.nan], [1.0, 1.0], "non-finite"),
    ([1.0], [0.0, 0.0], "denominator is zero"),
    ([1.0, 0.0, 0.0], [1.0, 1.0], "improper"),
    ([1.0], [], "non-empty"),
])
def test_lsim_refuses_unusable_transfer_functions(num, den, message):
    t = np.arange(0.0, 1.0, 0.01)
    with pytest.raises(ParameterError, match=message):
        lsim((num, den), t, np.ones_like(t))


def _diagonal_system(order, seed=0):
    """A stable all-pole system as (num, den) and as its diagonal (modal) realisation, built independently."""
    poles = -np.linspace(0.5, 3.0, order) * np.random.default_rng(seed).uniform(0.9, 1.1, order)
    gain = float(np.prod(-poles))
    residues = np.array([gain / np.prod([p - q for q in poles if q != p]) for p in poles])
    modal = ct.ss(np.diag(poles), np.ones((order, 1)), residues[None, :], 0.0)
    return ([gain], np.poly(poles)), modal


def test_lsim_is_accurate_up_to_max_order_and_refuses_higher_orders():
    t = np.arange(0.0, 10.0, 0.01)
    v = np.sin(t) + 0.5 * np.sign(np.sin(0.7 * t))
    tf, modal = _diagonal_system(MAX_ORDER)
    ref = ct.forced_response(modal, t, v).outputs
    assert np.max(np.abs(lsim(tf, t, v) - ref)) / np.max(np.abs(ref)) < 1e-4
    tf, modal = _diagonal_system(MAX_ORDER + 2)
    with pytest.raises(ParameterError, match=f"order {MAX_ORDER + 2}; at most {MAX_ORDER}"):
        lsim(tf, t, v)
    # a state-space model of that order is simulated from its own (well-conditioned) matrices
    np.testing.assert_allclose(lsim(modal, t, v), ct.forced_response(modal, t, v).outputs,
                               rtol=1e-8, atol=1e-10)


def test_an_unstable_simulation_warns_where_its_output_stops_being_finite():
    t = np.arange(200) * 0.01
    with pytest.warns(hc.SimulationWarning, match=r"simulate: the simulated output is not finite from sample \d+"):
        y = simulate(ct.tf([1.0], [1.0, -1000.0]), hc.Tanh(), [1.0, 1.0], t, np.sin(t))
    assert not np.all(np.isfinite(y))
