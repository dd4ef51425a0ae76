"""MIMO block-oriented models: records with several channels, structures, exact simulation, identification."""

import warnings

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl.exceptions import DataError, ParameterError
from hammerstein_ctrl.blocks._mimo import MIMOHammersteinStructure, MIMOHammersteinWienerStructure, MIMOWienerStructure
from hammerstein_ctrl.blocks._mimo_model import MIMOModel
from hammerstein_ctrl.blocks._mimo_sim import observable_realization
from hammerstein_ctrl.fit import MIMOCost

DT, N, SIGMA = 0.05, 3000, 0.01
#: The cross-coupled 2 x 2 plant: row 0 shares 1/(s^2 + 1.2 s + 2), row 1 1/(s^2 + 2.5 s + 1.5).
NUM = [[[1.0, 2.0], [1.0, 0.5]], [[0.6, 1.0], [0.8, 3.0]]]
DEN = [[1.0, 1.2, 2.0], [1.0, 2.5, 1.5]]


def plant() -> ct.TransferFunction:
    return ct.tf(NUM, [[DEN[i]] * 2 for i in range(2)], inputs=["u[0]", "u[1]"], outputs=["y[0]", "y[1]"])


def mimo_statespace(G: ct.TransferFunction) -> ct.StateSpace:
    """python-control's own MIMO state space of ``G``: its SISO elements' realisations appended, the inputs fanned
    out and the outputs summed (python-control converts MIMO transfer functions only with Slycot)."""
    p, m = G.noutputs, G.ninputs
    parts = [ct.ss(G[i, j]) for i in range(p) for j in range(m)]
    app = ct.append(*parts)
    fan = np.zeros((p * m, m))
    total = np.zeros((p, p * m))
    for i in range(p):
        for j in range(m):
            fan[i * m + j, j] = 1.0
            total[i, i * m + j] = 1.0
    return ct.ss(app.A, app.B @ fan, total @ app.C, total @ app.D @ fan)


def steps(rng, n=N, width=(5, 40), level=2.0):
    """A random staircase input (levels held 5-40 samples)."""
    lengths = rng.integers(*width, size=n)
    return np.repeat(rng.uniform(-level, level, size=n), lengths)[:n]


