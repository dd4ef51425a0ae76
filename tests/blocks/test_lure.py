"""Lur'e loops: friction fed back on velocity or output, simulated exactly through stick-slip, and identified."""

import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import hammerstein_ctrl as hc
from hammerstein_ctrl import Coulomb, Friction, LinearStructure, ParameterError, Tanh
from hammerstein_ctrl.blocks._lure import FEEDBACKS as FEEDBACK_DEGREE, LureModel, LureStructure, lure_structure
from hammerstein_ctrl.fit import LureCost

#: A sliding mass: force to position b / (p^2 + a p), Coulomb level fc and constant force c (input units).
MASS = (0.4, 2.0, 0.5, 0.05)


def _stick_slip_reference(A, B, C, Cz, fc, c, u, dt, hold, x0):
    """Sampled output of the Filippov solution, by solve_ivp with events (written apart from the package).

    Slipping: ``x' = A x + B (u - c -+ fc)`` until ``Cz x`` crosses 0; at ``z = 0`` the mass moves where the
    force beats friction, else sticks: ``x' = A_s x`` while the holding force stays within ``[-fc, fc]``.
    """
    A, B, C, Cz = (np.asarray(v, dtype=float) for v in (A, B, C, Cz))
    h = Cz @ B
    q = Cz @ A / h
    A_s = A - np.outer(B, q)

    def force(t, k):
        return u[k] + (u[k + 1] - u[k]) * t / dt if hold == "foh" else u[k]

    def direction(x, f):
        feq = f + q @ x
        up, down = h * (feq - fc) > 0, h * (feq + fc) < 0
        return 1 if up else (-1 if down else 0)

    x = np.asarray(x0, dtype=float)
    z = Cz @ x
    mode = 1 if z > 0 else (-1 if z < 0 else direction(x, u[0] - c))
    y = [C @ x]
    for k in range(len(u) - 1):
        t = 0.0
        if mode == 0 and abs(u[k] - c + q @ x) > fc:
            mode = 1 if (u[k] - c + q @ x) * h > 0 else -1
        while t < dt * (1 - 1e-13):
            m = mode
            if m:
                def rhs(s, xx, k=k, m=m):
                    return A @ xx + B * (force(s, k) - c - m * fc)

                def event(s, xx):
                    return Cz @ xx
                event.direction = -m
            else:
                def rhs(s, xx):
                    return A_s @ xx

                def event(s, xx, k=k):
                    return abs(force(s, k) - c + q @ xx) - fc
                event.direction = 1
            event.terminal = True
            sol = solve_ivp(rhs, (t, dt), x, events=event, rtol=1e-12, atol=1e-14, method="DOP853")
            x = sol.y[:, -1]
            if sol.status == 1 and t < sol.t[-1] < dt * (1 - 1e-13):
                t = sol.t[-1]
                f = force(t, k) - c
                mode = direction(x, f) if m else (1 if (f + q @ x) * h > 0 else -1)
            else:
                t = dt
        y.append(C @ x)
    return np.array(y)


def _python_control_mass(truth=MASS, band=1e-7):
    """The sliding mass as a python-control ``interconnect``: the mass ``b / (p^2 + a p)`` (position, velocity)
    and a friction block reading the velocity and the applied force.  Within ``band`` of zero velocity the block
    gives the force that holds the velocity (Karnopp's stick band) while it lies within the Coulomb level, so
    an ODE solver follows sticking instead of chattering; the band bounds the difference from the exact
    (Filippov) solution."""
    import control as ct

    b, a, fc, c = truth
    mass = ct.ss([[0, 1], [0, -a]], [[0], [b]], np.eye(2), np.zeros((2, 1)), inputs="w", outputs=["y", "v"])

    def friction(t, x, signals, params):
        v, f = signals
        if abs(v) < band:
            hold = f - a * v / b
            return [hold if abs(hold - c) <= fc else c + fc * np.sign(hold - c)]
        return [c + fc * np.sign(v)]

    block = ct.nlsys(None, friction, inputs=["v", "u"], outputs="f")
    junction = ct.summing_junction(inputs=["u", "-f"], output="w")
    return ct.interconnect([mass, block, junction], inputs="u", outputs="y")


def _excitation(t):
    return 1.5 * np.sin(0.7 * t) + np.sin(2.3 * t) + 0.5 * np.sign(np.sin(0.23 * t) + 1e-9)


