"""Records from real rigs: irregular time stamps, windows, trends, resampling, reading options."""

import argparse

import numpy as np
import pytest
import scipy.signal

from hammerstein_ctrl import DataError, IOData, load_emps, read_record
from hammerstein_ctrl.datasets import DataNotFoundError
from hammerstein_ctrl.records import add_record_arguments, record_from_args

DT = 1e-3
N = 1000
FREQ = 5.0  # Hz, the test sine


def sine(t):
    return np.sin(2 * np.pi * FREQ * t)


def jittered_times(fraction, seed=0, n=N):
    rng = np.random.default_rng(seed)
    return DT * np.arange(n) + rng.uniform(-fraction, fraction, n) * DT


# -- error messages point at the right sample ---------------------------------------
def test_dropped_sample_message_names_the_gap():
    t = np.delete(DT * np.arange(N), 500)
    with pytest.raises(DataError) as exc:
        IOData(sine(t), sine(t), t)
    msg = str(exc.value)
    assert "1 sample(s) missing between sample 499 (t = 0.499 s) and sample 500 (t = 0.501 s)" in msg
    assert "resample='linear'" in msg and "start=/stop=" in msg


def test_two_dropped_runs_count_the_gaps():
    t = np.delete(DT * np.arange(N), [100, 101, 102, 700])
    with pytest.raises(DataError, match=r"3 sample\(s\) missing between sample 99 .* \(2 irregular steps in all\)"):
        IOData(np.zeros(t.size), np.zeros(t.size), t)


def test_jitter_message_names_the_worst_sample_and_a_tolerance_that_works():
    t = jittered_times(0.10)
    worst = int(np.argmax(np.abs(t - DT * np.arange(N))))  # independent: the true grid is k*DT
    with pytest.raises(DataError) as exc:
        IOData(np.zeros(N), np.zeros(N), t)
    msg = str(exc.value)
    assert f"sample {worst} (t = {t[worst]:.10g} s)" in msg
    assert "beyond tolerance=0.001" in msg
    suggested = float(msg.split("pass tolerance=")[1].split()[0])
    assert 0.099 < suggested <= 0.11
    d = IOData(np.zeros(N), np.zeros(N), t, tolerance=suggested)  # the suggestion is accepted
    assert d.dt == DT
    np.testing.assert_array_equal(d.t, DT * np.arange(N))
    with pytest.raises(DataError, match="beyond tolerance=0.09"):
        IOData(np.zeros(N), np.zeros(N), t, tolerance=0.09)


def test_a_time_jump_is_located_where_it_happens():
    t = DT * np.arange(N)
    t[300:] += 0.3 * DT  # the clock jumps between samples 299 and 300
    with pytest.raises(DataError, match=r"sample 300 \(t = 0.3003 s\) is 0.1\d*\*dt away"):
        IOData(np.zeros(N), np.zeros(N), t)


def test_extra_and_duplicated_stamps():
    t = np.insert(DT * np.arange(20), 10, 0.0094)
    with pytest.raises(DataError, match=r"extra or misplaced time stamp: only 0.4\*dt between sample 9"):
        IOData(np.zeros(21), np.zeros(21), t)
    t = np.insert(0.125 * np.arange(20), 10, 1.125)
    with pytest.raises(DataError, match=r"t\[10\] = 1.125 follows t\[9\] = 1.125 \(a duplicated time stamp\)"):
        IOData(np.zeros(21), np.zeros(21), t)
    with pytest.raises(DataError, match=r"time runs backwards"):
        IOData(np.zeros(3), np.zeros(3), [0.0, 0.2, 0.1])


@pytest.mark.parametrize("tolerance", [0.5, -1e-3, "abc", np.nan])
def test_tolerance_is_validated(tolerance):
    with pytest.raises(DataError, match="tolerance must be"):
        IOData(np.zeros(3), np.zeros(3), dt=1.0, tolerance=tolerance)