def record(kind: str, seed: int, sigma=SIGMA):
    """A known-truth 2 x 2 record simulated by python-control, with its true beta."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) * DT
    u = np.column_stack([steps(rng), steps(rng)])
    G = mimo_statespace(plant())
    if kind == "hammerstein":
        v = np.column_stack([2.0 * np.tanh(1.5 * u[:, 0]), 0.8 * np.tanh(0.7 * u[:, 1])])
        y = ct.forced_response(G, t, v.T).outputs.T
        # B_0j monic: g_j carries B_0j's leading coefficient
        truth = [2.0, 0.5, 2.0, 1.2, 1.0, 0.6, 3.0, 0.8, 1.5, 2.5, 2.0, 1.5, 0.8, 0.7]
        s = MIMOHammersteinStructure(hc.LinearStructure(1, 2), [hc.Tanh(), hc.Tanh()], n_outputs=2)
    else:
        z = ct.forced_response(G, t, u.T).outputs.T
        y = np.column_stack([2.0 * np.tanh(0.5 * z[:, 0]), 1.5 * np.tanh(0.3 * z[:, 1])])
        # B_i0 monic: row 1's numerators divided by 0.6, h_1's input scale multiplied by it
        truth = [2.0, 0.5, 1.0, 2.0, 1.2, 1.0 / 0.6, 3.0 / 0.6, 0.8 / 0.6, 1.5, 2.5, 2.0, 0.5, 1.5, 0.18]
        s = MIMOWienerStructure(hc.LinearStructure(1, 2), [hc.Tanh(), hc.Tanh()], n_inputs=2)
    y = y + sigma * rng.standard_normal(y.shape)
    return hc.IOData(u, y, dt=DT, name=f"{kind}-{seed}"), s, np.array(truth)


# -- records ---------------------------------------------------------------------------
def test_a_record_takes_named_channels_and_selects_them():
    d = hc.IOData(np.ones((5, 2)), np.arange(15.0).reshape(5, 3), dt=0.1, input_name=["pitch", "yaw"],
                  output_unit=["rad", "rad", "V"])
    assert (d.n_inputs, d.n_outputs, d.is_siso) == (2, 3, False)
    assert d.output_names == ("y[0]", "y[1]", "y[2]") and d.output_units == ("rad", "rad", "V")
    siso = d.channel("yaw", 2)
    assert siso.is_siso and siso.input_name == "yaw" and siso.output_unit == "V"
    assert siso.y.tolist() == [2.0, 5.0, 8.0, 11.0, 14.0]
    assert d[1:3].outputs.shape == (2, 3)
    assert np.allclose(d.detrend().y.mean(axis=0), 0.0)


@pytest.mark.parametrize("u, y, words", [
    (np.ones((2, 500)), np.ones(500), "channels must be columns"),
    (np.ones((2, 50)), np.ones(50), "pass u.T?"),
    (np.ones(50), np.ones((3, 50)), "pass y.T?"),
    (np.ones((50, 2)), np.ones(49), "length mismatch"),
    (np.column_stack([np.ones(50), np.r_[np.ones(49), np.nan]]), np.ones(50), "u[:, 1] contains 1 non-finite"),
])
def test_a_malformed_multichannel_record_is_refused_in_one_line(u, y, words):
    with pytest.raises(DataError, match=None) as err:
        hc.IOData(u, y, dt=0.1)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_channel_labels_must_match_the_channels():
    with pytest.raises(DataError, match="3 label"):
        hc.IOData(np.ones((5, 2)), np.ones(5), dt=0.1, input_name=["a", "b", "c"])
    with pytest.raises(DataError, match="no input channel 'c'"):
        hc.IOData(np.ones((5, 2)), np.ones(5), dt=0.1).channel("c")


def test_a_siso_structure_refuses_a_mimo_record_saying_what_to_do():
    data, _, _ = record("hammerstein", 0)
    with pytest.raises(DataError, match=r"2 inputs and 2 outputs.*data.channel.*MIMO"):
        hc.identify(data, hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh()))


def test_structure_selection_refuses_a_mimo_record():
    data, _, _ = record("hammerstein", 0)
    with pytest.raises(DataError, match="select_structure takes one of each"):
        hc.select_structure(data, hc.candidate_structures([(0, 1)], [hc.Tanh()]))


def test_a_mimo_structure_refuses_a_record_with_other_channels():
    data, s, _ = record("hammerstein", 0)
    with pytest.raises(DataError, match="has 2 input"):
        hc.identify(data.channel(outputs=0), s)


# -- structures ------------------------------------------------------------------------------
def test_the_gain_convention_fixes_one_numerator_per_ambiguity():
    lin = hc.LinearStructure(0, 1)
    ham = MIMOHammersteinStructure(lin, [hc.Tanh()] * 2, n_outputs=2)
    wie = MIMOWienerStructure(lin, [hc.Tanh()] * 2, n_inputs=2)
    hw = MIMOHammersteinWienerStructure(lin, [hc.Saturation()] * 2, [hc.Tanh()] * 2)
    assert [n for n in ham.param_names if n.startswith("b")] == ["b0[1,0]", "b0[1,1]"]       # row 0 monic
    assert [n for n in wie.param_names if n.startswith("b")] == ["b0[0,1]", "b0[1,1]"]       # column 0 monic
    assert [n for n in hw.param_names if n.endswith("[g0]")] == ["limit[g0]"]                # g's gain fixed
    beta = np.arange(1.0, ham.n_params + 1)
    assert np.array_equal(ham.beta(ham.model(beta)), beta)


@pytest.mark.parametrize("make, words", [
    (lambda: MIMOHammersteinStructure(hc.LinearStructure(0, 1), hc.Tanh(), n_outputs=2), "one Nonlinearity per"),
    (lambda: MIMOHammersteinStructure(hc.LinearStructure(0, 1), [hc.Tanh()], n_outputs=1), "several inputs"),
    (lambda: MIMOHammersteinStructure(hc.LinearStructure(0, 1, delay=0.1), [hc.Tanh()] * 2, n_outputs=2),
     "orders of its LinearStructure only"),
    (lambda: MIMOWienerStructure(hc.LinearStructure(0, 1), [hc.Tanh(), "tanh"], n_inputs=2), "must be a Nonlinearity"),
])
def test_a_malformed_mimo_structure_is_refused(make, words):
    with pytest.raises(ParameterError, match=words):
        make()


# -- simulation ----------------------------------------------------------------------------------
@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_the_simulation_equals_python_controls_mimo_response(hold):
    """After the nonlinearities, the sampled simulation is forced_response of python-control's MIMO system (FOH),
    or of its ZOH discretisation."""
    rng = np.random.default_rng(3)
    t = np.arange(800) * DT
    u = np.column_stack([steps(rng, 800), np.sin(0.9 * t)])
    s = MIMOHammersteinStructure(hc.LinearStructure(1, 2), [hc.Tanh(), hc.Tanh()], n_outputs=2)
    _, _, truth = record("hammerstein", 0)
    model = s.model(truth, intersample=hold)
    y = model.simulate(t, u)
    G = mimo_statespace(plant())
    v = model.g(u)
    if hold == "foh":
        ref = ct.forced_response(G, t, v.T).outputs.T
    else:
        ref = ct.forced_response(ct.sample_system(G, DT, "zoh"), t, v.T).outputs.T
    assert np.max(np.abs(y - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_the_exports_are_the_same_linear_block():
    _, s, truth = record("hammerstein", 0)
    model = s.model(truth)
    G, S = model.linear, model.to_ss()
    assert (G.ninputs, G.noutputs, S.nstates) == (2, 2, 4)
    assert S.input_labels == ["u[0]", "u[1]"] and G.output_labels == ["y[0]", "y[1]"]
    for w in (0.1, 1.0, 7.0):
        assert np.allclose(G(1j * w), S(1j * w), rtol=1e-12)
        assert np.allclose(G(1j * w), plant()(1j * w), rtol=1e-12)     # row 0's leading coefficients are 1


def test_the_observable_realisation_matches_each_element():
    A, B, C, D = observable_realization(np.array(NUM)[:, :, :], np.array(DEN))
    S = ct.ss(A, B, C, D)
    G = plant()
    for s_ in (0.3j, 2.0 + 1j, 5.0):
        assert np.allclose(S(s_), G(s_), rtol=1e-12)


def test_the_nonlinear_export_has_named_signals_and_simulates_the_model():
    _, s, truth = record("hammerstein", 0)
    model = s.model(truth, input_names=["pitch", "yaw"], output_names=["a", "b"])
    sys = model.to_iosys()
    assert sys.input_labels == ["pitch", "yaw"] and sys.output_labels == ["a", "b"] and sys.nstates == 4
    t = np.arange(0, 10, 0.01)
    u = np.column_stack([np.sin(0.5 * t), 0.5 * np.cos(0.3 * t)])      # slow: g(u) is nearly linear per step
    ref = ct.input_output_response(sys, t, u.T, solve_ivp_kwargs={"rtol": 1e-10, "atol": 1e-12}).outputs.T
    assert np.max(np.abs(model.simulate(t, u) - ref)) < 1e-5 * np.max(np.abs(ref))


# -- identification ----------------------------------------------------------------------------------
def _identify(data, s, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return hc.identify(data, s, **kwargs)


@pytest.mark.parametrize("kind", ["hammerstein", "wiener"])
def test_a_cross_coupled_plant_is_identified_with_no_x0_within_four_standard_errors(kind):
    """Over four seeds: J at the noise level, every parameter within 4 standard errors of the truth."""
    for seed in range(4):
        data, s, truth = record(kind, seed)
        res = _identify(data, s)
        assert res.success, res.message
        se = np.sqrt(np.diag(res.covariance))
        assert np.all(np.abs(res.x - truth) < 4 * se), (seed, (res.x - truth) / se)
        assert abs(res.fun / (2 * N) / SIGMA**2 - 1) < 0.15
        assert set(res.output_fits) == {"y[0]", "y[1]"} and min(res.output_fits.values()) > 90


def test_the_standard_errors_match_the_spread_over_seeds():
    """The estimates' spread over 12 seeds agrees with the reported standard errors (ratio within 0.6-1.6)."""
    xs, ses = [], []
    for seed in range(12):
        data, s, truth = record("hammerstein", 100 + seed)
        res = _identify(data, s)
        xs.append(res.x)
        ses.append(np.sqrt(np.diag(res.covariance)))
    ratio = np.std(xs, axis=0, ddof=1) / np.mean(ses, axis=0)
    assert np.all((ratio > 0.5) & (ratio < 1.7)), ratio
    assert 0.75 < np.median(ratio) < 1.3


