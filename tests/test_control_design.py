"""Exact python-control export, the sampled PID loop and PID tuning (issue 9)."""

import inspect

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import control_design as cd
from hammerstein_ctrl.exact_export import linear_ss, sampled_iosys
from hammerstein_ctrl.exceptions import DataError, ParameterError, UnknownNameError
from hammerstein_ctrl.loop_sim import sampled_loop_iosys, simulate_loops
from hammerstein_ctrl.simulate import companion_realization

EMPS_OPT = [3.138764, 0.544501, -0.398365, 0.045066]
STEP = 0.1  # m, a position step well inside the EMPS record's range (0 .. 0.25 m)


def _with_settings(model, **settings):
    """The model with offset / initial_state / intersample (keywords if the class takes them)."""
    if "offset" in inspect.signature(hc.HammersteinModel.__init__).parameters:
        return hc.HammersteinModel(model.linear, model.nonlinearity, model.params, **settings)
    for k, v in settings.items():
        setattr(model, k, v)
    return model


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def _zoh_oracle(model, t, u, x0, offset):
    """Independent ZOH reference: python-control's own sampling and discrete simulation."""
    sysd = ct.sample_system(linear_ss(model), t[1] - t[0], method="zoh")
    return ct.forced_response(sysd, t, model.g(u), X0=x0).outputs + offset


@pytest.fixture(scope="module")
def emps_model(emps_case):
    return emps_case.structure.model(EMPS_OPT)


@pytest.fixture(scope="module")
def emps_limits(emps_case):
    return float(emps_case.data.u.min()), float(emps_case.data.u.max())


# ---------------------------------------------------------------------------
# exact export
# ---------------------------------------------------------------------------
def _check_export(model, data):
    t, u = data.t, data.u
    y = ct.input_output_response(model.to_iosys(dt=data.dt), t, u).outputs
    assert _rel(y, model.simulate(t, u)) < 1e-9
    # against python-control's FOH forced_response (independent of our kernels)
    assert _rel(y, ct.forced_response(model.linear, t, model.g(u)).outputs) < 1e-9
    # ZOH and a non-zero initial state and offset
    x0 = 0.01 * np.arange(1, model.linear.den[0][0].size)
    zmodel = _with_settings(model, intersample="zoh", initial_state=x0, offset=0.3)
    yz = ct.input_output_response(zmodel.to_iosys(dt=data.dt), t, u).outputs
    assert _rel(yz, _zoh_oracle(zmodel, t, u, x0, 0.3)) < 1e-9
    if "intersample" in inspect.signature(hc.HammersteinModel.__init__).parameters:
        assert _rel(yz, zmodel.simulate(t, u)) < 1e-9
    # FOH with the initial state: python-control's forced_response from X0 on to_ss()
    fmodel = _with_settings(model, intersample="foh", initial_state=x0, offset=0.3)
    yf = ct.input_output_response(fmodel.to_iosys(dt=data.dt), t, u).outputs
    ref = ct.forced_response(fmodel.to_ss(), t, model.g(u), X0=x0).outputs + 0.3
    assert _rel(yf, ref) < 1e-9
    if "initial_state" in inspect.signature(hc.HammersteinModel.__init__).parameters:
        assert _rel(yf, fmodel.simulate(t, u)) < 1e-9


def test_sampled_export_emps(emps_case):
    _check_export(emps_case.structure.model(EMPS_OPT), emps_case.data)


def test_sampled_export_trs(trs_case):
    _check_export(trs_case.structure.model(trs_case.true_beta), trs_case.data)


def test_to_ss_is_the_simulators_realisation(trs_case):
    model = trs_case.structure.model(trs_case.true_beta)
    A, B, C, D = companion_realization(model.linear.num[0][0], model.linear.den[0][0])
    ss = model.to_ss()
    np.testing.assert_array_equal(ss.A, A[0])
    np.testing.assert_array_equal(ss.B.ravel(), B[0])
    np.testing.assert_array_equal(ss.C.ravel(), C[0])
    assert ct.tf(ss).num[0][0][-1] == pytest.approx(model.linear.num[0][0][-1])


def test_sampled_export_rejects_bad_dt(trs_case):
    model = trs_case.structure.model(trs_case.true_beta)
    for dt in (0.0, -1.0, float("nan"), "x"):
        with pytest.raises(ParameterError, match="dt must be a positive"):
            sampled_iosys(model, dt)


