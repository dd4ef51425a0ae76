"""One result type: a fit just made and one read back from a file are both IdentificationResults."""

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl.exceptions import ParameterError
from hammerstein_ctrl.persistence import SavedResult
from hammerstein_ctrl.result import IdentificationResult


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
