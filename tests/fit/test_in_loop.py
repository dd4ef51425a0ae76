"""Identification inside a known control loop: the loop's simulation, the fit, refusals, the EMPS loop."""

import warnings

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import DataError, ParameterError
from hammerstein_ctrl.fit import KnownLoop, KnownLoopCost, identify_in_loop
from hammerstein_ctrl.blocks import lure_structure

DT = 0.01
#: A PI controller on the error, sampled: u = 10 e + 6 dt sum(e).
PI = ct.ss([[1.0]], [[DT]], [[6.0]], [[10.0]], DT)
TRUTH = np.array([0.4, 2.0, 0.3, 0.02])


def _reference(n=4000):
    t = np.arange(n) * DT
    return 0.5 * np.sign(np.sin(0.3 * t)) + 0.2 * np.sin(1.1 * t)


def test_loop_without_friction_equals_python_controls_sampled_feedback_loop():
    r = _reference(1500)
    loop = KnownLoop(PI, r)
    y, u = loop.simulate(lure_structure().model([0.4, 2.0, 0.0, 0.0]))
    plant = ct.sample_system(ct.tf([0.4], [1.0, 2.0, 0.0]), DT, method="zoh")
    T = np.arange(r.size) * DT
    ref_y = ct.forced_response(ct.feedback(PI * plant, 1), T, r).outputs
    ref_u = ct.forced_response(ct.feedback(PI, plant), T, r).outputs
    np.testing.assert_allclose(y, ref_y, rtol=0, atol=1e-9 * np.ptp(ref_y))
    np.testing.assert_allclose(u, ref_u, rtol=0, atol=1e-9 * np.ptp(ref_u))


def test_two_input_controller_equals_the_same_controller_on_the_error():
    r = _reference(800)
    model = lure_structure().model(TRUTH)
    on_error = KnownLoop(PI, r).simulate(model)
    A, B, C, D = PI.A, PI.B, PI.C, PI.D
    on_both = KnownLoop(ct.ss(A, np.hstack([B, -B]), C, np.hstack([D, -D]), DT), r).simulate(model)
    np.testing.assert_array_equal(on_error[0], on_both[0])
    np.testing.assert_array_equal(on_error[1], on_both[1])


def test_known_truth_plant_in_a_pi_loop_is_identified_within_its_standard_errors():
    r = _reference()
    loop = KnownLoop(PI, r)
    y, u = loop.simulate(lure_structure().model(TRUTH))
    z = []
    for seed in range(5):
        rng = np.random.default_rng(seed)
        data = hc.IOData(u + 0.01 * rng.standard_normal(u.size), y + 0.002 * rng.standard_normal(y.size), dt=DT,
                         intersample="zoh")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = identify_in_loop(data, lure_structure(), loop, seed=0)
        assert res.success, res.message
        assert res.output_fits["u (in loop)"] > 99 and res.output_fits["y (in loop)"] > 99
        z.append((res.x - TRUTH) / res.uncertainty.stderr)
    z = np.array(z)
    assert np.all(np.abs(z) < 4), z
    assert np.all(z.std(axis=0) < 1.7), z.std(axis=0)


@pytest.mark.parametrize("match, n_signals", [("output", 1), ("input", 1), ("both", 2)])
def test_residuals_stack_the_matched_signals_weighted(match, n_signals):
    r = _reference(300)
    loop = KnownLoop(PI, r)
    y, u = loop.simulate(lure_structure().model(TRUTH))
    data = hc.IOData(u + 1.0, y + 2.0, dt=DT, intersample="zoh")
    cost = KnownLoopCost(data, lure_structure(), loop, match=match, weights=[3.0] * n_signals)
    R = cost.residuals(TRUTH)
    assert R.shape == (n_signals * 300,)
    expected = {"output": [6.0], "input": [3.0], "both": [6.0, 3.0]}[match]
    np.testing.assert_allclose(R.reshape(n_signals, 300), np.array(expected)[:, None] * np.ones((1, 300)),
                               atol=1e-12)
    assert cost(TRUTH) == pytest.approx(300 * sum(e**2 for e in expected))
    assert isinstance(cost, hc.fit.Cost)
    np.testing.assert_allclose(cost.simulate(TRUTH), y, rtol=0, atol=1e-9)


