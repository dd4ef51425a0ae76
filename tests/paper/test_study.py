import json
import os
import signal
import subprocess
import sys
import time

import pytest

from hammerstein_ctrl import presets
from hammerstein_ctrl import study as study_module
from hammerstein_ctrl.optimize import BUDGET_EXHAUSTED, COMPLETED
from hammerstein_ctrl.paper.study import ResultsFileWarning, ranksum, record_digest, run_study, trial_seed

SMALL = {  # short budgets keep these tests quick; the paper's settings are exercised below
    "nspsa": {"method": "nspsa", "maxiter": 150,
              "options": presets.trs().methods["nspsa"]["options"]},
    "nlspsa": {"method": "nlspsa", "maxiter": 150,
               "options": presets.trs().methods["nlspsa"]["options"]},
}
# ~0.1 s per trial: leaves a wide window to kill the study between its 5th and 16th trial
KILLABLE = {m: {**kw, "maxiter": 600} for m, kw in SMALL.items()}


def _summary_numbers(study):
    s = study.summary()
    return {m: (s[m]["mean"], s[m]["best"], s[m]["worst"], s[m]["std"], s[m]["nfev"]) for m in study.methods}


def test_trial_seeds_are_stable_and_distinct():
    assert trial_seed(0, 5) == trial_seed(0, 5)
    assert len({trial_seed(0, i) for i in range(100)}) == 100
    assert trial_seed(1, 5) != trial_seed(0, 5)


def test_any_subset_reruns_identically(trs_case, tmp_path):
    full = run_study(trs_case, ["nspsa"], trials=4, seed=11, executor="serial", settings=SMALL)
    # trial 2 alone, by its derived seed, gives the same answer
    from hammerstein_ctrl import minimize

    rec = full.records[2]
    r = minimize(trs_case.cost, trs_case.x0, seed=trial_seed(11, 2), **SMALL["nspsa"])
    assert r.fun == rec["fun"] and r.x.tolist() == rec["x"]
    pool = run_study(trs_case, ["nspsa"], trials=4, seed=11, jobs=2, settings=SMALL)
    assert _summary_numbers(pool) == _summary_numbers(full)


@pytest.mark.slow
def test_interrupted_study_resumes_to_the_same_summary(trs_case, tmp_path):
    path = tmp_path / "results.jsonl"
    script = (
        "from hammerstein_ctrl import presets\n"
        "from hammerstein_ctrl.paper.study import run_study\n"
        "import test_study as T\n"
        f"run_study(presets.trs(), ['nspsa', 'nlspsa'], trials=8, seed=5, executor='serial', "
        f"results_path={str(path)!r}, settings=T.KILLABLE)\n"
    )
    here = os.path.dirname(os.path.abspath(__file__))
    proc = subprocess.Popen([sys.executable, "-c", script], env={**os.environ, "PYTHONPATH": here})
    deadline = time.time() + 120
    while time.time() < deadline:
        if path.exists() and len(path.read_text().splitlines()) >= 5:
            break
        if proc.poll() is not None:
            break
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    written = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    assert 5 <= len(written) < 16, "the study must be killed midway"
    with open(path, "a") as fh:  # an interruption can also leave half a line behind
        fh.write('{"case": "trs", "method": "nsp')
    with pytest.warns(ResultsFileWarning, match="cut short"):        # the torn line is set aside, and said so
        resumed = run_study(trs_case, ["nspsa", "nlspsa"], trials=8, seed=5, executor="serial",
                            results_path=path, settings=KILLABLE)
    assert resumed.resumed == len(written)
    fresh = run_study(trs_case, ["nspsa", "nlspsa"], trials=8, seed=5, executor="serial", settings=KILLABLE)
    assert _summary_numbers(resumed) == _summary_numbers(fresh)
    assert resumed.summary()["ranksum"] == fresh.summary()["ranksum"]
    # a second rerun runs nothing
    again = run_study(trs_case, ["nspsa", "nlspsa"], trials=8, seed=5, executor="serial",
                      results_path=path, settings=KILLABLE)
    assert again.resumed == 16


def test_changed_settings_are_not_mixed_into_a_resumed_file(trs_case, tmp_path):
    path = tmp_path / "r.jsonl"
    run_study(trs_case, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path, settings=SMALL)
    other = {"nspsa": {**SMALL["nspsa"], "maxiter": 100}}
    st = run_study(trs_case, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path, settings=other)
    assert st.resumed == 0 and st.records[0]["nfev"] == 201


def test_summary_statistics_and_ranksum(trs_case, tmp_path):
    st = run_study(trs_case, ["nspsa", "nlspsa"], trials=5, seed=1, executor="serial", settings=SMALL)
    s = st.summary()
    J = st.values("nspsa")
    assert s["nspsa"]["mean"] == pytest.approx(J.mean()) and s["nspsa"]["std"] == pytest.approx(J.std(ddof=1))
    assert s["nspsa"]["best"] == J.min() and s["nspsa"]["nfev"] == 301
    import scipy.stats

    ref = scipy.stats.ranksums(st.values("nspsa"), st.values("nlspsa"))
    assert s["ranksum"]["nspsa vs nlspsa"]["p"] == pytest.approx(ref.pvalue)
    st.to_json(tmp_path / "summary.json")
    data = json.loads((tmp_path / "summary.json").read_text())
    assert set(data) >= {"nspsa", "nlspsa", "ranksum"} and data["nspsa"]["n"] == 5
    assert "| N-SPSA | ours |" in st.table("markdown")
    assert st.table("csv").splitlines()[0] == "method,source,mean,best,worst,std,nfev,diverged,s/trial"
    assert st.best_model("nspsa").linear.den[0][0][0] == 1.0
    r = ranksum([1, 2, 3], [4, 5, float("nan")])
    assert r["h"] in (0, 1) and 0 < r["p"] <= 1


