import warnings

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import (Coulomb, HammersteinStructure, IOData, LinearStructure, ParameterError, Polynomial,
                              identify,)
from hammerstein_ctrl.fit._auto import MIN_REFINE_BUDGET
from hammerstein_ctrl.exceptions import HammersteinError
from hammerstein_ctrl.fit import HammersteinCost

DT = 0.01


def test_identify_known_truth_polynomial_system():
    """A noise-free synthetic system: LM recovers the true parameters."""
    structure = HammersteinStructure(LinearStructure(0, 2), Polynomial(3))
    truth = np.array([2.0, 1.5, 1.0, 0.0, 0.3])  # H = 1/(p^2 + 1.5p + 2), g = u + 0.3u^3
    rng = np.random.default_rng(4)
    t = np.arange(3000) * 0.01
    u = np.repeat(rng.uniform(-1.5, 1.5, 60), 50)
    y = structure.model(truth).simulate(t, u)
    data = IOData(u, y, t, name="synthetic")
    res = identify(data, structure, method="lm", x0=[1.0, 1.0, 0.5, 0.1, 0.1], maxfev=2000)
    np.testing.assert_allclose(res.x, truth, rtol=1e-6, atol=1e-8)
    assert res.fun < 1e-12 and res.fit_percent > 99.999
    assert isinstance(res.model.linear, ct.TransferFunction)
    assert res.params["a1"] == pytest.approx(1.5, rel=1e-6)


def test_identify_trs_nspsa_result_is_usable_in_python_control(trs_case):
    kw = {k: v for k, v in trs_case.minimize_kwargs("nspsa").items() if k != "method"}
    res = identify(trs_case.data, trs_case.structure, method="nspsa", x0=trs_case.x0, seed=3, **kw)
    assert 178.4 < res.fun < 180.0 and res.nfev == 2001
    # the paper's own start and budget reach 178.5; the linear model of the same order fits the reconstruction
    # to 178.145 (its tanh is nearly linear at the record's 1 V): the verdict says so and fails the fit
    assert not res.success and "worse-than-nested" in [v.code for v in res.verdicts] and "178.145" in res.message
    assert res.fun == pytest.approx(trs_case.cost(res.x), rel=1e-12)
    # the fitted model wires into a loop with a controller
    sys = res.model.to_iosys()
    loop = ct.interconnect([ct.summing_junction(["r", "-y"], "e"),
                            ct.tf([0.5], [1.0], inputs="e", outputs="u"), sys], inputs="r", outputs="y")
    assert loop.ninputs == 1 and loop.noutputs == 1
    d = res.to_dict()
    assert d["params"]["b0"] == res.x[0] and d["linear"]["den"][0] == 1.0
    assert "fit =" in res.summary()


def test_identify_emps_from_the_paper_start_and_validation(emps_case):
    res = identify(emps_case.data, emps_case.structure, method="lm", x0=emps_case.x0, maxfev=600)
    assert res.fun == pytest.approx(0.208517, abs=2e-6)
    assert res.nfev < 600
    val = res.validate(emps_case.validation())
    assert 75 < val["fit_percent"] < 90


def test_identify_input_errors(trs_case):
    s = HammersteinStructure(LinearStructure(0, 2, fixed={"a0": 0.0}), Coulomb())
    with pytest.raises(ParameterError, match=r"give an initial point x0 = \[a1, d0, d1, d2\].*method='auto'"):
        identify(trs_case.data, s, method="nspsa")
    with pytest.raises(ParameterError, match="method 'auto' does not take options, maxiter"):
        identify(trs_case.data, s, options={"a": 1.0}, maxiter=3)
    with pytest.raises(ParameterError, match="beta must have 4 entries"):
        identify(trs_case.data, s, x0=[1, 2, 3])
    with pytest.raises(ParameterError, match="got the name 'cstr'; the paper's cases are hc.presets.trs()"):
        identify(trs_case.data, "cstr")
    with pytest.raises(ParameterError, match="data must be an IOData"):
        identify(np.zeros(10), s, x0=[1, 1, 1, 1])
    res = identify(trs_case.data, s, method="amvo-sca", bounds=[(0, 5), (0, 1), (-1, 1), (-1, 1)],
                   maxfev=200, seed=0)
    assert res.nfev == 200  # x0 defaulted to the centre of the box


