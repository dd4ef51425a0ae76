import matplotlib

matplotlib.use("Agg")

import control  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import scipy.signal  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

import hammerstein_ctrl as hc  # noqa: E402
from hammerstein_ctrl import minimize  # noqa: E402
from hammerstein_ctrl import plotting as plots
from hammerstein_ctrl.plotting._figures import MIN_PEAK_BINS
from hammerstein_ctrl.exceptions import ParameterError  # noqa: E402
from hammerstein_ctrl.paper.settings import eq8_methods, eq8_objective  # noqa: E402
from hammerstein_ctrl.paper.study import run_study  # noqa: E402


def assert_labelled(fig, *, units=True):
    axes = [a for a in fig.axes if a.get_visible() and a.axison]
    assert axes
    for a in axes:
        # a zoom panel sharing its row's y axis is labelled by the panel to its left
        ylabel = a.get_ylabel() or next((b.get_ylabel() for b in a.get_shared_y_axes().get_siblings(a)
                                         if b.get_ylabel()), "")
        assert ylabel, "every axes needs a y label"
        if units:
            assert "(" in ylabel and ")" in ylabel, f"no unit in {ylabel!r}"
    assert any(a.get_title() for a in axes) or fig._suptitle is not None
    assert any(a.get_xlabel() for a in axes)
    assert any(a.get_legend() is not None for a in axes)


def legend_texts(ax):
    return [t.get_text() for t in ax.get_legend().get_texts()]


@pytest.fixture(autouse=True)
def no_pyplot_figures():
    """No helper may leave a figure registered with pyplot (Jupyter would show it a second time)."""
    plt.close("all")
    yield
    assert plt.get_fignums() == [], "a plot helper registered a figure with pyplot"


@pytest.fixture(scope="module")
def trs_study():
    from hammerstein_ctrl import presets

    return run_study(presets.trs(), ["spsa", "nlspsa", "nspsa", "lm"], trials=3, seed=0, executor="serial")


@pytest.fixture(scope="module")
def emps_study(emps_case):
    return run_study(emps_case, ["spsa", "nspsa", "lm"], trials=3, seed=0, executor="serial")


@pytest.fixture(scope="module")
def trs_result():
    from hammerstein_ctrl import presets

    case = presets.trs()
    return hc.identify(case.data, case.structure, method="lm", x0=case.x0, maxfev=300)


@pytest.mark.parametrize("which", ["trs", "emps"])
def test_study_figures_are_titled_labelled_with_units_and_legended(which, request):
    study = request.getfixturevalue(f"{which}_study")
    validation = study.case.validation() if study.case.validation else None
    figs = plots.study_figure_set(study, validation=validation)
    expected = {"time_response", "error", "psd", "bode", "nonlinearity", "convergence", "final_cost", "input"}
    assert expected <= set(figs)
    for name, fig in figs.items():
        assert isinstance(fig, Figure)
        assert_labelled(fig, units=name not in ("convergence", "final_cost", "nonlinearity"))
        if name not in ("convergence", "final_cost", "input"):  # the diverged method is named, not drawn
            titles = fig.axes[0].get_title() + str(fig._suptitle and fig._suptitle.get_text())
            assert "SPSA diverged: not shown" in titles
    tr = figs["time_response"]
    assert tr.axes[0].get_ylabel() == f"{study.case.data.output_name} ({study.case.data.output_unit})"
    assert tr.axes[0].get_xlabel() == "time (s)"
    labels = legend_texts(tr.axes[0])
    assert labels[0] == "measured" and "N-SPSA" in labels and "SPSA" not in labels
    # one error panel per shown method (full record + zoom), sharing the y scale
    shown = len(study.methods) - 1
    err = figs["error"]
    assert len(err.axes) == 2 * shown
    assert len({a.get_ylim() for a in err.axes}) == 1


def test_study_convergence_and_final_cost_keep_diverged_runs_out_of_the_scale(trs_study):
    figs = plots.study_figure_set(trs_study)
    top, lower = figs["convergence"].axes
    labels = legend_texts(top)
    assert "SPSA: all 3 runs diverged (lower panel)" in labels
    assert "N-SPSA: median of 3 runs" in labels
    best_J = max(trs_study.values("nlspsa").max(), trs_study.values("nspsa").max())
    assert top.get_ylim()[1] < 1e4 * best_J  # SPSA's 1e19 does not stretch the axis
    assert lower.get_ylim()[1] > 1e10 and lower.lines  # it is drawn, on its own scale, below
    fc = figs["final_cost"].axes[0]
    ticks = [t.get_text() for t in fc.get_xticklabels()]
    assert ticks[0] == "SPSA\n3/3 diverged" and ticks[2] == "N-SPSA"
    assert fc.get_ylim()[1] < 1e3
    assert "diverged (off scale)" in legend_texts(fc)