def test_epoch_time_stamps_are_regularised():
    t = 1.7e9 + DT * np.arange(N)  # Unix time: float64 resolution 2.4e-7 s = 2.4e-4 dt
    d = IOData(np.zeros(N), np.zeros(N), t)
    assert d.dt == DT and d.t[0] == 1.7e9


# -- resampling ----------------------------------------------------------------------
def test_dropped_sample_resampled_back_onto_the_original_grid():
    full = DT * np.arange(N)
    t = np.delete(full, 500)
    d = IOData(sine(t), 2 * sine(t), t, resample="linear")
    assert d.dt == DT and len(d) == N
    np.testing.assert_array_equal(d.t, full)
    keep = np.arange(N) != 500
    np.testing.assert_array_equal(d.u[keep], sine(t))  # the kept samples are untouched
    expected_500 = 0.5 * (sine(full[499]) + sine(full[501]))
    assert d.u[500] == pytest.approx(expected_500, abs=1e-15)
    assert abs(d.u[500] - sine(full[500])) < (2 * np.pi * FREQ * DT) ** 2 / 2


def test_jittered_sine_resampled_matches_the_true_uniform_samples():
    """Samples truly taken at 10 %-jittered times, interpolated back to k*dt."""
    t = jittered_times(0.10, seed=3)
    d = IOData(sine(t), sine(t), t, resample="linear")
    assert d.dt == DT and d.t[0] >= t[0] and d.t[-1] <= t[-1]
    truth = sine(d.t)
    err = float(np.max(np.abs(d.y - truth)))
    # linear interpolation error bound h^2/8 * max|y''| with the longest step h <= 1.2 dt
    bound = (1.2 * DT) ** 2 / 8 * (2 * np.pi * FREQ) ** 2
    assert err <= bound
    assert err > bound / 100  # the stamps were really irregular
    as_uniform = IOData(sine(t), sine(t), t, tolerance=0.11)  # stamps taken as a noisy uniform clock
    err_uniform = float(np.max(np.abs(as_uniform.y - sine(as_uniform.t))))
    assert err_uniform > 10 * err  # resampling is the right fix for samples truly taken at those times
    print(f"jittered sine resampled: max error {err:.3g} (bound {bound:.3g}); "
          f"taken as uniform instead: {err_uniform:.3g}")
    np.testing.assert_array_equal(d.u, d.y)


def test_zoh_resampling_holds_the_latest_sample():
    t = jittered_times(0.2, seed=5, n=200)
    u = np.random.default_rng(6).normal(size=200)
    d = IOData(u, u, t, resample="zoh", intersample="zoh")
    assert d.intersample == "zoh"
    expected = [u[max(j for j in range(200) if t[j] <= g)] for g in d.t]  # brute-force oracle
    np.testing.assert_array_equal(d.u, expected)
    np.testing.assert_allclose(d.y, np.interp(d.t, t, u), rtol=0, atol=1e-15)  # output stays linear


def test_resampling_onto_a_given_dt_and_its_limits():
    t = jittered_times(0.1, seed=1, n=100)
    d = IOData(t, t, t, dt=2 * DT, resample="linear")
    assert d.dt == 2 * DT and d.t[0] == t[0]
    np.testing.assert_allclose(d.u, d.t, rtol=0, atol=1e-15)  # a ramp is interpolated exactly
    gappy = np.delete(DT * np.arange(100), np.arange(40, 60))
    with pytest.raises(DataError, match=r"gap of 21\*dt \(typical step dt = 0.001 s\) between sample 39 "
                                        r"\(t = 0.039 s\) and sample 40 \(t = 0.06 s\)"):
        IOData(gappy, gappy, gappy, resample="linear")
    with pytest.raises(DataError, match="more than 100x"):
        IOData(t, t, t, dt=1e-9, resample="linear")
    with pytest.raises(DataError, match="resample must be one of"):
        IOData(t, t, t, resample="cubic")
    with pytest.raises(DataError, match="resample needs the sample times"):
        IOData(t, t, dt=DT, resample="linear")


