"""Exact python-control export, the sampled PID loop and PID tuning (issue 9)."""

import inspect

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import design as cd
from hammerstein_ctrl.design._pid import MS_SLACK
from hammerstein_ctrl.simulate import linear_ss, sampled_iosys
from hammerstein_ctrl.exceptions import DataError, ParameterError, UnknownNameError
from hammerstein_ctrl.simulate._loop import check_limits, sampled_loop_iosys, simulate_loops
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


@pytest.mark.slow
def test_continuous_loop_agrees_with_sampled_loop_for_smooth_g():
    model = hc.HammersteinModel(ct.tf([1.0], [1.0, 2.0, 1.0]), hc.Tanh(), [2.0, 0.8])
    pid = cd.tune_pid(model, "simc", tau_c=1.0)
    t = np.arange(0, 10, 0.001)
    r = np.ones_like(t)
    cont = ct.input_output_response(hc.design.closed_loop(model, pid, u_limit=(-1, 1)), t, r,
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
    a = hc.design.approximate(model, 0.5)
    assert a["kind"] == "self-regulating"
    assert (a["gain"], a["tau1"], a["tau2"], a["theta"]) == pytest.approx((2.0, 1.0, 0.22, 0.02), rel=1e-9)
    pid = cd.tune_pid(model, "simc", tau_c=0.1, u0=0.5)
    kc, ti, td = 1.0 / (2.0 * 0.12), min(1.0, 4 * 0.12), 0.22
    assert (pid.kp, pid.ki, pid.kd) == pytest.approx((kc * (1 + td / ti), kc / ti, kc * td), rel=1e-9)


def test_imc_first_order_plus_delay():
    # G = 3/(2s+1) with an inverse-response zero (-0.5s+1): theta = 0.5 (half rule)
    model = hc.HammersteinModel(ct.tf([-0.5, 1.0], [2.0, 1.0]), hc.Coulomb(), [1.0, 0.0, 0.0])
    a = hc.design.approximate(model, 0.0)
    assert (a["gain"], a["tau1"], a["theta"]) == pytest.approx((1.0, 2.0, 0.5))
    pid = cd.tune_pid(model, "imc", tau_c=1.0)
    tau, th, lam, k = 2.0, 0.5, 1.0, 1.0
    kc = (2 * tau + th) / (k * (2 * lam + th))  # Rivera, Morari & Skogestad (1986)
    assert (pid.kp, pid.ki, pid.kd) == pytest.approx(
        (kc, kc / (tau + th / 2), kc * tau * th / (2 * tau + th)), rel=1e-9)


# ---------------------------------------------------------------------------
# the EMPS position loop
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def emps_designs(emps_model, emps_limits):
    kwargs = dict(dt=1e-3, u_limit=emps_limits, step=STEP)
    simc = cd.tune_pid(emps_model, "simc", **kwargs)
    nspsa = cd.tune_pid(emps_model, "nspsa", seed=0, **kwargs)
    return simc, nspsa


def test_emps_pids_are_verified_stable_robust_and_tracking(emps_model, emps_limits, emps_designs):
    for pid in emps_designs + (cd.tune_pid(emps_model, dt=1e-3, u_limit=emps_limits, step=STEP),):
        assert pid.success, pid.message
        rep = hc.design.analyze_loop(emps_model, pid, u_limit=emps_limits, step=STEP)
        assert rep["stable"] and np.all(rep["poles"].real < 0)
        assert rep["Ms"] <= 1.6 * MS_SLACK and rep["Mt"] <= 1.6 * MS_SLACK
        assert rep["y"][-1] == pytest.approx(pid.operating_point.y0 + STEP, rel=0.02)
        assert pid.stable == rep["stable"] and pid.Ms == pytest.approx(rep["Ms"])


def test_emps_nspsa_improves_on_its_start(emps_designs):
    _, nspsa = emps_designs
    assert nspsa.cost <= nspsa.approximation["start"]["cost"] and nspsa.criterion == "itae"


def test_auto_rule_runs_nelder_mead_from_the_robust_design(emps_model, emps_limits):
    auto = cd.tune_pid(emps_model, "auto", dt=1e-3, u_limit=emps_limits, step=STEP)
    assert auto.optimize_result.method == "nelder-mead" and auto.success
    assert auto.cost <= auto.approximation["start"]["cost"]


def test_nspsa_tuning_is_deterministic(emps_model, emps_limits, emps_designs):
    again = cd.tune_pid(emps_model, "nspsa", seed=0, dt=1e-3, u_limit=emps_limits, step=STEP)
    assert (again.kp, again.ki, again.kd, again.tf) == tuple(emps_designs[1].gains[:4])


@pytest.mark.parametrize("start", [(40.0, 0.0, 0.0), (40.0, 20.0, 0.0), (40.0, 20.0, 5.0)], ids=["P", "PI", "PID"])
def test_nspsa_starts_from_a_p_a_pi_or_a_pid(emps_model, emps_limits, start):
    """Gains are searched as multiples of a scale (zeros allowed): a P or a PI start is a point like any other."""
    pid = cd.tune_pid(emps_model, "nspsa", start=start, dt=1e-3, u_limit=emps_limits, step=STEP, maxfev=201)
    assert pid.approximation["start"]["kp"] == start[0] and np.isfinite(pid.cost)
    assert pid.cost <= pid.approximation["start"]["cost"]


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
    with pytest.raises(UnknownNameError, match="unknown tuning rule 'ziegler'"):
        cd.tune_pid(emps_model, "ziegler")
    with pytest.raises(UnknownNameError, match="unknown cost criterion"):
        cd.tune_pid(emps_model, "nspsa", criterion="iae2", dt=1e-3, u_limit=(-4, 4))
    with pytest.raises(DataError, match="at least two samples"):
        cd.tune_pid(emps_model, "nspsa", reference=[0.1], dt=1e-3, u_limit=(-4, 4))
    for limits in [(4.0, -4.0), (1.0, 1.0), (np.nan, 1.0)]:
        with pytest.raises(ParameterError, match="lo < hi"):
            cd.tune_pid(emps_model, "simc", u_limit=limits)
    with pytest.raises(ParameterError, match=r"no input in \[1, 2\] where g\(u\) = 0"):
        cd.tune_pid(emps_model, "simc", u_limit=(1.0, 2.0))
    with pytest.raises(ParameterError, match="max_sensitivity must be between 1 and 10"):
        cd.tune_pid(emps_model, max_sensitivity=0.9)
    with pytest.raises(ParameterError, match="max_sensitivity or phase_margin, not both"):
        cd.tune_pid(emps_model, max_sensitivity=1.4, phase_margin=45)
    with pytest.raises(DataError, match="at least two finite samples"):
        simulate_loops(emps_model, [[1.0, 1.0, 0.0, 0.0]], [1.0], 1e-3)


# ---------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------
def _run_cli(argv, monkeypatch):
    from hammerstein_ctrl.cli import _main as cli

    return cli.main(argv)


def test_cli_tune(tmp_path, monkeypatch, capsys):
    model = hc.HammersteinModel(ct.tf([1], [1, 3.138764, 0]), hc.Coulomb(), EMPS_OPT[1:])
    model.save(tmp_path / "emps.json")
    plot = tmp_path / "loop.png"
    code = _run_cli(["tune", str(tmp_path / "emps.json"), "--rule", "simc", "--u-limit", "-4.3", "4.1",
                     "--step", "0.1", "--dt", "0.001", "--plot", str(plot)], monkeypatch)
    out = capsys.readouterr().out
    assert code == 0 and "kp =" in out and "phase margin" in out and "overshoot" in out and "[ok: verified" in out
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


# ---------------------------------------------------------------------------
# every rule on eight identified plants (records made with python-control)
# ---------------------------------------------------------------------------
PLANT_DT, PLANT_N = 0.02, 4000
#: Actuator limits of each plant's loop (the plant inputs of the records stay within +-2).
PLANT_LIMITS = (-3.0, 3.0)


def _multisine(rng, amp, lines=25):
    t = np.arange(PLANT_N) * PLANT_DT
    f = np.geomspace(0.01, 2.0, lines)
    u = np.sum(np.sin(2 * np.pi * f[:, None] * t + rng.uniform(0, 2 * np.pi, lines)[:, None]), axis=0)
    return amp * u / np.abs(u).max()


def _levels(rng, amp, hold=25, count=9):
    return np.repeat(rng.choice(np.linspace(-amp, amp, count), PLANT_N // hold + 1), hold)[:PLANT_N]


def _response(num, den, v, hold="foh"):
    t = np.arange(v.size) * PLANT_DT
    if hold == "zoh":
        return ct.forced_response(ct.sample_system(ct.ss(ct.tf(num, den)), PLANT_DT, "zoh"), t, v).outputs
    return ct.forced_response(ct.tf(num, den), t, v).outputs


def _clip(x, a):
    return np.clip(x, -a, a)


#: name: (input, output from the input, structure, hold)
PLANTS = {
    "rhp_zero_behind_saturation": (
        lambda r: _multisine(r, 2.0), lambda u: _response([-1.0, 2.0], [1, 3, 2], 1.5 * _clip(u, 1.0)),
        lambda: hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Saturation()), "foh"),
    "zeta_005_behind_dead_zone": (
        lambda r: _levels(r, 2.0), lambda u: _response([4.0], [1, 0.2, 4.0], u - _clip(u, 0.3)),
        lambda: hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.DeadZone()), "foh"),
    "integrator_coulomb": (
        lambda r: _levels(r, 1.0), lambda u: _response([1.0], [1, 2.0, 0.0], 0.6 * u + 0.3 * np.sign(u) + 0.05),
        lambda: hc.HammersteinStructure(hc.LinearStructure(0, 2, fixed={"a0": 0.0}), hc.Coulomb()), "foh"),
    "third_order": (
        lambda r: _multisine(r, 1.5), lambda u: _response([1.0], [1, 3, 3, 1], 2.0 * np.tanh(0.8 * u)),
        lambda: hc.HammersteinStructure(hc.LinearStructure(0, 3), hc.Tanh()), "foh"),
    "output_offset": (
        lambda r: _multisine(r, 1.5), lambda u: _response([2.0], [1, 3, 2], u + 0.4 * u ** 3) + 1.5,
        lambda: hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Polynomial(3), offset=True), "foh"),
    "zoh_input": (
        lambda r: _levels(r, 1.5, hold=5), lambda u: _response([3.0], [1, 2.5, 3.0], 1.5 * np.tanh(1.2 * u), "zoh"),
        lambda: hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Tanh()), "zoh"),
    "wiener": (
        lambda r: _multisine(r, 1.5), lambda u: 1.5 * np.tanh(1.2 * _response([1.0], [1, 1.2, 1.0], u)),
        lambda: hc.WienerStructure(hc.LinearStructure(0, 2), hc.Tanh()), "foh"),
    "hammerstein_wiener": (
        lambda r: _levels(r, 2.0), lambda u: 2.0 * _clip(_response([1.0], [1, 1.5, 1.0], u - _clip(u, 0.2)), 1.0),
        lambda: hc.HammersteinWienerStructure(hc.LinearStructure(0, 2), hc.DeadZone(), hc.Saturation()), "foh"),
}


