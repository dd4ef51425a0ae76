"""The defaults registry: every default read when a function is called, changed in one place, checked."""

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import config
from hammerstein_ctrl.design import tune_pid
from hammerstein_ctrl.exceptions import ParameterError


@pytest.fixture(autouse=True)
def fresh_defaults():
    config.reset_defaults()
    yield
    config.reset_defaults()


def _record():
    rng = np.random.default_rng(0)
    t = np.arange(600) * 0.05
    u = np.repeat(rng.uniform(-1.5, 1.5, 30), 20)
    y = ct.forced_response(ct.tf([1.0, 2.0], [1.0, 1.4, 4.0]), t, 1.5 * np.tanh(0.9 * u)).outputs
    return hc.IOData(u, y + 0.01 * rng.standard_normal(600), dt=0.05)


def test_auto_budget_follows_the_registry():
    structure = hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh())
    config.set_defaults("auto", maxfev=40)
    small = hc.identify(_record(), structure, seed=0)
    assert small.nfev <= 40
    config.reset_defaults()
    assert hc.identify(_record(), structure, seed=0).nfev > 40


def test_confidence_level_and_residual_lags_follow_the_registry():
    res = hc.identify(_record(), hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh()), seed=0)
    wide = res.conf_int()["a0"]
    config.set_defaults("uncertainty", level=0.5)
    narrow = res.conf_int()["a0"]
    assert narrow[1] - narrow[0] < 0.4 * (wide[1] - wide[0])          # t(0.75) / t(0.975) = 0.34
    assert narrow == pytest.approx(res.conf_int(level=0.5)["a0"])
    config.set_defaults("residual_analysis", lags=7)
    assert res.residual_analysis(_record()).lags[-1] == 7


def test_pid_rules_follow_the_registry():
    m = hc.HammersteinModel(ct.tf([1.0], [1.5, 1.0]), hc.Polynomial(1), [2.0], delay=0.37)
    config.set_defaults("control", simc_ti_factor=1.0)
    pid = tune_pid(m, "simc", tau_c=0.37)
    kc, ti = 1.5 / (2.0 * 0.74), min(1.5, 1.0 * 0.74)
    assert pid.gains[1] == pytest.approx(kc / ti, rel=1e-12)
    config.set_defaults("delay", pade_order=3)
    assert m.to_iosys().nstates == 1 + 3


@pytest.mark.parametrize("module, name, value, match", [
    ("verdicts", "nested_tests", 1, "True or False"),
    ("auto", "maxfev", 0, "auto.maxfev must be a whole number >= 1"),
    ("auto", "maxfev", 2.5, "auto.maxfev must be a whole number"),
    ("uncertainty", "level", 1.0, "uncertainty.level must be a number between 0 and 1"),
    ("control", "max_sensitivity", "big", "control.max_sensitivity must be a number"),
    ("auto", "maxfevs", 10, "unknown default 'auto.maxfevs'; known: auto.delay_joint_share"),
])
def test_bad_defaults_are_refused_and_change_nothing(module, name, value, match):
    before = dict(config.defaults)
    with pytest.raises(ParameterError, match=match):
        config.set_defaults(module, **{name: value})
    assert config.defaults == before


def test_a_default_assigned_by_hand_is_checked_where_it_is_read():
    config.defaults["auto.maxfev"] = -3
    with pytest.raises(ParameterError, match="auto.maxfev must be a whole number >= 1, got -3"):
        hc.identify(_record(), hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh()))
