import json
import os
import signal
import sys
import warnings

import pytest

from hammerstein_ctrl import load_trs
from hammerstein_ctrl.cli import main
from hammerstein_ctrl.paper.study import run_study

from _processes import alive, children, cli, lines, wait_for

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and fork")


@pytest.fixture
def trs_csv(tmp_path):
    return load_trs()[:2000].to_csv(tmp_path / "trs.csv")


@pytest.fixture
def tanh_csv(tmp_path):
    """A record of the TRS structure's form, ``(p + 0.5)/(p^2 + 1.2 p + 1)`` after ``2 tanh(1.2 u)``, from
    python-control, whose nonlinearity the record does show (the TRS reconstruction's is nearly linear)."""
    import control as ct
    import numpy as np

    from hammerstein_ctrl import IOData

    rng = np.random.default_rng(0)
    u = np.repeat(rng.uniform(-2.0, 2.0, 200), 10)
    t = 0.1 * np.arange(u.size)
    y = ct.forced_response(ct.tf([1.0, 0.5], [1.0, 1.2, 1.0]), t, 2.0 * np.tanh(1.2 * u)).outputs
    return IOData(u, y + 0.02 * rng.standard_normal(u.size), t).to_csv(tmp_path / "tanh.csv")


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_identify_a_users_csv(capsys, tmp_path, tanh_csv):
    code, out, err = run(capsys, "identify", "--data", str(tanh_csv), "--structure", "trs", "--maxfev", "800",
                         "--out", str(tmp_path / "m.json"), "--plot", str(tmp_path / "m.png"))
    assert code == 0, err
    assert "auto on 'tanh': J =" in out and "fit =" in out
    model = json.loads((tmp_path / "m.json").read_text())
    assert set(model["params"]) == {"b0", "a0", "a1", "d0", "d1"}
    assert (tmp_path / "m.png").stat().st_size > 10_000


def test_identify_estimates_a_dead_time_from_the_command_line(capsys, tmp_path):
    import control as ct
    import numpy as np

    from hammerstein_ctrl import IOData

    rng = np.random.default_rng(0)
    t = np.arange(600) * 0.1
    u = np.repeat(rng.uniform(-2, 2, 40), 15)
    w = np.r_[np.zeros(4), 1.5 * np.tanh(0.8 * u)][:600]                 # a dead time of 4 samples, ZOH
    y = ct.forced_response(ct.c2d(ct.ss(ct.tf([1.0], [1.5, 1.0])), 0.1, "zoh"), t, w).outputs
    path = IOData(u, y + 0.01 * rng.standard_normal(600), dt=0.1, intersample="zoh").to_csv(tmp_path / "dead.csv")
    code, out, err = run(capsys, "identify", "--data", path, "--orders", "0", "1", "--nonlinearity", "tanh",
                         "--delay", "estimate", "--intersample", "zoh")
    assert code == 0, err
    delay = float(out.split("delay = ")[1].split()[0])
    assert abs(delay - 0.4) < 0.01
    code, out, err = run(capsys, "identify", "--data", path, "--orders", "0", "1", "--nonlinearity", "tanh",
                         "--delay", "0.4", "--intersample", "zoh")              # a dead time given in seconds
    assert code == 0, err
    assert "e^{-0.4 p}" in out
    for bad in ("soon", "-0.1", "nan"):
        code, out, err = run(capsys, "identify", "--data", path, "--orders", "0", "1", "--nonlinearity", "tanh",
                             "--delay", bad)
        assert code == 2 and "--delay" in err and len(err.strip().splitlines()) == 1, err
    code, out, err = run(capsys, "identify", "--data", path, "--structure", "trs", "--delay", "0.1")
    assert code == 2 and "--delay cannot be combined with --structure trs" in err