def test_dask_executor_works_unchanged(trs_case):
    distributed = pytest.importorskip("distributed", reason="dask.distributed is an optional extra")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        st = run_study(trs_case, ["nspsa"], trials=4, seed=3, executor=client.get_executor(), settings=SMALL)
    ref = run_study(trs_case, ["nspsa"], trials=4, seed=3, executor="serial", settings=SMALL)
    assert _summary_numbers(st) == _summary_numbers(ref)


# -- the paper's comparisons with the paper's settings (issues 3 and 4) -----------------------------
@pytest.mark.slow
def test_reproduce_emps_table7(emps_case):
    st = run_study(emps_case, ["spsa", "nlspsa", "amvo-sca", "nspsa"], trials=25, seed=0)
    s = st.summary()
    assert 0.40 <= s["nspsa"]["mean"] <= 0.75
    assert 1.2 <= s["nlspsa"]["mean"] <= 2.6
    assert s["spsa"]["diverged"] >= 13  # "diverged in most runs"
    assert s["ranksum"]["nlspsa vs nspsa"]["p"] < 0.05
    assert s["amvo-sca"]["nfev"] == 5000 and s["nspsa"]["nfev"] == 2501
    assert s["nspsa"]["mean"] < s["amvo-sca"]["mean"] < s["nlspsa"]["mean"]


@pytest.mark.slow
def test_reproduce_trs_table3(trs_case):
    st = run_study(trs_case, ["spsa", "nlspsa", "amvo-sca", "nspsa"], trials=25, seed=0)
    s = st.summary()
    assert 178.0 <= s["nspsa"]["mean"] <= 180.0 and s["nspsa"]["std"] < 1.0
    assert s["spsa"]["diverged"] == 25
    assert s["ranksum"]["nlspsa vs nspsa"]["p"] < 0.05
    assert s["nspsa"]["std"] < s["nlspsa"]["std"] < s["amvo-sca"]["std"]


def test_resumed_study_does_not_mix_lm_records_of_the_old_status(trs_case, tmp_path, monkeypatch):
    """A results file written before the change is resumed as is: one LM run with two statuses.

    The fingerprint (RECORD_VERSION 3) did not change with the meaning of status/success/nit, so a
    rerun of ``reproduce`` keeps the parent commit's TRS LM trial (status 0, success True, nit = nfev
    = 2001, "evaluation budget of 2001 exhausted") beside new trials of the same deterministic run
    (status 5, success False, nit 346).  The old record is rebuilt here as 8c2b3cb wrote it, with its
    RECORD_VERSION 3 (checked against a real run of that commit: config b29493283d3cc5c2, the same
    seed and fields).
    """
    path = tmp_path / "results.jsonl"
    with monkeypatch.context() as m:
        m.setattr(study_module, "RECORD_VERSION", 3)        # the parent commit's
        new = run_study(trs_case, ["lm"], trials=1, seed=0).records[0]
    assert new["status"] == BUDGET_EXHAUSTED and new["nfev"] == 2001
    old = {**new, "status": COMPLETED, "success": True, "nit": new["nfev"],
           "message": f"evaluation budget of {new['nfev']} exhausted"}
    old["digest"] = record_digest(old)
    path.write_text(json.dumps(old) + "\n")
    study = run_study(trs_case, ["lm"], trials=2, seed=0, results_path=path)
    statuses = {(r["status"], r["success"], r["nit"]) for r in study.records}
    assert len(statuses) == 1, f"one deterministic run, {study.resumed} resumed: {statuses}"


def test_run_study_canonicalises_and_deduplicates_method_names(trs_case):
    study = run_study(trs_case, ["N-SPSA", "nspsa", "n-spsa"], trials=2, executor="serial")
    assert study.methods == ["nspsa"] and len(study.records) == 2


def _lines(path):
    """The lines of a results file (``_processes`` is imported here, not at the top: a child process of
    test_interrupted_study_resumes_to_the_same_summary imports this module without tests/ on its path)."""
    from _processes import lines

    return lines(path)


def _study_lines(trs, path):
    run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    return _lines(path)


@pytest.mark.parametrize("damage", ["42", "null", b"\xff\xfe{}", "trial_null", "fun_abc", "no_curve",
                                    "edited_fun"])
def test_untrustworthy_results_lines_are_set_aside_and_their_trials_rerun(trs_case, tmp_path, damage):
    path = tmp_path / "results.jsonl"
    good = _study_lines(trs_case, path)
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
        study = run_study(trs_case, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    assert study.resumed == (2 if damage == "edited_fun" else 1)
    after = [json.loads(x) for x in _lines(path)]  # trusted lines only, one per trial
    assert sorted((r["trial"], r["fun"]) for r in after) == [(r["trial"], r["fun"]) for r in map(json.loads, good)]
    assert study.values("nspsa").tolist() == [json.loads(g)["fun"] for g in good]
    assert (tmp_path / "results.rejected.jsonl").read_bytes() == raw + b"\n"
    # a clean file afterwards: no warning, every trial reused
    again = run_study(trs_case, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    assert again.resumed == 2 and again.rejected == []


def test_jobs_past_the_cores_are_capped_at_their_number():
    from hammerstein_ctrl._executors import make_executor, usable_cores

    pool, owned = make_executor(None, 10 * usable_cores() + 7)
    try:
        assert owned == (usable_cores() > 1)
        assert pool is None or pool._max_workers == usable_cores()
    finally:
        if owned:
            pool.shutdown()
