"""Defects found by an independent review (branch review-u); each test failed on main at e386eb2.

Oracles: python-control's own simulation (control.forced_response), the numpy
form of the nonlinearities, and the box the caller gave.
"""

import control
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl.exceptions import HammersteinError
from hammerstein_ctrl.nonlinearities import Coulomb, Saturation
from hammerstein_ctrl.simulate import simulate_batch, sse_batch
from hammerstein_ctrl.structure import HammersteinStructure, LinearStructure, WienerStructure

DT = 0.01


def _coulomb_record(n_samples=3000, offset=-0.5):
    """y = 1/(p^2 + 2p + 4) (u + 0.3 sign u + offset) with 1 % noise, simulated by python-control."""
    t = DT * np.arange(n_samples)
    u = np.sin(t) + 0.5 * np.sin(3.3 * t)
    g = 1.0 * u + 0.3 * np.sign(u) + offset
    y = control.forced_response(control.tf([1], [1, 2, 4]), t, g).outputs
    y = y + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    return hc.IOData(u, y, dt=DT)


def test_lm_with_bounds_never_evaluates_outside_the_box():
    """The trf Jacobian's forward steps flip only at the upper bound: at a negative lower bound
    the neighbour x - h lies outside the box (scipy's "2-point" flips at both bounds)."""
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    cost = hc.HammersteinCost(_coulomb_record(), structure)
    lo = np.array([0.1, 0.1, 0.1, 0.0, -0.3])   # the true offset -0.5 lies below the box: the optimum is at -0.3
    hi = np.array([10.0, 10.0, 5.0, 2.0, 1.0])
    seen = []
    batch, single = cost.residuals_batch, cost.residuals
    cost.residuals_batch = lambda X: (seen.extend(np.atleast_2d(X)), batch(X))[1]
    cost.residuals = lambda x: (seen.append(np.asarray(x)), single(x))[1]
    res = hc.minimize(cost, [3.0, 1.5, 0.8, 0.2, 0.0], method="lm", bounds=list(zip(lo, hi)))
    assert res.x[4] == pytest.approx(-0.3)
    S = np.array(seen)
    outside = np.any((S < lo) | (S > hi), axis=1)
    assert not outside.any(), f"{outside.sum()} of {len(S)} evaluations outside the box, e.g. {S[outside][0]}"


@pytest.mark.parametrize("order", [2, 9])       # 2: compiled output map; 9: numpy map after the recursion
def test_wiener_nan_limit_scores_inf_on_every_route(order):
    """A NaN saturation limit gives NaN outputs in numpy (np.clip) but is ignored by the compiled
    output map (min/max drop NaN), so for n <= 8 the cost is finite (the unsaturated value)."""
    t = DT * np.arange(800)
    data = hc.IOData(np.sin(3 * t), 0.3 * np.cos(2 * t), dt=DT)
    structure = WienerStructure(LinearStructure(0, order), Saturation())
    den = np.poly(-np.arange(1.0, order + 1))[::-1][:order]          # stable, poles -1 .. -n
    beta = np.r_[den, 2.0 * np.prod(np.arange(1.0, order + 1)), np.nan]
    cost = hc.HammersteinCost(data, structure)
    assert cost(beta) == np.inf
    assert cost.batch(np.vstack([beta] * 3)).tolist() == [np.inf] * 3
    assert np.isnan(cost.simulate(beta)).any()


def test_auto_with_a_small_budget_gives_a_usable_result_or_a_clear_error():
    """identify(method="auto", maxfev=10) returns x = NaN, model None and the message 'the final
    model cannot be simulated'; result.validate(data) then fails with AttributeError."""
    data = _coulomb_record()
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    res = hc.identify(data, structure, method="auto", maxfev=10)
    assert not res.success and "raise maxfev" in res.message
    if res.model is None:
        assert "no model" in res.message
        with pytest.raises(HammersteinError):
            res.validate(data)
    else:
        assert np.all(np.isfinite(res.x))
    res = hc.identify(data, structure, method="auto", maxfev=30)      # one short refinement
    assert not res.success and "within maxfev = 30" in res.message
    assert np.isfinite(res.validate(data)["fit_percent"])