def test_identify_with_explicit_structure(capsys, trs_csv):
    code, out, err = run(capsys, "identify", "--data", str(trs_csv), "--orders", "1", "2",
                         "--nonlinearity", "tanh", "--x0", "-2", "0.1", "5", "-5", "0.1",
                         "--method", "nspsa", "--maxfev", "401", "--gain-a", "0.025", "11", "0.3",
                         "--gain-c", "0.2", "0.3333")
    assert code == 1 and "the linear model of the same order" in out     # TRS: it does not show the tanh (below)
    assert "nfev = 400" in out      # the start, 199 iterations of two evaluations, the last iterate


@pytest.mark.parametrize("argv, message", [
    (["identify", "--data", "nope.csv", "--structure", "trs"], "data file not found: nope.csv"),
    (["identify", "--data", "{csv}", "--structure", "trs", "--method", "pso"], "unknown method 'pso'"),
    (["identify", "--data", "{csv}", "--structure", "trs", "--input", "volts"], "no input column 'volts'"),
    (["identify", "--data", "{bad}", "--structure", "trs"], "line 3: column 'u' holds 'oops', not a number"),
    (["identify", "--data", "{csv}", "--orders", "1", "2", "--nonlinearity", "cubic", "--x0", "1"],
     "unknown nonlinearity 'cubic'"),
    (["identify", "--data", "{csv}", "--orders", "1", "2", "--nonlinearity", "tanh", "--x0", "1", "2"],
     "beta must have 5 entries"),
    (["identify", "--data", "{csv}", "--orders", "1", "2", "--nonlinearity", "tanh", "--fix", "a0"],
     "--fix expects NAME=VALUE"),
    (["identify", "--data", "{csv}", "--structure", "trs", "--fix", "a0=0"],
     "--fix cannot be combined with --structure trs"),
    (["reproduce", "trs", "--data", "x"], "--data applies to the EMPS case only"),
])
def test_bad_inputs_exit_nonzero_with_one_clear_line(capsys, tmp_path, trs_csv, argv, message):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,u,y\n0,1,2\n0.1,oops,3\n")
    argv = [a.replace("{csv}", str(trs_csv)).replace("{bad}", str(bad)) for a in argv]
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert err.startswith("hammerstein-ctrl: error: ") and message in err.splitlines()[0]
    assert "Traceback" not in err


def test_argparse_rejects_bad_numbers(capsys):
    assert main(["identify", "--data", "x.csv", "--structure", "trs", "--x0", "1", "abc"]) == 2
    err = capsys.readouterr().err
    assert "abc" in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow
def test_reproduce_writes_tables_models_and_figures(capsys, tmp_path):
    out_dir = tmp_path / "trs"
    code, out, err = run(capsys, "reproduce", "trs", "--trials", "3", "--methods", "nspsa", "nlspsa", "spsa",
                         "--out", str(out_dir), "--jobs", "1", "--svg", "--no-progress")
    assert code == 0, err
    assert "paper" in out and "N-SPSA" in out and "Wilcoxon rank-sum" in out
    assert "forced_response" in out
    for name in ("results.jsonl", "summary.json", "summary.md", "summary.csv", "best_models.json"):
        assert (out_dir / name).stat().st_size > 0
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["nspsa"]["n"] == 3 and summary["spsa"]["diverged"] == 3
    for fig in ("time_response", "error", "psd", "bode", "nonlinearity", "convergence", "final_cost"):
        for ext in ("png", "svg"):
            assert (out_dir / "figures" / f"{fig}.{ext}").stat().st_size > 5_000
    # rerunning resumes from results.jsonl
    code, out, err = run(capsys, "reproduce", "trs", "--trials", "3", "--methods", "nspsa", "nlspsa", "spsa",
                         "--out", str(out_dir), "--jobs", "1", "--no-figures", "--no-progress")
    assert code == 0 and "9 trials reused" in out


def test_the_speed_benchmark_prints_ratios(capsys):
    import speed

    assert speed.main(["--cases", "trs"]) == 0
    out = capsys.readouterr().out
    assert "forced_response" in out and "x" in out and "evaluations in" in out