def test_study_figures_written_when_every_trial_diverged(tmp_path):
    from hammerstein_ctrl import presets

    study = run_study(presets.trs(), ["spsa"], trials=2, seed=0, executor="serial")
    paths = plots.study_figures(study, tmp_path)
    names = {p.stem for p in paths}
    assert {"time_response", "error", "psd", "nonlinearity", "convergence", "final_cost", "input"} <= names
    assert "bode" not in names  # no linear block to draw
    assert all(p.stat().st_size > 1000 for p in paths)


def lightly_damped_record(zeta=0.03, fn=0.8, dt=0.05, n=20_000, seed=1):
    """Hammerstein record with a known resonance, built with scipy only, plus a strong slow drift."""
    rng = np.random.default_rng(seed)
    wn = 2 * np.pi * fn
    t = dt * np.arange(n)
    u = rng.uniform(-1, 1, n)
    v = np.tanh(1.5 * u)
    _, y, _ = scipy.signal.lsim(([wn**2], [1, 2 * zeta * wn, wn**2]), v, t)
    drift = np.cumsum(rng.normal(0, 0.2, n))  # random walk: the PSD is largest at the DC end
    f_res = fn * np.sqrt(1 - 2 * zeta**2)  # maximum of |H(j 2 pi f)|
    return hc.IOData(u, y + drift + rng.normal(0, 0.01, n), dt=dt, name="resonant", output_unit="m"), f_res, wn


def test_psd_finds_a_known_resonance_within_one_bin_not_the_dc_end():
    data, f_res, wn = lightly_damped_record()
    f, p = scipy.signal.welch(data.y, fs=1 / data.dt, nperseg=1024)
    assert f[np.argmax(p[1:]) + 1] < 0.1  # the naive maximum is the DC end
    model = hc.HammersteinModel(control.tf([wn**2], [1, 2 * 0.03 * wn, wn**2]), hc.Tanh(), [1.0, 1.5])
    peaks = plots.dominant_frequency(data, {"true model": model})
    assert peaks["resolution"] == pytest.approx(1 / (1024 * data.dt))
    assert abs(peaks["measured"] - f_res) <= peaks["resolution"]
    assert abs(peaks["true model"] - f_res) <= peaks["resolution"]
    fig = plots.psd(data, model)
    assert f"resolution {peaks['resolution']:.3g} Hz" in fig.axes[0].get_title()
    assert f"measured (peak {peaks['measured']:.3g} Hz)" in legend_texts(fig.axes[0])


def test_psd_of_the_trs_reconstruction_reports_no_resonance(trs_study):
    # the reconstruction's true H has two real poles: a falling spectrum, no peak (not the first bin)
    peaks = plots.dominant_frequency(trs_study.case.data, trs_study.best_model("nspsa"))
    assert np.isnan(peaks["measured"]) and np.isnan(peaks["hammerstein"])
    assert peaks["fmin"] == pytest.approx(MIN_PEAK_BINS * 10.0 / 1024)


def test_convergence_of_eq8_example_shows_divergence_and_convergence():
    runs = {}
    for label, key in (("SPSA", "spsa"), ("N-SPSA", "nspsa")):
        runs[label] = [minimize(eq8_objective, np.zeros(10), seed=s, maxiter=300,
                                **{**eq8_methods()[key], "options": {**eq8_methods()[key]["options"], "monitor": 300}})
                       for s in range(3)]
    fig = plots.convergence(runs, quantity="estimate")
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    labels = legend_texts(ax)
    assert "N-SPSA: median of 3 runs" in labels
    assert any(lab.startswith("SPSA: all 3 runs diverged") for lab in labels)
    assert fig.axes[-1].get_xlabel() == "function evaluations (NFE)"
    # with nothing but diverged runs there is no scale to protect: they are drawn in the one panel
    only = plots.convergence({"SPSA": runs["SPSA"]}, quantity="fun")
    assert len(only.axes) == 1 and only.axes[0].get_yscale() == "log"
    assert legend_texts(only.axes[0]) == ["SPSA: 3 diverged runs"]
    assert max(line.get_ydata().max() for line in only.axes[0].lines) > 1e10
    with pytest.raises(ParameterError, match="quantity"):
        plots.convergence(runs, quantity="typo")
    with pytest.raises(ParameterError, match="history"):
        plots.convergence({"x": [1.0, 2.0]})


