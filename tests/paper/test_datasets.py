import sys

import numpy as np
import pytest
import scipy.io

from hammerstein_ctrl import DataError, IOData, load_emps, load_trs, read_record
from hammerstein_ctrl._checks import as_signal
from hammerstein_ctrl.paper.datasets import TRS_SEED, DataNotFoundError, make_trs_reconstruction
from hammerstein_ctrl.simulate import lsim


# -- IOData validation ---------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(u=[0, np.nan, 1], y=[0, 1, 2], dt=1.0), "u contains 1 non-finite value.*NaN at sample 1"),
        (dict(u=[0, 1, 2], y=[0, np.inf, 2], dt=1.0), "y contains 1 non-finite value.*inf at sample 1"),
        (dict(u=[0, 1, 2], y=[0, 1], dt=1.0), "length mismatch: u has 3 samples but y has 2"),
        (dict(u=[], y=[], dt=1.0), "u is empty"),
        (dict(u=[0, 1, 2], y=[0, 1, 2], t=[0, 2, 1]), "not strictly increasing"),
        (dict(u=[0, 1, 2, 3], y=[0, 1, 2, 3], t=[0, 1, 2.5, 3]),
         r"irregular time grid beyond tolerance=0.001.*sample 2 \(t = 2.5 s\) is 0.5\*dt away"),
        (dict(u=[0, 1, 2], y=[0, 1, 2], t=[0, 1]), "length mismatch: t has 2 samples"),
        (dict(u=[0, 1, 2], y=[0, 1, 2]), "give the sample times t or the sampling interval dt"),
        (dict(u=[0, 1, 2], y=[0, 1, 2], dt=-0.1), "dt must be a positive finite number"),
        (dict(u=np.zeros((2, 2, 2)), y=[0, 1], dt=1.0), r"u must be one signal \(N,\) or channels as columns"),
        (dict(u=["a", "b"], y=[0, 1], dt=1.0), "u must be numeric"),
    ],
)
def test_bad_records_raise_specific_errors(kwargs, message):
    with pytest.raises(DataError, match=message):
        IOData(**kwargs)


def test_nearly_regular_grid_is_regularised():
    t = np.arange(1000) * 1e-3
    jitter = t + np.random.default_rng(0).uniform(-3e-8, 3e-8, t.size)  # 3e-5 dt, like EMPS
    d = IOData(np.zeros(1000), np.zeros(1000), jitter)
    assert d.dt == 1e-3
    np.testing.assert_array_equal(d.t, np.arange(1000) * 1e-3)


def test_slicing_unpacking_and_segments():
    d = IOData(np.arange(10.0), 2 * np.arange(10.0), dt=0.5, name="toy")
    u, y = d
    assert u[3] == 3 and y[3] == 6
    s = d[2:8:2]
    assert len(s) == 3 and s.dt == 1.0 and s.t[0] == 1.0
    assert len(d.window(1.0, 3.0)) == 4  # t = 1, 1.5, 2, 2.5
    with pytest.raises(TypeError, match="slicing only"):
        d[3]
    with pytest.raises(DataError, match="positive step"):
        d[::-1]
    with pytest.raises(DataError, match="leaves 1 sample"):
        d[:1]


# -- EMPS -------------------------------------------------------------------------
def test_emps_records(emps_dir):
    est = load_emps(path=emps_dir)
    assert len(est) == 24841 and est.dt == 0.001
    np.testing.assert_array_equal(est.t, np.arange(24841) * 0.001)
    raw = scipy.io.loadmat(emps_dir / "DATA_EMPS.mat")
    np.testing.assert_array_equal(est.u, raw["vir"].ravel())
    np.testing.assert_array_equal(est.y, raw["qm"].ravel())
    first = load_emps("estimation", duration=12, path=emps_dir)
    assert len(first) == 12000 and first.t[-1] == pytest.approx(11.999)
    val = load_emps("validation", path=emps_dir / "DATA_EMPS_PULSES.mat")
    assert len(val) == 24841 and val.name == "EMPS validation"
    assert est.input_unit == "N" and est.output_unit == "m"


def test_emps_found_through_environment(emps_dir, monkeypatch):
    monkeypatch.setenv("HAMMERSTEIN_CTRL_DATA", str(emps_dir.parent))
    assert len(load_emps(duration=1.0)) == 1000


def test_missing_emps_explains_how_to_get_it(tmp_path, monkeypatch):
    monkeypatch.delenv("HAMMERSTEIN_CTRL_DATA", raising=False)
    monkeypatch.setitem(sys.modules, "nonlinear_benchmarks", None)  # as if not installed
    with pytest.raises(DataNotFoundError) as exc:
        load_emps(path=tmp_path)
    text = str(exc.value)
    assert "DATA_EMPS.mat" in text and str(tmp_path) in text
    assert "HAMMERSTEIN_CTRL_DATA" in text and "pip install nonlinear-benchmarks" in text
    with pytest.raises(DataError, match="unknown EMPS record 'test'"):
        load_emps("test")