@pytest.fixture(scope="module")
def identified():
    """Each plant identified (identify with no x0) from its generated record."""
    out = {}
    for name, (make_u, respond, structure, hold) in PLANTS.items():
        rng = np.random.default_rng(0)
        u = make_u(rng)
        y = respond(u)
        y = y + 0.005 * np.std(y) * rng.standard_normal(y.size)
        res = hc.identify(hc.IOData(u, y, dt=PLANT_DT, intersample=hold, name=name), structure(), maxfev=4000)
        assert res.success, (name, res.message)
        out[name] = res.model
    return out


def _check_verified(model, pid, u_limit=None):
    """A returned controller is verified (checked here with python-control, not by the package's flags), or says
    why it is not."""
    if not pid.success:
        assert pid.message and not pid.message.startswith("verified"), pid
        return False
    L = pid.controller * pid.linearized
    poles = ct.feedback(L, 1).poles()
    assert np.all(poles.real < 0), poles
    w = np.logspace(-4, 4, 8000) * max(1.0, float(np.max(np.abs(poles))))
    S = ct.frequency_response(ct.feedback(1, L), w).magnitude.ravel()
    assert S.max() <= 2.0 and S.max() == pytest.approx(pid.Ms, rel=0.05)
    st = pid.step
    assert st["final_error"] < 0.02
    lo, hi = check_limits(u_limit)
    assert lo <= pid.operating_point.u0 + 0 <= hi
    rep = hc.design.analyze_loop(model, pid, u_limit=u_limit)
    assert np.all((rep["u"] >= lo) & (rep["u"] <= hi))
    assert abs(rep["y"][-1] - (pid.operating_point.y0 + st["step"])) < 0.02 * abs(st["step"])
    return True