def test_uniform_record_resample():
    d = IOData([0.0, 1.0, 2.0, 3.0], [0.0, 10.0, 20.0, 30.0], dt=1.0, name="ramp", intersample="zoh")
    up = d.resample(0.25)
    assert len(up) == 13 and up.dt == 0.25 and up.intersample == "zoh" and up.name == "ramp"
    np.testing.assert_allclose(up.y, 10 * up.t, atol=1e-12)
    np.testing.assert_array_equal(up.u, np.floor(up.t + 1e-12))  # zoh follows intersample
    np.testing.assert_allclose(d.resample(0.25, "linear").u, up.t, atol=1e-12)
    down = IOData(np.arange(10.0), np.arange(10.0), dt=0.1).resample(0.3)
    np.testing.assert_allclose(down.t, [0, 0.3, 0.6, 0.9], atol=1e-12)
    np.testing.assert_allclose(down.u, [0, 3, 6, 9], atol=1e-12)


# -- window, detrend, offsets ----------------------------------------------------------
def test_window_in_seconds():
    d = IOData(np.arange(100.0), np.arange(100.0), dt=0.01, intersample="zoh")
    w = d.window(0.2, 0.5)
    assert w.t[0] == pytest.approx(0.2) and w.t[-1] == pytest.approx(0.49) and len(w) == 30
    assert w.u[0] == 20 and w.intersample == "zoh"
    assert len(d.window(start=0.95)) == 5 and len(d.window(stop=0.02)) == 2
    with pytest.raises(DataError, match=r"window\(start=0.5, stop=0.505\) keeps 1 sample"):
        d.window(0.5, 0.505)
    with pytest.raises(DataError, match="start must be a finite time"):
        d.window(np.nan)
    assert not hasattr(d, "segment")  # one name per concept


def test_detrend_matches_scipy():
    rng = np.random.default_rng(2)
    t = 0.1 * np.arange(50)
    u, y = rng.normal(size=50) + 3.0, rng.normal(size=50) + 0.4 * t + 2.0
    d = IOData(u, y, t)
    np.testing.assert_allclose(d.detrend("linear").y, scipy.signal.detrend(y, type="linear"), atol=1e-12)
    np.testing.assert_array_equal(d.detrend("linear").u, u)
    both = d.detrend("constant", which="both")
    np.testing.assert_allclose(both.u, scipy.signal.detrend(u, type="constant"), atol=1e-12)
    np.testing.assert_allclose(both.y, scipy.signal.detrend(y, type="constant"), atol=1e-12)
    with pytest.raises(DataError, match="kind must be one of"):
        d.detrend("quadratic")
    with pytest.raises(DataError, match="which must be one of"):
        d.detrend(which="x")


def test_remove_offset():
    d = IOData([1.0, 2.0, 4.0], [0.5, 0.7, 0.9], dt=1.0)
    assert d.remove_offset(y=0.5).y.tolist() == pytest.approx([0.0, 0.2, 0.4])
    assert d.remove_offset(u="initial").u.tolist() == [0.0, 1.0, 3.0]
    with pytest.raises(DataError, match="y offset must be a finite number or 'initial'"):
        d.remove_offset(y=[1, 2])
    with pytest.raises(DataError, match="u offset must be a finite number or 'initial', got inf"):
        d.remove_offset(u=np.inf)


def test_check_identifiable():
    IOData([0.0, 1.0], [0.0, 1.0], dt=1.0).check_identifiable(n_params=2)
    with pytest.raises(DataError, match=r"output y is constant \(every sample is 0.5\); nothing to identify"):
        IOData([0.0, 1.0, 2.0], [0.5, 0.5, 0.5], dt=1.0).check_identifiable()
    with pytest.raises(DataError, match="input u is zero throughout"):
        IOData([0.0, 0.0], [0.0, 1.0], dt=1.0).check_identifiable()
    with pytest.raises(DataError, match="only 2 samples for 4 parameters"):
        IOData([0.0, 1.0], [0.0, 1.0], dt=1.0).check_identifiable(n_params=4)


# -- read_record options ----------------------------------------------------------------
def _write(path, t, u, y, header="t,u,y"):
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",", fmt="%.17g", header=header, comments="")
    return path


