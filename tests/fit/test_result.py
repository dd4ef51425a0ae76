"""One result type: a fit just made and one read back from a file are both IdentificationResults."""

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl.exceptions import ParameterError
from hammerstein_ctrl.io import SavedResult
from hammerstein_ctrl.fit import IdentificationResult


def _record(seed, n=800, name="rig"):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.05
    u = np.repeat(rng.uniform(-1.5, 1.5, n // 20), 20)
    y = ct.forced_response(ct.tf([1.0, 2.0], [1.0, 1.4, 4.0]), t, 1.5 * np.tanh(0.9 * u)).outputs
    return hc.IOData(u, y + 0.01 * rng.standard_normal(n), dt=0.05, name=name)


@pytest.fixture(scope="module")
def fitted():
    structure = hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh())
    return hc.identify(_record(0), structure, seed=0)


def test_a_loaded_result_is_the_same_type_with_the_same_figures(fitted, tmp_path):
    hc.save_result(fitted, tmp_path / "r.json")
    back = hc.load_result(tmp_path / "r.json")
    assert SavedResult is IdentificationResult and isinstance(back, IdentificationResult)
    assert back.status == fitted.status and back.dof == fitted.dof == 800 - 5
    assert back.stderr == pytest.approx(fitted.stderr, rel=1e-12)
    assert back.record_name == "rig" and back.data["n_samples"] == 800
    other = _record(1, name="validation")
    assert back.validate(other) == pytest.approx(fitted.validate(other), rel=1e-12)
    a, b = back.residual_analysis(_record(0)), fitted.residual_analysis()
    np.testing.assert_allclose(a.autocorrelation, b.autocorrelation, rtol=1e-9, atol=1e-12)
    gain = back.propagate(lambda m: m.linear.dcgain())
    assert gain.value == pytest.approx(fitted.propagate(lambda m: m.linear.dcgain()).value, rel=1e-12)
    assert "rig" in back.summary()


def test_a_loaded_result_asks_for_the_record_where_it_needs_the_samples(fitted, tmp_path):
    hc.save_result(fitted, tmp_path / "r.json")
    back = hc.load_result(tmp_path / "r.json")
    for call in (back.residual_analysis, back.plot, back.compare):
        with pytest.raises(ParameterError, match="keeps only a description of its record 'rig': pass the record"):
            call()


def test_dof_of_a_joint_fit_counts_every_record():
    records = [_record(2, 600, "a"), _record(3, 400, "b")]
    structure = hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh(), offset=True)
    res = hc.identify(records, structure, seed=0)
    assert res.dof == 1000 - res.x.size


# -- validate: the initial state (and offset) estimated through the whole model ------------------------------
def _truth_record(kind, seed, x0=(0.6, -0.4), offset=0.0, n=1500, dt=0.05, noise=0.005):
    """A record of a known truth simulated by python-control (the linear block from ``x0``), its maps in numpy."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    u = np.repeat(rng.uniform(-1.5, 1.5, n // 15), 15)
    A, B, C, D = (np.array([[-1.2, -1.0], [1.0, 0.0]]), np.array([[1.0], [0.0]]), np.array([[0.0, 1.0]]),
                  np.zeros((1, 1)))            # 1 / (p^2 + 1.2 p + 1), companion form (the package's state)
    v = 1.5 * np.tanh(0.9 * u) if kind == "hammerstein-wiener" else u
    z = ct.forced_response(ct.ss(A, B, C, D), t, v, X0=list(x0)).outputs
    y = 1.2 * np.tanh(1.1 * z) if kind != "hammerstein" else z
    return hc.IOData(u, y + offset + noise * rng.standard_normal(n), dt=dt, name=f"{kind}-{seed}")


def _truth_structure(kind):
    lin = hc.LinearStructure(0, 2)
    common = dict(offset=True, initial_state="estimate")
    if kind == "wiener":
        return hc.WienerStructure(lin, hc.Tanh(), **common)
    if kind == "hammerstein-wiener":
        return hc.HammersteinWienerStructure(lin, hc.Tanh(), hc.Tanh(), **common)
    return hc.HammersteinStructure(lin, hc.Polynomial(1), **common)


@pytest.mark.parametrize("kind", ["wiener", "hammerstein-wiener", "hammerstein"])
def test_validate_estimates_the_initial_state_through_the_output_map(kind):
    """On its own record validate reproduces the fit; on a new record from another state and operating
    point it does as well as the truth simulated from that record's own state."""
    data = _truth_record(kind, 0)
    res = hc.identify(data, _truth_structure(kind), seed=0)
    assert res.success, res.message
    assert abs(res.validate(data)["fit_percent"] - res.fit_percent) < 0.1
    new = _truth_record(kind, 1, x0=(-0.8, 0.9), offset=0.3)
    truth_fit = hc.fit_percent(new.y, _truth_record(kind, 1, x0=(-0.8, 0.9), offset=0.3, noise=0.0).y)
    report = res.validate(new, offset="estimate")
    assert report["fit_percent"] > truth_fit - 0.5 and report["offset"] == pytest.approx(
        res.params["y0"] + 0.3, abs=0.02)
    assert res.validate(new)["fit_percent"] < report["fit_percent"] - 5   # the old offset misses by 0.3


def test_validate_of_a_lure_fit_with_an_estimated_state_reproduces_its_fit():
    t = np.arange(2000) * 0.01
    u = 1.5 * np.sin(0.7 * t) + np.sin(2.3 * t) + 0.5 * np.sign(np.sin(0.23 * t) + 1e-9)
    y = hc.lure_structure().model([0.4, 2.0, 0.5, 0.05]).simulate(t, u, initial_state=[0.3, 0.0])
    data = hc.IOData(u, y + 0.001 * np.random.default_rng(0).standard_normal(t.size), dt=0.01)
    res = hc.identify(data, hc.lure_structure(initial_state="estimate"), seed=0)
    assert res.success, res.message
    assert res.validate(data)["fit_percent"] == pytest.approx(res.fit_percent, abs=0.1)


def test_validate_refuses_an_unknown_offset_mode(fitted):
    with pytest.raises(ParameterError, match="offset must be 'model' or 'estimate', got 'mean'"):
        fitted.validate(_record(1), offset="mean")