@pytest.mark.parametrize("name", sorted(PLANTS))
def test_the_default_tunes_every_identified_plant(identified, name):
    """``tune_pid(model)`` with nothing else: a verified, robust controller (no delay, tau_c or limits needed)."""
    pid = cd.tune_pid(identified[name])
    assert pid.success, pid.message
    assert _check_verified(identified[name], pid)
    assert pid.rule == "robust" and pid.Ms <= 1.6 * MS_SLACK


@pytest.mark.parametrize("rule", ["robust", "simc", "imc"])
@pytest.mark.parametrize("name", sorted(PLANTS))
def test_every_rule_returns_a_verified_controller_or_says_why(identified, name, rule):
    pid = cd.tune_pid(identified[name], rule, u_limit=PLANT_LIMITS)
    _check_verified(identified[name], pid, PLANT_LIMITS)


@pytest.mark.parametrize("rule", ["nspsa", "auto"])
@pytest.mark.parametrize("name", ["rhp_zero_behind_saturation", "wiener"])
def test_model_based_rules_return_verified_controllers(identified, name, rule):
    pid = cd.tune_pid(identified[name], rule, u_limit=PLANT_LIMITS, maxfev=201)
    assert _check_verified(identified[name], pid, PLANT_LIMITS), pid.message


@pytest.mark.slow
@pytest.mark.parametrize("rule", ["nspsa", "auto"])
@pytest.mark.parametrize("name", sorted(PLANTS))
def test_model_based_rules_on_every_identified_plant(identified, name, rule):
    pid = cd.tune_pid(identified[name], rule, u_limit=PLANT_LIMITS)
    _check_verified(identified[name], pid, PLANT_LIMITS)


