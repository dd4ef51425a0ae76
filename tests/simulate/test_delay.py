"""Input dead time: exact fractional-delay simulation, its estimation, exports, persistence and the PID rules."""

import json
import warnings

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import HammersteinModel, HammersteinStructure, IOData, LinearStructure, Tanh, WienerStructure
from hammerstein_ctrl.design import approximate, tune_pid
from hammerstein_ctrl.simulate._delay import delayed_response, split_delay
from hammerstein_ctrl.fit._delay_fit import DelayedCost, delay_candidates
from hammerstein_ctrl.exceptions import ParameterError
from hammerstein_ctrl.blocks import Polynomial
from hammerstein_ctrl.fit import HammersteinCost

FINE = 50          # oracle grid: dt / FINE, on which every delay below falls exactly


def _delayed_oracle(num, den, v, dt, tau, hold):
    """The sampled output computed independently: python-control on a grid of dt/FINE holding the breakpoints
    (the input is zero before the record, joined to it by the same hold)."""
    N = v.size
    t = np.arange(N) * dt
    tf = np.arange((N - 1) * FINE + 1) * dt / FINE
    G = ct.tf(num, den)
    if hold == "foh":
        w = np.interp(tf - tau, np.r_[-dt, t], np.r_[0.0, v])          # zero samples before the record
        return ct.forced_response(G, tf, w).outputs[::FINE]
    k = np.floor((tf - tau) / dt + 1e-9).astype(int)
    w = np.where(k >= 0, v[np.clip(k, 0, N - 1)], 0.0)
    return ct.forced_response(ct.c2d(ct.ss(G), dt / FINE, "zoh"), np.arange(tf.size) * dt / FINE, w).outputs[::FINE]


@pytest.mark.parametrize("hold", ["foh", "zoh"])
@pytest.mark.parametrize("tau", [0.0, 0.04, 0.1, 0.37, 1.26])
@pytest.mark.parametrize("system", [([2.0], [1.5, 1.0]), ([0.5, 2.0], [1.0, 1.2, 1.0]),
                                    ([1.0, 0.3, 2.0], [1.0, 2.0, 3.0, 1.5])])
