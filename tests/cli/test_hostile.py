"""Hostile command-line arguments: each a single line ``hammerstein-ctrl: error: ...`` and exit 2.

Arguments and output paths must be refused before any work starts: the
``no_work`` fixture replaces the fit and the study with recorders, and each
case asserts that neither ran.  Cases whose problem can only be seen by the
optimiser (bounds against the initial point, option sets) run the real code
and must still fail before the first evaluation, as one line.

The hostile *data files* (NPZ/MAT/CSV garbage, encodings) have their own
corpus with ``read_record``; here the file is a valid record.
"""

import importlib
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from hammerstein_ctrl import load_trs
from hammerstein_ctrl.cli import main


linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and fork")

TRS = ["--structure", "trs"]
ORDERS = ["--orders", "1", "2", "--nonlinearity", "tanh"]

#: (argv, expected part of the error line); {csv} a valid record, {tmp} a scratch folder.
BEFORE_ANY_WORK = [
    # reproduce
    (["reproduce", "trs", "--seed", "-1"], "argument --seed: must be a non-negative integer"),
    (["reproduce", "trs", "--seed", "abc"], "argument --seed"),
    (["reproduce", "trs", "--seed", "1.5"], "argument --seed"),
    (["reproduce", "trs", "--seed", ""], "argument --seed"),
    (["reproduce", "trs", "--trials", "0"], "argument --trials: must be a positive integer"),
    (["reproduce", "trs", "--trials", "-3"], "argument --trials"),
    (["reproduce", "trs", "--trials", "1e3"], "argument --trials"),
    (["reproduce", "trs", "--jobs", "0"], "argument --jobs: must be a positive integer"),
    (["reproduce", "trs", "--jobs", "-1"], "argument --jobs: must be a positive integer"),
    (["reproduce", "trs", "--jobs", "two"], "argument --jobs"),
    (["reproduce", "trs", "--methods", "pso"], "unknown method 'pso'"),
    (["reproduce", "trs", "--methods", "nspsa", ""], "unknown method ''"),
    (["reproduce", "trs", "--methods"], "argument --methods: expected at least one argument"),
    (["reproduce", "emps", "--data", "{tmp}/nonexistent"], "nonexistent: no such file or folder"),
    (["reproduce", "trs", "--data", "{csv}"], "--data applies to the EMPS case only"),
    (["reproduce", "trs", "--out", "{csv}"], "exists and is not a directory"),
    (["reproduce", "trs", "--out", "/proc/forbidden/x"], "/proc/forbidden"),
    (["reproduce", "xyz"], "argument case: invalid choice: 'xyz'"),
    (["reproduce"], "the following arguments are required: case"),
    # identify: numbers
    (["identify", "--data", "{csv}", *TRS, "--seed", "-1"], "argument --seed: must be a non-negative integer"),
    (["identify", "--data", "{csv}", *TRS, "--dt", "0"], "dt must be a positive finite number, got 0.0"),
    (["identify", "--data", "{csv}", *TRS, "--dt", "-0.1"], "dt must be a positive finite number, got -0.1"),
    (["identify", "--data", "{csv}", *TRS, "--dt", "nan"], "dt must be a positive finite number, got nan"),
    (["identify", "--data", "{csv}", *TRS, "--dt", "inf"], "dt must be a positive finite number, got inf"),
    (["identify", "--data", "{csv}", *TRS, "--maxfev", "0"], "argument --maxfev: must be a positive integer"),
    (["identify", "--data", "{csv}", *TRS, "--maxfev", "-1"], "argument --maxfev"),
    (["identify", "--data", "{csv}", *TRS, "--maxfev", "nan"], "argument --maxfev"),
    (["identify", "--data", "{csv}", *TRS, "--maxfev", "2.5"], "argument --maxfev"),
    (["identify", "--data", "{csv}", *TRS, "--method", "powell", "--maxfev", "0"], "argument --maxfev"),
    (["identify", "--data", "{csv}", *TRS, "--maxiter", "0"], "argument --maxiter: must be a positive integer"),
    (["identify", "--data", "{csv}", *TRS, "--maxiter", "-4"], "argument --maxiter"),
    (["identify", "--data", "{csv}", *TRS, "--x0", "nan", "0", "5", "-5", "0"], "argument --x0: must be a finite"),
    (["identify", "--data", "{csv}", *TRS, "--x0", "inf", "0", "5", "-5", "0"], "argument --x0"),
    (["identify", "--data", "{csv}", *TRS, "--x0", "1", "abc"], "argument --x0: invalid float value: 'abc'"),
    (["identify", "--data", "{csv}", *ORDERS, "--bounds", "nan", "1"], "argument --bounds"),
    (["identify", "--data", "{csv}", *TRS, "--gain-a", "1", "2", "3", "4"], "--gain-a takes at most 3 numbers, got 4"),
    (["identify", "--data", "{csv}", *TRS, "--gain-a", "0"], "gain scale must be positive"),
    (["identify", "--data", "{csv}", *TRS, "--gain-a", "-1"], "gain scale must be positive"),
    (["identify", "--data", "{csv}", *TRS, "--gain-a", "nan"], "argument --gain-a"),
    (["identify", "--data", "{csv}", *TRS, "--gain-c", "1", "2", "3"], "--gain-c takes at most 2 numbers, got 3"),
    (["identify", "--data", "{csv}", *TRS, "--gain-c", "0"], "gain scale must be positive"),
    (["identify", "--data", "{csv}", *TRS, "--norm-limit", "0"], "argument --norm-limit"),
    (["identify", "--data", "{csv}", *TRS, "--norm-limit", "-1"], "argument --norm-limit"),
    (["identify", "--data", "{csv}", *TRS, "--norm-limit", "inf"], "argument --norm-limit"),
    (["identify", "--data", "{csv}", *TRS, "--pop-size", "1"], "argument --pop-size: must be an integer >= 2"),
    (["identify", "--data", "{csv}", *TRS, "--pop-size", "0"], "argument --pop-size"),
    (["identify", "--data", "{csv}", *ORDERS[:3], "--nonlinearity", "polynomial", "--degree", "-1"],
     "argument --degree"),
    # identify: names and structures
    (["identify", "--data", "{csv}", *TRS, "--method", "pso"], "unknown method 'pso'"),
    (["identify", "--data", "{csv}", *TRS, "--method", ""], "unknown method ''"),
    (["identify", "--data", "{csv}", "--orders", "0", "50", "--nonlinearity", "tanh"],
     "den_order 50 exceeds MAX_ORDER = 10"),
    (["identify", "--data", "{csv}", "--orders", "2", "1", "--nonlinearity", "tanh"], "improper structure"),
    (["identify", "--data", "{csv}", "--orders", "1", "0", "--nonlinearity", "tanh"], "den_order must be >= 1"),
    (["identify", "--data", "{csv}", "--orders", "-1", "2", "--nonlinearity", "tanh"], "argument --orders"),
    (["identify", "--data", "{csv}", "--orders", "1", "--nonlinearity", "tanh"], "argument --orders"),
    (["identify", "--data", "{csv}", "--orders", "1", "2", "--nonlinearity", "cubic"], "unknown nonlinearity"),
    (["identify", "--data", "{csv}", "--orders", "1", "2"], "give --structure trs|emps"),
    (["identify", "--data", "{csv}", *TRS, "--orders", "1", "2"], "cannot be combined with --structure"),
    (["identify", "--data", "{csv}", *ORDERS, "--fix", "a0"], "--fix expects NAME=VALUE"),
    (["identify", "--data", "{csv}", *ORDERS, "--fix", "a0=abc"], "is not a number"),
    (["identify", "--data", "{csv}", *ORDERS, "--fix", "zz=1"], "cannot fix unknown coefficient 'zz'"),
    (["identify", "--data", "{csv}", *ORDERS, "--fix", "a0=nan"], "must be finite"),
    (["identify", "--data", "{csv}", *TRS, "--structure", "xyz"], "argument --structure: invalid choice"),
    (["identify", "--data", "{csv}", *TRS, "--bounds", "0", "1"], "--bounds needs 10 numbers"),
    # identify: files
    (["identify", "--data", "{tmp}/nope.csv", *TRS], "data file not found"),
    (["identify", "--data", "{csv}", *TRS, "--input", "volts"], "no input column 'volts'"),
    (["identify", "--data", "{flat}", *TRS], "output y is constant"),
    (["identify", "--data", "{csv}", *TRS, "--plot", "{tmp}/x.xyz"], "unknown figure format '.xyz'"),
    (["identify", "--data", "{csv}", *TRS, "--plot", "{tmp}/figure"], "unknown figure format '(none)'"),
    (["identify", "--data", "{csv}", *TRS, "--plot", "{tmp}/no/dir/x.png"], "does not exist"),
    (["identify", "--data", "{csv}", *TRS, "--plot", "{tmp}"], "is a directory"),
    (["identify", "--data", "{csv}", *TRS, "--out", "{tmp}/no/dir/m.json"], "does not exist"),
    (["identify", "--data", "{csv}", *TRS, "--out", "{tmp}"], "is a directory"),
    (["identify", *TRS], "the following arguments are required: --data"),
    # the command itself
    ([], "the following arguments are required: command"),
    (["bogus"], "argument command: invalid choice: 'bogus'"),
    (["identify", "--data", "{csv}", *TRS, "--no-such-flag"], "unrecognized arguments: --no-such-flag"),
]