@pytest.mark.slow
def test_stick_slip_simulation_agrees_with_python_control():
    import control as ct

    t = np.arange(2000) * 0.01
    u = _excitation(t)
    y = lure_structure().model(MASS).simulate(t, u)
    ref = ct.input_output_response(_python_control_mass(), t, u, X0=[0.0, 0.0],
                                   solve_ivp_kwargs=dict(rtol=1e-10, atol=1e-13, max_step=0.0025)).outputs
    assert np.sum(np.diff(y) == 0) > 100                       # it sticks, often
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-6 * np.ptp(ref))


def _mass_record(n=4000, dt=0.01, noise=0.0, seed=0, truth=MASS, hold="foh"):
    t = np.arange(n) * dt
    u = _excitation(t)
    y = lure_structure().model(truth, intersample=hold).simulate(t, u)
    y = y + noise * np.random.default_rng(seed).standard_normal(n)
    return hc.IOData(u, y, dt=dt, intersample=hold)


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_stick_slip_simulation_equals_an_event_driven_reference(hold):
    b, a, fc, c = 0.385, 2.13, 0.61, -0.091
    t = np.arange(600) * 0.01
    u = np.sin(2 * np.pi * 0.3 * t) + 0.3 * np.sin(2 * np.pi * 1.1 * t)
    y = lure_structure().model([b, a, fc, c], intersample=hold).simulate(t, u)
    ref = _stick_slip_reference([[0, 1], [0, -a]], [0, b], [1, 0], [0, 1], fc, c, u, 0.01, hold, [0, 0])
    assert np.sum(np.diff(y) == 0) > 100                       # the record really sticks
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-9 * np.ptp(ref))


def test_output_feedback_simulation_equals_an_event_driven_reference():
    # force to velocity b / (p + a), friction on the output (the velocity itself)
    b, a, fc, c = 1.2, 0.8, 0.4, 0.1
    t = np.arange(500) * 0.02
    u = 0.9 * np.sin(1.3 * t) + 0.2
    m = LureModel(([b], [1.0, a]), Friction(), [fc, c], feedback="output")
    ref = _stick_slip_reference([[-a]], [1.0], [b], [b], fc, c, u, 0.02, "foh", [0.0])
    y = m.simulate(t, u)
    assert np.sum(np.abs(y) < 1e-15) > 20
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-9 * np.ptp(ref))


@pytest.mark.slow
def test_interconnect_export_agrees_with_the_sampled_simulation():
    import control as ct

    m = lure_structure().model([0.385, 2.13, 0.61, -0.091])
    t = np.arange(301) * 0.01
    u = 3 * np.cos(np.pi * t)                  # velocity reverses without sticking: the ODE solver can follow
    sys = m.to_iosys()
    assert isinstance(sys, ct.InterconnectedSystem)
    ref = ct.input_output_response(sys, t, u, X0=[1.0, 0.0],
                                   solve_ivp_kwargs=dict(rtol=1e-11, atol=1e-13, max_step=0.01)).outputs
    y = m.simulate(t, u, initial_state=[1.0, 0.0])
    assert np.sum(np.diff(np.sign(np.diff(y))) != 0) >= 2
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-6 * np.ptp(y))


@pytest.mark.slow
def test_known_truth_stick_slip_plant_is_identified_within_its_standard_errors():
    import control as ct

    t = np.arange(4000) * 0.01
    u = _excitation(t)
    truth = ct.input_output_response(_python_control_mass(), t, u, X0=[0.0, 0.0],          # generated apart
                                     solve_ivp_kwargs=dict(rtol=1e-10, atol=1e-13, max_step=0.0025)).outputs
    sigma, z, ratio = 0.002, [], []
    for seed in range(8):
        data = hc.IOData(u, truth + sigma * np.random.default_rng(seed).standard_normal(t.size), dt=0.01)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = hc.identify(data, lure_structure(), seed=0)
        assert r.success, r.message
        se = r.uncertainty.stderr
        z.append((r.x - MASS) / se)
        ratio.append(r.fun / len(data) / sigma**2)
    z = np.array(z)
    assert np.all(np.abs(z) < 4), z
    np.testing.assert_allclose(ratio, 1.0, rtol=0.15)
    spread = z.std(axis=0)                 # the estimates' spread in units of their standard errors
    assert np.all((spread > 0.4) & (spread < 1.7)), spread