def test_identify_accepts_a_nonlinear_benchmarks_style_record(trs_case):
    from types import SimpleNamespace

    d = trs_case.data
    record = SimpleNamespace(u=np.asarray(d.u), y=np.asarray(d.y), sampling_time=d.dt, name="bench")
    res = identify(record, trs_case.structure, maxfev=1500)
    assert res.data.name == "bench" and res.fun == pytest.approx(identify(d, trs_case.structure, maxfev=1500).fun)
    assert res.validate(record)["fit_percent"] == pytest.approx(res.fit_percent)


def test_auto_with_a_small_budget_gives_a_usable_result_or_a_clear_error(coulomb_record):
    """identify(method="auto", maxfev=10) returns x = NaN, model None and the message 'the final
    model cannot be simulated'; result.validate(data) then fails with AttributeError."""
    data = coulomb_record()
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    res = identify(data, structure, method="auto", maxfev=10)
    assert not res.success and "raise maxfev" in res.message
    if res.model is None:
        assert "no model" in res.message
        with pytest.raises(HammersteinError):
            res.validate(data)
    else:
        assert np.all(np.isfinite(res.x))
    res = identify(data, structure, method="auto", maxfev=30)      # one short refinement
    assert not res.success and "within maxfev = 30" in res.message
    assert np.isfinite(res.validate(data)["fit_percent"])