@pytest.mark.parametrize("dt", [0.0, -0.1])
def test_public_simulation_rejects_a_non_positive_sampling_interval(dt):
    """sse_batch / simulate_batch are public and documented with dt the sampling interval;
    dt <= 0 returns numbers (a simulation backwards in time for dt < 0) instead of an error."""
    t = 0.1 * np.arange(100)
    u, y = np.sin(t), np.cos(t)
    with pytest.raises(HammersteinError):
        sse_batch([[1.0]], [[1.0, 2.0]], u, dt, y)
    with pytest.raises(HammersteinError):
        simulate_batch([[1.0]], [[1.0, 2.0]], u, dt)


def test_normal_equations_checks_its_steps():
    """normal_equations(beta, steps) with a wrong number of steps raises numpy's reshape ValueError,
    and zero steps give NaN gradients silently."""
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    cost = hc.HammersteinCost(_coulomb_record(400), structure)
    beta = np.array([4.0, 2.0, 1.0, 0.3, -0.5])
    with pytest.raises(HammersteinError):
        cost.normal_equations(beta, steps=np.ones(6))
    with pytest.raises(HammersteinError):
        cost.normal_equations(beta, steps=np.zeros(5))


def test_auto_rejects_a_non_finite_x0_clearly():
    """identify(method="auto", x0=[nan, ...]) fails deep in numpy.roots with LinAlgError
    (method="lm" says 'x0 must be finite')."""
    data = _coulomb_record(1000)
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    with pytest.raises(HammersteinError):
        hc.identify(data, structure, method="auto", x0=[np.nan] * 5)


def test_bad_seed_and_beta_types_give_package_errors():
    """A seed numpy cannot use (a string, a negative int), a beta of strings and a complex beta
    reach numpy's own TypeError/ValueError/ComplexWarning instead of a ParameterError."""
    data = _coulomb_record(1000)
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    x0 = [4.0, 2.0, 1.0, 0.3, -0.5]
    for seed in ("abc", -1):
        with pytest.raises(HammersteinError):
            hc.identify(data, structure, method="nspsa", x0=x0, seed=seed, maxfev=50)
    cost = hc.HammersteinCost(data, structure)
    with pytest.raises(HammersteinError):
        cost(["a"] * 5)
    with pytest.raises(HammersteinError):
        cost(np.array(x0) + 1e-3j)


def test_simulate_batch_checks_the_rows_of_its_signals():
    """Three signals for two transfer functions: numpy's broadcast ValueError instead of a clear error."""
    u = np.sin(0.1 * np.arange(100))
    with pytest.raises(HammersteinError):
        simulate_batch([[1.0], [1.0]], [[1.0, 2.0], [1.0, 3.0]], np.vstack([u, u, u]), 0.1)


def test_identify_of_an_overflowing_model_does_not_leak_numpy_warnings():
    """LM from an unstable start ends at a model whose output overflows; summarising it
    (metrics.fit / rmse, a norm) prints numpy RuntimeWarnings ('overflow encountered in square')."""
    import warnings

    t = DT * np.arange(40000)
    data = hc.IOData(np.sin(t), np.cos(t), dt=DT)
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        res = hc.identify(data, structure, method="lm", x0=[0.0, -1.0, 1.0, 0.1, 0.1], maxfev=300)
    assert not res.success


def test_huge_residuals_are_booked_without_a_numpy_warning():
    """auto's MINPACK refinements book residuals of 1e150 stand-ins: their sum of squares is inf, silently."""
    import warnings

    from hammerstein_ctrl.optimize.least_squares import _CountedResiduals

    counted = _CountedResiduals(lambda x: np.full(3, 1e200), None)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        r = counted(np.zeros(2))
    assert r.shape == (3,) and counted.history.as_dict()["fun"].tolist() == [np.inf]