def test_fractional_delay_is_exact_under_both_holds(hold, tau, system):
    v = np.random.default_rng(3).normal(size=120)
    y = delayed_response(*system, v, 0.1, tau, intersample=hold)
    ref = _delayed_oracle(*system, v, 0.1, tau, hold)
    assert np.max(np.abs(y - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_zero_delay_is_the_undelayed_simulation():
    t = np.arange(200) * 0.05
    v = np.sin(1.3 * t) + 0.2 * np.cos(5 * t)
    ref = ct.forced_response(ct.tf([1.0, 2.0], [1.0, 0.8, 2.0]), t, v).outputs
    np.testing.assert_allclose(delayed_response([1.0, 2.0], [1.0, 0.8, 2.0], v, 0.05, 0.0), ref, rtol=0, atol=1e-12)


def test_split_delay_counts_whole_samples_and_the_fraction():
    assert split_delay(0.3, 0.1) == (3, 0.0)           # 0.3/0.1 = 2.9999999999999996 counts as 3
    d, a = split_delay(0.37, 0.1)
    assert d == 3 and a == pytest.approx(0.7)


@pytest.mark.parametrize("hold", ["foh", "zoh"])
@pytest.mark.parametrize("tau", [0.0, 0.05, 0.1, 0.37])
def test_exact_discrete_export_reproduces_the_delayed_model(hold, tau):
    m = HammersteinModel(ct.tf([1, 2.0], [1, 1.2, 1]), Tanh(), [2.0, 1.0], delay=tau, offset=0.3,
                         initial_state=[0.2, -0.1], intersample=hold)
    t = np.arange(80) * 0.1
    u = np.random.default_rng(1).normal(size=80)
    y = ct.input_output_response(m.to_iosys(dt=0.1), t, u).outputs
    np.testing.assert_allclose(y, m.simulate(t, u), rtol=0, atol=1e-12)


def test_continuous_export_carries_a_pade_approximant_after_the_linear_states():
    m = HammersteinModel(ct.tf([1.0], [1.0, 1.0]), Tanh(), [2.0, 1.0], delay=0.5)
    sys = m.to_iosys(pade_order=4)
    assert sys.nstates == 1 + 4 and sys.state_labels[0].startswith("H")
    # a slow input: the approximant's error is far below the delayed response's size
    t = np.arange(400) * 0.05
    u = np.sin(0.3 * t)
    y = ct.input_output_response(sys, t, u, X0=np.r_[m.state0(), np.zeros(4)],
                                 solve_ivp_kwargs={"rtol": 1e-9, "atol": 1e-11, "max_step": 0.05}).outputs
    undelayed = HammersteinModel(ct.tf([1.0], [1.0, 1.0]), Tanh(), [2.0, 1.0]).simulate(t, u)
    exact = m.simulate(t, u)
    assert np.max(np.abs(y - exact)) < 0.02 * np.max(np.abs(exact - undelayed))


def _fopdt_record(seed, hold, tau=0.37, dt=0.1, N=600, noise=0.02):
    """A Hammerstein first-order-plus-dead-time record, 1.5 tanh(0.8 u) -> 1/(1.5 s + 1) e^{-tau s}, made with
    python-control on a fine grid."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) * dt
    u = np.repeat(rng.uniform(-2, 2, N // 15 + 1), 15)[:N]
    if hold == "foh":
        u = u + 0.3 * np.sin(0.9 * t)
    v = 1.5 * np.tanh(0.8 * u)
    y = _delayed_oracle([1.0], [1.5, 1.0], v, dt, tau, hold) + noise * rng.standard_normal(N)
    return IOData(u, y, dt=dt, intersample=hold, name=f"fopdt{seed}")


TRUE_FOPDT = np.array([1 / 1.5, 1.0, 0.8, 0.37])         # a0, d0 (gain 1.5 / 1.5), d1, delay


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_dead_time_is_estimated_within_a_tenth_of_a_sample_without_x0(hold):
    s = HammersteinStructure(LinearStructure(0, 1, delay="estimate"), Tanh())
    for seed in range(5):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = hc.identify(_fopdt_record(seed, hold), s, seed=0)
        assert r.success, r.message
        assert r.structure.param_names[-1] == "delay"
        assert abs(r.x[-1] - 0.37) <= 0.1 * 0.1
        se = np.sqrt(np.diag(r.covariance))
        assert np.all(np.abs(r.x - TRUE_FOPDT) <= 4 * se), (r.x, se)
        assert r.fun / 600 == pytest.approx(0.02 ** 2, rel=0.2)
        assert r.model.delay == r.x[-1]


def test_a_fixed_dead_time_is_used_and_not_estimated():
    s = HammersteinStructure(LinearStructure(0, 1, delay=0.37), Tanh())
    assert "delay" not in s.param_names
    r = hc.identify(_fopdt_record(0, "foh"), s, seed=0)
    assert r.success and r.model.delay == 0.37
    np.testing.assert_allclose(r.x, TRUE_FOPDT[:3], rtol=0.02)
    wrong = hc.identify(_fopdt_record(0, "foh"), s.with_delay(0.1), seed=0)
    assert wrong.fun > 5 * r.fun                           # the dead time matters: a wrong one fits far worse


def test_wiener_structure_with_a_dead_time():
    rng = np.random.default_rng(5)
    N, dt = 500, 0.1
    u = np.repeat(rng.uniform(-2, 2, N // 10 + 1), 10)[:N]
    z = _delayed_oracle([1.0, 2.0], [1.0, 1.2, 1.0], u, dt, 0.23, "foh")
    y = z + 0.3 * z ** 3 + 0.01 * rng.standard_normal(N)
    s = WienerStructure(LinearStructure(1, 2, delay="estimate"), Polynomial(3))
    r = hc.identify(IOData(u, y, dt=dt), s, seed=0)
    assert r.success, r.message
    assert abs(r.model.delay - 0.23) < 0.01


def test_delay_candidates_rank_the_true_whole_sample_delay_first():
    rng = np.random.default_rng(2)
    t = np.arange(500) * 0.1
    u = np.repeat(rng.normal(size=50), 10)
    for d in (0, 3, 12):
        y = ct.forced_response(ct.tf([2.0], [1.0, 1.0]), t, np.r_[np.full(d, u[0]), u[:500 - d]]).outputs
        assert delay_candidates(IOData(u, y, dt=0.1), 1)[0] == d


def test_simc_uses_the_model_dead_time():
    m = HammersteinModel(ct.tf([1.0], [1.5, 1.0]), Polynomial(1), [2.0], delay=0.37)
    a = approximate(m, 0.0)
    assert a["theta"] == pytest.approx(0.37)
    assert approximate(m, 0.0, dt=0.1)["theta"] == pytest.approx(0.42)
    pid = tune_pid(m, "simc", tau_c=0.37)
    kc, ti = 1.5 / (2.0 * (0.37 + 0.37)), min(1.5, 4 * (0.37 + 0.37))      # Skogestad's SIMC, K = 2, tau1 = 1.5
    assert pid.gains[0] == pytest.approx(kc, rel=1e-9)
    assert pid.gains[1] == pytest.approx(kc / ti, rel=1e-9)


def test_loop_figures_of_a_delayed_plant_match_its_exact_frequency_response():
    m = HammersteinModel(ct.tf([1.0], [1.5, 1.0]), Polynomial(1), [2.0], delay=0.37)
    pid = tune_pid(m)
    assert pid.success
    kp, ki, kd, tf = pid.gains[:4]
    w = np.geomspace(1e-3, 1e3, 20000)
    s = 1j * w
    C = kp + ki / s + kd * s / (tf * s + 1)
    L = C * 2.0 / (1.5 * s + 1) * np.exp(-0.37 * s)
    assert pid.Ms == pytest.approx(np.max(1 / np.abs(1 + L)), rel=0.01)


def test_dead_time_survives_saving(tmp_path):
    m = HammersteinModel(ct.tf([1.0], [1.0, 1.0]), Tanh(), [2.0, 1.0], delay=0.37)
    m.save(tmp_path / "m.json")
    back = hc.load_model(tmp_path / "m.json")
    assert back.delay == 0.37
    t = np.arange(50) * 0.1
    np.testing.assert_array_equal(back.simulate(t, np.sin(t)), m.simulate(t, np.sin(t)))
    r = hc.identify(_fopdt_record(1, "foh"), HammersteinStructure(LinearStructure(0, 1, delay="estimate"), Tanh()),
                    seed=0)
    hc.save_result(r, tmp_path / "r.json")
    saved = hc.load_result(tmp_path / "r.json")
    assert saved.structure.linear.delay == "estimate" and saved.model.delay == r.model.delay


@pytest.mark.parametrize("value", [-0.1, "soon", float("nan"), float("inf"), True])
def test_bad_dead_times_are_refused(value):
    with pytest.raises(ParameterError, match="delay must be a finite number >= 0"):
        LinearStructure(1, 2, delay=value)
    with pytest.raises(ParameterError, match="delay"):
        HammersteinModel(ct.tf([1.0], [1.0, 1.0]), Tanh(), [1.0, 1.0], delay=value)


def test_saved_bad_dead_times_are_refused_naming_the_field(tmp_path):
    m = HammersteinModel(ct.tf([1.0], [1.0, 1.0]), Tanh(), [2.0, 1.0], delay=0.37)
    m.save(tmp_path / "m.json")
    for bad in (-1.0, "estimate", "1"):
        obj = json.loads((tmp_path / "m.json").read_text())
        obj["model"]["delay"] = bad
        (tmp_path / "bad.json").write_text(json.dumps(obj))
        with pytest.raises(ParameterError, match="model.delay"):
            hc.load_model(tmp_path / "bad.json")


def test_delayed_structures_are_refused_where_they_would_be_simulated_without_delay():
    s = HammersteinStructure(LinearStructure(0, 1, delay=0.2), Tanh())
    data = _fopdt_record(0, "foh", N=100)
    with pytest.raises(ParameterError, match="dead time"):
        HammersteinCost(data, s)


def test_delayed_cost_follows_the_least_squares_protocol():
    s = HammersteinStructure(LinearStructure(0, 1, delay="estimate"), Tanh(), offset=True)
    cost = DelayedCost(_fopdt_record(0, "foh", N=200), s)
    beta = np.array([0.7, 1.0, 0.8, 0.37, 0.1])
    r = cost.residuals(beta)
    assert cost(beta) == pytest.approx(r @ r, rel=1e-12)
    ne = cost.normal_equations(beta)
    assert ne.fun == pytest.approx(r @ r, rel=1e-12) and ne.gram.shape == (5, 5)
    np.testing.assert_allclose(cost.from_base(cost.to_base(beta), 0.37), beta)
    assert not np.isfinite(cost(np.array([0.7, 1.0, 0.8, -0.1, 0.1])))      # a negative dead time: no model
    for bad in ([0.1, 0.1], [1e-6, 0.0, 1e-6, 1e-6, 1e-6], [1e-6, np.nan, 1e-6, 1e-6, 1e-6]):
        with pytest.raises(ParameterError, match="steps must be 5 finite, non-zero numbers"):
            cost.normal_equations(beta, bad)


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_a_delayed_step_from_rest_waits_for_the_dead_time(hold):
    """At rest the samples before the record are zero: nothing moves before tau (under FOH the ramp from the zero
    sample before the record to the first one arrives one sample earlier), in simulate and in the export."""
    m = HammersteinModel(ct.tf([1.0], [1.0, 1.0]), Tanh(), [2.0, 1.0], delay=0.5, intersample=hold)
    t = np.arange(20) * 0.05
    y = m.simulate(t, np.ones(20))
    quiet = 0.5 - (0.05 if hold == "foh" else 0.0)
    assert np.all(y[t <= quiet + 1e-12] == 0.0) and np.all(y[t > quiet + 1e-12] > 0)
    np.testing.assert_allclose(ct.input_output_response(m.to_iosys(dt=0.05), t, np.ones(20)).outputs, y,
                               rtol=0, atol=1e-14)


def test_the_compiled_loop_simulator_refuses_a_dead_time_it_cannot_simulate():
    from hammerstein_ctrl.simulate import simulate_loops

    m = HammersteinModel(ct.tf([1.0], [1.0, 1.0]), Tanh(), [2.0, 1.0], delay=0.5, intersample="zoh")
    with pytest.raises(ParameterError, match="compiled loop simulator has no dead time.*without_delay"):
        simulate_loops(m, [[1.0, 0.5, 0.0, 0.0]], np.ones(50), 0.05)
    Y, _ = simulate_loops(m.without_delay(), [[1.0, 0.5, 0.0, 0.0]], np.ones(50), 0.05)
    assert np.isfinite(Y).all()


def test_bode_draws_the_dead_time():
    from hammerstein_ctrl import plotting as plots

    m = HammersteinModel(ct.tf([1.0], [1.0, 1.0]), Tanh(), [2.0, 1.0], delay=0.37)
    fig = plots.bode(m)
    phase_line = fig.axes[1].get_lines()[0]
    w, ph = phase_line.get_xdata(), phase_line.get_ydata()
    k = np.argmin(np.abs(w - 5.0))
    exact = np.degrees(np.unwrap(np.angle(1 / (1j * w + 1) * np.exp(-0.37j * w))))[k]
    assert ph[k] == pytest.approx(exact, abs=0.5)


@pytest.mark.parametrize("build, match", [
    (lambda: LinearStructure(0, 1, delay=1e300), "delay must be a finite number >= 0"),
    (lambda: HammersteinModel(ct.tf([1.0], [1.0, 1.0]), Tanh(), [1.0, 1.0], delay=1e20).to_iosys(dt=0.1),
     "would need that many states"),
])
def test_dead_times_beyond_any_use_are_refused_in_one_line(build, match):
    with pytest.raises(ParameterError, match=match):
        build()


def test_a_negative_dead_time_in_x0_and_a_fixed_one_longer_than_the_record_are_refused_before_any_work():
    data = _fopdt_record(0, "foh", N=100)
    s = HammersteinStructure(LinearStructure(0, 1, delay="estimate"), Tanh())
    with pytest.raises(ParameterError, match="x0's delay must be a dead time >= 0"):
        hc.identify(data, s, method="nspsa", x0=[0.7, 1.0, 0.8, -0.3], maxfev=50, seed=0)
    with pytest.raises(ParameterError, match="dead time 12 s is not shorter than the record"):
        hc.identify(data, s.with_delay(12.0))


@pytest.mark.parametrize("tau", [1e-320, 5e-324, 1e-13])
def test_a_dead_time_too_short_to_mean_one_is_refused(tau):
    with pytest.raises(ParameterError, match="too short to mean a dead time .*give 0 for none"):
        hc.LinearStructure(0, 2, delay=tau)


def test_a_custom_map_with_a_dead_time_takes_the_blocks_and_dead_time_as_x0():
    """Without x0 the refusal names the x0 to give (dead time included); given it, the offset and initial state
    follow by least squares and the fit finds the truth."""
    custom = hc.CustomNonlinearity(lambda v, q: q[0] * np.tanh(q[1] * v), 2, param_names=["k", "s"])
    rng = np.random.default_rng(0)
    t = np.arange(2000) * 0.05
    u = np.repeat(rng.uniform(-2, 2, 100), 20)
    y = ct.forced_response(ct.tf([1.0], [1.0, 1.0]), t, 2.0 * np.tanh(0.8 * u)).outputs
    y = np.r_[np.zeros(6), y[:-6]] + 0.3 + 0.01 * rng.standard_normal(t.size)          # 6 samples = 0.3 s
    s = hc.HammersteinStructure(hc.LinearStructure(0, 1, delay="estimate"), custom, offset=True,
                                initial_state="estimate")
    with pytest.raises(ParameterError, match=r"give x0 = \[a0, k, s, delay\] \(the offset and initial state then "
                                             r"follow by least squares; or the whole \[a0, k, s, delay, y0, xi0\]\)"):
        hc.identify(hc.IOData(u, y, dt=0.05), s)
    res = hc.identify(hc.IOData(u, y, dt=0.05), s, x0=[1.0, 2.0, 0.8, 0.3], seed=0)
    assert res.success
    np.testing.assert_allclose(res.x[:5], [1.0, 2.0, 0.8, 0.3, 0.3], atol=0.01)
