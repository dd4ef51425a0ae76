"""significance.py and nested.py: a fit must beat the models nested in it, whatever the noise's colour.

The F-test's calibration is checked over hundreds of seeds against plain-numpy least squares; the verdicts
through ``identify`` on records of pure noise, where nothing is to be found, and on the TRS reconstruction,
whose tanh is nearly linear at its 1 V input.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.signal

import hammerstein_ctrl as hc
from hammerstein_ctrl.fit._nested import delay_scan_count, nested_linear_structure
from hammerstein_ctrl.assess._significance import nested_f_test, whitened_sse
from hammerstein_ctrl.assess import NoiseModel


def _regression_pvalues(seeds, *, ar_pole=0.0, white=False, n=400):
    """p-values of ``y ~ 1 + x1 + x2`` against ``y ~ 1`` on records where x1 and x2 do nothing."""
    out = []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        e = scipy.signal.lfilter([1.0], [1.0, -ar_pole], rng.standard_normal(n + 200))[200:]
        X = np.column_stack([np.ones(n), scipy.signal.lfilter([1.0], [1.0, -0.9], rng.standard_normal((2, n)))
                             .T])                                   # smooth regressors, as a plant's signals
        r1 = e - X @ np.linalg.lstsq(X, e, rcond=None)[0]
        r0 = e - e.mean()
        noise = NoiseModel(0, np.ones(1), float(r1 @ r1) / n) if white else None
        out.append(nested_f_test(r1, r0, n, 3, 1, noise=noise).p_value)
    return np.array(out)


def test_the_f_test_is_calibrated_on_white_noise():
    p = _regression_pvalues(400)
    assert 0.03 <= np.mean(p < 0.05) <= 0.07
    assert 0.005 <= np.mean(p < 0.01) <= 0.02


def test_whitening_keeps_the_test_calibrated_on_coloured_noise_where_the_plain_test_is_not():
    whitened = _regression_pvalues(400, ar_pole=0.9)
    plain = _regression_pvalues(400, ar_pole=0.9, white=True)
    assert np.mean(whitened < 0.05) <= 0.09
    assert np.mean(plain < 0.05) >= 0.3          # the plain formula sees structure in smooth noise


def test_whitened_sums_by_blocks_equal_the_whole_filter(monkeypatch):
    from hammerstein_ctrl.assess import _significance as significance

    r = np.random.default_rng(1).standard_normal(1000)
    ar = np.array([1.0, -0.5, 0.2])
    whole = np.convolve(r, ar)[2:1000]
    monkeypatch.setattr(significance, "BLOCK", 37)
    assert whitened_sse(lambda a, b: r[a:b], 1000, ar) == pytest.approx(whole @ whole, rel=1e-12)


def test_bad_nested_models_are_refused_in_one_line():
    r = np.ones(10)
    with pytest.raises(hc.exceptions.ParameterError, match="must have fewer parameters"):
        nested_f_test(r, r, 10, 2, 2)
    with pytest.raises(hc.exceptions.ParameterError, match="has 9 samples, not 10"):
        nested_f_test(r, r[:9], 10, 3, 1)


def test_the_nested_linear_model_keeps_order_offset_state_and_dead_time():
    s = hc.WienerStructure(hc.LinearStructure(1, 2, delay="estimate"), hc.Tanh(), offset=True,
                           initial_state="estimate")
    nested = nested_linear_structure(s)
    assert nested.linear.num_order == 1 and nested.linear.den_order == 2 and nested.linear.estimates_delay
    assert nested.offset and nested.initial_state == "estimate" and nested.input_nonlinearity.n_params == 1
    assert nested_linear_structure(nested) is None
    assert delay_scan_count(s, 600) == 151 and delay_scan_count(nested.with_delay(None), 600) == 1


def _noise_fit(kind, delay, seed):
    rng = np.random.default_rng(seed)
    data = hc.IOData(rng.standard_normal(600), rng.standard_normal(600), dt=0.05)
    block = hc.HammersteinStructure if kind == "hammerstein" else hc.WienerStructure
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return hc.identify(data, block(hc.LinearStructure(0, 2, delay=delay), hc.Tanh()), seed=0)


def _assert_called_noise(res):
    assert not res.success
    assert "not-significant" in [v.code for v in res.verdicts], res.message
    assert "not significant" in res.message


@pytest.mark.parametrize("kind", ["hammerstein", "wiener"])
@pytest.mark.parametrize("delay", [None, "estimate"])
def test_pure_noise_is_not_a_model(kind, delay):
    for seed in range(3):
        _assert_called_noise(_noise_fit(kind, delay, seed))


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["hammerstein", "wiener"])
@pytest.mark.parametrize("delay", [None, "estimate"])
def test_pure_noise_is_not_a_model_on_twenty_seeds(kind, delay):
    for seed in range(20):
        _assert_called_noise(_noise_fit(kind, delay, seed))


def test_a_nearly_linear_tanh_is_called_not_significant(trs_case):
    res = hc.identify(trs_case.data, trs_case.structure)
    assert not res.success and res.verdicts[-1].code == "not-significant"
    assert res.message.startswith("the nonlinearity is not significant: the linear model of the same order fits "
                                  "as well") and "use the linear model" in res.message
    linear = hc.identify(trs_case.data, nested_linear_structure(trs_case.structure))
    assert linear.success and linear.fun <= res.fun * (1 + 1e-6)


def test_a_real_nonlinearity_is_significant():
    import control as ct

    rng = np.random.default_rng(0)
    u = np.repeat(rng.uniform(-2.0, 2.0, 200), 10)
    t = 0.1 * np.arange(u.size)
    y = ct.forced_response(ct.tf([1.0, 0.5], [1.0, 1.2, 1.0]), t, 2.0 * np.tanh(1.2 * u)).outputs
    data = hc.IOData(u, y + 0.02 * rng.standard_normal(u.size), t)
    res = hc.identify(data, hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh()), seed=0)
    assert res.success and not {"not-significant", "worse-than-nested"} & {v.code for v in res.verdicts}


def test_the_nested_tests_can_be_switched_off_for_monte_carlo_studies(trs_case):
    hc.config.set_defaults("verdicts", nested_tests=False)
    try:
        res = hc.identify(trs_case.data, trs_case.structure)
    finally:
        hc.config.reset_defaults()
    assert res.success and not any(v.code == "not-significant" for v in res.verdicts)


@pytest.mark.parametrize("family", [hc.Polynomial(2), hc.Coulomb()])
def test_a_nonlinearity_on_exactly_linear_data_is_never_significant(family):
    """Noise-free linear data: both fits are exact to rounding, so no F-test between them means anything; the
    nested linear model is exact and the verdict is always not significant (never a 'poor optimum')."""
    t = np.arange(800) * 0.05
    truth = hc.HammersteinModel(([2.0], [1.0, 3.0, 2.0]), hc.Polynomial(1), [1.0])
    for seed in range(6):
        u = np.repeat(np.random.default_rng(seed).uniform(-1, 1, 40), 20)
        res = hc.identify(hc.IOData(u, truth.simulate(t, u), dt=0.05),
                          hc.HammersteinStructure(hc.LinearStructure(0, 2), family), seed=0)
        assert [v.code for v in res.verdicts] == ["not-significant"], (seed, res.message)


def test_the_white_noise_option_does_not_switch_off_the_verdicts():
    """noise= describes the standard errors; the verdicts whiten by the residuals' own AR model either way: AR(1)
    noise (pole 0.97) unrelated to the input is not a model with noise='white' either."""
    s = hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Tanh())
    for seed in range(5):
        rng = np.random.default_rng(seed)
        u = np.repeat(rng.uniform(-1, 1, 40), 20)
        y = scipy.signal.lfilter([1.0], [1.0, -0.97], rng.standard_normal(800))
        assert not hc.identify(hc.IOData(u, y, dt=0.1), s, seed=0, noise="white").success