def test_a_hammerstein_wiener_plant_is_identified_with_no_x0():
    rng = np.random.default_rng(7)
    t = np.arange(N) * DT
    u = np.column_stack([steps(rng), steps(rng)])
    s = MIMOHammersteinWienerStructure(hc.LinearStructure(1, 2), [hc.Polynomial(3)] * 2, [hc.Tanh()] * 2)
    num = np.array(NUM) / np.array(NUM)[:, :1, :1]                  # B_i0 monic
    truth = MIMOModel(num, DEN, input_nonlinearities=s.input_nonlinearities,
                      input_params=[[1.0, 0.0, 0.3], [1.0, 0.2, -0.1]], output_nonlinearities=s.output_nonlinearities,
                      output_params=[[2.0, 0.4], [1.0, 0.5]])
    y = truth.simulate(t, u) + SIGMA * rng.standard_normal((N, 2))
    res = _identify(hc.IOData(u, y, dt=DT), s)
    assert res.success, res.message
    assert abs(res.fun / (2 * N) / SIGMA**2 - 1) < 0.15
    se = np.sqrt(np.diag(res.covariance))
    assert np.all(np.abs(res.x - s.beta(truth)) < 4 * se)


def test_an_output_the_inputs_do_not_drive_fails_naming_it():
    data, s, _ = record("hammerstein", 1)
    rng = np.random.default_rng(0)
    y = data.outputs.copy()
    y[:, 1] = rng.standard_normal(N)
    res = _identify(hc.IOData(data.inputs, y, dt=DT, output_name=["pitch", "yaw"]), s)
    assert not res.success
    assert "'yaw'" in res.message


def test_the_mimo_cost_keeps_the_least_squares_protocol():
    data, s, truth = record("wiener", 2)
    cost = MIMOCost(data, s)
    R = cost.residuals_batch(np.vstack([truth, truth * 1.01]))
    assert R.shape == (2, 2 * N)
    assert np.isclose(R[1] @ R[1], cost(truth * 1.01))
    assert np.allclose(cost.split(R[0])[1], data.outputs[:, 1] - s.model(truth).simulate(data)[:, 1])