# ---------------------------------------------------------------------------
# the compiled loop against python-control
# ---------------------------------------------------------------------------
def _check_loop(model, gains, r, dt, u_limit):
    Y, U = simulate_loops(model, gains, r, dt, u_limit=u_limit)
    t = dt * np.arange(r.size)
    for row, y_fast, u_fast in zip(np.atleast_2d(gains), Y, U):
        resp = ct.input_output_response(sampled_loop_iosys(model, row, dt, u_limit=u_limit), t, r)
        assert _rel(y_fast, resp.outputs[0]) < 1e-6
        assert _rel(u_fast, resp.outputs[1]) < 1e-6
    return Y, U


def test_fast_loop_matches_python_control_on_emps(emps_model, emps_limits):
    simc = cd.tune_pid(emps_model, "simc", dt=1e-3, u_limit=emps_limits, step=STEP)
    gains = np.array([simc.gains, [300.0, 900.0, 20.0, 0.01, 0.5]])  # the second saturates hard
    Y, U = _check_loop(emps_model, gains, np.full(1500, STEP), 1e-3, emps_limits)
    assert U[1].max() == emps_limits[1]  # the limit was active: anti-windup exercised


@pytest.mark.parametrize("nl, params", [
    (hc.Tanh(), [-4.7132, 0.1229]), (hc.Polynomial(3), [1.0, 0.1, 0.3]), (hc.Saturation(), [1.5, 0.8]),
    (hc.DeadZone(), [1.2, 0.05]), (hc.PiecewiseLinear([-1.0, 0.0, 1.0]), [-0.5, 0.0, 1.5]),
])
def test_fast_loop_matches_python_control_per_family(nl, params):
    model = hc.HammersteinModel(ct.tf([1.0, 2.0], [1.0, 3.0, 2.0, 0.5]), nl, params)
    sign = np.sign(nl.derivative(np.array([0.3]), params)[0])
    r = np.r_[np.zeros(20), np.ones(150), -0.5 * np.ones(130)]
    _check_loop(model, np.array([[2.0 * sign, sign, 0.3 * sign, 0.05]]), r, 0.02, (-1.0, 1.2))


def test_continuous_loop_agrees_with_sampled_loop_for_smooth_g():
    model = hc.HammersteinModel(ct.tf([1.0], [1.0, 2.0, 1.0]), hc.Tanh(), [2.0, 0.8])
    pid = cd.tune_pid(model, "simc", tau_c=1.0)
    t = np.arange(0, 10, 0.001)
    r = np.ones_like(t)
    cont = ct.input_output_response(cd.closed_loop(model, pid, u_limit=(-1, 1)), t, r,
                                    solve_ivp_kwargs={"rtol": 1e-8, "atol": 1e-10}).outputs[0]
    Y, _ = simulate_loops(model, pid.gains, r, 0.001, u_limit=(-1, 1))
    assert _rel(Y[0], cont) < 1e-2  # sampling at 1 ms vs continuous time


# ---------------------------------------------------------------------------
# tuning rules against hand-derived formulas
# ---------------------------------------------------------------------------
def test_simc_integrating_with_lag_formula(emps_model):
    pid = cd.tune_pid(emps_model, "simc", tau_c=0.2, dt=1e-3)
    a1, d0 = EMPS_OPT[0], EMPS_OPT[1]
    k, tau2, theta = d0 / a1, 1 / a1, 0.5e-3  # G = k/(s (tau2 s + 1)), delay dt/2
    kc, ti = 1 / (k * (0.2 + theta)), 4 * (0.2 + theta)  # Skogestad (2003) Table 1
    assert pid.approximation["kind"] == "integrating"
    assert pid.kp == pytest.approx(kc * (1 + tau2 / ti), rel=1e-9)
    assert pid.ki == pytest.approx(kc / ti, rel=1e-9)
    assert pid.kd == pytest.approx(kc * tau2, rel=1e-9)
    assert pid.tf == pytest.approx(pid.kd / pid.kp / 10, rel=1e-12)
    s = ct.tf("s")
    ref = pid.kp + pid.ki / s + pid.kd * s / (pid.tf * s + 1)
    w = np.logspace(-2, 3, 50)
    np.testing.assert_allclose(pid.controller(1j * w), ref(1j * w), rtol=1e-12)


