"""Records from real rigs: irregular time stamps, windows, trends, resampling, reading options."""

import argparse

import numpy as np
import pytest
import scipy.signal

from hammerstein_ctrl import DataError, IOData, load_emps, read_record
from hammerstein_ctrl.paper.datasets import DataNotFoundError
from hammerstein_ctrl.data._records import add_record_arguments, record_from_args

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


# -- large, special and binary files ------------------------------------------------------------------------
import os  # noqa: E402
import tracemalloc  # noqa: E402

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from hammerstein_ctrl.data import _records as records  # noqa: E402
from hammerstein_ctrl._safe_io import MAX_BYTES_ENV  # noqa: E402


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_special_files_are_refused_without_reading(tmp_path):
    fifo = tmp_path / "r.csv"
    os.mkfifo(fifo)                                 # opening it to read would block
    with pytest.raises(DataError, match="is a FIFO, not a regular file"):
        read_record(fifo)
    os.symlink("/dev/zero", tmp_path / "z.csv")     # reading it would never end
    with pytest.raises(DataError, match="is a device, not a regular file"):
        read_record(tmp_path / "z.csv")


def test_a_file_beyond_the_size_limit_names_its_size_and_the_variable(tmp_path, monkeypatch):
    path = tmp_path / "r.csv"
    path.write_text("u,y\n" + "1,2\n" * 1000)
    monkeypatch.setenv(MAX_BYTES_ENV, "1000")
    with pytest.raises(DataError, match=rf"4.0 kB, larger than the limit of 1.0 kB .*{MAX_BYTES_ENV}"):
        read_record(path)


def test_a_large_binary_file_is_refused_from_its_first_block(tmp_path):
    path = tmp_path / "nul.csv"
    with open(path, "wb") as fh:
        fh.truncate(200_000_000)        # 200 MB of NUL bytes, sparse
    tracemalloc.start()
    with pytest.raises(DataError, match="NUL bytes on line 1"):
        read_record(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 2_000_000             # the first block, not the file


def test_a_large_csv_is_read_in_about_the_memory_of_its_numbers(tmp_path):
    n = 300_000
    path = tmp_path / "big.csv"
    t = np.arange(n) * 1e-3
    np.savetxt(path, np.c_[t, np.sin(t), np.cos(t)], delimiter=",", header="t,u,y", comments="", fmt="%.9g")
    tracemalloc.start()
    d = read_record(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert len(d) == n and d.dt == 0.001
    assert peak / n < 120               # bytes per sample (the table is 24; Python lists of the text: > 500)


_FIELD = st.one_of(st.floats(-1e6, 1e6, allow_nan=False).map(repr), st.integers(-10**6, 10**6).map(str),
                   st.sampled_from(["", " ", "nan", "inf", "1e400", "x", "1,5", '"3"', "1_0", "0x10", "+.5", "-0"]))


@st.composite
def _csv_texts(draw):
    delimiter = draw(st.sampled_from([",", "\t", " ", ";"]))
    width = draw(st.sampled_from([2, 3]))
    header = draw(st.sampled_from([None, ["t", "u", "y"][-width:], ["time", "input", "output"][-width:]]))
    rows = draw(st.lists(st.lists(_FIELD, min_size=width - 1, max_size=width + 1), min_size=1, max_size=6))
    lines = ([delimiter.join(header)] if header else [])
    lines += [delimiter.join(r) for r in rows]
    if draw(st.booleans()):
        lines.insert(draw(st.integers(0, len(lines))), draw(st.sampled_from(["# comment", "", "   "])))
    end = draw(st.sampled_from(["\n", "\r\n"]))
    return end.join(lines) + (end if draw(st.booleans()) else "")


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(text=_csv_texts())
def test_the_fast_reader_agrees_with_the_line_checking_reader(tmp_path_factory, text):
    """Both readers give the same columns, or the fast one steps aside (None) and the careful one decides."""
    path = tmp_path_factory.mktemp("csv") / "r.csv"
    path.write_text(text)
    try:
        careful = records._careful_columns(path)
    except DataError:
        careful = None
    fast = records._fast_columns(path, records._head(path))
    if fast is not None:
        assert careful is not None and list(fast) == list(careful)
        for name in fast:
            np.testing.assert_array_equal(fast[name], careful[name])


@settings(max_examples=200, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(data=st.binary(max_size=400))
def test_any_bytes_give_a_record_or_a_data_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("csv") / "r.csv"
    path.write_bytes(data)
    try:
        read_record(path)
    except DataError:
        pass


def test_masked_samples_are_refused_not_ignored():
    u = np.ma.masked_array(np.ones(10), mask=[0] * 9 + [1])
    with pytest.raises(DataError, match="u has 1 masked sample"):
        IOData(u, np.ones(10), dt=0.1)
    d = IOData(np.ma.masked_array(np.ones(10)), np.ones(10), dt=0.1)     # nothing masked: its data
    assert d.u.tolist() == [1.0] * 10


def test_a_list_of_columns_reads_a_record_with_several_channels(tmp_path):
    path = tmp_path / "twin.csv"
    rows = "".join(f"{k / 10},{4 * k + 1},{4 * k + 2},{4 * k + 3},{4 * k + 4}\n" for k in range(5))
    path.write_text("time,v_pitch,v_yaw,pitch,yaw\n" + rows)
    d = read_record(path, input=["v_pitch", "v_yaw"], output=["pitch", "yaw"])
    assert (d.n_inputs, d.n_outputs) == (2, 2) and d.input_names == ("v_pitch", "v_yaw")
    assert d.outputs[:, 1].tolist() == [4.0, 8.0, 12.0, 16.0, 20.0] and d.dt == 0.1
    mixed = read_record(path, input=["v_pitch", "v_yaw"], output="yaw")
    assert mixed.n_outputs == 1 and mixed.output_name == "yaw"
    with pytest.raises(DataError, match="no output column 'roll'"):
        read_record(path, input=["v_pitch"], output=["pitch", "roll"])
    with pytest.raises(DataError, match="same column is chosen"):
        read_record(path, input=["v_pitch", "pitch"], output=["pitch"])


def test_a_jitter_near_half_a_step_suggests_only_what_the_check_accepts():
    import numpy as np

    from hammerstein_ctrl import DataError, IOData

    t = np.arange(10) * 0.1
    t[3] += 0.0496                                   # 0.496 of a step: the rounded-up 0.5 would be refused
    with pytest.raises(DataError) as info:
        IOData(np.zeros(10), np.zeros(10), t)
    assert "pass tolerance=" not in str(info.value) and "resample=" in str(info.value)
    t[3] = 0.3 + 0.046                               # 0.46 of a step: the suggested tolerance is accepted
    with pytest.raises(DataError, match="pass tolerance=0.46"):
        IOData(np.zeros(10), np.zeros(10), t)
    assert len(IOData(np.zeros(10), np.zeros(10), t, tolerance=0.46)) == 10
