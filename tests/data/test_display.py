"""What users pass in (records, models, results, arrays) normalised, and how results show: HTML reprs, DataFrames,
progress bars, TimeResponseData."""

import sys
from html import escape as html_escape

import control
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl.data import _display as display
from hammerstein_ctrl.data import _inputs as inputs
from hammerstein_ctrl.exceptions import DataError, ParameterError
from hammerstein_ctrl.paper.study import run_study


class Input_output_data:
    """Stand-in with the layout of nonlinear_benchmarks' record (no download)."""

    def __init__(self, u, y, sampling_time=None, name=None):
        self.u, self.y, self.sampling_time, self.name = u, y, sampling_time, name

    def __iter__(self):
        return iter((self.u, self.y))


@pytest.fixture(scope="module")
def result():
    case = hc.presets.trs()
    return hc.identify(case.data, case.structure, method="lm", x0=case.x0, maxfev=300)


@pytest.fixture(scope="module")
def study():
    return run_study(hc.presets.trs(), ["spsa", "nlspsa", "nspsa"], trials=3, seed=0, executor="serial")


# -- as_models / as_iodata -------------------------------------------------------
def test_as_models_normalises_every_accepted_form(trs_case, result):
    m = trs_case.structure.model(trs_case.true_beta)
    assert inputs.as_models(m) == {"hammerstein": m}
    assert inputs.as_models(result) == {"LM*": result.model}
    assert inputs.as_models([m, result, result]) == {"model 1": m, "LM*": result.model, "LM* (2)": result.model}
    assert inputs.as_models({"a": result}) == {"a": result.model}
    assert inputs.as_models(None, allow_empty=True) == {}
    y = np.arange(5.0)
    np.testing.assert_array_equal(inputs.as_models({"sim": y}, arrays=True)["sim"], y)
    assert list(inputs.as_models(y, arrays=True)) == ["simulated"]
    assert list(inputs.as_models([0.0, 1.0], arrays=True)) == ["simulated"]
    assert list(inputs.as_models([y, y], arrays=True)) == ["simulated 1", "simulated 2"]
    tf = control.tf([1], [1, 1])
    assert inputs.as_models([tf], systems=True, need=("linear",)) == {"model 1": tf}


@pytest.mark.parametrize("bad, match", [
    ("model", "must be a HammersteinModel or an IdentificationResult, got str"),
    ({"x": 3.0}, "model 'x' must be"),
    ([], "at least one model"),
    (None, "at least one model"),
])
def test_as_models_rejects_clearly(bad, match):
    with pytest.raises(ParameterError, match=match):
        inputs.as_models(bad)


def test_as_models_checks_what_a_helper_needs():
    tf = control.tf([1], [1, 1])
    with pytest.raises(ParameterError, match="got TransferFunction"):
        inputs.as_models(tf, need=("g",))


def test_benchmark_record_becomes_iodata_and_works_everywhere(trs_case):
    d = trs_case.data
    rec = Input_output_data(d.u.reshape(-1, 1), d.y, sampling_time=d.dt, name="train TRS")
    data = inputs.as_iodata(rec)
    assert isinstance(data, hc.IOData) and data.name == "train TRS" and data.dt == d.dt
    np.testing.assert_array_equal(data.u, d.u)
    np.testing.assert_array_equal(data.t, d.t)
    assert inputs.as_iodata(d) is d
    model = trs_case.structure.model(trs_case.true_beta)
    from hammerstein_ctrl import plotting as plots

    fits = plots.compare_fits(rec, model)
    assert fits["train TRS"]["hammerstein"] == pytest.approx(hc.fit_percent(d.y, model.simulate(d)))
    resp = model.response(rec)
    np.testing.assert_allclose(resp.outputs, model.simulate(d))


def test_benchmark_record_errors_are_clear():
    with pytest.raises(DataError, match="no sampling_time"):
        inputs.as_iodata(Input_output_data([0, 1, 2], [0, 1, 2]))
    with pytest.raises(ParameterError, match="got a tuple of 2"):
        inputs.as_iodata((Input_output_data([0, 1], [0, 1], 0.1), Input_output_data([0, 1], [0, 1], 0.1)))
    with pytest.raises(ParameterError, match="u, y and sampling_time"):
        inputs.as_iodata(np.zeros((10, 2)))
    with pytest.raises(DataError, match="length mismatch"):
        inputs.as_iodata(Input_output_data([0, 1, 2], [0, 1], sampling_time=0.1))


# -- progress --------------------------------------------------------------------
def test_progress_is_off_under_pytest_and_can_be_forced(monkeypatch):
    assert not display.progress_enabled()  # PYTEST_CURRENT_TEST is set
    bar = display.progress(range(3), desc="x")
    assert bar.disable and list(bar) == [0, 1, 2]
    monkeypatch.setenv(display.PROGRESS_ENV, "1")
    assert display.progress_enabled()
    monkeypatch.setenv(display.PROGRESS_ENV, "0")
    monkeypatch.delenv("PYTEST_CURRENT_TEST")
    assert not display.progress_enabled()
    monkeypatch.delenv(display.PROGRESS_ENV)
    monkeypatch.setattr(sys, "stderr", open("/dev/null", "w"))  # a pipe or file, not a terminal
    assert not display.progress_enabled()
    with display.progress(5, enabled=True, file=sys.stderr) as bar:
        assert not bar.disable and bar.total == 5
        bar.update(5)
        assert bar.n == 5