def test_half_rule_and_simc_self_regulating():
    # G = 2/((s+1)(0.2s+1)(0.04s+1)): tau1 = 1, tau2 = 0.2 + 0.02, theta = 0.02 (half rule)
    model = hc.HammersteinModel(ct.tf([1.0], np.polymul(np.polymul([1, 1], [0.2, 1]), [0.04, 1])),
                                hc.Coulomb(), [2.0, 0.0, 0.0])
    a = cd.approximate(model, 0.5)
    assert a["kind"] == "self-regulating"
    assert (a["gain"], a["tau1"], a["tau2"], a["theta"]) == pytest.approx((2.0, 1.0, 0.22, 0.02), rel=1e-9)
    pid = cd.tune_pid(model, "simc", tau_c=0.1, u0=0.5)
    kc, ti, td = 1.0 / (2.0 * 0.12), min(1.0, 4 * 0.12), 0.22
    assert (pid.kp, pid.ki, pid.kd) == pytest.approx((kc * (1 + td / ti), kc / ti, kc * td), rel=1e-9)


def test_imc_first_order_plus_delay():
    # G = 3/(2s+1) with an inverse-response zero (-0.5s+1): theta = 0.5 (half rule)
    model = hc.HammersteinModel(ct.tf([-0.5, 1.0], [2.0, 1.0]), hc.Coulomb(), [1.0, 0.0, 0.0])
    a = cd.approximate(model, 0.0)
    assert (a["gain"], a["tau1"], a["theta"]) == pytest.approx((1.0, 2.0, 0.5))
    pid = cd.tune_pid(model, "imc", tau_c=1.0)
    tau, th, lam, k = 2.0, 0.5, 1.0, 1.0
    kc = (2 * tau + th) / (k * (2 * lam + th))  # Rivera, Morari & Skogestad (1986)
    assert (pid.kp, pid.ki, pid.kd) == pytest.approx(
        (kc, kc / (tau + th / 2), kc * tau * th / (2 * tau + th)), rel=1e-9)


# ---------------------------------------------------------------------------
# the EMPS position loop: SIMC vs N-SPSA
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def emps_designs(emps_model, emps_limits):
    kwargs = dict(dt=1e-3, u_limit=emps_limits, step=STEP)
    simc = cd.tune_pid(emps_model, "simc", **kwargs)
    nspsa = cd.tune_pid(emps_model, "nspsa", seed=0, **kwargs)
    return simc, nspsa


def test_emps_both_pids_stable_with_small_overshoot(emps_model, emps_limits, emps_designs):
    for pid in emps_designs:
        rep = cd.analyze_loop(emps_model, pid, u_limit=emps_limits, step=STEP)
        assert rep["stable"] and np.all(rep["poles"].real < 0)
        assert rep["max_overshoot"] < 0.2 and rep["step_info"]["Overshoot"] < 20
        assert rep["phase_margin"] > 30 and rep["Ms"] < 2
        assert rep["y"][-1] == pytest.approx(STEP, rel=0.02)


def test_emps_nspsa_beats_simc_on_itae(emps_model, emps_limits, emps_designs):
    simc, nspsa = emps_designs
    itae = [cd.analyze_loop(emps_model, p, u_limit=emps_limits, step=STEP)["itae"] for p in emps_designs]
    assert itae[1] < 0.8 * itae[0]
    assert nspsa.cost == pytest.approx(itae[1], rel=1e-12)  # the overshoot bound is not active
    assert nspsa.approximation["start"]["cost"] == pytest.approx(itae[0], rel=1e-12)


def test_auto_rule_improves_on_simc(emps_model, emps_limits, emps_designs):
    auto = cd.tune_pid(emps_model, "auto", dt=1e-3, u_limit=emps_limits, step=STEP)
    rep = cd.analyze_loop(emps_model, auto, u_limit=emps_limits, step=STEP)
    assert auto.optimize_result.method == "nelder-mead" and rep["stable"]
    assert rep["itae"] < 0.8 * auto.approximation["start"]["cost"]


def test_nspsa_tuning_is_deterministic(emps_model, emps_limits, emps_designs):
    again = cd.tune_pid(emps_model, "nspsa", seed=0, dt=1e-3, u_limit=emps_limits, step=STEP)
    assert (again.kp, again.ki, again.kd, again.tf) == tuple(emps_designs[1].gains[:4])