@pytest.mark.parametrize("make, error, match", [
    (lambda r: KnownLoop(ct.tf([1.0], [1.0, 1.0]), r), ParameterError, "discrete-time"),
    (lambda r: KnownLoop(ct.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]], 0.02), r), DataError, "dt"),
    (lambda r: KnownLoop(ct.ss([[1.0]], [[1.0, 1.0, 1.0]], [[1.0]], [[0.0, 0.0, 0.0]], DT), r), ParameterError,
     "one input"),
    (lambda r: KnownLoop("pid", r), ParameterError, "StateSpace or TransferFunction"),
    (lambda r: KnownLoop(PI, np.r_[r[:-1], np.nan]), DataError, "non-finite"),
    (lambda r: KnownLoop(PI, r, added=np.ones(1)), DataError, "added must be one signal of at least 2"),
    (lambda r: KnownLoop(PI, r, added=np.ones(50)), DataError, "added has 50 samples"),
    (lambda r: KnownLoop(PI, np.column_stack([r, r])), DataError, "one signal"),
    (lambda r: KnownLoop(PI, r, initial_state=[1.0, 2.0]), ParameterError, "controller's 1 state"),
    (lambda r: KnownLoop(ct.tf([1.0, 2.0, 3.0], [1.0, 0.5], DT), r), ParameterError, "improper"),
    (lambda r: KnownLoop(ct.ss([[np.nan]], [[1.0]], [[1.0]], [[0.0]], DT), r), ParameterError, "non-finite"),
    (lambda r: KnownLoop(ct.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]], True), r), ParameterError, "dt set"),
])
def test_bad_loops_are_refused_in_one_line(make, error, match):
    r = _reference(100)
    data = hc.IOData(np.zeros(100), np.zeros(100), dt=DT)
    with pytest.raises(error, match=match) as err:
        KnownLoopCost(data, lure_structure(), make(r))
    assert "\n" not in str(err.value)


def test_bad_match_and_weights_are_refused():
    r = _reference(100)
    data = hc.IOData(np.zeros(100), np.zeros(100), dt=DT)
    with pytest.raises(ParameterError, match="match must be one of"):
        KnownLoopCost(data, lure_structure(), KnownLoop(PI, r), match="force")
    with pytest.raises(ParameterError, match="2 number.s. between 1e-100 and 1e100"):
        KnownLoopCost(data, lure_structure(), KnownLoop(PI, r), weights=[1.0])
    with pytest.raises(ParameterError, match="between 1e-100 and 1e100"):
        KnownLoopCost(data, lure_structure(), KnownLoop(PI, r), weights=[1e-300, 1e-300])     # J would underflow
    with pytest.raises(DataError, match="measured output and control signal is constant"):
        KnownLoopCost(data, lure_structure(), KnownLoop(PI, r))
    with pytest.raises(DataError, match="reference has 100 samples, the record 50"):
        KnownLoopCost(data[:50], lure_structure(), KnownLoop(PI, r))


def test_emps_controller_reproduces_the_recorded_force(emps_dir):
    from hammerstein_ctrl.paper.emps_loop import load_emps_loop

    record, loop, gains = load_emps_loop("estimation", path=emps_dir)
    qm, qg = record.y.ravel(), loop.reference
    vir = gains["kv"] * (gains["kp"] * (qg - qm) - np.r_[0.0, np.diff(qm)] / record.dt)
    assert hc.fit_percent(record.u.ravel(), vir) > 96.0
    K = ct.ss(loop.controller)
    out = ct.forced_response(K, np.arange(len(qm)) * record.dt, np.vstack([qg, qm]), X0=[qm[0]]).outputs
    np.testing.assert_allclose(np.ravel(out)[1:], vir[1:], rtol=1e-9, atol=1e-9)