def test_read_record_tolerance_resample_window(tmp_path):
    t = jittered_times(0.1, seed=4)
    path = _write(tmp_path / "jitter.csv", t, sine(t), sine(t))
    with pytest.raises(DataError, match=r"jitter.csv: t is an irregular time grid.*pass tolerance=0.1"):
        read_record(path)
    assert read_record(path, tolerance=0.11).dt == DT
    r = read_record(path, resample="linear")
    assert r.dt == DT and np.max(np.abs(r.y - sine(r.t))) < 1e-3
    gap = np.delete(DT * np.arange(N), np.arange(600, 650))
    path = _write(tmp_path / "gap.csv", gap, sine(gap), sine(gap))
    with pytest.raises(DataError, match=r"50 sample\(s\) missing between sample 599"):
        read_record(path)
    before = read_record(path, stop=0.6)  # keep the part before the gap
    assert len(before) == 600 and before.t[-1] == pytest.approx(0.599)
    after = read_record(path, start=0.62, intersample="zoh")
    assert len(after) == 350 and after.t[0] == pytest.approx(0.65) and after.intersample == "zoh"
    with pytest.raises(DataError, match=r"start=5.0, stop=None keep 0 sample"):
        read_record(path, start=5.0)
    np.savetxt(tmp_path / "nodt.csv", np.column_stack([np.arange(10.0), np.arange(10.0)]), delimiter=",")
    w = read_record(tmp_path / "nodt.csv", dt=0.5, start=1.0, stop=2.0)
    assert w.t.tolist() == [1.0, 1.5] and w.u.tolist() == [2.0, 3.0]


def test_cli_arguments_build_the_record(tmp_path):
    t = np.delete(DT * np.arange(200), 50)
    path = _write(tmp_path / "rig.csv", t, sine(t), sine(t), header="time,force,position")
    parser = argparse.ArgumentParser()
    add_record_arguments(parser)
    args = parser.parse_args(["--data", str(path), "--input", "force", "--output", "position",
                              "--resample", "zoh", "--intersample", "zoh", "--start", "0.01", "--stop", "0.1"])
    d = record_from_args(args)
    assert d.intersample == "zoh" and d.dt == DT and len(d) == 90 and d.t[0] == pytest.approx(0.01)
    assert d.u[41] == d.u[40] == pytest.approx(sine(0.049))  # the dropped t = 0.05 is held
    args = parser.parse_args(["--data", str(path), "--input", "force", "--output", "position"])
    with pytest.raises(DataError, match="1 sample"):
        record_from_args(args)
    args = parser.parse_args(["--data", str(path), "--input", "force", "--output", "position", "--tolerance", "2"])
    with pytest.raises(DataError, match=r"tolerance must be in \[0, 0.5\)"):
        record_from_args(args)
    with pytest.raises(SystemExit):
        parser.parse_args(["--data", str(path), "--resample", "cubic"])


# -- explicit paths are never replaced by the environment ---------------------------------
def test_explicit_emps_path_is_the_only_place_searched(emps_dir, monkeypatch):
    from hammerstein_ctrl import presets

    monkeypatch.setenv("HAMMERSTEIN_CTRL_DATA", str(emps_dir.parent))
    assert len(load_emps(duration=1.0)) == 1000  # the environment works without a path
    for bad in ("/nonexistent", "/nonexistent/DATA_EMPS.mat"):
        with pytest.raises(DataNotFoundError) as exc:
            load_emps(path=bad)
        assert "/nonexistent" in str(exc.value) and "is not used" in str(exc.value)
    with pytest.raises(DataNotFoundError, match="/nonexistent"):
        presets.emps(path="/nonexistent")


def test_garbage_emps_file_is_a_data_error(tmp_path):
    (tmp_path / "DATA_EMPS.mat").write_bytes(b"not a mat file at all" * 10)
    with pytest.raises(DataError, match="DATA_EMPS.mat is not a readable MAT file"):
        load_emps(path=tmp_path)
