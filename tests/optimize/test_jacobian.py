"""Levenberg-Marquardt's batched forward-difference Jacobian against scipy's own 2-point scheme.

``levenberg_marquardt`` evaluates all perturbed parameter vectors of a
Jacobian in one ``cost.residuals_batch`` call.  It must be the very Jacobian
scipy's ``"2-point"`` differences give (same steps, same formula), count one
evaluation per column exactly as before, and so leave the whole run unchanged.
"""

import warnings

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative

import hammerstein_ctrl as hc
from hammerstein_ctrl.blocks import Coulomb
from hammerstein_ctrl.optimize import levenberg_marquardt
from hammerstein_ctrl.optimize._least_squares import _BatchedJacobian, _CountedResiduals
from hammerstein_ctrl.blocks import HammersteinStructure, LinearStructure


class ResidualsOnly:
    """The same residuals without ``residuals_batch``: the Jacobian is formed column by column."""

    def __init__(self, cost):
        self.cost = cost

    def residuals(self, beta):
        return self.cost.residuals(beta)


def _jacobian(cost, x, bounds=None):
    counted = _CountedResiduals(cost.residuals, None)
    box = None if bounds is None else (np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds]))
    J = _BatchedJacobian(counted, cost.residuals_batch, box)(np.asarray(x, dtype=float))
    return J, counted.nfev


@pytest.mark.parametrize("point", ["x0", "paper"])
def test_trs_jacobian_equals_scipy_2point(trs_case, point):
    x = trs_case.x0 if point == "x0" else np.asarray(trs_case.paper["nspsa"]["beta"])
    J, nfev = _jacobian(trs_case.cost, x)
    ref = approx_derivative(trs_case.cost.residuals, x, method="2-point")
    assert J.shape == (len(trs_case.data), x.size) and nfev == x.size + 1
    np.testing.assert_allclose(J, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


def test_emps_jacobian_equals_scipy_2point_and_central_differences(emps_case):
    x = np.asarray(emps_case.paper["nspsa"]["beta"])
    J, _ = _jacobian(emps_case.cost, x)
    np.testing.assert_allclose(J, approx_derivative(emps_case.cost.residuals, x, method="2-point"),
                               rtol=1e-12, atol=1e-12)
    # and it is a derivative: close to the (more accurate) central differences
    central = approx_derivative(emps_case.cost.residuals, x, method="3-point")
    assert np.abs(J - central).max() < 1e-5 * np.abs(central).max()


def test_jacobian_steps_inward_at_an_upper_bound(trs_case):
    x = np.asarray(trs_case.paper["nspsa"]["beta"], dtype=float)
    bounds = [(v - 1.0, v) for v in x]  # every parameter at its upper bound
    J, _ = _jacobian(trs_case.cost, x, bounds)
    lb, ub = np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])
    ref = approx_derivative(trs_case.cost.residuals, x, method="2-point", bounds=(lb, ub))
    np.testing.assert_allclose(J, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


@pytest.mark.parametrize("case", ["trs_case", "emps_case"])
def test_lm_iterates_exactly_as_scipy_least_squares(case, request):
    """From the paper's (ill-conditioned) starts: the same MINPACK run as scipy's least_squares(method="lm").

    The normal-equation solver's first pass finds the scaled Gram matrix too
    ill-conditioned and hands the start over to lmder: that pass (n + 1
    evaluations) is the only difference.
    """
    case = request.getfixturevalue(case)
    calls = []

    def residuals(x):
        calls.append(1)
        return case.cost.residuals(x)

    ours = levenberg_marquardt(case.cost, case.x0)
    ref = least_squares(residuals, case.x0, method="lm", ftol=1e-10, xtol=1e-10, gtol=1e-10)
    np.testing.assert_array_equal(ours.x, ref.x)
    assert ours.fun == 2 * ref.cost and ours.message == ref.message and ours.success == ref.success
    # scipy evaluates one Jacobian more, at the solution, for its report (and the point itself if
    # it was not the last one evaluated)
    n = case.x0.size
    assert len(calls) - n - 1 + (n + 1) <= ours.nfev <= len(calls) - n + (n + 1)


@pytest.mark.parametrize("maxfev", [None, 7, 23, 60])
def test_lm_run_unchanged_by_batching(trs_case, maxfev):
    """Same iterates, value, evaluation count and history, including a budget running out mid-Jacobian.

    The batched run takes the compiled normal-equation pass (tanh's signals
    selected per lane), which sums the same differences in another order:
    values agree to rounding, counts exactly.
    """
    cost = trs_case.cost
    batched = levenberg_marquardt(cost, trs_case.x0, maxfev=maxfev)
    columns = levenberg_marquardt(ResidualsOnly(cost), trs_case.x0, maxfev=maxfev)
    assert batched.nfev == columns.nfev
    if maxfev is not None:
        assert batched.nfev == maxfev
    np.testing.assert_allclose(batched.x, columns.x, rtol=1e-12)
    assert batched.fun == pytest.approx(columns.fun, rel=1e-12)
    assert batched.best_fun == pytest.approx(columns.best_fun, rel=1e-12)
    np.testing.assert_array_equal(batched.history["nfev"], columns.history["nfev"])
    for key in ("fun", "best"):
        np.testing.assert_allclose(batched.history[key], columns.history[key], rtol=1e-12)


def test_lm_with_bounds_unchanged_by_batching(trs_case):
    bounds = [(-5.0, 5.0)] * 3 + [(-10.0, 10.0), (-1.0, 1.0)]
    batched = levenberg_marquardt(trs_case.cost, trs_case.x0, bounds=bounds, maxfev=300)
    columns = levenberg_marquardt(ResidualsOnly(trs_case.cost), trs_case.x0, bounds=bounds, maxfev=300)
    assert batched.nfev == columns.nfev
    np.testing.assert_array_equal(batched.x, columns.x)


def test_lm_reaches_the_emps_optimum_with_batched_jacobian(emps_case):
    r = levenberg_marquardt(emps_case.cost, emps_case.x0, maxfev=2501)
    # the least-squares optimum of the EMPS record (below every value of the paper's Table 7)
    assert abs(r.fun - 0.208517) < 1e-6 and r.nfev < 400


def test_lm_with_bounds_never_evaluates_outside_the_box(coulomb_record):
    """The trf Jacobian's forward steps flip only at the upper bound: at a negative lower bound
    the neighbour x - h lies outside the box (scipy's "2-point" flips at both bounds)."""
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    cost = hc.HammersteinCost(coulomb_record(), structure)
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


def test_counted_residuals_book_huge_residuals_without_a_numpy_warning():
    """auto's MINPACK refinements book residuals of 1e150 stand-ins: their sum of squares is inf, silently."""
    counted = _CountedResiduals(lambda x: np.full(3, 1e200), None)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        r = counted(np.zeros(2))
    assert r.shape == (3,) and counted.history.as_dict()["fun"].tolist() == [np.inf]