def test_emps_force_is_reproduced_inside_the_loop(emps_dir):
    from hammerstein_ctrl.paper.emps_loop import load_emps_loop

    record, loop, _ = load_emps_loop("estimation", path=emps_dir)
    val, val_loop, _ = load_emps_loop("validation", path=emps_dir)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_in_loop(record, lure_structure(), loop, seed=0)
    assert res.success, res.message
    _, u = val_loop.simulate(res.model)
    assert hc.fit_percent(val.u.ravel(), u) >= 92.0


def test_identify_takes_the_loop_as_its_front_door():
    r = _reference(1500)
    loop = KnownLoop(PI, r)
    y, u = loop.simulate(lure_structure().model(TRUTH))
    data = hc.IOData(u + 0.01 * np.random.default_rng(0).standard_normal(u.size), y, dt=DT, intersample="zoh")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        direct = identify_in_loop(data, lure_structure(), loop, match="input", seed=0)
        front = hc.identify(data, lure_structure(), loop=loop, match="input", seed=0)
    np.testing.assert_array_equal(front.x, direct.x)
    with pytest.raises(ParameterError, match="method='auto'"):
        hc.identify(data, lure_structure(), method="lm", loop=loop)
    with pytest.raises(ParameterError, match="does not take offset"):
        hc.identify(data, lure_structure(), loop=loop, offset=True)


def test_a_fit_in_a_loop_saves_and_loads_with_its_loop_fits(tmp_path):
    r = _reference(1500)
    loop = KnownLoop(PI, r)
    y, u = loop.simulate(lure_structure().model(TRUTH))
    rng = np.random.default_rng(20)
    data = hc.IOData(u + 0.01 * rng.standard_normal(u.size), y + 0.002 * rng.standard_normal(y.size), dt=DT,
                     intersample="zoh")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = hc.identify(data, lure_structure(), loop=loop, seed=0)
    hc.save_result(res, tmp_path / "loop.json")
    back = hc.load_result(tmp_path / "loop.json")
    np.testing.assert_array_equal(back.x, res.x)
    assert back.output_fits == pytest.approx(res.output_fits) and list(back.output_fits) == ["y (in loop)",
                                                                                           "u (in loop)"]
    assert type(hc.load_model(tmp_path / "loop.json")).__name__ == "LureModel"


# -- block structures (Hammerstein, Wiener, H-W) inside a known loop --------------------------------------------
BLOCK_DT = 0.05
#: A PI on the error, sampled: u = 1.5 e + 1.0 dt sum(e).
BLOCK_PI = ct.ss([[1.0]], [[BLOCK_DT]], [[1.0]], [[1.5]], BLOCK_DT)
#: 2 tanh(0.8 u) -> 1/(p^2 + 1.2 p + 2), in the structure's layout (a0, a1, d0, d1).
BLOCK_TRUTH = np.array([2.0, 1.2, 2.0, 0.8])