def test_a_user_tau_c_is_kept_and_judged(identified):
    """SIMC on the right-half-plane-zero plant with a fast tau_c: kept as given, and reported as not robust."""
    model = identified["rhp_zero_behind_saturation"]
    pid = cd.tune_pid(model, "simc", tau_c=0.05)
    assert pid.approximation["tau_c"] == 0.05 and not pid.success
    assert "unstable" in pid.message or "not robust" in pid.message
    auto = cd.tune_pid(model, "simc")
    assert auto.success and auto.approximation["tau_c"] > 0.05


# ---------------------------------------------------------------------------
# operating points
# ---------------------------------------------------------------------------
def test_the_offset_plant_is_regulated_around_its_operating_point(identified):
    """Step figures relative to the operating point agree with a loop built by hand in python-control."""
    from hammerstein_ctrl.design._operating_point import rest_model

    model = identified["output_offset"]
    pid = cd.tune_pid(model, y0=1.7, step=0.2, dt=0.01)
    op = pid.operating_point
    assert pid.success and op.y0 == pytest.approx(1.7) and model.offset == pytest.approx(1.5, abs=1e-3)
    # by hand: error junction, the discrete PID with its bias, the exact held plant started at rest
    dt, n = 0.01, int(round(pid.step["t_final"] / 0.01)) + 1
    plant = rest_model(model, op).to_iosys(dt=dt, inputs="u", outputs="y", intersample="zoh")
    err = ct.summing_junction(inputs=["r", "-y"], output="e", dt=dt)
    from hammerstein_ctrl.simulate import discrete_pid_iosys
    loop = ct.interconnect([err, discrete_pid_iosys(pid.gains, dt, bias=op.u0),
                            ct.nlsys(None, lambda t, x, u, p: u[:1], inputs=["uc"], outputs=["u"], dt=dt), plant],
                           inputs=["r"], outputs=["y", "u"], dt=dt)
    t = dt * np.arange(n)
    resp = ct.input_output_response(loop, t, np.full(n, op.y0 + 0.2))
    y = resp.outputs[0]
    assert y[0] == pytest.approx(op.y0, rel=1e-9)                   # at rest at the operating point
    info = ct.step_info(y - op.y0, t, yfinal=0.2)
    for key in ("RiseTime", "SettlingTime", "Overshoot"):
        assert pid.step[key] == pytest.approx(info[key], rel=1e-6, abs=1e-9), key
    assert y[-1] == pytest.approx(op.y0 + 0.2, rel=0.02)