@pytest.fixture
def full_trs_csv(tmp_path):
    return load_trs().to_csv(tmp_path / "trs_full.csv")


def test_identify_prints_standard_errors_and_warnings(capsys, tanh_csv):
    code, out, err = run(capsys, "identify", "--data", str(tanh_csv), "--orders", "2", "3", "--nonlinearity", "tanh")
    assert code == 0, err
    assert "a1 = " in out and " ± " in out
    assert "warning: " in out and "cancel" in out          # one order too many: a pole and a zero cancel
    assert "IdentificationWarning" not in err and "warning" not in err     # listed once, in the summary


def test_identify_says_when_the_records_nonlinearity_is_not_significant(capsys, full_trs_csv):
    """The TRS reconstruction's tanh is nearly linear at its 1 V input: the linear model of the same order
    fits it as well, the fit fails (exit 1) and says so, with the standard errors still shown."""
    code, out, err = run(capsys, "identify", "--data", str(full_trs_csv), "--structure", "trs")
    assert code == 1
    assert "the nonlinearity is not significant" in out and "use the linear model" in out
    assert "a1 = " in out and " ± " in out


def test_select_ranks_structures_and_writes_the_table_and_the_best_fit(capsys, tmp_path, tanh_csv):
    table, best = tmp_path / "rank.csv", tmp_path / "best.json"
    code, out, err = run(capsys, "select", "--data", str(tanh_csv), "--orders", "0", "1", "1", "2",
                         "--nonlinearity", "tanh", "--criterion", "bic", "--jobs", "1",
                         "--table", str(table), "--out", str(best))
    assert code == 0, err
    assert out.splitlines()[0] == "structures ranked by bic (best first):"
    assert "1. H(p) = (p + b0)/(p^2 + a1 p + a0); g = tanh(d0, d1)" in out
    rows = table.read_text().splitlines()
    assert rows[0].startswith("rank,structure,n_params,J") and len(rows) == 3
    assert json.loads(best.read_text())["structure"]["linear"]["den_order"] == 2


@pytest.mark.parametrize("argv, message", [
    (["select", "--data", "{csv}", "--orders", "0", "1", "1", "--nonlinearity", "tanh"], "--orders takes pairs"),
    (["select", "--data", "{csv}", "--orders", "0", "1", "--nonlinearity", "cubic"], "unknown nonlinearity"),
    (["select", "--data", "{csv}", "--orders", "0", "1", "--nonlinearity", "tanh", "--criterion", "validation"],
     "needs a validation record"),
    (["select", "--data", "{csv}", "--orders", "0", "1"], "no candidate structures"),
])
def test_select_refuses_bad_arguments_with_one_line(capsys, trs_csv, argv, message):
    code, out, err = run(capsys, *[a.replace("{csv}", str(trs_csv)) for a in argv])
    assert code == 2 and err.startswith("hammerstein-ctrl: error: ") and message in err.splitlines()[0]


def test_reproduce_runs_duplicate_method_names_once(capsys, tmp_path):
    code, out, err = run(capsys, "reproduce", "trs", "--trials", 3, "--methods", "nspsa", "n-spsa", "NSPSA",
                         "--out", tmp_path, "--no-figures", "--jobs", 1)
    assert code == 0, err
    assert "only 1 different ones (nspsa)" in err
    assert "over 3 independent trials" in out
    assert sum(row.startswith("N-SPSA ") for row in out.splitlines()) == 1
    assert "rank-sum" not in out  # one method: nothing to compare
    assert len(lines(tmp_path / "results.jsonl")) == 3
    assert json.loads((tmp_path / "summary.json").read_text())["nspsa"]["n"] == 3