def test_emps_duration_out_of_range(emps_dir):
    with pytest.raises(DataError, match="duration 100 s gives 100000 samples"):
        load_emps(duration=100, path=emps_dir)


# -- TRS reconstruction ------------------------------------------------------------
def test_bundled_trs_matches_regeneration():
    bundled, fresh = load_trs(), make_trs_reconstruction(seed=TRS_SEED)
    assert len(bundled) == 6001 and bundled.dt == 0.1 and bundled.t[-1] == 600.0
    np.testing.assert_allclose(bundled.u, fresh.u, rtol=0, atol=1e-15)
    np.testing.assert_allclose(bundled.y, fresh.y, rtol=1e-12, atol=1e-14)
    assert np.all(np.abs(bundled.u) <= 1.0)


def test_trs_noise_is_rescaled_for_any_seed(trs_case):
    from hammerstein_ctrl import HammersteinCost

    for seed in (1, 2):
        d = make_trs_reconstruction(seed=seed)
        J = HammersteinCost(d, trs_case.structure)(trs_case.true_beta)
        assert J == pytest.approx(178.5, rel=1e-12)
    raw = make_trs_reconstruction(seed=1, noise_sse=None)
    assert (np.std(raw.y - make_trs_reconstruction(seed=1, noise_std=0.0, noise_sse=None).y)
            == pytest.approx(0.17, rel=0.05))


# -- user files --------------------------------------------------------------------
def test_read_record_layouts(tmp_path, emps_dir):
    d = IOData(np.sin(np.arange(50.0)), np.cos(np.arange(50.0)), dt=0.01, name="x")
    back = read_record(d.to_csv(tmp_path / "rec.csv"))
    np.testing.assert_array_equal(back.u, d.u)
    np.testing.assert_array_equal(back.y, d.y)
    assert back.dt == 0.01
    (tmp_path / "plain.csv").write_text("1,2\n3,4\n5,6\n")
    plain = read_record(tmp_path / "plain.csv", dt=0.5)
    assert plain.u.tolist() == [1, 3, 5] and plain.dt == 0.5
    (tmp_path / "named.csv").write_text("time,volts,angle\n0,1,2\n1,3,4\n2,5,6\n")
    named = read_record(tmp_path / "named.csv", input="volts", output="angle")
    assert named.y.tolist() == [2, 4, 6]
    mat = read_record(emps_dir / "DATA_EMPS.mat", input="vir", output="qm")
    assert len(mat) == 24841 and mat.dt == 0.001
    np.savez(tmp_path / "r.npz", t=np.arange(5.0), u=np.ones(5), y=np.zeros(5))
    assert len(read_record(tmp_path / "r.npz")) == 5


def test_read_record_errors(tmp_path):
    with pytest.raises(DataNotFoundError, match="data file not found"):
        read_record(tmp_path / "nope.csv")
    (tmp_path / "named.csv").write_text("time,volts,angle\n0,1,2\n1,3,4\n")
    with pytest.raises(DataError, match="no input column 'u2'; available: time, volts, angle"):
        read_record(tmp_path / "named.csv", input="u2", output="angle")
    with pytest.raises(DataError, match="cannot tell which column is the input"):
        read_record(tmp_path / "named.csv")
    (tmp_path / "bad.csv").write_text("t,u,y\n0,1,2\n1,x,4\n")
    with pytest.raises(DataError, match=r"bad.csv: line 3: column 'u' holds 'x', not a number"):
        read_record(tmp_path / "bad.csv")
    (tmp_path / "nan.csv").write_text("t,u,y\n0,1,2\n1,nan,4\n")
    with pytest.raises(DataError, match="u contains 1 non-finite value"):
        read_record(tmp_path / "nan.csv")
    (tmp_path / "x.xlsx").write_text("")
    with pytest.raises(DataError, match="unsupported file type '.xlsx'"):
        read_record(tmp_path / "x.xlsx")
    (tmp_path / "notime.csv").write_text("u,y\n1,2\n3,4\n")
    with pytest.raises(DataError, match="no time column"):
        read_record(tmp_path / "notime.csv")


def test_complex_and_object_signals_are_refused():
    with pytest.raises(DataError, match="complex"):
        as_signal(np.ones(5) + 1j, "u")
    with pytest.raises(DataError, match="numeric"):
        as_signal(np.array([1.0, None, 2.0], dtype=object), "u")
    t = np.arange(0.0, 1.0, 0.1)
    with pytest.raises(DataError, match="complex"):
        lsim(([1.0], [1.0, 1.0]), t, np.ones_like(t) * (1 + 1e-3j))