def test_identification_under_zero_order_hold_with_offset():
    truth = np.r_[MASS, 0.03]
    t = np.arange(3000) * 0.01
    u = 1.5 * np.sin(0.7 * t) + np.sin(2.3 * t)
    s = lure_structure(offset=True)
    y = s.model(truth, intersample="zoh").simulate(t, u) + 0.001 * np.random.default_rng(3).standard_normal(t.size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = hc.identify(hc.IOData(u, y, dt=0.01, intersample="zoh"), s, seed=1)
    assert r.success
    assert np.all(np.abs(r.x - truth) < 4 * r.uncertainty.stderr)


def test_cost_scores_hostile_candidates_inf_and_counts_exactly():
    data = _mass_record(n=500)
    cost = LureCost(data, lure_structure())
    assert cost(MASS) == 0.0
    J = cost.batch([MASS, [np.nan, 2.0, 0.5, 0.0], [0.0, 2.0, 0.5, 0.0], [1e300, -1e300, 1.0, 0.0]])
    assert J[0] == 0.0 and np.all(np.isinf(J[1:]))
    R = cost.residuals_batch([[np.nan, 2.0, 0.5, 0.0]])
    assert np.all(np.isfinite(R))
    with pytest.raises(ParameterError, match="4 entries"):
        cost([1.0, 2.0])


def test_friction_level_is_reported_non_negative():
    s = lure_structure()
    assert s.normalize([0.4, 2.0, -0.5, 0.05])[2] == 0.5
    y1 = s.model([0.4, 2.0, -0.5, 0.05]).simulate(np.arange(200) * 0.01, np.sin(np.arange(200) * 0.05))
    y2 = s.model([0.4, 2.0, 0.5, 0.05]).simulate(np.arange(200) * 0.01, np.sin(np.arange(200) * 0.05))
    np.testing.assert_array_equal(y1, y2)


@pytest.mark.parametrize("make, match", [
    (lambda: LureStructure(LinearStructure(1, 2, monic_numerator=False), Tanh()), "relative degree at least 2"),
    (lambda: LureStructure(LinearStructure(0, 2, monic_numerator=False), "tanh"), "must be a Nonlinearity"),
    (lambda: lure_structure(nonlinearity=Tanh(), substeps=0), "substeps"),
    (lambda: LureStructure(LinearStructure(1, 2, monic_numerator=False), Friction()), "relative degree 2"),
    (lambda: LureStructure(LinearStructure(0, 2, monic_numerator=False), Friction(), feedback="output"),
     "relative degree 1"),
    (lambda: LureStructure(LinearStructure(0, 2), Friction()), "monic_numerator=False"),
    (lambda: LureStructure(LinearStructure(0, 2, monic_numerator=False, delay=0.1), Friction()), "dead time"),
    (lambda: LureStructure(LinearStructure(0, 2, monic_numerator=False), Friction(), feedback="position"),
     "feedback must be one of"),
    (lambda: lure_structure(initial_state="guess"), "initial_state"),
])
def test_ill_posed_loops_are_refused_in_one_line(make, match):
    with pytest.raises(ParameterError, match=match) as err:
        make()
    assert "\n" not in str(err.value)


def test_coulomb_map_with_a_viscous_term_matches_the_same_loop_with_that_damping():
    t = np.arange(800) * 0.01
    u = np.sin(0.9 * t) + 0.4
    viscous = LureModel(([0.4], [1.0, 1.5, 0.0]), Coulomb(), [1.25, 0.5, 0.05]).simulate(t, u)
    damped = LureModel(([0.4], [1.0, 2.0, 0.0]), Friction(), [0.5, 0.05]).simulate(t, u)
    np.testing.assert_allclose(viscous, damped, rtol=0, atol=1e-12)


def test_emps_lure_model_from_rest_validates_beyond_the_published_models(emps_dir):
    from hammerstein_ctrl.paper.datasets import load_emps

    est = load_emps("estimation", duration=12.0, path=emps_dir)
    full, val = load_emps("estimation", path=emps_dir), load_emps("validation", path=emps_dir)

    def validation(data):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = hc.identify(data, lure_structure(), seed=0)
        y = r.model.simulate(val)
        return r, hc.data.fit_report(val.y.ravel(), y)

    r, rep = validation(est)
    assert r.success
    assert rep["fit_percent"] >= 89.5 and rep["rmse"] <= 8.7e-3
    from hammerstein_ctrl.paper.emps_loop import EMPS_PHYSICAL, load_emps_loop, physical_parameters

    phys = physical_parameters(r.x, load_emps_loop("estimation", path=emps_dir)[2]["gtau"])
    for key in ("mass", "viscous", "coulomb", "offset"):       # the published physical identification
        assert phys[key] == pytest.approx(EMPS_PHYSICAL[key], rel=0.05), key
    r, rep = validation(full)
    assert r.success and rep["fit_percent"] >= 92.0


def _fitted():
    data = _mass_record(n=2000, noise=0.002, seed=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return hc.identify(data, lure_structure(offset=True), seed=0), data


def test_model_and_result_files_round_trip(tmp_path):
    r, data = _fitted()
    hc.save_model(r.model, tmp_path / "m.json")
    back = hc.load_model(tmp_path / "m.json")
    np.testing.assert_array_equal(back.simulate(data), r.model.simulate(data))
    hc.save_result(r, tmp_path / "r.json")
    res = hc.load_result(tmp_path / "r.json")
    np.testing.assert_array_equal(res.x, r.x)
    assert res.structure.param_names == r.structure.param_names
    np.testing.assert_array_equal(res.model.simulate(data), r.model.simulate(data))


def test_result_figure_shows_the_feedback_map():
    import matplotlib

    matplotlib.use("Agg")
    r, _ = _fitted()
    fig = r.plot()
    assert any("feedback map" in ax.get_title() for ax in fig.axes)


def test_linear_tools_take_the_motion_model_and_refuse_the_loop():
    from hammerstein_ctrl import design as control_design

    model = LureModel(([0.4], [1.0, 1.5, 0.0]), Coulomb(), [1.25, 0.5, 0.05])
    assert model.linearize().den[0][0].tolist() == [1.0, 2.0, 0.0]
    with pytest.raises(ParameterError, match="motion_model") as err:
        control_design.tune_pid(model)
    assert "\n" not in str(err.value)
    pid = control_design.tune_pid(model.motion_model())
    assert pid.success and pid.stable


def test_command_line_fits_a_loop(tmp_path):
    import subprocess
    import sys

    data = _mass_record(n=1500, noise=0.001)
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.column_stack([data.t, data.u.ravel(), data.y.ravel()]), delimiter=",", header="t,u,y",
               comments="")
    cmd = [sys.executable, "-m", "hammerstein_ctrl.cli", "identify", "--data", str(path), "--input", "u", "--output",
           "y", "--orders", "0", "2", "--fix", "a0=0", "--nonlinearity", "friction", "--feedback", "velocity"]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    import re

    assert "Lur'e loop" in out.stdout
    assert abs(float(re.search(r"fc = ([-+.\de]+)", out.stdout).group(1).rstrip(",")) - 0.5) < 0.01
    bad = subprocess.run(cmd[:-6] + ["--orders", "1", "2", "--nonlinearity", "friction", "--feedback", "velocity"],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1


# -- speed (wall-clock: `make bench` runs these, never `make test`) ------------------------------------------
def test_the_speed_report_compares_lure_and_hammerstein_on_one_record(emps_case):
    from speed import format_lure_speed, lure_speed

    r = lure_speed(emps_case, pairs=1, number=2)
    assert r["n_samples"] == len(emps_case.data) and r["lure_s"] > 0 and r["hammerstein_s"] > 0
    assert "Lur'e" in format_lure_speed(r)


@pytest.mark.timing
def test_a_lure_evaluation_costs_at_most_three_hammerstein_ones(emps_case):
    from speed import lure_speed

    r = lure_speed(emps_case)
    assert r["ratio"] <= 3.0, r


def _finer(m, t, u, hold, k):
    """The same model on a grid ``k`` times finer carrying the same input (held or interpolated), subsampled."""
    fine = np.arange((t.size - 1) * k + 1) * (t[1] - t[0]) / k
    uf = np.repeat(u, k)[:fine.size] if hold == "zoh" else np.interp(fine, t, u)
    return m.simulate(fine, uf, intersample=hold)[::k]


def test_higher_order_loops_resolve_every_switch_inside_a_sample(rng):
    # switches inside one sample: a reversal and a return to zero, a stick and a breakaway between two samples
    t = np.arange(300) * 0.1
    u = 1.5 * np.sin(0.7 * t) + np.sin(2.3 * t + 1) + 0.6 * np.sign(np.sin(0.23 * t))
    worst = 0.0
    for _ in range(60):
        n = int(rng.integers(3, 5))
        feedback = str(rng.choice(["output", "velocity"]))
        num = rng.uniform(0.5, 2.0, size=n - FEEDBACK_DEGREE[feedback] + 1)
        hold = str(rng.choice(["zoh", "foh"]))
        m = LureModel((num, np.real(np.poly(-rng.uniform(0.3, 4.0, size=n)))), Friction(),
                      [rng.uniform(0.05, 0.5), rng.uniform(-0.1, 0.1)], feedback=feedback, intersample=hold)
        y = m.simulate(t, u)
        worst = max(worst, np.max(np.abs(y - _finer(m, t, u, hold, 100))) / np.ptp(y))
    assert worst < 1e-9


def test_stiff_blocks_simulate_exactly():
    t = np.arange(200) * 0.01
    u = np.sin(2 * t)
    for k in (1e2, 1e6, 1e9):                  # poles at -10 k: |p| dt up to 1e8
        m = LureModel(([2 * k], [1.0, 10 * k, 0.0]), Friction(), [0.5, 0.0])
        y = m.simulate(t, u)                  # the matrix exponential where a Taylor series would need 1e8 pieces
        np.testing.assert_allclose(y, _finer(m, t, u, "foh", 50), rtol=0, atol=1e-12 * np.ptp(y))


@pytest.mark.parametrize("make, match", [
    (lambda: LureModel(([0.0], [1.0, 2.0, 0.0]), Friction(), [0.5, 0.0]), "gain is zero"),
    (lambda: LureModel(([0.4], [1.0, 2.0, 0.0]), Friction(), [np.nan, 0.0]), "finite numbers"),
    (lambda: LureModel(([0.4], [1.0, 2.0, 0.0]), Friction(), [0.5, 0.0], initial_state=[1.0]), "2 finite numbers"),
    (lambda: LureModel(([0.4], [1.0, 2.0, 0.0]), Friction(), [0.5, 0.0], offset="a"), "offset must be a number"),
    (lambda: LureModel(([0.4], [1.0, 2.0, 0.0]), Friction(), [0.5, 0.0], feedback=["velocity"]), "feedback"),
    (lambda: LureModel("abc", Friction(), [0.5, 0.0]), "TransferFunction"),
    (lambda: LureStructure(LinearStructure(0, 2, monic_numerator=False, fixed={"b0": 0.0}), Friction()),
     "all fixed to 0"),
    (lambda: lure_structure(offset="no"), "True or False"),
])
def test_unusable_models_are_refused_at_construction(make, match):
    with pytest.raises(ParameterError, match=match) as err:
        make()
    assert "\n" not in str(err.value)


def test_discrete_or_mimo_blocks_are_refused():
    import control as ct

    with pytest.raises(ParameterError, match="continuous-time"):
        LureModel(ct.tf([0.4], [1.0, -1.9, 0.9], 0.01), Friction(), [0.5, 0.0])
    with pytest.raises(ParameterError, match="SISO"):
        LureModel(ct.tf([[[1.0]], [[1.0]]], [[[1.0, 2.0, 0.0]], [[1.0, 2.0, 0.0]]]), Friction(), [0.5, 0.0])


def test_a_numerator_coefficient_fixed_at_zero_counts_in_the_relative_degree():
    """b1 fixed at 0 makes (b0)/(a2 p^2 + ...) of relative degree 2: refused for output feedback at construction
    (not after the search), accepted for velocity feedback."""
    lin = hc.LinearStructure(1, 2, monic_numerator=False, fixed={"b1": 0.0})
    with pytest.raises(ParameterError, match=r"relative degree 1 .*got 2 \(b1 is fixed at 0, so the numerator's "
                                             r"degree is 0\)"):
        hc.LureStructure(lin, hc.Friction(), feedback="output")
    assert hc.LureStructure(lin, hc.Friction(), feedback="velocity").param_names[:3] == ("b0", "a0", "a1")


# -- loops with any static map --------------------------------------------------------------------------------------
def _loop_reference(num, den, g, k, t, u, hold="foh"):
    """The sampled output of ``x' = A x + B (u - g(z))``, ``z = y^(k)``, by solve_ivp (rtol 1e-10) on python-control's
    realisation of ``num/den`` (written apart from the package's loop)."""
    import control

    sys = control.tf2ss(num, den)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    Cz = C @ np.linalg.matrix_power(A, k)
    dt = t[1] - t[0]

    def rhs(tt, x):
        v = np.interp(tt, t, u) if hold == "foh" else u[min(int(tt / dt + 1e-9), u.size - 1)]
        return A @ x + B * (v - g(Cz @ x))

    x, y = np.zeros(A.shape[0]), [0.0]
    for i in range(1, t.size):
        x = solve_ivp(rhs, (t[i - 1], t[i]), x, rtol=1e-10, atol=1e-13, method="DOP853").y[:, -1]
        y.append(C @ x)
    return np.array(y)


#: Loops with a map of each kind: (linear block, map, parameters, feedback).
MAP_LOOPS = {
    "duffing": (([2.0], [1.0, 0.6, 0.0]), hc.Polynomial(3), [4.0, 0.0, 3.0], "output"),
    "tanh friction": (([1.0], [1.0, 0.2, 0.0]), Tanh(), [0.5, 25.0], "velocity"),
    "saturation": (([1.5], [1.0, 1.0, 2.0]), hc.Saturation(), [2.0, 0.4], "output"),
    "dead zone, third order": (([2.0, 4.0], [1.0, 3.0, 3.0, 1.0]), hc.DeadZone(), [3.0, 0.2], "output"),
}


@pytest.fixture(scope="module", params=sorted(MAP_LOOPS))
def map_loop(request):
    (num, den), nl, p, feedback = MAP_LOOPS[request.param]
    t = np.arange(300) * 0.05
    u = np.sin(0.7 * t) + 0.6 * np.sign(np.sin(0.23 * t))
    k = {"output": 0, "velocity": 1}[feedback]
    return request.param, LureModel((num, den), nl, p, feedback=feedback), t, u, _loop_reference(
        num, den, lambda z: nl(np.array([z]), p)[0], k, t, u)


@pytest.mark.parametrize("substeps, bound", [(1, 2e-3), (32, 2e-6)])
def test_map_loops_match_an_ode_solver_to_the_substeps_bound(map_loop, substeps, bound):
    name, model, t, u, ref = map_loop
    m = LureModel((model._num, model._den), model.nonlinearity, model.params, feedback=model.feedback,
                  substeps=substeps)
    assert np.max(np.abs(m.simulate(t, u) - ref)) / np.ptp(ref) <= bound, name


def test_map_loops_are_certified_to_a_millionth_of_the_range_at_sixty_four_substeps(map_loop):
    name, model, t, u, ref = map_loop
    m = LureModel((model._num, model._den), model.nonlinearity, model.params, feedback=model.feedback, substeps=64)
    assert np.max(np.abs(m.simulate(t, u) - ref)) / np.ptp(ref) <= 1e-6, name


def test_an_affine_map_in_the_loop_is_exact():
    import control

    m = LureModel(([2.0], [1.0, 0.6, 0.0]), hc.Polynomial(1), [4.0], feedback="output")
    t = np.arange(200) * 0.05
    u = np.sin(0.9 * t)
    ref = control.forced_response(control.tf([2.0], [1.0, 0.6, 8.0]), t, u).outputs
    np.testing.assert_allclose(m.simulate(t, u), ref, rtol=0, atol=1e-10)


def test_compiled_map_loop_equals_its_python_twin():
    from hammerstein_ctrl.simulate._lure_map import loop_setup, python_run, run

    nl, P = hc.Sigmoid(), np.array([[1.5, 4.0, 0.2], [0.8, 9.0, -0.1]])
    num, den = np.array([[1.0, 2.0], [0.5, 1.0]]), np.array([[1.0, 2.0, 3.0, 1.0], [1.0, 1.0, 2.0, 0.5]])
    u = np.sin(np.arange(400) * 0.07)
    for zoh in (False, True):
        loop = loop_setup(num, den, 0.05, 3, nl, P, 1)
        Y = run(nl, loop, P, np.array([0.1, -0.2]), np.zeros((2, 3)), u, zoh)
        for b in range(2):
            np.testing.assert_allclose(Y[b], python_run(nl, loop, b, P[b], [0.1, -0.2][b], np.zeros(3), u, zoh),
                                       rtol=1e-12, atol=1e-12)


def test_custom_maps_run_in_the_loop():
    cubic = hc.CustomNonlinearity(lambda z, p: p[0] * z**3, 1, ["k3"])
    m = LureModel(([2.0], [1.0, 0.6, 4.0]), cubic, [3.0], feedback="output")
    ref = LureModel(([2.0], [1.0, 0.6, 4.0]), hc.Polynomial(3), [0.0, 0.0, 3.0], feedback="output")
    t = np.arange(300) * 0.05
    u = np.sin(0.7 * t)
    np.testing.assert_allclose(m.simulate(t, u), ref.simulate(t, u), rtol=0, atol=1e-12)


#: Known truths of the issue: (structure, truth, input amplitude, noise level).
LOOP_TRUTHS = {
    "duffing on the output": (LureStructure(LinearStructure(0, 2, monic_numerator=False, fixed={"a0": 0.0}),
                                            hc.Polynomial(3), feedback="output", substeps=8),
                              [2.0, 0.6, 4.0, 0.0, 3.0], 1.5),
    "tanh(25 v) friction on the velocity": (LureStructure(LinearStructure(0, 2, monic_numerator=False,
                                                                          fixed={"a0": 0.0}),
                                                          Tanh(), feedback="velocity", substeps=8),
                                            [1.0, 0.2, 0.5, 25.0], 1.0),
    "saturation in the feedback": (LureStructure(LinearStructure(0, 2, monic_numerator=False),
                                                 hc.Saturation(), feedback="output", substeps=8),
                                   [1.5, 1.0, 0.5, 2.0, 0.4], 2.0),
}


def _loop_found_within_four_standard_errors(case, seeds):
    s, truth, amplitude = LOOP_TRUTHS[case]
    (num, den) = s.linear.coefficients(np.asarray(truth)[:s.linear.n_params])
    t = np.arange(3000) * 0.05
    k = {"output": 0, "velocity": 1}[s.feedback]
    for seed in seeds:
        rng = np.random.default_rng(200 + seed)
        u = amplitude * np.repeat(rng.uniform(-1, 1, 150), 20)
        clean = _loop_reference(num[0], den[0], lambda z: s.nonlinearity(np.array([z]), truth[s.linear.n_params:])[0],
                                k, t, u)
        y = clean + 0.01 * np.std(clean) * rng.standard_normal(t.size)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = hc.identify(hc.IOData(u, y, dt=0.05), s, seed=seed)
        assert r.success, (case, seed, r.message)
        z = np.abs(s.normalize(r.x) - s.normalize(truth)) / np.sqrt(np.diag(r.uncertainty.covariance))
        assert np.all(z < 4.0), (case, seed, dict(zip(s.param_names, np.round(z, 2))))


@pytest.mark.parametrize("case", sorted(LOOP_TRUTHS))
def test_a_loop_known_truth_is_found_without_x0_within_four_standard_errors(case):
    _loop_found_within_four_standard_errors(case, [0])


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(LOOP_TRUTHS))
def test_loop_known_truths_are_found_without_x0_within_four_standard_errors_over_five_seeds(case):
    _loop_found_within_four_standard_errors(case, range(5))


def test_a_map_loop_inside_a_known_controller_is_refused_in_one_line():
    import control

    from hammerstein_ctrl.fit import KnownLoop, KnownLoopCost

    s = LureStructure(LinearStructure(0, 2, monic_numerator=False, fixed={"a0": 0.0}), hc.Polynomial(3),
                      feedback="output")
    loop = KnownLoop(control.ss([], [], [], [[2.0]], dt=0.05), np.ones(100))
    with pytest.raises(ParameterError, match="takes a friction map"):
        loop.simulate(s.model([2.0, 0.6, 4.0, 0.0, 3.0]))
    with pytest.raises(ParameterError, match="takes a friction map"):
        KnownLoopCost(hc.IOData(np.ones(100), np.arange(100.0), dt=0.05), s, loop)


@pytest.mark.parametrize("seed", range(3))
def test_pure_noise_through_a_map_loop_is_not_called_a_model(seed):
    s = LureStructure(LinearStructure(0, 2, monic_numerator=False, fixed={"a0": 0.0}), hc.Polynomial(3),
                      feedback="output")
    rng = np.random.default_rng(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = hc.identify(hc.IOData(rng.standard_normal(2000), rng.standard_normal(2000), dt=0.05), s, seed=seed)
    assert not r.success and "not significantly better" in r.message