# -- persistence ----------------------------------------------------------------------------------------
def test_a_mimo_model_and_result_save_and_load_bit_for_bit(tmp_path):
    data, s, _ = record("wiener", 5)
    res = _identify(data, s)
    hc.save_result(res, tmp_path / "r.json")
    back = hc.load_result(tmp_path / "r.json")
    assert back.x.tolist() == res.x.tolist() and back.structure.param_names == s.param_names
    assert type(back.structure) is type(s) and back.output_fits == res.output_fits
    assert np.array_equal(back.covariance, res.covariance)
    assert np.array_equal(back.model.simulate(data), res.model.simulate(data))
    hc.save_model(res.model, tmp_path / "m.json")
    model = hc.load_model(tmp_path / "m.json")
    assert model.output_names == ("y[0]", "y[1]") and model.kind == "mimo-wiener"
    assert np.array_equal(model.numerators, res.model.numerators)


@pytest.mark.parametrize("edit, words", [
    (lambda m: m.update(kind="mimo-nothing"), "unknown structure"),
    (lambda m: m.update(input_nonlinearities=[]), "must be null"),
    (lambda m: m["linear"].update(num=[[["a"]]]), "must hold numbers"),
    (lambda m: m.update(outputs="y"), "list of channel names"),
    (lambda m: m.update(offset=[0.0, "nan"]), "offset"),
])
def test_a_corrupt_mimo_model_file_is_refused_naming_the_field(tmp_path, edit, words):
    import json

    _, s, truth = record("wiener", 0)
    hc.save_model(s.model(truth), tmp_path / "m.json")
    obj = json.loads((tmp_path / "m.json").read_text())
    edit(obj["model"])
    (tmp_path / "m.json").write_text(json.dumps(obj))
    with pytest.raises(hc.HammersteinError, match=words):
        hc.load_model(tmp_path / "m.json")


# -- results ----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def fitted():
    data, s, truth = record("hammerstein", 0)
    return data, truth, _identify(data, s)


def test_validation_reports_each_output(fitted):
    data, _, res = fitted
    report = res.validate(data)
    assert set(report["outputs"]) == {"y[0]", "y[1]"}
    assert report["fit_percent"] == pytest.approx(res.fit_percent)
    assert report["outputs"]["y[1]"]["fit_percent"] == pytest.approx(res.output_fits["y[1]"])
    with pytest.raises(ParameterError, match="from rest"):
        res.validate(data, initial_state="estimate")


def test_characteristics_give_each_rows_poles_and_each_elements_gain_with_uncertainty(fitted):
    _, truth, res = fitted
    table = {q: (v, se) for q, v, se, _, _ in res.characteristics()}
    true_poles = np.roots(DEN[1])                                  # row 1: real poles -0.75 +- ...
    assert np.allclose(sorted(v for q, (v, _) in table.items() if q.startswith("pole") and "[y[1]]" in q),
                       sorted(true_poles.real), atol=4 * max(se for q, (_, se) in table.items() if "[y[1]]" in q))
    gain = table["DC gain [y[1] <- u[0]]"]
    assert abs(gain[0] - 1.0 / 1.5) < 4 * gain[1]                 # B_10(0)/F_1(0) = 1.0 / 1.5
    prop = res.propagate(lambda m: [m.linear.dcgain()[1, 0]])
    assert prop.stderr[0] == pytest.approx(gain[1], rel=0.02)


def test_the_figures_show_every_channel(fitted):
    import matplotlib.pyplot as plt

    data, _, res = fitted
    fig = res.plot()
    titles = [a.get_title() for a in fig.axes]
    assert sum(t.startswith("y[") for t in titles) == 2 and sum(t.startswith("g") for t in titles) == 2
    fig2 = res.compare()
    assert len(fig2.axes) == 2 and "fit" in fig2.axes[1].get_legend_handles_labels()[1][1]
    plt.close("all")


def test_residual_analysis_takes_an_output_and_an_input(fitted):
    data, _, res = fitted
    a = res.residual_analysis(output="y[1]", input=1)
    assert "y[1] against u[1]" in a.name and a.passed


# -- command line ------------------------------------------------------------------------------------------
def test_the_command_line_identifies_a_mimo_record_from_named_columns(tmp_path, capsys):
    from hammerstein_ctrl.cli import main

    data, _, truth = record("hammerstein", 3)
    path = tmp_path / "twin.csv"
    columns = np.column_stack([data.t, data.inputs, data.outputs])
    np.savetxt(path, columns, delimiter=",", header="t,v_pitch,v_yaw,pitch,yaw", comments="", fmt="%.17g")
    code = main(["identify", "--data", str(path), "--inputs", "v_pitch", "v_yaw", "--outputs", "pitch", "yaw",
                 "--orders", "1", "2", "--nonlinearity", "tanh", "--out", str(tmp_path / "r.json"),
                 "--plot", str(tmp_path / "f.png")])
    out = capsys.readouterr().out
    assert code == 0, out
    res = hc.load_result(tmp_path / "r.json")
    assert set(res.output_fits) == {"pitch", "yaw"} and res.model.input_names == ("v_pitch", "v_yaw")
    se = np.sqrt(np.diag(res.covariance))
    assert np.all(np.abs(res.x - truth) < 4 * se)
    assert (tmp_path / "f.png").stat().st_size > 0