#: Problems only the optimiser can see; they must still fail before the first evaluation.
AT_THE_OPTIMISER = [
    (["--method", "lm", "--bounds", "0", "1", "0", "10", "0", "10", "-10", "0", "0", "1"],
     r"x0\[0\] = -2 lies outside its bounds \[0, 1\]"),
    (["--method", "lm", "--bounds", "-5", "-5", "0", "10", "0", "10", "-10", "0", "0", "1"], "needs low < high"),
    (["--method", "lm", "--bounds", "0", "-5", "0", "10", "0", "10", "-10", "0", "0", "1"], "invalid bounds"),
    (["--method", "lm", "--maxiter", "5"], "supports neither maxiter nor callback"),
    (["--method", "lm", "--gain-a", "1"], r"unknown option\(s\) \['a'\] for method 'lm'"),
    (["--method", "nspsa", "--norm-limit", "0.1"], r"unknown option\(s\) \['norm_limit'\]"),
    (["--method", "amvo-sca"], "amvo-sca needs finite bounds"),
    (["--method", "amvo-sca", "--pop-size", "500", "--maxfev", "10", "--bounds", "-5", "0", "0", "10", "0", "10",
      "-10", "0", "0", "1"], "budget too small"),
    (["--method", "nspsa", "--bounds", "0", "1", "0", "10", "0", "10", "-10", "0", "0", "1"], "outside the bounds"),
]