def test_plots_draw_into_a_given_axes_and_never_show(trs_case, monkeypatch):
    monkeypatch.setattr(plt, "show", lambda *a, **k: pytest.fail("plots must not call plt.show()"))
    fig = Figure()
    ax = fig.subplots()
    out = plots.time_response(trs_case.data, {"truth": trs_case.structure.model(trs_case.true_beta)}, ax=ax)
    assert out is fig and len(ax.lines) == 2
    out = plots.nonlinearity({"truth": trs_case.structure.model(trs_case.true_beta)}, (-1, 1), unit_in="V", ax=ax)
    assert out is fig
    with pytest.raises(ParameterError, match="zoom window"):
        plots.time_response(trs_case.data, {}, zoom=(5, 1))


def test_error_response_in_one_axes_draws_the_largest_error_first(trs_case):
    truth = trs_case.structure.model(trs_case.true_beta)
    start = trs_case.structure.model(np.array([-2.0, 0.1, 5.0, -5.0, 0.3]))
    ax = Figure().subplots()
    plots.error_response(trs_case.data, {"truth": truth, "start": start}, ax=ax)
    first, second = ax.lines[:2]
    assert first.get_label().startswith("start") and second.get_label().startswith("truth")
    assert first.get_alpha() < 1


# -- every helper takes a model, a list, a dict and an IdentificationResult --------
HELPERS = {
    "time_response": lambda d, m: plots.time_response(d, m),
    "error_response": lambda d, m: plots.error_response(d, m, zoom=(100, 150)),
    "psd": lambda d, m: plots.psd(d, m),
    "dominant_frequency": lambda d, m: plots.dominant_frequency(d, m),
    "bode": lambda d, m: plots.bode(m),
    "bode_u0": lambda d, m: plots.bode(m, u0=0.2),
    "nonlinearity": lambda d, m: plots.nonlinearity(m, (-1, 1)),
    "compare": lambda d, m: plots.compare(d, m),
}


@pytest.mark.parametrize("kind", ["model", "list", "dict", "result"])
@pytest.mark.parametrize("helper", sorted(HELPERS))
def test_every_helper_accepts_a_model_a_list_a_dict_and_a_result(helper, kind, trs_case, trs_result):
    truth = trs_case.structure.model(trs_case.true_beta)
    models, label = {"model": (truth, "hammerstein"), "list": ([truth, trs_result], "LM*"),
                     "dict": ({"truth": truth}, "truth"), "result": (trs_result, "LM*")}[kind]
    out = HELPERS[helper](trs_case.data, models)
    if helper == "dominant_frequency":
        assert label in out and "measured" in out
        return
    assert isinstance(out, Figure)
    texts = " | ".join(t for a in out.axes if a.get_legend() for t in legend_texts(a))
    assert label in texts


@pytest.mark.parametrize("helper", sorted(HELPERS))
def test_every_helper_rejects_a_wrong_model_type_clearly(helper, trs_case):
    with pytest.raises(ParameterError, match="must be a HammersteinModel or an IdentificationResult"):
        HELPERS[helper](trs_case.data, {"bad": "not a model"})
    with pytest.raises(ParameterError, match="must be a HammersteinModel"):
        HELPERS[helper](trs_case.data, 42)


def test_wrong_record_and_argument_types_are_clear_errors(trs_case, trs_result):
    truth = trs_case.structure.model(trs_case.true_beta)
    with pytest.raises(ParameterError, match="IOData record or an object with u, y and sampling_time"):
        plots.time_response("data.csv", truth)
    with pytest.raises(ParameterError, match="at least one model"):
        plots.bode([])
    with pytest.raises(ParameterError, match="u_range"):
        plots.nonlinearity(truth)
    with pytest.raises(ParameterError, match="bins"):
        plots.input_signal(trs_case.data, bins=1)
    with pytest.raises(ParameterError, match="StudyResult"):
        plots.final_cost(trs_result)
    with pytest.raises(ParameterError, match="shape"):
        plots.time_response(trs_case.data, {"short": np.zeros(3)})


def test_bode_small_signal_gain_is_g_prime_times_h(trs_case):
    b0, a0, a1, d0, d1 = trs_case.true_beta
    model = trs_case.structure.model(trs_case.true_beta)
    u0 = 0.3
    fig = plots.bode({"truth": model}, u0=u0, omega=np.logspace(-4, 1, 50))
    mag = fig.axes[0].lines[0].get_ydata()
    g_prime = d0 * d1 * (1 - np.tanh(d1 * u0) ** 2)  # independent closed form of d/du d0 tanh(d1 u)
    dc = abs(g_prime * b0 / a0)  # H(0) = b0 / a0
    assert mag[0] == pytest.approx(20 * np.log10(dc), abs=0.01)
    plain = plots.bode({"truth": model}, omega=np.logspace(-4, 1, 50)).axes[0].lines[0].get_ydata()
    assert plain[0] == pytest.approx(20 * np.log10(abs(b0 / a0)), abs=0.01)
    assert "g'(0.3)·H(p)" in legend_texts(fig.axes[0])[0]