@pytest.mark.parametrize("extra, words", [
    (["--fix", "a0=0"], "--fix cannot be used with a record of 2 inputs"),
    (["--initial-state", "estimate"], "--initial-state estimate cannot be used"),
    ([], "needs --orders"),
])
def test_the_command_line_refuses_what_a_mimo_fit_cannot_take_in_one_line(tmp_path, capsys, extra, words):
    from hammerstein_ctrl.cli import main

    path = tmp_path / "twin.csv"
    path.write_text("t,a,b,c,d\n" + "\n".join(f"{k * 0.1},{k % 3},{k % 5},{k % 7},{k % 2}" for k in range(50)))
    args = ["identify", "--data", str(path), "--inputs", "a", "b", "--outputs", "c", "d"]
    if words != "needs --orders":
        args += ["--orders", "0", "1", "--nonlinearity", "tanh"]
    code = main(args + extra)
    err = capsys.readouterr().err
    assert code == 2 and words in err and err.count("\n") == 1


# -- speed (wall-clock: `make bench` runs these, never `make test`) ------------------------------------------
def test_the_speed_report_compares_mimo_and_siso_on_one_record_length():
    from speed import format_mimo_speed, mimo_speed

    r = mimo_speed(2000, batch=3, pairs=1, number=2)
    assert set(r) == {"n_samples", "batch", "single", "batched"} and r["single"]["mimo_s"] > 0
    assert "2 x 2" in format_mimo_speed(r)


@pytest.mark.timing
def test_a_2x2_evaluation_costs_at_most_four_siso_ones():
    from speed import mimo_speed

    r = mimo_speed(24841)
    assert r["single"]["ratio"] <= 4.0 and r["batched"]["ratio"] <= 4.0, r


# -- dead time per input ----------------------------------------------------------------------------------
TAUS = [0.37, 0.82]


def delayed_record(seed: int, hold: str):
    """The 2 x 2 Hammerstein plant with dead times 0.37 s and 0.82 s on its inputs, dt 0.1 s."""
    from hammerstein_ctrl.simulate._delay import delayed_response

    rng = np.random.default_rng(seed)
    dt, n = 0.1, 3000
    u = np.column_stack([steps(rng, n), steps(rng, n)])
    v = np.column_stack([2.0 * np.tanh(1.5 * u[:, 0]), 0.8 * np.tanh(0.7 * u[:, 1])])
    y = np.column_stack([sum(delayed_response(NUM[i][j], DEN[i], v[:, j], dt, TAUS[j], intersample=hold)
                             for j in range(2)) for i in range(2)])
    y += SIGMA * rng.standard_normal(y.shape)
    s = MIMOHammersteinStructure(hc.LinearStructure(1, 2), [hc.Tanh(), hc.Tanh()], n_outputs=2, delay="estimate")
    _, _, truth = record("hammerstein", 0)
    return hc.IOData(u, y, dt=dt, intersample=hold), s, np.concatenate([truth, TAUS])


def test_dead_times_per_input_simulate_as_python_control_on_a_fine_grid():
    """FOH: the inputs delayed exactly (0.37 s and 0.82 s, not multiples of dt = 0.1 s) and simulated by
    python-control's MIMO system on a 50x finer grid, on which the delayed signals are exactly linear (before
    the record the samples are zero, joined to the first one by the same hold)."""
    data, s, truth = delayed_record(0, "foh")
    model = s.model(truth)
    y = model.simulate(data)[:400]
    v = np.vstack([np.zeros((1, 2)), model.g(data.inputs)[:401]])
    t = np.r_[-data.dt, data.t[:401]]
    fine = np.linspace(0.0, t[-1], 50 * 400 + 1)
    w = np.column_stack([np.interp(fine - tau, t, v[:, j], left=0.0) for j, tau in enumerate(TAUS)])
    ref = ct.forced_response(mimo_statespace(plant()), fine, w.T).outputs.T[::50][:400]
    assert np.max(np.abs(y - ref)) <= 1e-9 * np.max(np.abs(ref))


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_dead_times_per_input_are_estimated_with_no_x0(hold):
    """Both dead times within 0.1 dt of the truth, every parameter within 4 standard errors, over two seeds."""
    for seed in range(2):
        data, s, truth = delayed_record(seed, hold)
        res = _identify(data, s)
        assert res.success, res.message
        delays = [res.params["delay[u0]"], res.params["delay[u1]"]]
        assert np.allclose(delays, TAUS, atol=0.01), delays
        se = np.sqrt(np.diag(res.covariance))
        assert np.all(np.abs(res.x - truth) < 4 * se), (res.x - truth) / se


def test_a_model_with_dead_times_saves_loads_and_exports_through_pade(tmp_path):
    data, s, truth = delayed_record(0, "foh")
    model = s.model(truth)
    hc.save_model(model, tmp_path / "m.json")
    back = hc.load_model(tmp_path / "m.json")
    assert back.delays.tolist() == TAUS and np.array_equal(back.simulate(data), model.simulate(data))
    sys = model.to_iosys()
    assert sys.nstates == 4 + 2 * 6                      # the rows' states and a 6th-order Pade per input
    t = np.arange(0, 20, 0.01)
    u = np.column_stack([np.sin(0.3 * t), 0.5 * np.sin(0.2 * t)])    # smooth from 0: what a Pade form follows
    ref = ct.input_output_response(sys, t, u.T, solve_ivp_kwargs={"rtol": 1e-10, "atol": 1e-12}).outputs.T
    assert np.max(np.abs(model.simulate(t, u) - ref)) < 1e-4 * np.max(np.abs(ref))
    saved = hc.io.result_to_dict(_identify(data, s))
    assert saved["structure"]["delays"] == ["estimate", "estimate"]