def _run(capsys, argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _assert_one_error_line(code, err, pattern):
    assert code == 2, err
    assert "Traceback" not in err
    rows = [r for r in err.splitlines() if r.strip()]
    assert len(rows) == 1, err
    assert rows[0].startswith("hammerstein-ctrl: error: "), err
    assert re.search(pattern, rows[0]), rows[0]


@pytest.fixture
def files(tmp_path):
    t = np.arange(0.0, 2.0, 0.01)
    flat = tmp_path / "flat.csv"
    np.savetxt(flat, np.column_stack([t, np.sin(t), np.full_like(t, 3.0)]), delimiter=",", header="t,u,y",
               comments="")
    return {"{csv}": str(load_trs()[:600].to_csv(tmp_path / "trs.csv")), "{tmp}": str(tmp_path),
            "{flat}": str(flat)}


def _fill(argv, files):
    for key, value in files.items():
        argv = [a.replace(key, value) for a in argv]
    return argv


def test_the_work_recorder_sees_the_fit_a_good_command_starts(capsys, files, no_work):
    """The recorder that the refusals below rely on does intercept a fit the command line starts."""
    try:                                          # the recorder returns no result: what follows may fail, no matter
        _run(capsys, _fill(["identify", "--data", "{csv}", "--orders", "0", "2", "--nonlinearity", "tanh"], files))
    except Exception:                             # noqa: BLE001
        pass
    assert no_work == ["fit"]


@pytest.mark.parametrize("argv, pattern", BEFORE_ANY_WORK, ids=[" ".join(a)[-60:] for a, _ in BEFORE_ANY_WORK])
def test_refused_before_any_work(capsys, files, no_work, argv, pattern):
    code, out, err = _run(capsys, _fill(argv, files))
    _assert_one_error_line(code, err, re.escape(pattern))
    assert no_work == []



@pytest.mark.parametrize("extra, pattern", AT_THE_OPTIMISER, ids=[" ".join(a)[:60] for a, _ in AT_THE_OPTIMISER])
def test_refused_by_the_optimiser_before_evaluating(capsys, files, monkeypatch, extra, pattern):
    from hammerstein_ctrl.fit import HammersteinCost

    calls = []
    for name in ("__call__", "batch", "residuals"):
        original = getattr(HammersteinCost, name)
        monkeypatch.setattr(HammersteinCost, name,
                            lambda self, *a, _o=original, **k: (calls.append(1), _o(self, *a, **k))[1])
    code, out, err = _run(capsys, _fill(["identify", "--data", "{csv}", *TRS, *extra], files))
    _assert_one_error_line(code, err, pattern)
    assert calls == []


def test_a_real_process_prints_one_line_and_exits_2(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "hammerstein_ctrl.cli", "reproduce", "trs", "--seed", "-1"],
                          capture_output=True, text=True, env={"PYTHONSAFEPATH": "1", "PATH": "/usr/bin:/bin"},
                          timeout=120)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.splitlines() == [
        "hammerstein-ctrl: error: argument --seed: must be a non-negative integer, got '-1' "
        "(see hammerstein-ctrl reproduce --help)"]