def test_reproduce_with_every_trial_diverged_writes_tables_and_figures(capsys, tmp_path):
    code, out, err = run(capsys, "reproduce", "trs", "--methods", "spsa", "--trials", 1, "--seed", 1,
                         "--out", tmp_path, "--jobs", 1)
    assert code == 0, err
    assert "1/1" in out  # the diverged column
    assert "no trial ended with a finite J" in out
    names = {p.stem for p in (tmp_path / "figures").glob("*.png")}
    assert {"time_response", "error", "psd", "nonlinearity", "convergence", "final_cost"} <= names
    assert "bode" not in names  # no linear block to draw
    best = json.loads((tmp_path / "best_models.json").read_text())
    assert best["spsa"]["diverged"] is True


def test_debug_shows_the_traceback(capsys, tmp_path):
    code, out, err = run(capsys, "reproduce", "emps", "--data", tmp_path / "none")
    assert code == 2 and "Traceback" not in err
    code, out, err = run(capsys, "--debug", "reproduce", "emps", "--data", tmp_path / "none")
    assert code == 2 and "Traceback (most recent call last)" in err
    assert err.rstrip().splitlines()[-1].startswith("hammerstein-ctrl: error: --data ")
    code, out, err = run(capsys, "reproduce", "trs", "--debug", "--out", "/proc/forbidden")
    assert code == 2 and "Traceback (most recent call last)" in err


@pytest.fixture
def thousand_sample_trs_csv(tmp_path):
    return load_trs()[:1000].to_csv(tmp_path / "trs.csv")


def test_identify_out_writes_standard_json_for_a_diverged_fit(capsys, tmp_path, thousand_sample_trs_csv):
    out_path = tmp_path / "m.json"
    code, out, err = run(capsys, "identify", "--data", thousand_sample_trs_csv, "--structure", "trs",
                         "--method", "spsa", "--maxfev", 201, "--gain-a", 50, "--out", out_path)
    text = out_path.read_text()

    def reject(constant):
        raise AssertionError(f"non-standard JSON constant {constant}")

    model = json.loads(text, parse_constant=reject)
    assert code == 1 and model  # spsa with a huge gain diverges: J is not finite
    assert "Infinity" not in text and "NaN" not in text


def test_reproduce_reports_the_trials_it_reuses(capsys, tmp_path):
    argv = ["reproduce", "trs", "--methods", "nspsa", "--out", tmp_path, "--no-figures", "--jobs", 1]
    assert run(capsys, *argv, "--trials", 4)[0] == 0
    code, out, err = run(capsys, *argv, "--trials", 2)
    assert code == 0 and "2 trials, " in out and "(2 trials reused from" in out


@linux
@pytest.mark.parametrize("sig", [signal.SIGKILL, pytest.param(signal.SIGTERM, marks=pytest.mark.slow)],
                         ids=["SIGKILL", "SIGTERM"])
def test_workers_end_with_a_killed_run_and_the_resumed_run_matches(capsys, tmp_path, trs_case, sig):
    trials = 10
    proc = cli("reproduce", "trs", "--methods", "nspsa", "--trials", trials, "--jobs", 2, "--out", tmp_path,
               "--no-figures", "--no-progress")
    try:
        assert wait_for(lambda: len(children(proc.pid)) == 2 and lines(tmp_path / "results.jsonl")), \
            "the run never started two workers and a first trial"
        workers = children(proc.pid)
        os.kill(proc.pid, sig)
        proc.wait(timeout=30)
        assert wait_for(lambda: not any(map(alive, workers)), timeout=5.0), \
            f"workers {[w for w in workers if alive(w)]} still alive 5 s after the parent's {sig.name}"
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()
    # A SIGKILL can land inside the write of a line (Linux stops a write to a file between pages on a fatal
    # signal): that trial was never saved.  Saved are the complete lines; a torn last one must be rejected.
    text = (tmp_path / "results.jsonl").read_text()
    saved = text.count("\n")
    torn = 0 if text.endswith("\n") or not text else 1
    assert 1 <= saved < trials
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        resumed = run_study(trs_case, ["nspsa"], trials=trials, seed=0, jobs=2,
                            results_path=tmp_path / "results.jsonl")
    assert resumed.resumed == saved
    assert len(resumed.rejected) == torn, (resumed.rejected, [str(w.message) for w in caught])
    reference = run_study(trs_case, ["nspsa"], trials=trials, seed=0, executor="serial")
    a, b = resumed.summary()["nspsa"], reference.summary()["nspsa"]
    for key in ("n", "mean", "best", "worst", "std", "median", "nfev", "diverged"):
        assert a[key] == b[key], key


