"""The ten reproductions of issue 11 ("Nothing lost, nothing silently wrong"), one test (or more) each.

Items 6 (``load_emps(path=...)``) and the data-file half of item 9 (NPZ/CSV
garbage) are covered with the hostile data-file corpus of ``read_record``;
here they are checked through the command line only.
"""

import importlib
import json
import math
import os
import signal
import sys
import warnings

import control
import numpy as np
import pytest
import scipy.optimize

from hammerstein_ctrl import load_trs, presets
from hammerstein_ctrl._checks import MAX_ORDER, as_signal
from hammerstein_ctrl.cli import main
from hammerstein_ctrl.exceptions import DataError, ParameterError
from hammerstein_ctrl.optimize import minimize
from hammerstein_ctrl.optimize.presets import TRS_BOUNDS
from hammerstein_ctrl.simulate import lsim
from hammerstein_ctrl.study import ResultsFileWarning, run_study

from _processes import alive, children, cli, lines, wait_for

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and fork")


def run(capsys, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse's own refusals
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def one_error_line(err: str) -> str:
    """The single stderr line of a failed command (fails the test if there is more, or a traceback)."""
    assert "Traceback" not in err
    rows = [r for r in err.splitlines() if r.strip()]
    assert len(rows) == 1, err
    assert rows[0].startswith("hammerstein-ctrl: error: "), err
    return rows[0]


@pytest.fixture(scope="module")
def trs():
    return presets.trs()


@pytest.fixture
def trs_csv(tmp_path):
    return load_trs()[:1000].to_csv(tmp_path / "trs.csv")


# 1 -------------------------------------------------------------------------------------------
def test_item1_duplicate_method_names_run_once(capsys, tmp_path):
    code, out, err = run(capsys, "reproduce", "trs", "--trials", 3, "--methods", "nspsa", "n-spsa", "NSPSA",
                         "--out", tmp_path, "--no-figures", "--jobs", 1)
    assert code == 0, err
    assert "only 1 different ones (nspsa)" in err
    assert "over 3 independent trials" in out
    assert sum(row.startswith("N-SPSA ") for row in out.splitlines()) == 1
    assert "rank-sum" not in out  # one method: nothing to compare
    assert len(lines(tmp_path / "results.jsonl")) == 3
    assert json.loads((tmp_path / "summary.json").read_text())["nspsa"]["n"] == 3


def test_item1_run_study_canonicalises_and_deduplicates(trs):
    study = run_study(trs, ["N-SPSA", "nspsa", "n-spsa"], trials=2, executor="serial")
    assert study.methods == ["nspsa"] and len(study.records) == 2


# 2 -------------------------------------------------------------------------------------------
def test_item2_leading_zero_denominator_is_trimmed_not_zeroed():
    t = np.arange(0.0, 5.0 + 1e-9, 0.01)
    v = np.ones_like(t)
    y = lsim(([1.0], [0.0, 1.0, 1.0]), t, v)
    ref = control.forced_response(control.tf([1.0], [1.0, 1.0]), t, v).outputs
    assert ref[-1] == pytest.approx(0.9933, abs=1e-4)
    np.testing.assert_allclose(y, ref, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("num, den, message", [
    ([1.0], [np.nan, 1.0], "non-finite"),
    ([1.0], [1.0, np.inf], "non-finite"),
    ([np.nan], [1.0, 1.0], "non-finite"),
    ([1.0], [0.0, 0.0], "denominator is zero"),
    ([1.0, 0.0, 0.0], [1.0, 1.0], "improper"),
    ([1.0], [], "non-empty"),
])
def test_item2_unusable_transfer_functions_raise(num, den, message):
    t = np.arange(0.0, 1.0, 0.01)
    with pytest.raises(ParameterError, match=message):
        lsim((num, den), t, np.ones_like(t))


# 3 -------------------------------------------------------------------------------------------
@linux
@pytest.mark.parametrize("sig", [signal.SIGKILL, pytest.param(signal.SIGTERM, marks=pytest.mark.slow)],
                         ids=["SIGKILL", "SIGTERM"])
def test_item3_workers_end_with_a_killed_run_and_the_rerun_matches(capsys, tmp_path, trs, sig):
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
        resumed = run_study(trs, ["nspsa"], trials=trials, seed=0, jobs=2,
                            results_path=tmp_path / "results.jsonl")
    assert resumed.resumed == saved
    assert len(resumed.rejected) == torn, (resumed.rejected, [str(w.message) for w in caught])
    reference = run_study(trs, ["nspsa"], trials=trials, seed=0, executor="serial")
    a, b = resumed.summary()["nspsa"], reference.summary()["nspsa"]
    for key in ("n", "mean", "best", "worst", "std", "median", "nfev", "diverged"):
        assert a[key] == b[key], key


# 4 -------------------------------------------------------------------------------------------
def test_item4_a_study_where_every_trial_diverges_writes_tables_and_figures(capsys, tmp_path):
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


# 5 -------------------------------------------------------------------------------------------
def test_item5_tnc_runs_and_agrees_with_scipy():
    f = lambda x: float(np.sum((x - np.array([1.0, -2.0])) ** 2))  # noqa: E731
    seen = []
    r = minimize(f, np.zeros(2), method="tnc", maxfev=200, callback=lambda res: seen.append(res.x.copy()))
    ref = scipy.optimize.minimize(f, np.zeros(2), method="tnc")
    assert r.success and r.nfev <= 200 and seen
    np.testing.assert_allclose(r.x, ref.x, atol=1e-6)
    np.testing.assert_allclose(r.x, [1.0, -2.0], atol=1e-4)


def test_item5_tnc_on_the_trs_cost(trs):
    r = minimize(trs.cost, trs.x0, method="tnc", maxfev=150)
    assert r.nfev <= 150 and math.isfinite(r.fun) and r.fun < trs.cost(trs.x0)


# 6 -------------------------------------------------------------------------------------------
def test_item6_a_wrong_data_path_is_an_error_not_other_data(capsys, tmp_path):
    code, out, err = run(capsys, "reproduce", "emps", "--data", tmp_path / "nonexistent", "--out", tmp_path / "o")
    assert code == 2
    assert "nonexistent: no such file or folder" in one_error_line(err)
    assert not (tmp_path / "o").exists()


# 7 -------------------------------------------------------------------------------------------
class Counted:
    def __init__(self):
        self.calls = 0

    def __call__(self, x):
        self.calls += 1
        return float(np.sum((np.asarray(x) - 1.0) ** 2))


@pytest.mark.parametrize("method", ["spsa", "nlspsa", "nspsa"])
def test_item7_maxfev_alone_sets_the_iterations(method):
    f = Counted()
    r = minimize(f, np.zeros(2), method=method, maxfev=20_001, seed=0)
    # not 1 000 iterations / 2 001 evaluations; 8 evaluations calibrate the (automatic) gains, 1 scores the start
    assert r.nit == (20_001 - 1 - 8 - 1) // 2 and r.nfev == 20_001 - 1 == f.calls


def test_item7_monitor_evaluations_are_paid_from_maxfev():
    f = Counted()
    r = minimize(f, np.zeros(3), method="nspsa", maxfev=201, seed=0, options={"monitor": 50})
    assert f.calls == r.nfev + r.nfev_monitor <= 201
    assert r.nfev_monitor > 0 and np.isfinite(r.history["estimate"]).sum() > 1


@pytest.mark.parametrize("method", ["lm", "nelder-mead", "powell", "bfgs", "nspsa", "amvo-sca"])
@pytest.mark.parametrize("maxfev", [float("nan"), 0, -5, 2.5, float("inf")])
def test_item7_a_budget_that_is_not_a_positive_integer_is_refused(trs, method, maxfev):
    bounds = TRS_BOUNDS if method == "amvo-sca" else None
    with pytest.raises(ParameterError, match="maxfev must be a positive integer"):
        minimize(trs.cost, trs.x0, method=method, maxfev=maxfev, bounds=bounds)


# 8 -------------------------------------------------------------------------------------------
def _study_lines(trs, path):
    run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    return lines(path)


@pytest.mark.parametrize("damage", ["42", "null", b"\xff\xfe{}", "trial_null", "fun_abc", "no_curve",
                                    "edited_fun"])
def test_item8_untrustworthy_lines_are_reported_and_their_trial_rerun(trs, tmp_path, damage):
    path = tmp_path / "results.jsonl"
    good = _study_lines(trs, path)
    rec = json.loads(good[1])
    if damage == "trial_null":
        rec["trial"] = None
    elif damage == "fun_abc":
        rec["fun"] = "abc"
    elif damage == "no_curve":
        del rec["curve"]
    elif damage == "edited_fun":
        rec["fun"] = -1.67e8
    raw = damage if isinstance(damage, bytes) else (damage if damage in ("42", "null") else json.dumps(rec)).encode()
    if damage != "edited_fun":  # replace trial 1 with the damaged line; the edit is appended as a copy
        path.write_bytes((good[0] + "\n").encode() + raw + b"\n")
    else:
        path.write_bytes("".join(g + "\n" for g in good).encode() + raw + b"\n")
    with pytest.warns(ResultsFileWarning, match=r"1 line\(s\) rejected"):
        study = run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    assert study.resumed == (2 if damage == "edited_fun" else 1)
    after = [json.loads(x) for x in lines(path)]  # trusted lines only, one per trial
    assert sorted((r["trial"], r["fun"]) for r in after) == [(r["trial"], r["fun"]) for r in map(json.loads, good)]
    assert study.values("nspsa").tolist() == [json.loads(g)["fun"] for g in good]
    assert (tmp_path / "results.rejected.jsonl").read_bytes() == raw + b"\n"
    # a clean file afterwards: no warning, every trial reused
    again = run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    assert again.resumed == 2 and again.rejected == []


# 9 -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, message", [
    (["reproduce", "trs", "--seed", "-1"], "argument --seed: must be a non-negative integer"),
    (["reproduce", "trs", "--jobs", "-1"], "argument --jobs: must be a positive integer"),
    (["identify", "--data", "{csv}", "--structure", "trs", "--gain-a", "1", "2", "3", "4"],
     "--gain-a takes at most 3 numbers, got 4"),
    (["identify", "--data", "{csv}", "--structure", "trs", "--plot", "{tmp}/x.xyz"], "unknown figure format '.xyz'"),
    (["identify", "--data", "{csv}", "--structure", "trs", "--method", "powell", "--maxfev", "0"],
     "argument --maxfev: must be a positive integer"),
    (["identify", "--data", "{csv}", "--structure", "trs", "--plot", "{tmp}/no/such/dir/x.png"], "does not exist"),
    (["identify", "--data", "{csv}", "--structure", "trs", "--out", "{tmp}"], "is a directory"),
])
def test_item9_bad_arguments_are_one_line_before_any_work(capsys, tmp_path, trs_csv, no_work, argv, message):
    argv = [a.replace("{csv}", str(trs_csv)).replace("{tmp}", str(tmp_path)) for a in argv]
    code, out, err = run(capsys, *argv)
    assert code == 2 and no_work == []
    assert message in one_error_line(err)