# -- round 3: a generated corpus of numbers, outputs and inputs, each refused in one line with nothing written ----
#: Numeric options of each command, and values none of them may accept (non-finite, not a number, overflowing).
NUMERIC_OPTIONS = {
    "identify": ["--dt", "--maxfev", "--seed", "--tolerance", "--start", "--stop", "--norm-limit", "--pop-size",
                 "--maxiter"],
    "tune": ["--max-sensitivity", "--phase-margin", "--y0", "--step", "--dt", "--u0", "--tau-c", "--t-final",
             "--maxfev", "--seed"],
    "select": ["--maxfev", "--seed", "--jobs", "--degree", "--dt"],
    "reproduce": ["--seed", "--trials", "--jobs"],
}
BAD_NUMBERS = ["nan", "inf", "-inf", "", "abc", "1e400", "-1e400", "1.2.3", "0x1g", "\u0661e400"]
PREFIX = {"identify": ["identify", "--data", "{csv}", *TRS], "tune": ["tune", "{model}"],
          "select": ["select", "--data", "{csv}", "--orders", "0", "1", "--nonlinearity", "tanh"],
          "reproduce": ["reproduce", "trs", "--out", "{tmp}/out"]}
ROUND3_NUMBERS = [(PREFIX[cmd] + [opt, value], opt.lstrip("-").replace("-", "[-_ ]")) for cmd, opts in
                  NUMERIC_OPTIONS.items() for opt in opts for value in BAD_NUMBERS]

