import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from hammerstein_ctrl import minimize, plots  # noqa: E402
from hammerstein_ctrl.optimize.presets import eq8_methods, eq8_objective  # noqa: E402
from hammerstein_ctrl.study import run_study  # noqa: E402


def assert_labelled(fig, *, units=True):
    axes = [a for a in fig.axes if a.get_visible()]
    assert axes
    for a in axes:
        assert a.get_ylabel(), "every axes needs a y label"
        if units:
            assert "(" in a.get_ylabel() and ")" in a.get_ylabel(), f"no unit in {a.get_ylabel()!r}"
    assert any(a.get_title() for a in axes) or fig._suptitle is not None
    assert any(a.get_xlabel() for a in axes)
    assert any(a.get_legend() is not None for a in axes)


@pytest.fixture(scope="module")
def trs_study():
    from hammerstein_ctrl import presets

    return run_study(presets.trs(), ["spsa", "nlspsa", "nspsa", "lm"], trials=3, seed=0, executor="serial")


@pytest.fixture(scope="module")
def emps_study(emps_case):
    return run_study(emps_case, ["spsa", "nspsa", "lm"], trials=3, seed=0, executor="serial")


@pytest.mark.parametrize("which", ["trs", "emps"])
def test_study_figures_are_titled_labelled_with_units_and_legended(which, request):
    study = request.getfixturevalue(f"{which}_study")
    validation = study.case.validation() if study.case.validation else None
    figs = plots.study_figure_set(study, validation=validation)
    expected = {"time_response", "error", "psd", "bode", "nonlinearity", "convergence", "final_cost"}
    assert expected <= set(figs)
    for name, fig in figs.items():
        assert_labelled(fig, units=name not in ("convergence", "final_cost", "nonlinearity"))
        if name not in ("convergence", "final_cost"):  # the diverged method is named, not drawn
            assert "SPSA diverged: not shown" in (fig.axes[0].get_title() + str(fig._suptitle and fig._suptitle.get_text()))
        plt.close(fig)
    tr = figs["time_response"]
    assert tr.axes[0].get_ylabel() == f"{study.case.data.output_name} ({study.case.data.output_unit})"
    assert tr.axes[0].get_xlabel() == "time (s)"
    labels = [t.get_text() for t in tr.axes[0].get_legend().get_texts()]
    assert labels[0] == "measured" and "N-SPSA" in labels and "SPSA" not in labels


def test_psd_peak_of_trs_measured_and_identified_agree_within_a_bin(trs_study):
    model = trs_study.best_model("nspsa")
    peaks = plots.dominant_frequency(trs_study.case.data, {"N-SPSA": model})
    assert abs(peaks["measured"] - peaks["N-SPSA"]) <= peaks["resolution"]
    assert peaks["resolution"] == pytest.approx(10.0 / 1024)


def test_convergence_of_eq8_example_shows_divergence_and_convergence():
    runs = {}
    for label, key in (("SPSA", "spsa"), ("N-SPSA", "nspsa")):
        runs[label] = [minimize(eq8_objective, np.zeros(10), seed=s, maxiter=300,
                                **{**eq8_methods()[key], "options": {**eq8_methods()[key]["options"], "monitor": 300}})
                       for s in range(3)]
    fig = plots.convergence(runs, quantity="estimate")
    ax = fig.axes[0]
    assert ax.get_yscale() == "log" and ax.get_xlabel() == "function evaluations (NFE)"
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any(l.startswith("N-SPSA") for l in labels)
    plt.close(fig)


def test_plots_draw_into_a_given_axes_and_never_show(trs_case, monkeypatch):
    monkeypatch.setattr(plt, "show", lambda *a, **k: pytest.fail("plots must not call plt.show()"))
    fig, ax = plt.subplots()
    out = plots.time_response(trs_case.data, {"truth": trs_case.structure.model(trs_case.true_beta)}, ax=ax)
    assert out is fig and len(ax.lines) == 2
    out = plots.nonlinearity({"truth": trs_case.structure.model(trs_case.true_beta)}, (-1, 1), unit_in="V", ax=ax)
    assert out is fig
    plt.close(fig)
    with pytest.raises(ValueError, match="zoom window"):
        plots.time_response(trs_case.data, {}, zoom=(5, 1))