def test_an_unreachable_operating_point_is_refused(identified):
    with pytest.raises(ParameterError, match="gives the output y0 = 5"):
        cd.tune_pid(identified["wiener"], y0=5.0)       # tanh output map: |y| < 1.5


# ---------------------------------------------------------------------------
# discrete loops
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["P", "PI", "PID"])
def test_discrete_loops_close_around_the_held_export_and_match_the_compiled_loop(identified, kind):
    """P, PI and PID digital controllers around ``to_iosys(dt, intersample="zoh")``: no algebraic loop in
    python-control, and the package's loop simulation to 1e-9."""
    from hammerstein_ctrl.simulate import simulate_controller_loop

    model = identified["third_order"]
    pid = cd.tune_pid(model, dt=0.02)
    gains = {"P": (pid.kp, 0.0, 0.0, 0.0), "PI": (pid.kp, pid.ki, 0.0, 0.0), "PID": tuple(pid.gains[:4])}[kind]
    C = ct.sample_system(cd.pid_controller(*gains), 0.02, method="tustin")
    C = ct.tf(C.num, C.den, 0.02, inputs="e", outputs="uc")
    plant = model.to_iosys(dt=0.02, inputs="uc", outputs="y", intersample="zoh")
    err = ct.summing_junction(inputs=["r", "-y"], output="e", dt=0.02)
    loop = ct.interconnect([err, C, plant], inputs=["r"], outputs=["y", "uc"], dt=0.02)
    t = 0.02 * np.arange(400)
    r = np.r_[np.zeros(20), np.full(380, 0.5)]
    resp = ct.input_output_response(loop, t, r)
    y, u = simulate_controller_loop(model, C, r, 0.02)
    np.testing.assert_allclose(y, resp.outputs[0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(u, resp.outputs[1], rtol=1e-9, atol=1e-12)


def test_to_discrete_is_verified_on_the_exact_discrete_plant(identified):
    pid = cd.tune_pid(identified["third_order"])
    fast = pid.to_discrete(0.01)
    assert fast.success and fast.controller.dt == 0.01 and np.all(np.abs(fast.poles) < 1)
    slow = pid.to_discrete(2.0)
    assert not slow.success and ("unstable" in slow.message or "sample faster" in slow.message)


def test_the_continuous_export_reproduces_the_held_model_to_1e6():
    """Documented settings: a ZOH model, the held input on a refined grid, tight solver tolerances."""
    m = hc.HammersteinModel(ct.tf([2.0, 1.0], [1, 3, 2]), hc.Tanh(), [1.5, 0.8], intersample="zoh", offset=0.2)
    dt = 0.05
    t = np.arange(0, 4, dt)
    u = np.sin(0.7 * t) + 0.5 * np.sign(np.sin(2.3 * t))
    eps = 1e-9 * dt
    T = np.sort(np.concatenate([t, t[1:] - eps]))
    U = u[np.searchsorted(t, T + eps / 2, side="right") - 1]
    r = ct.input_output_response(m.to_iosys(), T, U,
                                 solve_ivp_kwargs={"rtol": 1e-10, "atol": 1e-12, "max_step": dt})
    y = m.simulate(t, u)
    assert np.max(np.abs(np.interp(t, r.time, r.outputs) - y)) < 1e-6 * np.max(np.abs(y))


@pytest.mark.parametrize("num, den, params, message", [
    ([1e-300], [1, 3.1, 1], [1, 1], r"gain \|P\(jw\)\| lies in"),
    ([1], [1, 3.1, 1], [1e-300, 1], r"gain \|P\(jw\)\| lies in"),
    ([1e80], [1, 3.1, 1], [1e60, 1], r"gain \|P\(jw\)\| lies in"),
    ([1], [1e-200, 3.1, 1], [1, 1], r"coefficients .* span more than 1e\+100"),
    ([1], [1, 1e90, 1], [1, 1], r"gain \|P\(jw\)\| lies in"),
])
def test_tuning_refuses_models_beyond_numerical_range(num, den, params, message):
    model = hc.HammersteinModel(ct.tf(num, den), hc.Tanh(), params)
    with pytest.raises(ParameterError, match=message):
        cd.tune_pid(model)


def test_a_sampled_plant_of_mismatched_arrays_is_refused():
    """The compiled loops read Ad, Bd and C at the order x0 gives: arrays that disagree are refused when the plant is
    made, never read past."""
    from hammerstein_ctrl.simulate._loop import IDENTITY, SampledPlant

    good = dict(Ad=np.eye(2) * 0.5, Bd=np.ones(2), C=np.ones(2), x0=np.zeros(2), offset=0.0, code=IDENTITY,
                params=np.zeros(1), breakpoints=np.zeros(2), dt=0.1)
    Y, U = simulate_loops(SampledPlant(**good), [[1.0, 0.5, 0.0, 0.0]], np.ones(5), 0.1)
    assert np.all(np.isfinite(Y)) and Y[0, 0] == 0.0
    for name, value in (("Ad", np.eye(3)), ("Bd", np.ones(3)), ("C", np.ones(1)), ("x0", np.zeros((1, 2)))):
        with pytest.raises(ParameterError, match="a sampled plant needs Ad"):
            SampledPlant(**{**good, name: value})


@pytest.mark.parametrize("rule", ["robust", "simc", "imc"])
def test_a_design_at_dt_succeeds_only_if_its_digital_loop_does(rule):
    """tune_pid(dt=...) verifies the loop to_discrete(dt) builds (Tustin controller, held plant): the two
    verdicts agree, and a design that succeeds meets the target in its digital loop too."""
    model = hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Tanh()).model([4.0, 2.4, 8.0, 0.8])
    for dt in (0.01, 0.05, 0.2, 0.5):
        pid = cd.tune_pid(model, rule, dt=dt)
        digital = pid.to_discrete(dt)
        assert pid.success == digital.success, (dt, pid.message, digital.message)
        if pid.success:
            assert max(digital.Ms, digital.Mt) <= 1.6 * 1.02
        else:
            assert "digital loop" in pid.message and "tune with dt" not in pid.message
    assert cd.tune_pid(model, rule, dt=0.05).success


def test_a_custom_map_runs_the_same_loops_in_python_and_tunes_as_its_builtin_twin():
    from hammerstein_ctrl.simulate import simulate_controller_loop, simulate_loops

    custom = hc.CustomNonlinearity(lambda v, q: q[0] * np.tanh(q[1] * v), 2, param_names=["k", "s"])
    twin = [hc.HammersteinStructure(hc.LinearStructure(0, 2), g).model([4.0, 2.4, 8.0, 0.8])
            for g in (custom, hc.Tanh())]
    r, gains = np.full(800, 0.5), [[2.0, 5.0, 0.4, 0.02], [1.0, 1.0, 0.0, 0.0]]
    (Y1, U1), (Y2, U2) = (simulate_loops(m, gains, r, 0.01, u_limit=(-1.0, 1.0)) for m in twin)
    np.testing.assert_allclose(Y1, Y2, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(U1, U2, rtol=1e-12, atol=1e-13)
    C = ct.sample_system(ct.tf([0.5, 1.0], [1.0, 0.0]), 0.01, method="tustin")
    (y1, _), (y2, _) = (simulate_controller_loop(m, C, r, 0.01, u_limit=(-1.0, 1.0)) for m in twin)
    np.testing.assert_allclose(y1, y2, rtol=1e-12, atol=1e-13)
    pc, pt = (cd.tune_pid(m, dt=0.05) for m in twin)
    assert pc.success and pc.to_discrete(0.05).success
    np.testing.assert_allclose(pc.gains, pt.gains, rtol=1e-9)