#: Output options and what may stand where a file is to be written.
OUTPUTS = [["identify", "--data", "{csv}", *TRS, "--out"], ["identify", "--data", "{csv}", *TRS, "--plot"],
           ["tune", "{model}", "--plot"],
           ["select", "--data", "{csv}", "--orders", "0", "1", "--nonlinearity", "tanh", "--table"],
           ["select", "--data", "{csv}", "--orders", "0", "1", "--nonlinearity", "tanh", "--out"]]
BAD_OUTPUTS = [("{tmp}/link-to-victim.png", "symbolic link"), ("{tmp}/dangling.png", "symbolic link"),
               ("{tmp}/fifo.png", "not a regular file|is a FIFO|not writable"), ("{tmp}", "directory|folder"),
               ("{tmp}/missing/x.png", "does not exist")]
ROUND3_OUTPUTS = [(cmd + [path], pattern) for cmd in OUTPUTS for path, pattern in BAD_OUTPUTS]
ROUND3_OUTPUTS += [(["reproduce", "trs", "--out", path], pattern) for path, pattern in
                   [("{tmp}/dangling.png", "dangling symbolic link"), ("{tmp}/fifo.png", "not a directory"),
                    ("{csv}", "not a directory"), ("{tmp}/link-to-victim.png", "not a directory")]]

#: Input options and special or broken files.
INPUTS = [["identify", *TRS, "--data"], ["select", "--orders", "0", "1", "--nonlinearity", "tanh", "--data"],
          ["tune"], ["tune", "{model}", "--reference"], ["reproduce", "emps", "--out", "{tmp}/out", "--data"]]
BAD_INPUTS = [("{tmp}/fifo.csv", "FIFO|neither a folder"), ("{tmp}/zero.csv", "device|neither a folder"),
              ("{tmp}/missing.csv", "not found|no such"),
              ("{tmp}/empty.csv", "empty|no data|not valid JSON|holds no samples|neither a folder"),
              ("{tmp}/binary.csv", "NUL|UTF-8|not a file of numbers|not a UTF-8|neither a folder")]
ROUND3_INPUTS = [(cmd + [path], pattern) for cmd in INPUTS for path, pattern in BAD_INPUTS]
ROUND3_INPUTS += [(INPUTS[-1] + ["{tmp}/fifo.mat"], "is a FIFO"), (INPUTS[-1] + ["{tmp}/zero.mat"], "is a device")]

ROUND3 = ROUND3_NUMBERS + ROUND3_OUTPUTS + ROUND3_INPUTS


@pytest.fixture
def hostile_tree(tmp_path, files, monkeypatch):
    """A scratch folder with a victim elsewhere, links, a FIFO and broken files; the working folder inside it."""
    import control

    from hammerstein_ctrl import Coulomb, HammersteinModel, save_model

    victim_dir = tmp_path / "elsewhere"
    victim_dir.mkdir()
    (victim_dir / "victim.txt").write_text("precious\n")
    os.symlink(victim_dir / "victim.txt", tmp_path / "link-to-victim.png")
    os.symlink(tmp_path / "nowhere", tmp_path / "dangling.png")
    os.symlink(victim_dir, tmp_path / "victim-dir-link")
    os.mkfifo(tmp_path / "fifo.png")
    os.mkfifo(tmp_path / "fifo.csv")
    os.symlink("/dev/zero", tmp_path / "zero.csv")
    os.symlink("/dev/zero", tmp_path / "zero.mat")
    os.mkfifo(tmp_path / "fifo.mat")
    (tmp_path / "empty.csv").write_bytes(b"")
    (tmp_path / "binary.csv").write_bytes(bytes(range(256)) * 4)
    save_model(HammersteinModel(control.tf([1], [1, 3.1, 0]), Coulomb(), [0.5, -0.4, 0.05]), tmp_path / "m.json")
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    return {**files, "{model}": str(tmp_path / "m.json")}