# -- TimeResponseData -------------------------------------------------------------
def test_response_matches_python_control_forced_response(trs_case):
    model = trs_case.structure.model(trs_case.true_beta)
    data = trs_case.data
    resp = model.response(data)
    assert isinstance(resp, control.TimeResponseData)
    expected = control.forced_response(model.linear, data.t, model.g(data.u)).outputs
    np.testing.assert_allclose(resp.outputs, expected, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(resp.inputs, data.u)
    assert resp.input_labels == ["voltage u (V)"] and resp.output_labels == ["pitch y (rad)"]
    t = np.arange(0, 5, 0.1)
    r2 = model.response(t, np.ones_like(t))
    np.testing.assert_allclose(r2.outputs, model.simulate(t, np.ones_like(t)))
    assert r2.output_labels == ["y"]
    with pytest.raises(ParameterError, match="needs the input u"):
        model.response(t)


def test_response_plots_with_python_control():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.close("all")  # python-control draws into pyplot's current figure
    model = hc.HammersteinModel(control.tf([1], [1, 1]), hc.Tanh(), [1.0, 1.0])
    t = np.linspace(0, 5, 51)
    cplt = model.response(t, np.ones_like(t)).plot()
    assert len(cplt.axes.ravel()) == 2  # input and output panels
    plt.close("all")


# -- HTML and DataFrames --------------------------------------------------------------
def test_result_html_lists_parameters_fit_and_status(result):
    html = result._repr_html_()
    for name, value in result.params.items():
        assert f"<td>{name}</td><td>{value:.6g}</td>" in html
    assert f"fit {result.fit_percent:.2f} %" in html and f"NFE = {result.nfev}" in html
    status = "success" if result.success else "FAILED"  # maxfev=300 stops LM early: an honest failure
    assert f"<b style='color:{'green' if result.success else 'firebrick'}'>{status}</b>" in html
    assert html_escape(result.message) in html and "LM*" in html


def test_result_html_and_frame_show_the_results_standard_errors_and_intervals(result):
    se, intervals = result.stderr, result.conf_int()
    html = result._repr_html_()
    assert "std. error" in html and "95 % interval" in html
    first = result.structure.param_names[0]
    assert f"<td>{se[first]:.6g}</td>" in html
    assert f"[{intervals[first][0]:.6g}, {intervals[first][1]:.6g}]" in html
    frame = result.to_frame()
    assert list(frame.index) == list(result.structure.param_names)
    np.testing.assert_array_equal(frame["value"].to_numpy(), result.x)
    np.testing.assert_allclose(frame["stderr"].to_numpy(), list(se.values()))
    np.testing.assert_allclose(frame[["low", "high"]].to_numpy(), list(intervals.values()))
    assert frame.attrs["J"] == result.fun and frame.attrs["method"] == "lm"
    assert frame.attrs["warnings"] == result.warnings


def test_a_result_without_covariance_shows_no_standard_errors(trs_case):
    bare = hc.identify(trs_case.data, trs_case.structure, uncertainty=False)
    assert bare.covariance is None and "std. error" not in bare._repr_html_()
    assert bare.to_frame()["stderr"].isna().all()
    with pytest.raises(ParameterError, match="no covariance"):
        bare.conf_int()


def test_study_html_and_frames(study):
    html = study._repr_html_()
    assert "<table>" in html and "SPSA" in html and "N-SPSA" in html
    assert "3/3" in html  # SPSA's diverged count
    assert "Wilcoxon rank-sum SPSA vs N-SPSA" in html
    assert "Wilcoxon rank-sum NL-SPSA vs N-SPSA" in html and "paper: p = 5.08e-08, h = 1" in html
    assert "<td><i>N/A</i></td>" in html  # the paper gives no SPSA mean
    assert "<td><i>179.008</i></td>" in html  # Table 3's N-SPSA mean
    s = study.summary()
    assert f"{s['nspsa']['mean']:.6g}" in html
    frame = study.to_frame()
    assert list(frame.index) == ["spsa", "nlspsa", "nspsa"]
    assert frame.loc["nspsa", "mean"] == pytest.approx(s["nspsa"]["mean"])
    assert frame.loc["spsa", "diverged"] == 3
    trials = study.to_frame(trials=True)
    assert len(trials) == 9 and trials.loc[("nspsa", 1), "J"] == pytest.approx(study.values("nspsa")[1])
    assert set(study.case.structure.param_names) <= set(trials.columns)


def test_to_frame_without_pandas_names_the_extra(monkeypatch, result, study):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match=r"pip install hammerstein_ctrl\[frames\]"):
        result.to_frame()
    with pytest.raises(ImportError, match=r"pip install hammerstein_ctrl\[frames\]"):
        study.to_frame()


def test_result_text_view_in_ipython_is_the_summary(result):
    pretty = pytest.importorskip("IPython.lib.pretty")
    assert pretty.pretty(result) == result.summary()


def test_figures_returned_to_ipython_render_as_one_png(monkeypatch):
    IPython = pytest.importorskip("IPython")
    from IPython.core.formatters import PNGFormatter
    from matplotlib.figure import Figure

    from IPython.core import pylabtools  # noqa: F401  (loaded before the shell is faked)

    class Shell:  # the part of an IPython shell the registration touches
        display_formatter = type("DF", (), {"formatters": {"image/png": PNGFormatter()}})()

    shell = Shell()
    monkeypatch.setattr(IPython, "get_ipython", lambda: shell)
    fig = hc.plotting.input_signal(hc.presets.trs().data)
    png = shell.display_formatter.formatters["image/png"](fig)
    assert isinstance(png, bytes) and png.startswith(b"\x89PNG")
    assert Figure in shell.display_formatter.formatters["image/png"].type_printers