def test_a_negative_or_mistyped_dead_time_is_refused():
    with pytest.raises(ParameterError, match="delay must be a finite number >= 0"):
        MIMOHammersteinStructure(hc.LinearStructure(0, 1), [hc.Tanh()] * 2, n_outputs=2, delay=[0.1, -1.0])
    with pytest.raises(ParameterError, match="3 values for 2 inputs"):
        MIMOHammersteinStructure(hc.LinearStructure(0, 1), [hc.Tanh()] * 2, n_outputs=2, delay=[0.1, 0.2, 0.3])


# -- the SISO tools ----------------------------------------------------------------------------------------
def test_an_element_is_the_siso_model_from_one_input_to_one_output():
    data, s, truth = record("hammerstein", 0)
    model = s.model(truth, input_names=["a", "b"], output_names=["p", "q"])
    e = model.element("q", "a")
    siso = data.channel(0, 1)
    alone = hc.IOData(siso.u, siso.y, dt=DT)
    U = np.column_stack([data.inputs[:, 0], np.zeros(N)])          # the other input held at zero
    assert np.allclose(e.simulate(alone), model.simulate(data.t, U)[:, 1], rtol=1e-12, atol=1e-12)
    pid = hc.design.tune_pid(model.element(0, 0))
    assert np.isfinite(pid.kp)


@pytest.mark.parametrize("call", [
    lambda m, d: hc.design.tune_pid(m),
    lambda m, d: hc.plotting.bode(m),
    lambda m, d: hc.plotting.time_response(d, m),
    lambda m, d: hc.plotting.psd(d),
])
def test_the_siso_tools_refuse_a_mimo_model_or_record_naming_the_way_out(call):
    data, s, truth = record("hammerstein", 0)
    with pytest.raises(hc.HammersteinError, match=r"element\(output, input\)|data.channel"):
        call(s.model(truth), data)


def test_estimated_dead_times_of_a_plant_without_any_come_out_at_zero():
    """The boundary: dead times of 0 estimated as 0 (within 0.1 dt), the blocks as well as without the option."""
    data, s, truth = record("hammerstein", 2)
    res = _identify(data, s.with_delay("estimate"))
    assert res.success, res.message
    assert res.params["delay[u0]"] < 0.1 * DT and res.params["delay[u1]"] < 0.1 * DT
    plain = _identify(data, s)
    assert res.fun <= plain.fun * 1.0001
    se = np.sqrt(np.diag(plain.covariance))
    assert np.all(np.abs(res.x[:-2] - truth) < 4 * se)


# -- hostile inputs ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("make, words", [
    (lambda: MIMOModel(np.zeros((0, 2, 1)), np.zeros((0, 2))), "p, m >= 1"),
    (lambda: MIMOModel([[[1.0]], [[1.0]]], [[1.0, 1.0], [1.0, 2.0]], offset=[1, 2, 3]), "offset must be 2"),
    (lambda: MIMOModel([[[1.0]], [[1.0]]], [[1.0, 1.0], [1.0, 2.0]], offset=[np.nan, 0]), "offset must be 2"),
    (lambda: MIMOModel([[[1.0], [1.0]]], [[1.0, 1.0]], input_names=["a", "a"]), "2 distinct names"),
    (lambda: MIMOModel([[[1.0], [1.0]]], [[1.0, 1.0]], input_names="ab"), "list of 2 non-empty strings"),
    (lambda: MIMOModel([[[1.0], [1.0]]], [[1.0, 1.0]], input_names=[1, 2]), "list of 2 non-empty strings"),
    (lambda: MIMOModel([[[1.0], [1.0]]], np.zeros((1, 0))), "nf >= 1"),
    (lambda: MIMOModel([[[1.0], [1.0]]], [[1.0, 1.0]], input_nonlinearities=[hc.Tanh()] * 2, input_params=5),
     "one parameter vector per input"),
    (lambda: MIMOHammersteinStructure(hc.LinearStructure(0, 1), 5, n_outputs=2), "must be a list"),
    (lambda: MIMOHammersteinStructure(hc.LinearStructure(0, 1), [hc.Tanh()] * 2, n_outputs=10**9), "exceeds 64"),
    (lambda: MIMOHammersteinStructure(hc.LinearStructure(0, 1), [hc.Tanh()] * 2, n_outputs=2, delay=1 + 2j),
     "delay must be"),
    (lambda: MIMOHammersteinStructure(hc.LinearStructure(0, 1), [hc.Tanh()] * 2, n_outputs=2, offset="no"),
     "offset must be True or False"),
    (lambda: hc.mimo_structure(hc.LinearStructure(0, 1), [hc.Tanh()] * 2, [hc.Tanh()] * 2, n_outputs=3),
     "n_outputs = 3"),
    (lambda: hc.IOData(np.ones((50, 0)), np.ones(50), dt=0.1), "u is empty"),
    (lambda: hc.IOData([[1, 2], [3]], [1, 2], dt=0.1), "rows of different lengths"),
    (lambda: hc.IOData(np.ones((5, 2)), np.ones(5), dt=0.1, input_name=5), "string or a list of strings"),
    (lambda: hc.IOData(np.ones((5, 2)), np.ones(5), dt=0.1).channel(1.0), "neither a name"),
    (lambda: hc.IOData(np.ones((2, 50)), np.ones((2, 50)), dt=0.1), "pass u.T and y.T"),
])
def test_malformed_mimo_arguments_are_refused_in_one_line(make, words):
    with pytest.raises(hc.HammersteinError, match=None) as err:
        make()
    assert words in str(err.value) and "\n" not in str(err.value)