def _tree(folder):
    return {str(p.relative_to(folder)): (p.is_symlink(), p.lstat().st_size, p.lstat().st_mtime_ns)
            for p in sorted(folder.rglob("*"))}


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs and symbolic links")
@pytest.mark.parametrize("argv, pattern", ROUND3, ids=[" ".join(a)[-70:] for a, _ in ROUND3])
def test_round3_refused_in_one_line_with_nothing_written(capsys, tmp_path, hostile_tree, no_work, argv, pattern):
    before = _tree(tmp_path)
    code, out, err = _run(capsys, _fill(argv, hostile_tree))
    assert code == 2 and "unexpected failure" not in err, (code, err)
    _assert_one_error_line(code, err, pattern)
    assert no_work == [] and _tree(tmp_path) == before      # no file made, moved or touched, the victim included





# -- a wrong data path, bad arguments, bounds, orders and records, a killed worker: one line each --------------------
@pytest.fixture
def trs_csv(tmp_path):
    return load_trs()[:1000].to_csv(tmp_path / "trs.csv")


def test_a_wrong_emps_data_path_is_an_error_not_other_data(capsys, tmp_path):
    code, out, err = _run(capsys, ["reproduce", "emps", "--data", tmp_path / "nonexistent", "--out", tmp_path / "o"])
    _assert_one_error_line(code, err, re.escape("nonexistent: no such file or folder"))
    assert not (tmp_path / "o").exists()


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
def test_bad_arguments_are_refused_in_one_line_before_any_work(capsys, tmp_path, trs_csv, no_work, argv, message):
    argv = [a.replace("{csv}", str(trs_csv)).replace("{tmp}", str(tmp_path)) for a in argv]
    code, out, err = _run(capsys, argv)
    assert no_work == []
    _assert_one_error_line(code, err, re.escape(message))


@pytest.mark.parametrize("bounds, message", [
    (["0", "1", "0", "10", "0", "10", "-10", "0", "0", "1"], r"x0\[0\] = -2 lies outside its bounds \[0, 1\]"),
    (["-5", "-5", "0", "10", "0", "10", "-10", "0", "0", "1"], "needs low < high"),
])
def test_lm_bounds_problems_are_refused_in_one_line(capsys, trs_csv, bounds, message):
    code, out, err = _run(capsys, ["identify", "--data", trs_csv, "--structure", "trs", "--method", "lm",
                                   "--bounds", *bounds])
    _assert_one_error_line(code, err, message)


def test_orders_past_max_order_are_refused_before_any_work(capsys, trs_csv, no_work):
    code, out, err = _run(capsys, ["identify", "--data", trs_csv, "--orders", 0, 50, "--nonlinearity", "tanh"])
    assert no_work == []
    _assert_one_error_line(code, err, re.escape("den_order 50 exceeds MAX_ORDER = 10"))


def test_a_constant_output_is_refused_before_the_fit(capsys, tmp_path, no_work):
    t = np.arange(0.0, 2.0, 0.01)
    path = tmp_path / "flat.csv"
    np.savetxt(path, np.column_stack([t, np.sin(t), np.full_like(t, 3.0)]), delimiter=",",
               header="t,u,y", comments="")
    code, out, err = _run(capsys, ["identify", "--data", path, "--structure", "trs"])
    assert no_work == []
    _assert_one_error_line(code, err, re.escape("output y is constant"))


def _die(*args):  # a trial whose worker is killed (as by the OOM killer)
    os._exit(9)


@linux
def test_a_killed_worker_is_reported_in_one_line(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(importlib.import_module("hammerstein_ctrl.paper.study"), "_run_trial", _die)
    code, out, err = _run(capsys, ["reproduce", "trs", "--methods", "nspsa", "--trials", 2, "--jobs", 2,
                                   "--out", tmp_path, "--no-figures"])
    _assert_one_error_line(code, err, re.escape("a worker process died unexpectedly"))