def test_input_signal_figure_shows_time_histogram_and_psd(trs_case):
    fig = plots.input_signal(trs_case.data, bins=20)
    hist = next(a for a in fig.axes if a.get_title() == "amplitude distribution")
    assert sum(p.get_height() for p in hist.patches) == len(trs_case.data)
    assert {a.get_xlabel() for a in fig.axes} == {"time (s)", "voltage u (V)", "frequency (Hz)"}
    assert_labelled(fig)


def test_compare_reports_fit_percent_against_python_control(trs_case, trs_result):
    other = hc.IOData(trs_case.data.u[:3000], trs_case.data.y[:3000], dt=trs_case.data.dt, name="first half")
    fits = plots.compare_fits([trs_case.data, other], trs_result)
    m = trs_result.model
    for rec in (trs_case.data, other):
        yhat = control.forced_response(m.linear, rec.t, m.g(rec.u)).outputs
        expected = 100 * (1 - np.linalg.norm(rec.y - yhat) / np.linalg.norm(rec.y - rec.y.mean()))
        assert fits[rec.name]["LM*"] == pytest.approx(expected, rel=1e-6)
    fig = trs_result.compare(trs_case.data, other)
    assert len(fig.axes) == 2
    assert f"LM*: fit {fits['first half']['LM*']:.1f} %" in legend_texts(fig.axes[1])


def test_result_plot_shows_fit_residual_and_nonlinearity(trs_result):
    fig = trs_result.plot()
    assert isinstance(fig, Figure) and len(fig.axes) == 3
    assert f"LM*: fit {trs_result.fit_percent:.1f} %" in legend_texts(fig.axes[0])
    resid = fig.axes[1].lines[0].get_ydata()
    assert np.sqrt(np.sum(resid**2)) == pytest.approx(np.sqrt(trs_result.fun), rel=1e-6)
    assert fig.axes[2].get_ylabel() == "g(u) (input of H)"


def test_convergence_and_nonlinearity_take_identification_results(trs_case, trs_result):
    fig = plots.convergence(trs_result)
    assert legend_texts(fig.axes[0]) == ["LM*"]
    line = fig.axes[0].lines[0]
    assert line.get_ydata()[-1] == pytest.approx(trs_result.optimize_result.best_fun)
    fig = plots.convergence([trs_result, trs_result])
    assert legend_texts(fig.axes[0]) == ["LM*: median of 2 runs"]
    fig = plots.nonlinearity(trs_result)  # the input range defaults to the result's record
    u = fig.axes[0].lines[0].get_xdata()
    assert (u[0], u[-1]) == (trs_case.data.u.min(), trs_case.data.u.max())


def test_wiener_blocks_plot_their_output_nonlinearity(trs_case, trs_result):
    import dataclasses

    wiener = hc.WienerModel(control.tf([1], [1, 1]), hc.Saturation(), [2.0, 0.5])
    fig = plots.nonlinearity(wiener, (-1, 1), block="output")
    z = fig.axes[0].lines[0].get_xdata()
    np.testing.assert_allclose(fig.axes[0].lines[0].get_ydata(), wiener.h(z))
    assert fig.axes[0].get_ylabel().startswith("h(z)")
    with pytest.raises(ParameterError, match="has no input nonlinearity"):
        plots.nonlinearity(wiener, (-1, 1))
    with pytest.raises(ParameterError, match="has no middle nonlinearity"):
        plots.nonlinearity(wiener, (-1, 1), block="middle")
    with pytest.raises(ParameterError, match="block must be one of"):
        plots.nonlinearity(wiener, (-1, 1), block="sideways")
    fake = dataclasses.replace(trs_result, model=wiener)  # a result holding a Wiener model
    fig = plots.result_figure(fake)
    assert len(fig.axes) == 3 and fig.axes[2].get_ylabel().startswith("h(z)")
    zr = fig.axes[2].lines[0].get_xdata()
    z_true = control.forced_response(wiener.linear, trs_case.data.t, trs_case.data.u).outputs
    assert (zr[0], zr[-1]) == pytest.approx((float(np.min(z_true)), float(np.max(z_true))), rel=1e-6)