def test_a_record_is_matched_to_the_model_by_channel_name():
    data, s, truth = record("hammerstein", 0)
    model = s.model(truth, input_names=["a", "b"], output_names=["p", "q"])
    named = hc.IOData(data.inputs, data.outputs, dt=DT, input_name=["a", "b"], output_name=["p", "q"])
    swapped = hc.IOData(data.inputs[:, ::-1], data.outputs[:, ::-1], dt=DT, input_name=["b", "a"],
                        output_name=["q", "p"])
    assert np.array_equal(model.simulate(swapped), model.simulate(named)[:, ::-1])
    other = hc.IOData(data.inputs, data.outputs, dt=DT, input_name=["x", "z"], output_name=["p", "q"])
    with pytest.raises(DataError, match=r"names its inputs \['x', 'z'\], the model \['a', 'b'\]"):
        model.simulate(other)
    with pytest.raises(DataError, match="has 1 output"):
        model.simulate(named.channel(outputs="p"))
    with pytest.warns(hc.ChannelWarning, match="matched by position"):           # default names: by position
        assert np.array_equal(model.simulate(data), model.simulate(named))


def test_a_plant_without_the_reference_element_is_refused_saying_which_channels_to_reorder():
    rng = np.random.default_rng(0)
    t = np.arange(2000) * 0.02
    u = np.repeat(rng.uniform(-2, 2, (200, 2)), 10, axis=0)
    diagonal = MIMOModel([[[1.0], [0.0]], [[0.0], [1.0]]], [[1.0, 2.0], [1.0, 3.0]],
                         input_nonlinearities=[hc.Tanh()] * 2, input_params=[[1, 1], [1, 1]])
    y = diagonal.simulate(t, u) + 0.01 * rng.standard_normal((2000, 2))
    s = MIMOHammersteinStructure(hc.LinearStructure(0, 1), [hc.Tanh()] * 2, n_outputs=2)
    with pytest.raises(ParameterError, match="input 1 hardly acts on output 0.*reorder the channels"):
        hc.identify(hc.IOData(u, y, dt=0.02), s)


def test_auto_takes_the_block_parameters_alone_as_x0_with_offsets():
    data, s, truth = record("hammerstein", 0)
    shifted = hc.IOData(data.inputs, data.outputs + [0.5, -0.2], dt=DT)
    res = _identify(shifted, s.with_options(offset=True), x0=truth)
    assert res.success and np.allclose(res.x[-2:], [0.5, -0.2], atol=0.01)


def test_a_model_without_the_structures_conventions_has_no_beta():
    _, s, truth = record("hammerstein", 0)
    model = s.model(truth)
    scaled = MIMOModel(model.numerators * 2, model.denominators * 2, input_nonlinearities=model.input_nonlinearities,
                       input_params=model.input_params)
    assert np.allclose(s.beta(scaled), truth)                        # a common factor of a row is the same model
    gained = MIMOModel(model.numerators * 2, model.denominators, input_nonlinearities=model.input_nonlinearities,
                       input_params=model.input_params)
    with pytest.raises(ParameterError, match=r"numerator \(0, 0\) has leading coefficient 2"):
        s.beta(gained)
    other = MIMOModel(model.numerators, model.denominators, input_nonlinearities=[hc.Saturation()] * 2,
                      input_params=[[1.0, 1.0], [1.0, 1.0]])
    with pytest.raises(ParameterError, match="input nonlinearities"):
        s.beta(other)
    offset = MIMOModel(model.numerators, model.denominators, input_nonlinearities=model.input_nonlinearities,
                       input_params=model.input_params, offset=[0.1, 0.0])
    with pytest.raises(ParameterError, match="offset=True"):
        s.beta(offset)
    with pytest.raises(ParameterError, match="fixes it to 0.2 s"):
        s.with_delay(0.2).beta(model)


