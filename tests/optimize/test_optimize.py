import math
import warnings

import numpy as np
import pytest
import scipy.optimize

from hammerstein_ctrl import ParameterError, UnknownNameError, minimize
from hammerstein_ctrl.optimize import (
    BUDGET_EXHAUSTED, CALLBACK_STOP, COMPLETED, DIVERGED, NO_FINITE_VALUE, SOLVER_FAILED, PerturbationGain, StepGain,
    amvo_sca, normalized_difference, nspsa,
)
from hammerstein_ctrl.paper.settings import TRS_BOUNDS, eq8_methods, eq8_objective

SEEDS = range(5)


@pytest.fixture(autouse=True)
def no_warnings():
    """Hostile objectives must not flood the user with numpy warnings."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


# -- Section 4.1 (Eq. 8) ---------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_eq8_spsa_blows_up_and_says_so(seed):
    r = minimize(eq8_objective, np.zeros(10), seed=seed, maxiter=1000, **eq8_methods()["spsa"])
    fun = r.history["fun"][:30]
    assert np.any(~np.isfinite(fun) | (fun > 1e6))
    assert r.status == DIVERGED and not r.success and "diverged" in r.message
    assert r.nit <= 30


@pytest.mark.parametrize("seed", SEEDS)
def test_eq8_nspsa_converges(seed):
    r = minimize(eq8_objective, np.zeros(10), seed=seed, maxiter=1000, **eq8_methods()["nspsa"])
    assert r.success and r.status == COMPLETED and r.nit == 1000 and r.nfev == 2001
    assert r.fun < 0.2
    assert r.fun == pytest.approx(eq8_objective(r.x), rel=0, abs=0)


# -- N-SPSA's hbar corners ------------------------------------------------------------------
@pytest.mark.parametrize("fp, fm, h", [
    (2.0, 1.0, 0.5), (1.0, 2.0, -0.5),            # Eq. 11-12
    (3.0, 3.0, 1.0), (0.0, 0.0, 1.0),              # ties, including max = 0
    (math.inf, 5.0, 1.0), (5.0, math.inf, -1.0),   # one infinite value
    (math.inf, math.inf, 1.0), (math.nan, math.nan, 1.0),
    (math.nan, 5.0, 1.0), (5.0, math.nan, -1.0),   # NaN counts as +inf
    (-2.0, -1.0, -0.5), (-1.0, -2.0, 0.5),         # negatives keep the descent direction
    (-math.inf, 1.0, -1.0), (1.0, 0.0, 1.0),
])
def test_normalized_difference_corners(fp, fm, h):
    assert normalized_difference(fp, fm) == h


# -- determinism and counting ---------------------------------------------------------------
@pytest.mark.parametrize("method", ["spsa", "nlspsa", "nspsa", "amvo-sca"])
def test_same_seed_same_result_bit_for_bit(trs_case, method):
    kw = trs_case.minimize_kwargs(method)
    kw.pop("maxiter", None)
    kw["maxfev"] = 601
    r1 = minimize(trs_case.cost, trs_case.x0, seed=7, **kw)
    r2 = minimize(trs_case.cost, trs_case.x0, seed=np.random.default_rng(7), **kw)
    r3 = minimize(trs_case.cost, trs_case.x0, seed=8, **kw)
    assert np.array_equal(r1.x, r2.x) and r1.fun == r2.fun and r1.nfev == r2.nfev
    assert np.array_equal(r1.history["fun"], r2.history["fun"], equal_nan=True)
    if method != "spsa":  # SPSA may diverge identically in one step for two seeds
        assert not np.array_equal(r1.x, r3.x)


@pytest.mark.parametrize("maxfev", [1, 2, 3, 100, 101, 999])
def test_nfev_is_exact_and_maxfev_never_exceeded(maxfev):
    calls = []

    def f(x):
        calls.append(1)
        return float(np.sum(x**2))

    def spent(reserved):  # reserved, then the start, k iterations of two and the last iterate (k >= 1)
        k = (maxfev - reserved - 2) // 2
        return reserved + (2 * k + 2 if k >= 1 else 1)   # no iteration: one evaluation, the start's

    r = nspsa(f, np.ones(3), maxfev=maxfev, seed=0, a=StepGain(0.1, 10), c=PerturbationGain(0.1))
    assert r.nfev == len(calls) == spent(0) <= maxfev
    calls.clear()
    r = nspsa(f, np.ones(3), maxfev=maxfev, seed=0, a=StepGain(0.1, 10), c=PerturbationGain(0.1),
              estimate="last")                            # the paper's: no evaluation of the start
    assert r.nfev == len(calls) == 2 * ((maxfev - 1) // 2) + 1 <= maxfev
    calls.clear()
    # automatic gains spend 8 counted evaluations on calibration, inside the budget (when it leaves
    # room for an iteration; smaller budgets use Spall's default gains uncalibrated)
    r = nspsa(f, np.ones(3), maxfev=maxfev, seed=0)
    assert r.nfev == len(calls) == spent(8 if maxfev >= 11 else 0) <= maxfev
    calls.clear()
    r = amvo_sca(f, np.ones(3), bounds=[(-2, 2)] * 3, maxfev=maxfev + 10, pop_size=10, seed=0)
    assert r.nfev == len(calls) == 10 * ((maxfev + 10) // 10) <= maxfev + 10
    calls.clear()
    r = minimize(f, np.ones(3), method="nelder-mead", maxfev=maxfev + 5)
    assert r.nfev == len(calls) <= maxfev + 5


def test_batch_evaluation_is_used_and_counted(trs_case):
    r = minimize(trs_case.cost, trs_case.x0, seed=0, **trs_case.minimize_kwargs("amvo-sca"))
    assert r.nfev == 5000 and r.nit == 100
    assert np.all(np.diff(r.history["best"]) <= 0)
    assert r.fun == pytest.approx(trs_case.cost(r.x), rel=1e-12)
    assert np.all(r.x >= [b[0] for b in trs_case.methods["amvo-sca"]["bounds"]])


# -- hostile objectives -------------------------------------------------------------------------
def test_overflowing_objective_makes_spsa_report_divergence():
    def f(x):  # Python-float overflow raises OverflowError: scored as inf
        return float(sum(abs(v) ** 50.0 for v in x.tolist())) if np.max(np.abs(x)) > 3 else float(np.sum(x**2))

    r = minimize(f, np.full(4, 2.0), method="spsa", seed=0, maxiter=200,
                 options={"a": StepGain(10.0, 0, 0.602), "c": PerturbationGain(0.5)})
    assert r.status == DIVERGED and not r.success and "diverged" in r.message


@pytest.mark.parametrize("method", ["spsa", "nlspsa", "nspsa"])
def test_all_nan_objective_does_not_crash(method):
    r = minimize(lambda x: float("nan"), np.zeros(3), method=method, seed=0, maxiter=50,
                 options={"norm_limit": 0.1} if method == "nlspsa" else None)
    assert not r.success and r.nfev <= 101 + 8 + 1 and np.all(np.isfinite(r.x))  # calibration 8, the start 1
    assert r.status == NO_FINITE_VALUE and "non-finite" in r.message


def test_all_inf_objective_in_amvo_sca():
    r = amvo_sca(lambda x: math.inf, np.zeros(2), bounds=[(-1, 1)] * 2, maxfev=200, pop_size=10, seed=0)
    assert r.status == NO_FINITE_VALUE and not r.success and "no universe" in r.message


def test_zero_objective_keeps_nspsa_moving():
    r = nspsa(lambda x: 0.0, np.zeros(2), maxiter=10, seed=0, a=StepGain(0.1, 1), c=PerturbationGain(0.1))
    assert r.success and r.fun == 0.0 and not np.allclose(r.x, 0.0)  # hbar = 1 on the tie


def test_negative_objective_is_minimised_by_nspsa():
    def f(x):
        return -float(np.exp(-np.sum((x - 2.0) ** 2)))

    r = nspsa(f, np.full(2, 1.5), maxiter=2000, seed=3, a=StepGain(0.05, 10, 0.602), c=PerturbationGain(0.05))
    assert r.fun < -0.99 and np.allclose(r.x, 2.0, atol=0.1)


def test_nlspsa_steps_respect_the_norm_limit():
    xs = []
    minimize(lambda x: float(np.sum(x**4)) * 1e6, np.full(3, 5.0), method="nlspsa", seed=0, maxiter=100,
             options={"a": StepGain(1.0, 10, 0.6), "c": PerturbationGain(0.1), "norm_limit": 0.05},
             callback=lambda r: xs.append(r.x))
    steps = np.linalg.norm(np.diff(np.array(xs), axis=0), axis=1)
    assert steps.max() <= 0.05 + 1e-12 and steps.max() > 0.049


def test_nlspsa_with_an_infinite_side_takes_a_limited_step():
    def f(x):
        return math.inf if x[0] > 1.0 else float(np.sum(x**2))

    r = minimize(f, np.array([1.0, 1.0]), method="nlspsa", seed=0, maxiter=20,
                 options={"a": StepGain(0.1), "c": PerturbationGain(0.2), "norm_limit": 0.1})
    assert np.all(np.isfinite(r.x)) and r.fun < 2.0


# -- API ------------------------------------------------------------------------------------
def test_api_errors():
    def f(x):
        return float(np.sum(x**2))

    with pytest.raises(UnknownNameError, match="unknown method 'pso'"):
        minimize(f, [1.0], method="pso")
    with pytest.raises(ParameterError, match=r"unknown option\(s\) \['alpha'\] for method 'nspsa'"):
        minimize(f, [1.0], "nspsa", options={"alpha": 1})
    with pytest.raises(ParameterError, match="amvo-sca needs finite bounds"):
        minimize(f, [1.0], method="amvo-sca")
    with pytest.raises(ParameterError, match="bounds has 1 pairs but x0 has 2"):
        minimize(f, [1.0, 2.0], "nspsa", bounds=[(0, 1)])
    with pytest.raises(ParameterError, match="x0 must be finite"):
        minimize(f, [np.nan], "nspsa")
    with pytest.raises(ParameterError, match="option 'a' must be a StepGain"):
        minimize(f, [1.0], "nspsa", options={"a": "big"})


def test_callback_and_bounds():
    seen = []

    def cb(res):
        seen.append(res.x)
        return len(seen) == 5

    r = minimize(lambda x: float(np.sum((x - 3) ** 2)), [0.0, 0.0], "nspsa", seed=0, bounds=[(-1, 1), (-1, 1)],
                 options={"a": StepGain(1.0), "c": PerturbationGain(0.1)}, callback=cb)
    assert r.status == CALLBACK_STOP and r.nit == 5 and r.success
    assert np.all(np.abs(np.array(seen)) <= 1.0)


def test_gain_sequences():
    a = StepGain(0.66, 24, 0.9)
    assert a(1) == pytest.approx(0.66 / 25**0.9)
    c = PerturbationGain(0.2, 1 / 6)
    assert c(3) == pytest.approx(0.2 / 4 ** (1 / 6))
    assert StepGain.spall(1.0, 500) == StepGain(1.0, 50.0, 0.602)
    with pytest.raises(ParameterError, match="scale must be positive"):
        StepGain(-1.0)


# -- the paper's presets, a few seeds (the 25-seed statistics are in the study benchmark) --------
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_emps_presets_few_seeds(emps_case, seed):
    r = {m: minimize(emps_case.cost, emps_case.x0, seed=seed, **emps_case.minimize_kwargs(m))
         for m in ("spsa", "nlspsa", "nspsa")}
    assert r["spsa"].status == DIVERGED
    assert r["nspsa"].success and r["nspsa"].fun < 1.5 and r["nspsa"].nfev == 2501
    assert r["nlspsa"].success and r["nlspsa"].fun < 10.0


@pytest.mark.parametrize("seed", [0, 1])
def test_trs_nspsa_few_seeds(trs_case, seed):
    r = minimize(trs_case.cost, trs_case.x0, seed=seed, **trs_case.minimize_kwargs("nspsa"))
    assert 178.4 < r.fun < 180.0 and r.nfev == 2001


# -- unusable residuals and the best point seen ---------------------------------------------------------------
class _Residuals:
    def __init__(self, f):
        self.f, self.calls = f, 0

    def residuals(self, x):
        self.calls += 1
        return self.f(x, self.calls)

    def __call__(self, x):
        r = np.asarray(self.residuals(x), dtype=float)
        return float(r @ r)


@pytest.mark.parametrize("bounds", [None, [(-5, 5), (-5, 5)]], ids=["normal-equations", "trf"])
@pytest.mark.parametrize("f, status, message", [
    (lambda x, k: np.full(10, np.nan), NO_FINITE_VALUE, "no evaluated point had finite residuals"),
    (lambda x, k: np.full(10, np.inf), NO_FINITE_VALUE, "no evaluated point had finite residuals"),
    (lambda x, k: np.r_[x - 1, np.nan], NO_FINITE_VALUE, "no evaluated point had finite residuals"),
    (lambda x, k: np.ones(5 + k % 2) * (x[0] - 1), SOLVER_FAILED, "changed length between evaluations"),
    (lambda x, k: 3.0, SOLVER_FAILED, "non-empty 1-D array"),
    (lambda x, k: np.zeros(0), SOLVER_FAILED, "non-empty 1-D array"),
    (lambda x, k: np.ones((2, 2)), SOLVER_FAILED, "non-empty 1-D array"),
    (lambda x, k: "abc", SOLVER_FAILED, "array of numbers"),
], ids=["nan", "inf", "one-nan", "length-changes", "scalar", "empty", "matrix", "text"])
def test_lm_reports_unusable_residuals_as_a_failure(f, status, message, bounds):
    r = minimize(_Residuals(f), np.zeros(2), method="lm", maxfev=200, bounds=bounds)
    assert not r.success and r.status == status and message in r.message, (r.status, r.message)


@pytest.mark.parametrize("method", ["spsa", "nlspsa", "nspsa"])
def test_the_spsa_family_never_returns_a_point_worse_than_its_start(method):
    """From the optimum, gains far too large throw every iterate away: the start is what comes back."""
    f = lambda x: float(np.sum((x - 1.0) ** 2)) + 1e-3  # noqa: E731
    options = {"a": StepGain(50.0, 1, 0.602), "c": PerturbationGain(0.5), "divergence_factor": 1e12}
    if method == "nlspsa":
        options["norm_limit"] = 5.0
    for seed in range(10):
        r = minimize(f, np.ones(3), method=method, maxiter=40, seed=seed, options=options)
        assert r.fun <= f(np.ones(3)) and r.fun == f(r.x) and r.fun <= r.best_fun
        assert r.last_fun > r.fun      # the last iterate is worse: the paper's estimate would be
        paper = minimize(f, np.ones(3), method=method, maxiter=40, seed=seed, options={**options, "estimate": "last"})
        assert paper.fun == paper.last_fun and np.array_equal(paper.x, r.last_x)
        if r.fun == f(np.ones(3)):
            assert "no point evaluated improved on the start" in r.message


def test_the_paper_presets_score_the_last_iterate(trs_case):
    for method in ("spsa", "nlspsa", "nspsa"):
        assert trs_case.methods[method]["options"]["estimate"] == "last"


def _rosenbrock(x):
    return float(100.0 * (x[1] - x[0] ** 2) ** 2 + (1.0 - x[0]) ** 2)


@pytest.mark.parametrize("method", ["nelder-mead", "powell"])
def test_nelder_mead_and_powell_stopped_by_maxfev_report_budget_exhausted(method):
    """Nelder-Mead and Powell stopped by our maxfev say SOLVER_FAILED (4), not BUDGET_EXHAUSTED (5).

    minimize hands maxfev to scipy for these two, so scipy stops itself at the budget ("Maximum number
    of function evaluations has been exceeded.", its status 1) and _scipy_minimize maps every scipy
    failure to SOLVER_FAILED; the other scipy methods, stopped by BudgetExhausted, say 5.  Unlimited,
    both converge (status 0) on Rosenbrock from (-1.2, 1) in 159 and 607 evaluations.
    """
    x0 = np.array([-1.2, 1.0])
    full = minimize(_rosenbrock, x0, method=method)
    assert full.status == COMPLETED and full.success and full.nfev > 100
    bfgs = minimize(_rosenbrock, x0, method="bfgs", maxfev=50)
    assert bfgs.status == BUDGET_EXHAUSTED                    # the rule for scipy's methods
    r = minimize(_rosenbrock, x0, method=method, maxfev=50)
    assert r.nfev == 50 and not r.success
    assert r.status == BUDGET_EXHAUSTED, (r.status, r.message)
    assert "exhausted before convergence" in r.message


def test_tnc_runs_and_agrees_with_scipy():
    f = lambda x: float(np.sum((x - np.array([1.0, -2.0])) ** 2))  # noqa: E731
    seen = []
    r = minimize(f, np.zeros(2), method="tnc", maxfev=200, callback=lambda res: seen.append(res.x.copy()))
    ref = scipy.optimize.minimize(f, np.zeros(2), method="tnc")
    assert r.success and r.nfev <= 200 and seen
    np.testing.assert_allclose(r.x, ref.x, atol=1e-6)
    np.testing.assert_allclose(r.x, [1.0, -2.0], atol=1e-4)


class _Counted:
    def __init__(self):
        self.calls = 0

    def __call__(self, x):
        self.calls += 1
        return float(np.sum((np.asarray(x) - 1.0) ** 2))


@pytest.mark.parametrize("method", ["spsa", "nlspsa", "nspsa"])
def test_maxfev_alone_sets_the_spsa_family_iterations(method):
    f = _Counted()
    r = minimize(f, np.zeros(2), method=method, maxfev=20_001, seed=0)
    # not 1 000 iterations / 2 001 evaluations; 8 evaluations calibrate the (automatic) gains, 1 scores the start
    assert r.nit == (20_001 - 1 - 8 - 1) // 2 and r.nfev == 20_001 - 1 == f.calls


def test_monitor_evaluations_are_paid_from_maxfev():
    f = _Counted()
    r = minimize(f, np.zeros(3), method="nspsa", maxfev=201, seed=0, options={"monitor": 50})
    assert f.calls == r.nfev + r.nfev_monitor <= 201
    assert r.nfev_monitor > 0 and np.isfinite(r.history["estimate"]).sum() > 1


@pytest.mark.parametrize("method", ["lm", "nelder-mead", "powell", "bfgs", "nspsa", "amvo-sca"])
@pytest.mark.parametrize("maxfev", [float("nan"), 0, -5, 2.5, float("inf")])
def test_a_maxfev_that_is_not_a_positive_integer_is_refused(trs_case, method, maxfev):
    bounds = TRS_BOUNDS if method == "amvo-sca" else None
    with pytest.raises(ParameterError, match="maxfev must be a positive integer"):
        minimize(trs_case.cost, trs_case.x0, method=method, maxfev=maxfev, bounds=bounds)


def test_tnc_stays_within_maxfev_and_lowers_the_trs_cost_without_leaking_numpy_warnings(trs_case):
    """scipy's finite differences meet candidates scored inf (inf - inf): no RuntimeWarning reaches the user
    (this file turns every warning into an error)."""
    r = minimize(trs_case.cost, trs_case.x0, method="tnc", maxfev=150)
    assert r.nfev <= 150 and math.isfinite(r.fun) and r.fun < trs_case.cost(trs_case.x0)


def test_the_default_method_is_least_squares_for_a_least_squares_cost_and_scipys_otherwise(trs_case):
    assert minimize(trs_case.cost, trs_case.x0, maxfev=3000).method == "lm"
    r = minimize(lambda x: float(np.sum((x - 3) ** 2)), [0.0, 0.0])
    assert np.allclose(r.x, 3.0, atol=1e-5)
    assert minimize(lambda x: float(np.sum((x - 3) ** 2)), [0.0], bounds=[(0, 1)]).x[0] == pytest.approx(1.0)