def test_auto_called_directly_runs_its_start_search_in_one_blas_thread(coulomb_record, monkeypatch):
    """identify holds BLAS to one thread, but auto_minimize is public too: called directly it factored each
    start regression (thousands of rows, a few columns) with OpenBLAS's threads, 84 ms median on the EMPS
    against 43 ms in one thread on this 2-core machine."""
    from threadpoolctl import threadpool_info

    from hammerstein_ctrl.optimize import _streamed_lstsq as streamed_lstsq
    from hammerstein_ctrl.fit._auto import auto_minimize
    from hammerstein_ctrl.fit import HammersteinCost

    if max(info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas") < 2:
        pytest.skip("BLAS runs one thread here anyway")
    threads, rank_check = [], streamed_lstsq._clear_of_rank_loss      # LAPACK's SVD of each start's factor

    def spy(*args, **kwargs):
        if not threads:                             # threadpool_info is slow: look once
            threads.append(max(info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"))
        return rank_check(*args, **kwargs)
    monkeypatch.setattr(streamed_lstsq, "_clear_of_rank_loss", spy)
    res = auto_minimize(HammersteinCost(coulomb_record(1000), HammersteinStructure(LinearStructure(0, 2), Coulomb())),
                        seed=0)
    assert res.success and threads == [1]
    assert max(info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas") >= 2   # restored


def test_auto_rejects_a_non_finite_x0_clearly(coulomb_record):
    """identify(method="auto", x0=[nan, ...]) fails deep in numpy.roots with LinAlgError
    (method="lm" says 'x0 must be finite')."""
    data = coulomb_record(1000)
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    with pytest.raises(HammersteinError):
        identify(data, structure, method="auto", x0=[np.nan] * 5)


def test_bad_seed_and_beta_types_give_package_errors(coulomb_record):
    """A seed numpy cannot use (a string, a negative int), a beta of strings and a complex beta
    reach numpy's own TypeError/ValueError/ComplexWarning instead of a ParameterError."""
    data = coulomb_record(1000)
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    x0 = [4.0, 2.0, 1.0, 0.3, -0.5]
    for seed in ("abc", -1):
        with pytest.raises(HammersteinError):
            identify(data, structure, method="nspsa", x0=x0, seed=seed, maxfev=50)
    cost = HammersteinCost(data, structure)
    with pytest.raises(HammersteinError):
        cost(["a"] * 5)
    with pytest.raises(HammersteinError):
        cost(np.array(x0) + 1e-3j)


def test_identify_of_an_overflowing_model_does_not_leak_numpy_warnings():
    """LM from an unstable start ends at a model whose output overflows; summarising it
    (metrics.fit / rmse, a norm) prints numpy RuntimeWarnings ('overflow encountered in square')."""
    t = DT * np.arange(40000)
    data = IOData(np.sin(t), np.cos(t), dt=DT)
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        res = identify(data, structure, method="lm", x0=[0.0, -1.0, 1.0, 0.1, 0.1], maxfev=300)
    assert not res.success


def test_auto_does_not_say_the_budget_ran_out_with_half_of_it_left(trs_case):
    """maxfev=60 on TRS: the start search spends its half (30), no start is found, and the result says
    'evaluation budget of 60 exhausted' with 30 evaluations unspent (EMPS: maxfev=30 gives a model,
    maxfev=40 none, with 18 spent)."""
    r = identify(trs_case.data, trs_case.structure, method="auto", maxfev=60, seed=0)
    if r.model is None and "exhausted" in r.message:
        assert r.nfev > 60 - MIN_REFINE_BUDGET, r.message


def test_a_custom_map_given_x0_is_fitted_even_where_the_search_drifts():
    """A block with a zero whose search drifts is rescued from automatic starts, which a custom map has none of:
    the rescue (and the offset probe) step aside instead of refusing the user's x0."""
    rng = np.random.default_rng(0)
    t = np.arange(1500) * 0.05
    u = np.repeat(rng.uniform(-2, 2, 50), 30)
    y = hc.HammersteinModel(([3.0], [1.0, 1.5, 2.0]), hc.Tanh(), [1.0, 1.0]).simulate(t, u)
    data = hc.IOData(u, y + 0.01 * rng.standard_normal(t.size), dt=0.05)
    custom = hc.CustomNonlinearity(lambda v, p: p[0] * np.tanh(p[1] * v), 2)
    s = hc.HammersteinStructure(hc.LinearStructure(1, 2), custom)
    for x0 in ([50.0, 2.0, 1.5, 0.06, 1.0], [1e4, 2.0, 1.5, 3e-4, 1.0]):
        res = hc.identify(data, s, x0=x0, seed=0)           # the truth has no zero: b0 runs off, honestly
        assert np.isfinite(res.fun) and res.fit_percent > 98.5


def test_a_callback_that_stops_auto_stops_it():
    from hammerstein_ctrl.fit._auto import auto_minimize

    rng = np.random.default_rng(0)
    t = np.arange(1500) * 0.05
    u = np.repeat(rng.uniform(-2, 2, 50), 30)
    y = hc.HammersteinModel(([3.0], [1.0, 1.5, 2.0]), hc.Tanh(), [1.0, 1.0]).simulate(t, u)
    data = hc.IOData(u, y + 0.01 * rng.standard_normal(t.size), dt=0.05)
    calls = []
    res = auto_minimize(HammersteinCost(data, hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh())), seed=0,
                        callback=lambda r: calls.append(r.nfev) or True)
    assert len(calls) == 1 and res.nit == 1 and res.nfev < 3000


def _records_of_every_family():
    """A small record, and the structure of each family with the records it takes."""
    t = np.arange(300) * 0.05
    u = np.sin(0.7 * t) + 0.5 * np.sin(2.3 * t)
    y = 0.5 * np.tanh(u) + 0.1 * np.cos(0.3 * t)
    siso, ham = IOData(u, y, dt=0.05), HammersteinStructure(LinearStructure(0, 1), hc.Tanh())
    mimo = IOData(np.column_stack([u, -u]), np.column_stack([y, 0.5 * y]), dt=0.05)
    return {
        "HammersteinCost": (ham, (siso,)),
        "DelayedCost": (HammersteinStructure(LinearStructure(0, 1, delay=0.1), hc.Tanh()), (siso,)),
        "RecordsCost": (ham, (siso, siso)),
        "MIMOCost": (hc.MIMOHammersteinStructure(LinearStructure(0, 1), [hc.Tanh(), hc.Tanh()], n_outputs=2), (mimo,)),
        "LureCost": (hc.lure_structure(), (siso,)),
        "WienerHammersteinCost": (hc.wiener_hammerstein_structure((0, 1), hc.Tanh(), (0, 1)), (siso,)),
    }


@pytest.mark.parametrize("cost_name", sorted(_records_of_every_family()))
def test_each_family_of_structures_is_routed_to_its_cost_and_every_cost_keeps_the_protocol(cost_name):
    structure, records = _records_of_every_family()[cost_name]
    way = hc.fit.route(structure, records)
    cost = way.make(records, structure)
    assert type(cost).__name__ == cost_name and isinstance(cost, hc.fit.Cost)
    x = np.asarray(structure.normalize(np.ones(structure.n_params)) if hasattr(structure, "normalize")
                   else np.ones(structure.n_params))
    assert np.isclose(cost(x), float(np.sum(cost.residuals(x) ** 2)), rtol=1e-9, equal_nan=True)


def test_a_structure_of_no_family_and_records_a_family_does_not_take_are_refused_in_one_line():
    siso = IOData(np.ones(50), np.ones(50), dt=0.1)
    with pytest.raises(ParameterError, match="got the name 'tanh'"):
        hc.fit.route("tanh", (siso,))
    with pytest.raises(ParameterError, match="got dict"):
        hc.fit.route({}, (siso,))
    with pytest.raises(ParameterError, match="several records in one Lur'e fit"):
        hc.fit.route(hc.lure_structure(), (siso, siso))