def test_reference_profile_and_criteria(emps_model, emps_limits):
    r = np.r_[np.linspace(0, 0.1, 500), np.full(1000, 0.1)]
    pid = cd.tune_pid(emps_model, "nspsa", dt=1e-3, u_limit=emps_limits, reference=r, criterion="ise",
                      maxfev=101)
    assert pid.criterion == "ise" and pid.cost <= pid.approximation["start"]["cost"]


# ---------------------------------------------------------------------------
# bad requests
# ---------------------------------------------------------------------------
def test_bad_requests_raise_clear_errors(emps_model):
    unstable = hc.HammersteinModel(ct.tf([1.0], [1.0, -1.0]), hc.Coulomb(), [1.0, 0.0, 0.0])
    with pytest.raises(ParameterError, match="the model is unstable"):
        cd.tune_pid(unstable, "simc", tau_c=1.0)
    nonfinite = hc.HammersteinModel(ct.tf([1.0], [1.0, 1.0]), hc.Tanh(), [1.0, 1.0])
    nonfinite.linear = ct.tf([1.0], [1.0, np.nan])
    with pytest.raises(ParameterError, match="non-finite"):
        cd.tune_pid(nonfinite, "simc", tau_c=1.0)
    dead = hc.HammersteinModel(ct.tf([1.0], [1.0, 1.0]), hc.DeadZone(), [1.0, 0.5])
    with pytest.raises(ParameterError, match=r"g'\(u0\) = 0 at the operating point u0 = 0"):
        cd.tune_pid(dead, "simc", tau_c=1.0)
    with pytest.raises(UnknownNameError, match="unknown tuning rule 'ziegler'"):
        cd.tune_pid(emps_model, "ziegler")
    with pytest.raises(UnknownNameError, match="unknown cost criterion"):
        cd.tune_pid(emps_model, "nspsa", criterion="iae2", dt=1e-3, u_limit=(-4, 4))
    with pytest.raises(DataError, match="at least two samples"):
        cd.tune_pid(emps_model, "nspsa", reference=[0.1], dt=1e-3, u_limit=(-4, 4))
    for limits in [(4.0, -4.0), (1.0, 1.0), (np.nan, 1.0)]:
        with pytest.raises(ParameterError, match="lo < hi"):
            cd.tune_pid(emps_model, "simc", u_limit=limits)
    with pytest.raises(ParameterError, match="give tau_c"):
        cd.tune_pid(emps_model, "simc")
    with pytest.raises(ParameterError, match="not inside the actuator limits"):
        cd.tune_pid(emps_model, "simc", u_limit=(1.0, 2.0))
    with pytest.raises(DataError, match="at least two finite samples"):
        simulate_loops(emps_model, [[1.0, 1.0, 0.0, 0.0]], [1.0], 1e-3)


# ---------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------
def _run_cli(argv, monkeypatch):
    from hammerstein_ctrl import cli

    return cli.main(argv)


def test_cli_tune(tmp_path, monkeypatch, capsys):
    model = hc.HammersteinModel(ct.tf([1], [1, 3.138764, 0]), hc.Coulomb(), EMPS_OPT[1:])
    model.save(tmp_path / "emps.json")
    plot = tmp_path / "loop.png"
    code = _run_cli(["tune", str(tmp_path / "emps.json"), "--rule", "simc", "--u-limit", "-4.3", "4.1",
                     "--step", "0.1", "--dt", "0.001", "--plot", str(plot)], monkeypatch)
    out = capsys.readouterr().out
    assert code == 0 and "kp =" in out and "phase margin" in out and "overshoot" in out
    assert plot.stat().st_size > 1000
    code = _run_cli(["tune", str(tmp_path / "emps.json"), "--rule", "simc", "--u-limit", "4", "-4"],
                    monkeypatch)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("hammerstein-ctrl: error:")
    assert "actuator limits need lo < hi" in err[0]
    ref = tmp_path / "ref.txt"
    ref.write_text("0.1\n")
    code = _run_cli(["tune", str(tmp_path / "emps.json"), "--rule", "nspsa", "--reference", str(ref),
                     "--dt", "0.001", "--u-limit", "-4", "4"], monkeypatch)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "at least two samples" in err[0]