def test_an_integrating_output_is_marginal_not_unstable():
    """Row 1 = 1/(p^2 + 2.5 p): its pole at the origin comes out within its uncertainty of the axis, on either
    side, over six seeds; never a failure."""
    for seed in range(6):
        rng = np.random.default_rng(seed)
        t = np.arange(N) * DT
        u = np.column_stack([steps(rng), steps(rng)])
        u -= u.mean(axis=0)
        s = MIMOHammersteinStructure(hc.LinearStructure(1, 2), [hc.Tanh(), hc.Tanh()], n_outputs=2)
        _, _, truth = record("hammerstein", 0)
        x = truth.copy()
        x[s.param_names.index("a0[1]")] = 0.0
        y = s.model(x).simulate(t, u) + SIGMA * rng.standard_normal((N, 2))
        res = _identify(hc.IOData(u, y, dt=DT), s)
        assert res.success, (seed, res.message)
        assert not any(v.code == "unstable" for v in res.verdicts)


def test_outputs_with_different_noise_levels_are_weighted_and_their_standard_errors_hold():
    """Output noise 0.002 and 0.1: auto weighs the outputs by the inverse of their noise levels, and the
    standard errors (each output's own noise model) match the estimates' spread over 12 seeds."""
    xs, ses = [], []
    for seed in range(12):
        data, s, truth = record("hammerstein", 300 + seed, sigma=0.0)
        y = data.outputs + np.random.default_rng(seed).standard_normal(data.outputs.shape) * [0.002, 0.1]
        res = _identify(hc.IOData(data.inputs, y, dt=DT), s)
        assert res.success and "weighted by the inverse of their noise levels" in res.message, res.message
        w = res.optimize_result.output_weights
        assert 35 < w[0] / w[1] < 65                  # 0.1 / 0.002, from the first fit's residuals
        xs.append(res.x)
        ses.append(np.sqrt(np.diag(res.covariance)))
    ratio = np.std(xs, axis=0, ddof=1) / np.mean(ses, axis=0)
    assert np.all((ratio > 0.5) & (ratio < 1.7)), ratio
    assert 0.75 < np.median(ratio) < 1.3


def test_channels_matched_by_position_say_so():
    """A model with default channel names meets a record with named channels: matched by position, with a
    warning naming each pair; the same names on both sides match by name, silently."""
    model = hc.MIMOModel([[[1.0], [2.0]]], [[1.0, 1.0]])
    t = np.arange(200) * 0.05
    U = np.column_stack([np.sin(t), np.cos(t)])
    named = hc.IOData(U, np.zeros(200), dt=0.05, input_name=["valve_b", "valve_a"])
    with pytest.warns(hc.ChannelWarning, match=r"matched by position \(u\[0\] = 'valve_b', u\[1\] = 'valve_a'\)"):
        model.simulate(named)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.simulate(hc.IOData(U, np.zeros(200), dt=0.05))


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_an_output_in_other_units_fits_as_well(scale):
    """One output in mm (or km) beside one in m: the start and the search compare outputs in their own units, so
    the fit is the same as with both in m (each output's fit % to 0.01)."""
    data, s, _ = record("hammerstein", 0)
    base = hc.identify(data, s, seed=0)
    scaled = hc.IOData(data.inputs, data.outputs * np.array([1.0, scale]), dt=data.dt)
    res = hc.identify(scaled, s, seed=0)
    assert base.success and res.success, res.message
    for name in base.output_fits:
        assert res.output_fits[name] == pytest.approx(base.output_fits[name], abs=0.01)


def _staircase(rng, n):
    lengths = rng.integers(5, 40, size=n)
    return np.repeat(rng.uniform(-2.0, 2.0, size=n), lengths)[:n]


def test_a_reference_numerator_of_too_high_a_degree_is_named_not_blamed_on_the_budget():
    """Row 0 from input 0 is 1/(p^2 + 1.2 p + 2): with num_order 1 its monic numerator p + b0 can only mimic a
    constant by b0 -> infinity, the gain draining into g_0.  The failure says so and does not ask for maxfev."""
    rng = np.random.default_rng(5)
    t = np.arange(3000) * 0.05
    u = np.column_stack([_staircase(rng, 3000), _staircase(rng, 3000)])
    v = np.column_stack([2.0 * np.tanh(1.5 * u[:, 0]), 0.8 * np.tanh(0.7 * u[:, 1])])
    G = [[ct.tf([1.0], [1.0, 1.2, 2.0]), ct.tf([0.5], [1.0, 1.2, 2.0])],
         [ct.tf([0.8], [1.0, 1.5]), ct.tf([1.2], [1.0, 1.5])]]
    y = np.column_stack([sum(ct.forced_response(G[i][j], t, v[:, j]).outputs for j in range(2)) for i in range(2)])
    data = hc.IOData(u, y + 0.01 * rng.standard_normal(y.shape), dt=0.05)
    s = MIMOHammersteinStructure(hc.LinearStructure(1, 2), [hc.Tanh(), hc.Tanh()], n_outputs=2)
    res = _identify(data, s)
    assert not res.success and res.message.startswith("the monic numerator from 'u[0]' to 'y[0]' has a zero at")
    assert "lower num_order" in res.message and "maxfev" not in res.message.split("[")[0]
    ok = _identify(data, MIMOHammersteinStructure(hc.LinearStructure(0, 2), [hc.Tanh(), hc.Tanh()], n_outputs=2))
    assert not any(v.code == "monic-drift" for v in ok.verdicts)
