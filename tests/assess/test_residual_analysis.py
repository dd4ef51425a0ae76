"""residual_analysis.py: MATLAB-style correlations with bounds, and the coherence test behind the adequacy verdict.

The test's promise is two-sided and checked over many seeds: residuals
independent of the input pass (white or strongly coloured, with white or
smooth inputs), and residuals that hold linear dynamics of the input, a
nonlinear function of it, or a function of the simulated output are found,
named by the smallest regressor set that explains them.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from hammerstein_ctrl.assess import _residuals as RA
from hammerstein_ctrl.assess._input_tests import COHERENCE_SEGMENTS, SEGMENT_MAX
from hammerstein_ctrl.exceptions import ParameterError
from hammerstein_ctrl.assess import residual_analysis

N = 4000


def smooth(rng, n=N, pole=0.95):
    """A low-pass (strongly coloured) unit-variance signal."""
    x = scipy.signal.lfilter([1.0], [1.0, -pole], rng.standard_normal(n))
    return x / x.std()


@pytest.mark.parametrize("kind", ["white", "coloured"])
def test_residuals_independent_of_the_input_pass(kind):
    """False findings over 200 seeds: at most 2 (1 %), with the residuals white or an AR(1) of pole 0.95."""
    found = 0
    for seed in range(200):
        rng = np.random.default_rng(seed)
        u = smooth(rng) if kind == "coloured" else rng.standard_normal(N)
        e = smooth(rng) if kind == "coloured" else rng.standard_normal(N)
        y = scipy.signal.lfilter([0.2], [1.0, -0.8], np.tanh(u))
        found += not residual_analysis(e, u, dt=0.01, simulated=y).passed
    assert found <= 2, found


@pytest.mark.parametrize("make, group", [
    (lambda u, y: scipy.signal.lfilter([0.0, 0.3], [1.0, -0.7], u), "dynamics"),
    (lambda u, y: scipy.signal.lfilter([0.3], [1.0, -0.7], u ** 2 - np.mean(u ** 2)), "input nonlinearity"),
    (lambda u, y: 0.5 * (y ** 2 - np.mean(y ** 2)), "output nonlinearity"),
])
def test_what_the_input_explains_is_found_and_named(make, group):
    hits = 0
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        u = smooth(rng, pole=0.6)
        y = scipy.signal.lfilter([0.2], [1.0, -0.9], u)
        missing = make(u, y)
        e = missing / missing.std() + 0.7 * smooth(rng)       # the missing part under coloured noise
        a = residual_analysis(e, u, dt=0.01, simulated=y)
        hits += (not a.passed) and a.findings[0].group == group
        if not a.passed:
            assert group in a.verdict()
    assert hits >= 19, hits


def test_correlations_follow_matlabs_resid_conventions():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(N)
    e = np.r_[np.zeros(3), u[:-3]] + 0.1 * rng.standard_normal(N)      # the input leads the residual by 3
    a = residual_analysis(e, u, dt=0.5)
    assert a.cross_lags[np.argmax(a.cross_correlation)] == 3
    assert a.autocorrelation[0] == pytest.approx(1.0)
    ec, uc = e - e.mean(), u - u.mean()
    for k in (-4, 0, 3, 7):
        ref = (ec[k:] @ uc[:N - k] if k >= 0 else ec[:N + k] @ uc[-k:]) / np.sqrt((ec @ ec) * (uc @ uc))
        assert a.cross_correlation[a.cross_lags.tolist().index(k)] == pytest.approx(ref, rel=1e-10)
    assert a.autocorrelation_bound == pytest.approx(2.5758 / np.sqrt(N), rel=1e-4)
    assert not a.independence and not a.passed


def test_the_cross_correlation_bound_widens_for_coloured_signals():
    """Bartlett's variance: about 1/N for white signals, much more when both are smooth (as real records are)."""
    rng = np.random.default_rng(1)
    white = residual_analysis(rng.standard_normal(N), rng.standard_normal(N), dt=1.0)
    assert white.cross_correlation_bound == pytest.approx(2.5758 / np.sqrt(N), rel=0.1)
    u, e = smooth(rng), smooth(rng)
    coloured = residual_analysis(e, u, dt=1.0)
    # (1/N) sum_k rho_uu(k) rho_ee(k) for two AR(1) of pole 0.95 is (1 + 0.95^2) / (1 - 0.95^2) / N
    expected = 2.5758 * np.sqrt((1 + 0.95 ** 2) / (1 - 0.95 ** 2) / N)
    assert coloured.cross_correlation_bound == pytest.approx(expected, rel=0.3)


def test_a_short_record_is_analysed_without_the_coherence_test():
    rng = np.random.default_rng(2)
    a = residual_analysis(rng.standard_normal(60), rng.standard_normal(60), dt=1.0, lags=10)
    assert a.coherence == [] and a.passed and a.lags[-1] == 10


def test_bad_arguments_are_refused():
    with pytest.raises(ParameterError, match="one length"):
        residual_analysis(np.ones(10), np.ones(9), dt=1.0)
    with pytest.raises(ParameterError, match="lags"):
        residual_analysis(np.ones(10), np.ones(10), dt=1.0, lags=20)
    with pytest.raises(ParameterError, match="finite"):
        residual_analysis(np.r_[np.ones(99), np.nan], np.ones(100), dt=1.0)


def test_the_figure_has_the_two_correlations_with_their_bounds():
    rng = np.random.default_rng(3)
    a = residual_analysis(rng.standard_normal(500), rng.standard_normal(500), dt=0.1, name="rec")
    fig = a.plot()
    assert [ax.get_title() for ax in fig.axes] == ["autocorrelation of e", "cross-correlation of u and e"]
    assert "rec" in fig._suptitle.get_text()
    assert "whiteness" in a.summary()


def test_the_test_uses_bounded_memory_on_long_records():
    import tracemalloc

    rng = np.random.default_rng(4)
    n = 2_000_000
    e, u, y = rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)
    residual_analysis(e[:5000], u[:5000], dt=1.0, simulated=y[:5000])
    tracemalloc.start()
    a = residual_analysis(e, u, dt=1.0, simulated=y)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert a.passed
    assert peak < 40e6          # segments of at most SEGMENT_MAX samples: a constant, not a multiple of n
    assert COHERENCE_SEGMENTS * SEGMENT_MAX < n


def test_lags_past_the_record_are_refused_before_any_sum():
    """A lag of the record's length or more has no overlap: the analysis refuses it by name (the lagged sums read
    past the signals before), whichever door it comes through."""
    e, u = np.ones(5), np.arange(5.0)
    with pytest.raises(ParameterError, match="lags must be an integer between 1 and 4"):
        RA.ResidualAnalysis(e, u, 0.1, lags=5, coherence=[], cross_bound=0.5)
    with pytest.raises(ParameterError, match="lags must be an integer between 1 and 4"):
        residual_analysis(e, u, dt=0.1, lags=50)
    with pytest.raises(ValueError, match="reach past a record of 5 samples"):
        RA._lagged_sums(e, u, -5, 0)
    e = np.array([1.0, -1.0, 2.0, 0.5, -0.5])
    analysis = RA.ResidualAnalysis(e, u, 0.1, lags=4, coherence=[], cross_bound=0.5)      # the longest lag there is
    d = e - e.mean()
    np.testing.assert_allclose(analysis.autocorrelation, np.correlate(d, d, "full")[4:] / (d @ d), rtol=1e-12)