def _staircase(rng, n, width=(40, 120)):
    levels = rng.uniform(-1.0, 1.0, n // width[0] + 1)
    return np.repeat(levels, rng.integers(*width, size=levels.size))[:n]


def _pi_loop_record(seed, n=3000, noise=0.02):
    """The plant in the PI loop, simulated sample by sample with python-control's ZOH discretisation; the
    measurement noise reaches u through the controller.  ``(reference, u, y measured, y noise-free)``."""
    rng = np.random.default_rng(seed)
    ref = _staircase(rng, n)
    Pd = ct.ss(ct.sample_system(ct.tf([1.0], [1.0, 1.2, 2.0]), BLOCK_DT, method="zoh"))
    A, B, C = np.asarray(Pd.A), np.asarray(Pd.B).ravel(), np.asarray(Pd.C).ravel()
    x, z = np.zeros(2), 0.0
    u, y, clean = np.zeros(n), np.zeros(n), np.zeros(n)
    e_noise = noise * rng.standard_normal(n)
    for k in range(n):
        clean[k] = C @ x
        y[k] = clean[k] + e_noise[k]
        e = ref[k] - y[k]
        u[k] = z + 1.5 * e
        z += BLOCK_DT * e
        x = A @ x + B * (2.0 * np.tanh(0.8 * u[k]))
    return ref, u, y, clean


def _block_structure(g=None):
    return hc.HammersteinStructure(hc.LinearStructure(0, 2), g or hc.Tanh())


def test_a_block_model_in_the_loop_equals_the_loop_simulated_by_python_control():
    ref, u, _, clean = _pi_loop_record(0, n=1500, noise=0.0)
    y_sim, u_sim = KnownLoop(BLOCK_PI, ref).simulate(_block_structure().model(BLOCK_TRUTH, intersample="zoh"))
    np.testing.assert_allclose(y_sim, clean, rtol=0, atol=1e-9 * np.ptp(clean))
    np.testing.assert_allclose(u_sim, u, rtol=0, atol=1e-9 * np.ptp(u))
    custom = hc.CustomNonlinearity(lambda v, q: q[0] * np.tanh(q[1] * v), 2, param_names=["k", "s"])
    y_py, _ = KnownLoop(BLOCK_PI, ref).simulate(_block_structure(custom).model(BLOCK_TRUTH, intersample="zoh"))
    np.testing.assert_allclose(y_py, y_sim, rtol=0, atol=1e-12 * np.ptp(clean))   # the Python loop's twin


def test_a_hammerstein_plant_in_a_pi_loop_is_identified_within_four_standard_errors():
    z = []
    for seed in range(5):
        ref, u, y, _ = _pi_loop_record(seed)
        data = hc.IOData(u, y, dt=BLOCK_DT, intersample="zoh")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = hc.identify(data, _block_structure(), loop=KnownLoop(BLOCK_PI, ref), match="output", seed=0)
        assert res.success, res.message
        assert res.output_fits["y (in loop)"] > 90
        z.append((res.x - BLOCK_TRUTH) / np.array([res.stderr[k] for k in res.structure.param_names]))
    z = np.array(z)
    assert np.all(np.abs(z) < 4), z


def test_a_block_structure_with_a_dead_time_is_refused_in_a_loop():
    ref, u, y, _ = _pi_loop_record(0, n=300)
    s = hc.HammersteinStructure(hc.LinearStructure(0, 2, delay=0.1), hc.Tanh())
    with pytest.raises(ParameterError, match="cannot have a dead time yet"):
        hc.identify(hc.IOData(u, y, dt=BLOCK_DT, intersample="zoh"), s, loop=KnownLoop(BLOCK_PI, ref))


def test_residual_tests_for_a_closed_loop_record_fitted_in_open_loop():
    """Fitted from its own u and y, a record of the PI loop draws the open-loop residual warning (which says so
    and names closed_loop=True); the closed-loop test finds nothing on ten seeds."""
    for seed in range(10):
        ref, u, y, _ = _pi_loop_record(seed)
        data = hc.IOData(u, y, dt=BLOCK_DT, intersample="zoh")
        closed = hc.identify(data, _block_structure(), closed_loop=True, seed=0)
        assert closed.success and closed.verdicts == [], closed.warnings
    opened = hc.identify(data, _block_structure(), seed=0)
    assert any("closed_loop=True" in w for w in opened.warnings)


def test_the_known_loop_simulator_refuses_signals_of_other_lengths():
    from hammerstein_ctrl.simulate._loop import sampled_plant, simulate_known_loop

    plant = sampled_plant(_block_structure().model(BLOCK_TRUTH, intersample="zoh"), BLOCK_DT)
    controller = KnownLoop(BLOCK_PI, np.ones(50))._matrices
    with pytest.raises(ParameterError, match="the added signal must have the reference's 50 samples"):
        simulate_known_loop(plant, controller, np.ones(50), np.zeros(1))
    with pytest.raises(ParameterError, match="the controller's 1 states; got 50 and 3"):
        simulate_known_loop(plant, controller, np.ones(50), np.zeros(50), initial_state=[0.0, 0.0, 0.0])


def test_the_old_cost_names_still_import_with_a_deprecation_warning():
    from hammerstein_ctrl.design import _pid as control_design
    from hammerstein_ctrl.fit import _in_loop as in_loop

    with pytest.warns(DeprecationWarning, match="KnownLoopCost"):
        assert in_loop.LoopCost is in_loop.KnownLoopCost
    with pytest.warns(DeprecationWarning, match="TuningCost"):
        assert control_design.LoopCost is control_design.TuningCost
