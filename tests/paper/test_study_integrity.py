"""A study's results file is checked, never trusted; one run at a time writes it."""

import fcntl
import json
import sys

import pytest

from hammerstein_ctrl import presets
from hammerstein_ctrl.cli import main
from hammerstein_ctrl.paper.study import (RECORD_SCHEMA, ResultsFileWarning, StudyLockedError, record_digest, run_study,
                                          validate_record)

from _processes import cli, lines, wait_for

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses flock and /proc")


@pytest.fixture(scope="module")
def trs():
    return presets.trs()


@pytest.fixture(scope="module")
def record(trs, tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "results.jsonl"
    run_study(trs, ["nspsa"], trials=1, seed=0, executor="serial", results_path=path)
    return json.loads(lines(path)[0])


def test_a_fresh_record_is_valid_and_its_digest_covers_every_field(record):
    assert validate_record(record) is None
    assert set(record) == set(RECORD_SCHEMA)
    for key in RECORD_SCHEMA:
        if key != "digest":
            changed = {**record, key: "changed"}
            assert record_digest(changed) != record["digest"], key


#: A field set to a value of the wrong kind; each must be refused by the schema.
WRONG_VALUES = [("case", 1), ("method", None), ("trial", -1), ("trial", 1.5), ("trial", True), ("seed", "0"),
                ("config", 3), ("fun", "abc"), ("fun", None), ("fun", [1]), ("x", []), ("x", ["abc"]),
                ("x", 3.0), ("nfev", -1), ("nfev", 2.0), ("nit", None), ("status", "0"), ("success", 1),
                ("diverged", "no"), ("message", 0), ("best_fun", {}), ("nfev_monitor", -2),
                ("elapsed", -1.0), ("elapsed", "inf"), ("curve", None), ("curve", {"nfev": [1], "best": [],
                                                                                    "estimate": []}),
                ("curve", {"nfev": ["a"], "best": [1.0], "estimate": [1.0]}), ("digest", None)]


@pytest.mark.parametrize("key, value", WRONG_VALUES)
def test_schema_refuses_wrong_values(record, key, value):
    bad = {**record, key: value}
    bad["digest"] = record_digest(bad) if key != "digest" else value  # a consistent digest does not help
    assert "invalid value" in validate_record(bad)


@pytest.mark.parametrize("change", ["missing", "extra", "edited"])
def test_schema_refuses_missing_extra_and_edited(record, change):
    if change == "missing":
        bad = {k: v for k, v in record.items() if k != "curve"}
        expected = "missing field(s) ['curve']"
    elif change == "extra":
        bad = {**record, "note": "hi"}
        expected = "unknown field(s) ['note']"
    else:
        bad = {**record, "fun": record["fun"] * 0.5}
        expected = "does not match its digest"
    assert expected in validate_record(bad)


def test_a_line_cut_short_is_moved_aside_and_its_trial_rerun(trs, tmp_path):
    path = tmp_path / "results.jsonl"
    run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    good = lines(path)
    path.write_text(good[0] + "\n" + good[1][: len(good[1]) // 2])  # interrupted mid-write
    with pytest.warns(ResultsFileWarning, match="cut short"):
        study = run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    assert study.resumed == 1 and len(lines(path)) == 2
    assert (tmp_path / "results.rejected.jsonl").read_text() == good[1][: len(good[1]) // 2] + "\n"


def test_lines_of_other_settings_are_kept_but_not_used(trs, tmp_path):
    path = tmp_path / "results.jsonl"
    run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    other = run_study(trs, ["nspsa"], trials=2, seed=1, executor="serial", results_path=path)
    assert other.resumed == 0 and other.rejected == [] and len(lines(path)) == 4
    again = run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    assert again.resumed == 2 and len(lines(path)) == 4


def test_a_repeated_line_is_dropped(trs, tmp_path):
    path = tmp_path / "results.jsonl"
    run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    good = lines(path)
    path.write_text("\n".join(good + good[:1]) + "\n")
    with pytest.warns(ResultsFileWarning, match="line 3: a repeat of a trial already in the file"):
        study = run_study(trs, ["nspsa"], trials=2, seed=0, executor="serial", results_path=path)
    assert study.resumed == 2 and lines(path) == good


@linux
def test_a_held_lock_refuses_a_second_run_at_once(trs, tmp_path):
    path = tmp_path / "results.jsonl"
    with open(tmp_path / "results.jsonl.lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        fh.write("4242")
        fh.flush()
        with pytest.raises(StudyLockedError, match=r"another run \(pid 4242\) is writing .*results.jsonl"):
            run_study(trs, ["nspsa"], trials=1, executor="serial", results_path=path)
    assert not path.exists()
    # released: the run proceeds
    assert run_study(trs, ["nspsa"], trials=1, executor="serial", results_path=path).resumed == 0


@pytest.mark.slow
@linux
def test_two_concurrent_runs_one_proceeds_the_other_reports_the_lock(capsys, tmp_path):
    trials = 12
    first = cli("reproduce", "trs", "--methods", "nspsa", "--trials", trials, "--jobs", 1, "--out", tmp_path,
                "--no-figures", "--no-progress")
    lock = tmp_path / "results.jsonl.lock"
    try:
        assert wait_for(lambda: lock.is_file() and lock.read_text() == str(first.pid)), "first run never locked"
        code = main(["reproduce", "trs", "--methods", "nspsa", "--trials", str(trials), "--jobs", "1",
                     "--out", str(tmp_path), "--no-figures", "--no-progress"])
        err = capsys.readouterr().err
        assert code == 2
        assert err.splitlines() == [f"hammerstein-ctrl: error: another run (pid {first.pid}) is writing "
                                    f"{tmp_path / 'results.jsonl'}; wait for it to finish or choose another "
                                    "output directory"]
        out, errs = first.communicate(timeout=300)
    finally:
        if first.poll() is None:
            first.kill()
            first.communicate()
    assert first.returncode == 0, errs
    keys = [(r["method"], r["trial"]) for r in map(json.loads, lines(tmp_path / "results.jsonl"))]
    assert sorted(keys) == [("nspsa", i) for i in range(trials)]  # every trial once, no duplicates


_POOL_WITHOUT_PDEATHSIG = """
import sys, time, concurrent.futures as cf, multiprocessing, os
import hammerstein_ctrl._executors as executors
sys.platform = "not-linux"  # the workers rely on the parent watch alone
pool = cf.ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork"),
                              initializer=executors.worker_init, initargs=(os.getpid(),))
list(pool.map(abs, range(4)))
print("ready", flush=True)
time.sleep(600)
"""


@linux
def test_without_pdeathsig_the_parent_watch_ends_the_workers(tmp_path):
    import os
    import signal
    import subprocess

    from _processes import alive, children
    from hammerstein_ctrl._executors import PARENT_WATCH_INTERVAL

    proc = subprocess.Popen([sys.executable, "-c", _POOL_WITHOUT_PDEATHSIG], stdout=subprocess.PIPE, text=True,
                            env=dict(os.environ))
    try:
        assert proc.stdout.readline().strip() == "ready"
        workers = children(proc.pid)
        assert len(workers) == 2
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        assert wait_for(lambda: not any(map(alive, workers)), timeout=5.0)
        assert PARENT_WATCH_INTERVAL < 5.0
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()