@pytest.mark.parametrize("bounds, message", [
    (["0", "1", "0", "10", "0", "10", "-10", "0", "0", "1"], r"x0\[0\] = -2 lies outside its bounds \[0, 1\]"),
    (["-5", "-5", "0", "10", "0", "10", "-10", "0", "0", "1"], "needs low < high"),
])
def test_item9_lm_bounds_problems_are_one_line(capsys, trs_csv, bounds, message):
    code, out, err = run(capsys, "identify", "--data", trs_csv, "--structure", "trs", "--method", "lm",
                         "--bounds", *bounds)
    assert code == 2
    assert pytest.importorskip("re").search(message, one_error_line(err))


def _die(*args):  # a trial whose worker is killed (as by the OOM killer)
    os._exit(9)


@linux
def test_item9_a_killed_worker_is_one_line(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(importlib.import_module("hammerstein_ctrl.study"), "_run_trial", _die)
    code, out, err = run(capsys, "reproduce", "trs", "--methods", "nspsa", "--trials", 2, "--jobs", 2,
                         "--out", tmp_path, "--no-figures")
    assert code == 2
    assert "a worker process died unexpectedly" in one_error_line(err)


def test_item9_debug_shows_the_traceback(capsys, tmp_path):
    code, out, err = run(capsys, "reproduce", "emps", "--data", tmp_path / "none")
    assert code == 2 and "Traceback" not in err
    code, out, err = run(capsys, "--debug", "reproduce", "emps", "--data", tmp_path / "none")
    assert code == 2 and "Traceback (most recent call last)" in err
    assert err.rstrip().splitlines()[-1].startswith("hammerstein-ctrl: error: --data ")
    code, out, err = run(capsys, "reproduce", "trs", "--debug", "--out", "/proc/forbidden")
    assert code == 2 and "Traceback (most recent call last)" in err


# 10 ------------------------------------------------------------------------------------------
def _diagonal_system(order, seed=0):
    """A stable all-pole system as (num, den) and as its diagonal (modal) realisation, built independently."""
    poles = -np.linspace(0.5, 3.0, order) * np.random.default_rng(seed).uniform(0.9, 1.1, order)
    gain = float(np.prod(-poles))
    residues = np.array([gain / np.prod([p - q for q in poles if q != p]) for p in poles])
    modal = control.ss(np.diag(poles), np.ones((order, 1)), residues[None, :], 0.0)
    return ([gain], np.poly(poles)), modal


def test_item10_orders_up_to_max_are_accurate_and_beyond_are_refused():
    t = np.arange(0.0, 10.0, 0.01)
    v = np.sin(t) + 0.5 * np.sign(np.sin(0.7 * t))
    tf, modal = _diagonal_system(MAX_ORDER)
    ref = control.forced_response(modal, t, v).outputs
    assert np.max(np.abs(lsim(tf, t, v) - ref)) / np.max(np.abs(ref)) < 1e-4
    tf, modal = _diagonal_system(MAX_ORDER + 2)
    with pytest.raises(ParameterError, match=f"order {MAX_ORDER + 2}; at most {MAX_ORDER}"):
        lsim(tf, t, v)
    # a state-space model of that order is simulated from its own (well-conditioned) matrices
    np.testing.assert_allclose(lsim(modal, t, v), control.forced_response(modal, t, v).outputs,
                               rtol=1e-8, atol=1e-10)


def test_item10_orders_0_50_are_refused(capsys, trs_csv, no_work):
    code, out, err = run(capsys, "identify", "--data", trs_csv, "--orders", 0, 50, "--nonlinearity", "tanh")
    assert code == 2 and no_work == []
    assert "den_order 50 exceeds MAX_ORDER = 10" in one_error_line(err)


def test_item10_complex_and_object_input_are_refused():
    with pytest.raises(DataError, match="complex"):
        as_signal(np.ones(5) + 1j, "u")
    with pytest.raises(DataError, match="numeric"):
        as_signal(np.array([1.0, None, 2.0], dtype=object), "u")
    t = np.arange(0.0, 1.0, 0.1)
    with pytest.raises(DataError, match="complex"):
        lsim(([1.0], [1.0, 1.0]), t, np.ones_like(t) * (1 + 1e-3j))


def test_item10_a_constant_output_is_refused_before_the_fit(capsys, tmp_path, no_work):
    t = np.arange(0.0, 2.0, 0.01)
    path = tmp_path / "flat.csv"
    np.savetxt(path, np.column_stack([t, np.sin(t), np.full_like(t, 3.0)]), delimiter=",",
               header="t,u,y", comments="")
    code, out, err = run(capsys, "identify", "--data", path, "--structure", "trs")
    assert code == 2 and no_work == []
    assert "output y is constant" in one_error_line(err)


def test_item10_identify_out_is_standard_json(capsys, tmp_path, trs_csv):
    out_path = tmp_path / "m.json"
    code, out, err = run(capsys, "identify", "--data", trs_csv, "--structure", "trs", "--method", "spsa",
                         "--maxfev", 201, "--gain-a", 50, "--out", out_path)
    text = out_path.read_text()

    def reject(constant):
        raise AssertionError(f"non-standard JSON constant {constant}")

    model = json.loads(text, parse_constant=reject)
    assert code == 1 and model  # spsa with a huge gain diverges: J is not finite
    assert "Infinity" not in text and "NaN" not in text


def test_item10_reuse_count_is_what_is_used(capsys, tmp_path):
    argv = ["reproduce", "trs", "--methods", "nspsa", "--out", tmp_path, "--no-figures", "--jobs", 1]
    assert run(capsys, *argv, "--trials", 4)[0] == 0
    code, out, err = run(capsys, *argv, "--trials", 2)
    assert code == 0 and "2 trials, " in out and "(2 trials reused from" in out