def _wh_csv(tmp_path):
    """A record of a Wiener-Hammerstein system ``G1 -> 1.5 tanh(0.8 x) -> G2`` from the package's own model."""
    import numpy as np

    import hammerstein_ctrl as hc

    s = hc.WienerHammersteinStructure((0, 2), hc.Tanh(), (1, 2), time_unit=1.0)
    rng = np.random.default_rng(0)
    u = np.repeat(rng.uniform(-2.0, 2.0, 200), 10)
    t = 0.05 * np.arange(u.size)
    y = s.model([0.3, 0.25, 0.33, 0.33, 0.17, 1.5, 0.8]).simulate(t, u)
    return hc.IOData(u, y + 0.01 * rng.standard_normal(u.size), t).to_csv(tmp_path / "wh.csv")


def test_identify_a_wiener_hammerstein_model_from_the_command_line(capsys, tmp_path):
    code, out, err = run(capsys, "identify", "--data", str(_wh_csv(tmp_path)), "--orders", "0", "2",
                         "--second-orders", "1", "2", "--nonlinearity", "tanh", "--out", str(tmp_path / "r.json"),
                         "--plot", str(tmp_path / "r.png"))
    assert code == 0, err
    assert "[ok" in out and "G2(p) = (1 + b1 q)/(1 + a1 q + a2 q^2)" in out
    assert (tmp_path / "r.png").stat().st_size > 0
    import hammerstein_ctrl as hc

    r = hc.load_result(tmp_path / "r.json")
    assert r.structure.kind == "wiener-hammerstein" and r.fit_percent > 99


@pytest.mark.parametrize("extra, match", [
    (["--fix", "a0=1"], "--fix cannot be combined with --second-orders"),
    (["--delay", "estimate"], "--delay estimate cannot be combined with --second-orders"),
    (["--free-gain"], "--free-gain cannot be combined with --second-orders"),
    (["--feedback", "output"], "--second-orders cannot be combined with --feedback"),
])
def test_wiener_hammerstein_options_that_do_not_apply_are_refused_in_one_line(capsys, tmp_path, extra, match):
    code, out, err = run(capsys, "identify", "--data", str(_wh_csv(tmp_path)), "--orders", "0", "2",
                         "--second-orders", "1", "2", "--nonlinearity", "tanh", *extra)
    assert code == 2 and match in err and len(err.strip().splitlines()) == 1


def test_a_lure_loop_with_a_cubic_spring_from_the_command_line(capsys, tmp_path):
    code, out, err = run(capsys, "identify", "--data", str(_wh_csv(tmp_path)), "--orders", "0", "2", "--feedback",
                         "output", "--nonlinearity", "polynomial", "--degree", "3", "--fix", "a0=0", "--substeps", "2")
    assert code == 0, err
    assert "g = polynomial" in out



def test_a_wiener_hammerstein_model_with_a_fixed_dead_time_from_the_command_line(capsys, tmp_path):
    code, out, err = run(capsys, "identify", "--data", str(_wh_csv(tmp_path)), "--orders", "0", "2",
                         "--second-orders", "1", "2", "--nonlinearity", "tanh", "--delay", "0.05")
    assert code in (0, 1), err
    assert "dead time 0.05 s" in out
