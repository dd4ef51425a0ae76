"""The fused normal-equation pass and the Levenberg-Marquardt solver built on it.

Oracles: the same sums formed from the stored N x p forward-difference
Jacobian (``residuals_batch``), scipy's own 2-point Jacobian, and
``scipy.optimize.least_squares(method="lm")`` (MINPACK) for the optimum.
"""

import os
import tracemalloc
import warnings

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative

import hammerstein_ctrl as hc
from hammerstein_ctrl import identify
from hammerstein_ctrl.fit import _objective as objective
from hammerstein_ctrl import presets
from hammerstein_ctrl.simulate import _simulate as simulate
from hammerstein_ctrl.optimize import _streamed_lstsq as streamed_lstsq
from hammerstein_ctrl.fit._auto import auto_minimize
from hammerstein_ctrl.exceptions import HammersteinError, ParameterError
from hammerstein_ctrl.optimize._normal_equations import forward_steps, from_residuals, neighbours
from hammerstein_ctrl.fit import HammersteinCost
from hammerstein_ctrl.optimize import BUDGET_EXHAUSTED, COMPLETED, levenberg_marquardt
from hammerstein_ctrl.optimize import minimize
from hammerstein_ctrl.optimize import _normal_lm as normal_lm
from hammerstein_ctrl.optimize import _least_squares as ls


def _stored(cost, x):
    """The oracle: the same sums from the stored Jacobian, through scipy's 2-point differences."""
    x = np.asarray(x, dtype=float)
    r = cost.residuals(x)
    J = approx_derivative(cost.residuals, x, method="2-point")
    return float(r @ r), J.T @ r, J.T @ J


def _check(cost, x, rtol=1e-6):
    ne = cost.normal_equations(x)
    f, g, G = _stored(cost, x)
    assert abs(ne.fun - f) <= 1e-12 * f
    np.testing.assert_allclose(ne.gram, G, rtol=rtol, atol=rtol * np.abs(G).max())
    np.testing.assert_allclose(ne.gradient, g, rtol=rtol, atol=rtol * np.abs(g).max())
    return ne


def test_emps_fused_pass_matches_the_stored_jacobian(emps_case):
    x = np.asarray(emps_case.paper["nspsa"]["beta"])
    assert emps_case.cost._fused_normal_equations(
        x + np.vstack([np.zeros(4), np.diag(forward_steps(x))]), forward_steps(x)) is not None
    ne = _check(emps_case.cost, x)
    # the neighbours' sums of squares follow from the sums exactly (r_j = r + h_j J_j)
    X = x + np.vstack([np.zeros(4), np.diag(ne.steps)])
    np.testing.assert_allclose(ne.neighbour_values(), emps_case.cost.batch(X)[1:], rtol=1e-9)


def _synthetic(hold, n=3, N=3000, seed=0):
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-2, 2, N // 30), 30)
    t = np.arange(N) * 0.01
    return hc.IOData(u, np.sin(t) + 0.1 * rng.normal(size=N), dt=0.01, intersample=hold, name="syn")


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_offset_initial_state_and_hold_in_the_fused_pass(hold):
    data = _synthetic(hold)
    structure = hc.HammersteinStructure(hc.LinearStructure(1, 3), hc.Polynomial(2), offset=True,
                                        initial_state="estimate")
    cost = HammersteinCost(data, structure)
    x = np.random.default_rng(1).uniform(0.5, 2.0, structure.n_params)
    x[:5] = [1.0, 0.5, 3.0, 3.0, 1.0]  # b1, b0, a2, a1, a0: a stable block
    _check(cost, x)


def test_blocks_of_a_recomputed_basis_give_the_same_sums(emps_case, monkeypatch):
    x = np.asarray(emps_case.paper["nspsa"]["beta"])
    whole = emps_case.cost.normal_equations(x)
    monkeypatch.setattr(objective, "BASIS_MAX_BYTES", 0)
    monkeypatch.setattr(objective, "BASIS_BLOCK", 7919)  # a prime: blocks end mid-level
    streamed = HammersteinCost(emps_case.data, emps_case.structure)
    assert streamed._basis is None
    ne = streamed.normal_equations(x)
    assert abs(ne.fun - whole.fun) <= 1e-12 * whole.fun
    np.testing.assert_allclose(ne.gram, whole.gram, rtol=1e-9)


def test_g_without_a_basis_and_output_maps_take_the_fused_pass(trs_case):
    """TRS (tanh, not linear in its parameters): its signals selected per lane in the compiled pass;
    Wiener and Hammerstein-Wiener models: the output map applied in the pass.  All as the stored Jacobian."""
    x = np.asarray(trs_case.paper["nspsa"]["beta"])
    h = forward_steps(x)
    assert trs_case.cost._fused_normal_equations(neighbours(x, h), h) is not None
    _check(trs_case.cost, x)
    for hold in ("foh", "zoh"):
        data = _synthetic(hold, N=1500)
        for structure, xs in ((hc.WienerStructure(hc.LinearStructure(0, 2), hc.Tanh()), [2.0, 3.0, 1.5, 0.7]),
                              (hc.WienerStructure(hc.LinearStructure(1, 2), hc.Saturation(), offset=True),
                               [0.5, 2.0, 3.0, 1.2, 0.05, 0.1]),
                              (hc.HammersteinWienerStructure(hc.LinearStructure(0, 2), hc.Coulomb(), hc.Tanh()),
                               [2.0, 3.0, 0.2, 0.1, 1.5, 0.7])):
            cost = HammersteinCost(data, structure)
            xs = np.array(xs)
            hs = forward_steps(xs)
            assert cost._fused_normal_equations(neighbours(xs, hs), hs) is not None
            _check(cost, xs)


def test_from_residuals_replaces_nonfinite_residuals():
    R = np.array([[1.0, np.nan], [2.0, 1.0]])
    ne = from_residuals(R, [0.5])
    assert np.isfinite(ne.fun) and ne.finite


@pytest.mark.parametrize("case", ["emps_case", "trs_case"])
def test_lm_reaches_minpacks_optimum_from_perturbed_starts(case, request):
    case = request.getfixturevalue(case)
    rng = np.random.default_rng(7)
    best = levenberg_marquardt(case.cost, case.x0).fun
    x_opt = levenberg_marquardt(case.cost, case.x0).x
    ratios = []
    for _ in range(9):
        x0 = x_opt * (1 + rng.uniform(-0.3, 0.3, x_opt.size))
        ours = levenberg_marquardt(case.cost, x0)
        ref = least_squares(case.cost.residuals, x0, method="lm", ftol=1e-10, xtol=1e-10, gtol=1e-10)
        assert ours.success
        assert ours.fun <= 2 * ref.cost * (1 + 1e-8) and ours.fun <= best * (1 + 1e-7)
        # scipy counts the residual calls outside its Jacobians; each of our steps is one pass of p + 1
        ratios.append(ours.nfev / ((x0.size + 1) * (ref.nfev + 2)))
    # near the optimum the last steps' acceptance turns on rounding (the ftol test compares reductions
    # of ~1e-12 relative), so single starts vary: on EMPS 40 starts took 45 evaluations in the median
    # and 73 at most, against MINPACK's 45; as many passes in the median, never twice as many
    assert np.median(ratios) <= 1.0 and max(ratios) <= 2.0, ratios


def test_emps_from_the_nspsa_vector_stays_on_the_normal_equations(emps_case, monkeypatch):
    """A stable start: every step from the fused pass (no hand-over to MINPACK), to the optimum."""
    from hammerstein_ctrl.optimize import _least_squares as ls

    def refuse(*args, **kwargs):
        raise AssertionError("handed over to MINPACK")

    monkeypatch.setattr(ls, "lmder", refuse)
    r = levenberg_marquardt(emps_case.cost, np.asarray(emps_case.paper["nspsa"]["beta"]))
    assert r.success and abs(r.fun - 0.208517) < 1e-6 and r.nit < 20
    assert r.nfev % 5 == 0  # passes of p + 1 = 5 evaluations only (no trial was rejected)


def test_ill_conditioning_hands_over_to_minpack(emps_case):
    ne = emps_case.cost.normal_equations(emps_case.x0)  # the paper's unstable start
    scale = normal_lm._column_norms(ne.gram)
    ill = normal_lm._iteration(ne.gram, ne.gradient, ne.fun, scale, normal_lm.INITIAL_DAMPING,
                               np.asarray(emps_case.x0, float), True, normal_lm.ILL_CONDITIONED, 1e-10)[1]
    assert ill


@pytest.mark.parametrize("maxfev", [3, 5, 12, 23])
def test_budget_is_exact_on_the_normal_equations(emps_case, maxfev):
    r = levenberg_marquardt(emps_case.cost, np.asarray(emps_case.paper["nspsa"]["beta"]), maxfev=maxfev)
    assert r.nfev == maxfev and len(r.history["fun"]) == maxfev
    assert r.fun == min(r.history["fun"]) and "budget" in r.message


def test_a_nan_cosine_never_passes_the_gtol_test():
    """An infinite Jacobian column makes MINPACK's cosine NaN, as numpy's max would: no false convergence."""
    gram, gradient = np.array([[np.inf, np.inf], [np.inf, 1.0]]), np.array([np.inf, 1e-12])
    cosine, ill = normal_lm._iteration(gram, gradient, 1.0, np.ones(2), 1e-3, np.ones(2), True,
                                       normal_lm.ILL_CONDITIONED, 1e-10)[:2]
    assert np.isnan(cosine) and ill


def test_normal_pass_checks_shapes_and_keeps_a_given_state(emps_case):
    from hammerstein_ctrl.exceptions import DataError, ParameterError
    from hammerstein_ctrl.optimize._normal_equations import from_difference_sums
    from hammerstein_ctrl.simulate._simulate import normal_pass

    cost = emps_case.cost
    x = np.asarray(emps_case.paper["nspsa"]["beta"], float)
    h = forward_steps(x)
    X = neighbours(x, h)
    num, den = emps_case.structure.linear.coefficients(X[:, :1])
    P = X[:, 1:]
    x0 = np.zeros((5, 2))
    ne = normal_pass(num, den, emps_case.data.dt, cost._y, P, [cost._basis], h, x0=x0)
    ref = normal_pass(num, den, emps_case.data.dt, cost._y, P, [cost._basis], h)
    np.testing.assert_array_equal(ne.gram, ref.gram)
    assert not x0.any()                                   # the caller's state is not written
    # the neighbours of the basis coefficients share the point's linear block: two rows serve five lanes
    shared = normal_pass(num[:2], den[:2], emps_case.data.dt, cost._y, P, [cost._basis], h)
    assert shared.fun == ref.fun
    np.testing.assert_array_equal(shared.gram, ref.gram)
    np.testing.assert_array_equal(shared.gradient, ref.gradient)
    with pytest.raises(ParameterError, match="one row of basis coefficients per candidate"):
        normal_pass(num, den, emps_case.data.dt, cost._y, P[:2], [cost._basis], h)
    with pytest.raises(ParameterError, match="at most as many linear blocks"):
        normal_pass(np.vstack([num, num[:1]]), np.vstack([den, den[:1]]), emps_case.data.dt, cost._y, P,
                    [cost._basis], h)
    with pytest.raises(DataError, match="cover 100 samples"):
        normal_pass(num, den, emps_case.data.dt, cost._y, P, [cost._basis[:, :100]], h)
    with pytest.raises(DataError, match="non-zero"):
        normal_pass(num, den, emps_case.data.dt, np.zeros(0), P, [], h)
    with pytest.raises(ValueError, match="do not fit 2 steps"):
        from_difference_sums([1.0, 2.0], [0.1, 0.2])


def test_a_nonfinite_last_signal_sample_makes_the_pass_nonfinite():
    """ZOH, strictly proper, no offset: the pass leaves d = 0 out, so the last signal sample must be checked."""
    from hammerstein_ctrl.simulate._simulate import normal_pass

    N = 40
    u = np.full(N, 1e-200)
    u[-1] = 1e200
    num, den = np.ones((2, 1)), np.tile([1.0, 1.0], (2, 1))
    P = np.array([[1e200], [1e200 * (1 + 1e-8)]])
    ne = normal_pass(num, den, 0.01, np.zeros(N), P, [u[None]], np.array([1e192]), intersample="zoh")
    assert not ne.finite
    ok = normal_pass(num, den, 0.01, np.zeros(N), P, [np.full((1, N), 1e-200)], np.array([1e192]), intersample="zoh")
    assert ok.finite


def test_up_to_sixteen_lanes_take_the_fused_pass():
    """A degree-7 polynomial g with a (2, 3) block and an offset: 14 lanes, the stored Jacobian's sums;
    with x(0) estimated too (17 lanes) the residuals give them on a record this short (lane groups on long
    ones: see test_lane_groups_*)."""
    import control

    from hammerstein_ctrl._kernels import MAX_NORMAL_LANES

    t = 0.01 * np.arange(4000)
    u = np.sin(t) + 0.5 * np.sin(3.3 * t)
    y = control.forced_response(control.tf([1, 2], [1, 2, 4, 3]), t, u + 0.2 * u ** 3).outputs
    data = hc.IOData(u, y, dt=0.01)
    s = hc.HammersteinStructure(hc.LinearStructure(2, 3), hc.Polynomial(7), offset=True)
    cost = HammersteinCost(data, s)
    x = np.random.default_rng(0).uniform(0.5, 2.0, s.n_params)
    h = forward_steps(x)
    assert s.n_params + 1 == 14 <= MAX_NORMAL_LANES
    assert cost._fused_normal_equations(neighbours(x, h), h) is not None
    ne = cost.normal_equations(x)
    f, g, G = _stored(cost, x)
    assert ne.fun == pytest.approx(f, rel=1e-12)
    scale = np.sqrt(np.outer(np.diag(G), np.diag(G)))
    assert np.max(np.abs(ne.gram - G) / scale) < 1e-5
    wide = HammersteinCost(data, hc.HammersteinStructure(hc.LinearStructure(2, 3), hc.Polynomial(7), offset=True,
                                                         initial_state="estimate"))
    xw = np.random.default_rng(1).uniform(0.5, 2.0, wide.n_params)
    hw = forward_steps(xw)
    assert wide.n_params + 1 == 17 > MAX_NORMAL_LANES
    assert wide._fused_normal_equations(neighbours(xw, hw), hw) is None
    assert wide.normal_equations(xw).fun == pytest.approx(wide(xw), rel=1e-12)


def _lane_group_cases():
    import control

    t = 0.01 * np.arange(4000)
    u = np.sin(t) + 0.5 * np.sin(3.3 * t)
    y = control.forced_response(control.tf([1, 2], [1, 2, 4, 3]), t, u + 0.2 * u ** 3).outputs
    data = hc.IOData(u, y, dt=0.01)
    knots = np.linspace(-0.9, 0.9, 11)
    return data, {
        # 17 lanes, 8 basis signals: two groups on the same basis rows
        "lanes": hc.HammersteinStructure(hc.LinearStructure(2, 3), hc.Polynomial(7), offset=True,
                                         initial_state="estimate"),
        # 17 lanes, 11 basis signals: groups on row 0's signal and the rows their neighbours move
        "lanes and basis": hc.HammersteinStructure(hc.LinearStructure(1, 3), hc.PiecewiseLinear(knots), offset=True),
        # 12 lanes, 11 basis signals
        "basis": hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.PiecewiseLinear(knots[1:-1])),
        # an output saturation with 18 lanes and 11 basis signals: a compiled output map in every group
        "output map": hc.HammersteinWienerStructure(hc.LinearStructure(1, 3), hc.PiecewiseLinear(knots),
                                                    hc.Saturation(), offset=True),
    }


@pytest.mark.parametrize("case", ["lanes", "lanes and basis", "basis", "output map"])
def test_lane_groups_give_the_stored_jacobians_sums(case):
    """Past one pass (more than 16 lanes or 8 basis signals) groups of passes run side by side:
    the sums and the QR factor are the stored forward-difference Jacobian's."""
    from hammerstein_ctrl._kernels import MAX_LANE_BASIS, MAX_NORMAL_LANES
    from hammerstein_ctrl.simulate._normal_pass import _LaneGroups

    data, structures = _lane_group_cases()
    s = structures[case]
    cost = HammersteinCost(data, s)
    x = np.random.default_rng(1).uniform(0.5, 2.0, s.n_params)
    h = forward_steps(x)
    assert s.n_params + 1 > MAX_NORMAL_LANES or s.input_nonlinearity.n_params > MAX_LANE_BASIS, s.n_params
    groups = []
    original = _LaneGroups.prepare.__func__

    def spy(cls, *args):
        groups.append(original(cls, *args))
        return groups[-1]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(_LaneGroups, "prepare", classmethod(spy))
        mp.setattr("hammerstein_ctrl.simulate._normal_pass.GROUPS_MIN_BYTES", 0)    # a short record: same groups
        ne, qr = cost.normal_equations(x, h), cost.normal_factor(x, h)
    assert len(groups) == 2 and all(g is not None and len(g.groups) >= 2 for g in groups)
    f, g, G = _stored(cost, x)
    scale = np.sqrt(np.outer(np.diag(G), np.diag(G)))
    for result in (ne, qr):
        assert result.fun == pytest.approx(f, rel=1e-12)
        assert np.max(np.abs(result.gram - G) / scale) < 1e-5
        assert np.max(np.abs(result.gradient - g) / np.sqrt(np.diag(G) * f)) < 1e-5


def test_lane_groups_keep_memory_bounded_on_long_records():
    """17 lanes and 11 basis signals: the peak grows by under 4 B per sample between 1e6 and 2e6 samples,
    where p + 1 stored residual vectors take 136 (the rest is a few blocks of samples: basis, lane outputs)."""
    import tracemalloc

    s = _lane_group_cases()[1]["lanes and basis"]
    x = np.random.default_rng(1).uniform(0.5, 2.0, s.n_params)
    x[:4] = [1.0, 1.0, 3.0, 3.0]                            # H = 1 / (p + 1)^3: stable over 1e6 samples
    peaks = {}
    for n in (1_000_000, 2_000_000):
        t = 0.01 * np.arange(n)
        cost = HammersteinCost(hc.IOData(np.sin(0.3 * t) + 0.5 * np.sin(3.3 * t), np.cos(t), dt=0.01), s)
        cost.normal_equations(x), cost.normal_factor(x)     # compile, allocate caches
        for method in (cost.normal_equations, cost.normal_factor):
            tracemalloc.start()
            try:
                ne = method(x)
                peak = tracemalloc.get_traced_memory()[1]
            finally:
                tracemalloc.stop()
            assert np.isfinite(ne.fun)
            peaks[method.__name__, n] = peak
    for name in ("normal_equations", "normal_factor"):
        growth = (peaks[name, 2_000_000] - peaks[name, 1_000_000]) / 1_000_000
        assert growth < 4, (name, growth, peaks)


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_an_output_map_without_a_compiled_form_is_applied_to_the_lanes_outputs(hold):
    """A custom h: the pass hands out the lanes' linear outputs a block at a time, mapped (and offset) in
    numpy, so no p + 1 residual vectors are stored; the sums are the stored Jacobian's."""
    cubic = hc.CustomNonlinearity(lambda v, p: p[0] * v + p[1] * v ** 3, n_params=2)
    for offset, x in ((False, [2.0, 3.0, 1.5, 0.1]), (True, [2.0, 3.0, 1.5, 0.1, 0.2])):
        cost = HammersteinCost(_synthetic(hold, N=1500),
                               hc.WienerStructure(hc.LinearStructure(0, 2), cubic, offset=offset))
        x = np.array(x)
        h = forward_steps(x)
        assert cubic.compiled_map is None and cost._fused_normal_equations(neighbours(x, h), h) is not None
        _check(cost, x)


@pytest.mark.parametrize("case", ["emps_case", "trs_case"])
def test_normal_factor_matches_the_sums_and_the_stored_jacobian(case, request):
    case = request.getfixturevalue(case)
    x = np.asarray(case.paper["nspsa"]["beta"], float)
    qr = case.cost.normal_factor(x)
    f, g, G = _stored(case.cost, x)
    scale = np.sqrt(np.outer(np.diag(G), np.diag(G)))
    assert qr.fun == pytest.approx(f, rel=1e-12)
    assert np.max(np.abs(qr.gram - G) / scale) < 1e-6
    np.testing.assert_allclose(qr.gradient, g, rtol=1e-6, atol=1e-6 * np.abs(g).max())
    R, qtr = qr.factor
    assert np.allclose(np.triu(R), R)                       # upper triangular
    # a Wiener model (compiled map) and a custom output map (the stored residuals' QR) agree as well
    for h in (hc.Saturation(), hc.CustomNonlinearity(lambda v, p: p[0] * v + p[1] * v ** 3, n_params=2)):
        cost = HammersteinCost(_synthetic("zoh", N=1500), hc.WienerStructure(hc.LinearStructure(0, 2), h))
        xs = np.array([2.0, 3.0, 1.5, 0.3])
        a, b = cost.normal_factor(xs), cost.normal_equations(xs)
        assert a.fun == pytest.approx(b.fun, rel=1e-12)
        np.testing.assert_allclose(a.gram, b.gram, rtol=1e-6, atol=1e-9 * np.abs(b.gram).max())


@pytest.mark.parametrize("case", ["emps_case", "trs_case"])
def test_lm_on_the_qr_factor_reaches_minpacks_optimum(case, request, monkeypatch):
    """From the paper's x0 the Gram matrix is too ill-conditioned: below MINPACK_MAX_BYTES MINPACK's lmder
    takes over; past it (forced here) the solver goes on with the streamed QR factor, to the same optimum."""
    from hammerstein_ctrl.optimize import _least_squares as ls

    case = request.getfixturevalue(case)
    minpack = levenberg_marquardt(case.cost, case.x0)
    monkeypatch.setattr(ls, "MINPACK_MAX_BYTES", 0)
    factored = levenberg_marquardt(case.cost, case.x0)
    assert factored.success and minpack.success
    assert factored.fun == pytest.approx(minpack.fun, rel=1e-7)
    # not above MINPACK's beyond the spread of converged values (the ftol test stops within ~3e-12 of
    # each other on EMPS: 40 perturbed starts spanned 2.8e-12 relative)
    assert factored.fun <= minpack.fun * (1 + 1e-11)
    if case.name == "emps":             # TRS's tanh has a nearly flat direction (d0 d1 fixed): J, not x
        np.testing.assert_allclose(factored.x, minpack.x, rtol=1e-5)


def test_blocks_past_the_unrolled_kernels_take_the_pass():
    """A 10-state block (the most a LinearStructure takes; J's kernels unroll 8): the normal-equation pass
    applies, with the stored Jacobian's sums, so LM stores no p + 1 residual vectors for it either."""
    import control

    from hammerstein_ctrl._kernels import MAX_PASS_STATES, MAX_UNROLLED_STATES

    t = 0.01 * np.arange(3000)
    u = np.sin(t) + 0.5 * np.sin(3.3 * t)
    den = np.real(np.poly(-np.linspace(0.5, 3.0, 10)))
    y = control.forced_response(control.tf([1.0], den), t, 0.8 * u + 0.2 * np.sign(u)).outputs
    s = hc.HammersteinStructure(hc.LinearStructure(0, 10), hc.Coulomb())
    assert s.linear.den_order == MAX_PASS_STATES > MAX_UNROLLED_STATES
    cost = HammersteinCost(hc.IOData(u, y, dt=0.01), s)
    x = np.r_[den[1:][::-1], 0.8, 0.2, 0.0] * 1.01
    h = forward_steps(x)
    ne = cost._fused_normal_equations(neighbours(x, h), h)
    assert ne is not None
    ref = from_residuals(cost.residuals_batch(neighbours(x, h)), h)
    assert ne.fun == pytest.approx(ref.fun, rel=1e-9)
    scale = np.sqrt(np.outer(np.diag(ref.gram), np.diag(ref.gram)))
    assert np.max(np.abs(ne.gram - ref.gram) / scale) < 1e-4        # forward differences of a 10-state block


@pytest.mark.parametrize("maxfev", [5, 10, 14, 20, 44])
def test_a_budget_that_ends_before_convergence_fails_with_the_steps_taken(emps_case, maxfev):
    """status BUDGET_EXHAUSTED and success False, as scipy's own methods report running out of evaluations.

    From the N-SPSA vector every step's trial point is a full pass (the point and its p = 4 neighbours,
    5 evaluations) and every trial is accepted on the way to the optimum, which a budget of 45 reaches
    in 8 steps: so a budget of ``maxfev`` evaluates the trial points (row 0 of a pass) of
    ``(maxfev - 1) // 5`` steps.
    """
    x = np.asarray(emps_case.paper["nspsa"]["beta"])
    p1 = x.size + 1
    full = levenberg_marquardt(emps_case.cost, x, maxfev=45)
    assert full.success and full.status == COMPLETED and full.nfev == 45 and full.nit == (45 - p1) // p1
    r = levenberg_marquardt(emps_case.cost, x, maxfev=maxfev)
    assert r.status == BUDGET_EXHAUSTED and not r.success and "exhausted before convergence" in r.message
    assert r.nit == (maxfev - 1) // p1 and r.nfev == maxfev


def test_scipy_methods_and_identify_report_the_budgets_end(emps_case):
    """The same status from scipy's methods stopped by our budget, and a failed identification that says why."""
    r = minimize(emps_case.cost, np.asarray(emps_case.paper["nspsa"]["beta"]), method="l-bfgs-b", maxfev=12)
    assert r.status == BUDGET_EXHAUSTED and not r.success and r.nfev == 12
    res = identify(emps_case.data, emps_case.structure, method="lm", x0=emps_case.x0, maxfev=20)
    assert not res.success and "exhausted before convergence" in res.message
    auto = identify(emps_case.data, emps_case.structure, maxfev=60, seed=0)
    assert not auto.success and auto.optimize_result.status == BUDGET_EXHAUSTED


def test_auto_leaves_the_advice_to_identify(trs_case):
    """auto's own message says how the best refinement stopped and gives no advice: identify adds it, from the
    verdicts (diagnostics.budget_advice)."""
    from types import SimpleNamespace

    from scipy.optimize import OptimizeResult

    from hammerstein_ctrl.fit._auto import _result
    from hammerstein_ctrl.fit._initialize import Budget
    from hammerstein_ctrl.optimize import SOLVER_FAILED, History

    x = np.asarray(trs_case.true_beta, dtype=float)
    merged = SimpleNamespace(history=History(), ends=[])
    for status in (SOLVER_FAILED, BUDGET_EXHAUSTED):
        best = OptimizeResult(x=x, fun=trs_case.cost(x), status=status, message="the solver's own words")
        r = _result(trs_case.cost, best, Budget(500), 2, 3, merged, False, 0.0)
        assert r.status == status and not r.success and "the solver's own words" in r.message
        assert "raise" not in r.message


def _lane_outputs_by_hand(E, C, D, X, Y0, P, Phi, hold):
    """Every lane's output samples and last state from the recursion written out in numpy (as the kernels document
    it)."""
    lanes, n = X.shape
    out, last = np.empty((lanes, Phi.shape[1])), np.empty((lanes, n))
    for g in range(lanes):
        e = g if g < E.shape[0] else 0
        A, B0, B1 = E[e, :, :n], E[e, :, n], E[e, :, n + 1]
        v = P[g] @ Phi
        x = X[g].copy()
        for i in range(v.size):
            if i:
                x = A @ x + ((B0 - B1) * v[i - 1] + B1 * v[i] if hold == "foh" else B0 * v[i - 1])
            out[g, i] = C[e] @ x + D[e] * v[i] + Y0[g]
        last[g] = x
    return out, last


@pytest.mark.parametrize("n, hold, lanes, direct, offset", [
    (1, "zoh", 2, True, True), (2, "foh", 5, False, False), (3, "zoh", 9, True, False),
    (2, "foh", 3, False, False), (3, "zoh", 6, True, False),     # fewer lanes in the same vectors (same kernels)
    (1, "foh", 12, False, True),    # three vectors: the sums of products across them
    pytest.param(4, "foh", 16, False, True, marks=pytest.mark.slow),     # the widest vector pass: 10 s to compile
    (5, "foh", 6, True, True),      # past MAX_VECTOR_STATES: the lanes in an array
])
def test_pass_sums_match_the_recursion_written_out(n, hold, lanes, direct, offset):
    """Both pass layouts against numpy: the sums over two blocks of samples, the carried states, and a
    neighbour equal to the point contributing exact zeros (the point and the neighbours round alike)."""
    from hammerstein_ctrl._kernels import get_normal_kernel

    rng = np.random.default_rng(n * 100 + lanes)
    K, N, split = 3, 400, 157
    A = 0.9 * np.eye(n) + 0.02 * rng.standard_normal((n, n))
    E = np.concatenate([np.broadcast_to(A, (lanes, n, n)), 0.1 * rng.standard_normal((lanes, n, 2))], axis=2)
    E[1:, :, :n] += 1e-3 * rng.standard_normal((lanes - 1, n, n))
    C, X = rng.standard_normal((lanes, n)), rng.standard_normal((lanes, n))
    D = rng.standard_normal(lanes) if direct else np.zeros(lanes)
    Y0 = rng.standard_normal(lanes) if offset else np.zeros(lanes)
    P, Phi, y = rng.standard_normal((lanes, K)), rng.standard_normal((K, N)), rng.standard_normal(N)
    for arr in (E, C, X, P):                  # the last neighbour is the point itself
        arr[-1] = arr[0]
    D[-1], Y0[-1] = D[0], Y0[0]
    Yh, last = _lane_outputs_by_hand(E, C, D, X, Y0, P, Phi, hold)
    r, Dif = y - Yh[0], Yh[0] - Yh[1:]
    kernel = get_normal_kernel(n, hold, lanes, K, direct, offset)
    acc, Xk, VP = np.zeros(1 + (lanes - 1) * lanes), X.copy(), np.zeros(lanes)
    for a, b in ((0, split), (split, N)):
        kernel(E, C, D, Xk, Y0, VP, P, np.ascontiguousarray(Phi[:, a:b]), np.zeros((lanes, 0)), np.zeros(0),
               y[a:b], a, acc)
    p = lanes - 1
    np.testing.assert_allclose(acc[0], r @ r, rtol=1e-12)
    np.testing.assert_allclose(acc[1:1 + p], Dif @ r, rtol=1e-9, atol=1e-12 * np.abs(Dif).sum())
    H = acc[1 + p:].reshape(p, p)
    np.testing.assert_allclose(H, Dif @ Dif.T, rtol=1e-9, atol=1e-12 * (Dif ** 2).sum())
    assert np.array_equal(H, H.T)
    assert np.all(H[-1] == 0) and acc[p] == 0        # the neighbour equal to the point: exact zeros
    np.testing.assert_allclose(Xk, last, rtol=1e-10, atol=1e-12)        # carried to a next block
    np.testing.assert_allclose(VP, P @ Phi[:, -1], rtol=1e-12)


def test_one_pass_serves_every_lane_count_and_refuses_arrays_too_small_for_it():
    """A pass counts its lanes at run time (the length of VP): every count from 2 to 16 is one kernel of the core,
    and arrays too small for the lanes counted are refused, never read past."""
    from hammerstein_ctrl._kernels import get_normal_kernel

    kernel = get_normal_kernel(2, "foh", 5, 3, False, False)
    assert all(get_normal_kernel(2, "foh", lanes, 3, False, False).number == kernel.number for lanes in range(2, 17))
    E = np.zeros((1, 2, 4))

    def run(lanes=4, P_rows=4, acc=13, Phi_rows=3, y=10):
        kernel(E, np.zeros((1, 2)), np.zeros(1), np.zeros((lanes, 2)), np.zeros(lanes), np.zeros(lanes),
               np.zeros((P_rows, 3)), np.zeros((Phi_rows, 10)), np.zeros((lanes, 0)), np.zeros(0), np.zeros(y), 0,
               np.zeros(acc))

    run()
    run(lanes=6, P_rows=6, acc=31)
    for bad in ({"lanes": 17, "P_rows": 17, "acc": 273}, {"P_rows": 2}, {"acc": 12}, {"Phi_rows": 2}, {"y": 9}):
        with pytest.raises(ValueError, match="the pass takes 2 to 16 lanes"):
            run(**bad)


def _plain_case(name):
    """``(cost, x)`` of a plain structure (no offset, initial state or output map), by name."""
    cases = {"zoh, 3 states": (hc.LinearStructure(1, 3), [0.5, 1.0, 3.0, 3.0], "zoh"),
             "biproper, direct term": (hc.LinearStructure(2, 2), [1.0, 0.5, 2.0, 3.0], "foh"),
             "6 states, array pass": (hc.LinearStructure(0, 6), np.poly(-np.arange(1.0, 7.0))[1:][::-1], "foh"),
             "fast pole, scipy's expm": (hc.LinearStructure(0, 1), [1e4], "foh")}
    linear, lin_x, hold = cases[name]
    structure = hc.HammersteinStructure(linear, hc.Polynomial(2))
    x = np.r_[lin_x, 0.3, 1.2]
    return HammersteinCost(_synthetic(hold), structure), x


@pytest.mark.parametrize("name", ["emps", "zoh, 3 states", "biproper, direct term", "6 states, array pass",
                                  "fast pole, scipy's expm"])
def test_plain_structures_pass_from_the_coefficients_with_the_general_passs_sums(name, emps_case):
    """One compiled call from the coefficients (discretisation and pass) gives the bits of the general
    pass (simulate.normal_pass, the same kernel); a row the compiled Pade cannot take goes the general way."""
    from hammerstein_ctrl.simulate._simulate import normal_pass

    cost, x = (emps_case.cost, np.asarray(emps_case.paper["nspsa"]["beta"])) if name == "emps" else _plain_case(name)
    h = forward_steps(x)
    X = neighbours(x, h)
    P, basis = cost._basis_form(X)
    direct = cost._direct_normal_equations(X, h, P, basis)
    assert (direct is None) == (name == "fast pole, scipy's expm")
    num, den = cost.structure.linear._coefficients(X[:, :cost.structure.linear.n_params])
    general = normal_pass(num, den, cost.data.dt, cost.data.y, P, [basis], h, intersample=cost.data.intersample)
    ne = cost.normal_equations(x, h)
    assert ne.fun == general.fun and np.isfinite(ne.fun) and ne.fun > 0
    np.testing.assert_array_equal(ne.gradient, general.gradient)
    np.testing.assert_array_equal(ne.gram, general.gram)     # (the general pass against stored Jacobians: above)


def test_a_pass_books_its_best_neighbour_as_the_row_of_neighbours():
    """LM's pass books p + 1 evaluations; a neighbour that becomes the best point is the row neighbours() gives."""
    from hammerstein_ctrl.optimize._least_squares import _CountedResiduals

    counted = _CountedResiduals(lambda x: x, maxfev=100)
    x = np.array([0.1, -3.0, 7.0])
    h = forward_steps(x)
    counted.charge(4)
    counted.record_neighbourhood(x, h, [5.0, 6.0, 2.0, 3.0])
    assert counted.best_fun == 2.0
    np.testing.assert_array_equal(counted.best_x, neighbours(x, h)[2])
    assert counted.best_x[1] != x[1]
    counted.record_neighbourhood(x, h, [1.0, np.inf, 4.0, 3.0])          # the point itself
    np.testing.assert_array_equal(counted.best_x, x)
    assert counted.history.as_dict()["best"].tolist() == [5.0, 5.0, 2.0, 2.0, 1.0, 1.0, 1.0, 1.0]


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_a_biproper_block_whose_direct_term_is_fixed_at_zero_passes_with_the_general_passs_bits(hold):
    """num and den of one width, but b_n fixed at 0 (D = 0 in every lane): the general pass leaves the
    direct term out (simulate.output_terms: D.any() is False), and so must the one call from the
    coefficients.  With the term in, d v = 0 is added to each output, which changes how the compiled
    pass fuses ``r = y - c x`` (one state: a lone product) and so the rounding of the sums.
    Review of 9464198: the direct flag was chosen from the widths alone."""
    from hammerstein_ctrl.simulate._simulate import normal_pass

    linear = hc.LinearStructure(1, 1, monic_numerator=False, fixed={"b1": 0.0})     # b0 / (p + a0)
    cost = HammersteinCost(_synthetic(hold), hc.HammersteinStructure(linear, hc.Polynomial(2)))
    x = np.array([1.5, 2.0, 0.3, 1.2])                                               # b0, a0, d1, d2
    h = forward_steps(x)
    X = neighbours(x, h)
    P, basis = cost._basis_form(X)
    direct = cost._direct_normal_equations(X, h, P, basis)
    num, den = linear._coefficients(X[:, :linear.n_params])
    general = normal_pass(num, den, cost.data.dt, cost.data.y, P, [basis], h, intersample=hold)
    assert direct is not None and general is not None
    assert direct.fun == general.fun
    np.testing.assert_array_equal(direct.gradient, general.gradient)
    np.testing.assert_array_equal(direct.gram, general.gram)
    np.testing.assert_allclose(direct.gram, from_residuals(cost.residuals_batch(X), h).gram, rtol=1e-5)


@pytest.mark.parametrize("name", ["emps", "zoh, 3 states", "biproper, direct term", "fast pole, scipy's expm"])
def test_the_compiled_lm_loop_gives_the_python_loops_bits(name, emps_case, monkeypatch):
    """LM with its loop compiled around the pass (normal_lm.get_loop) against the Python loop alone (the
    cost's direct_pass hidden): the same x, J, steps, evaluations, message and history, bit for bit,
    from starts that converge and that reject steps (the Python loop takes over after each), with
    budgets that end inside the compiled loop, and with calls of the loop cut short (LOOP_MAX_WORK)."""
    from hammerstein_ctrl.optimize import _least_squares as least_squares

    cost, x = (emps_case.cost, np.asarray(emps_case.paper["nspsa"]["beta"])) if name == "emps" else _plain_case(name)
    rng = np.random.default_rng(7)
    starts = [x] + [x * np.exp(rng.normal(0.0, 0.3, x.size)) for _ in range(3)]
    booked, codes = [], []
    record, loop = least_squares._CountedResiduals.record_passes, normal_lm._Passes.loop
    monkeypatch.setattr(least_squares._CountedResiduals, "record_passes",
                        lambda self, xs, *a: booked.append(len(xs)) or record(self, xs, *a))

    def spy(self, *args):
        out = loop(self, *args)
        codes.append(out[3])
        return out
    monkeypatch.setattr(normal_lm._Passes, "loop", spy)
    whole, pass_work = normal_lm.LOOP_MAX_WORK, cost.n_samples * (x.size + 1) * cost.direct_pass().n
    for x0 in starts:
        for maxfev, work in ((None, whole), (6 * (x.size + 1) + 2, whole), (None, 3 * pass_work)):
            monkeypatch.setattr(normal_lm, "LOOP_MAX_WORK", work)    # 3 passes' work: 3 passes per call
            compiled = levenberg_marquardt(cost, x0, maxfev=maxfev)
            with monkeypatch.context() as m:
                m.setattr(HammersteinCost, "direct_pass", lambda self: None)
                python = levenberg_marquardt(cost, x0, maxfev=maxfev)
            for key in ("x", "fun", "nit", "nfev", "status", "message", "best_x", "best_fun"):
                np.testing.assert_array_equal(compiled[key], python[key], err_msg=key)
            for key, column in python.history.items():
                np.testing.assert_array_equal(compiled.history[key], column, err_msg=key)
    assert sum(booked) > 0 and normal_lm.HAND_BACK in codes, (codes, booked)
    assert normal_lm.HAND_BACK_ALONE in codes or name == "fast pole, scipy's expm", codes


def test_a_subclass_that_redefines_its_evaluation_gets_no_compiled_lm_loop(emps_case):
    """The compiled LM loop runs the pass itself: for a subclass that redefines how the cost is
    evaluated (here the normal equations, counted) it would bypass the override, so the subclass
    gets none and LM calls the override at every pass.  A subclass that only adds keeps the loop."""
    calls = []

    class Counted(HammersteinCost):
        def normal_equations(self, beta, steps=None):
            calls.append(1)
            return super().normal_equations(beta, steps)

    class Named(HammersteinCost):
        label = "mine"

    data, structure = emps_case.data, emps_case.structure
    x = np.asarray(emps_case.paper["nspsa"]["beta"])
    assert Counted(data, structure).direct_pass() is None
    assert Named(data, structure).direct_pass() is not None
    res = levenberg_marquardt(Counted(data, structure), x)
    plain = levenberg_marquardt(emps_case.cost, x)
    assert len(calls) == res.nfev // (x.size + 1) > 0
    assert res.fun == plain.fun and res.nit == plain.nit


def test_normal_equations_checks_its_steps(coulomb_record):
    """normal_equations(beta, steps) with a wrong number of steps raises numpy's reshape ValueError,
    and zero steps give NaN gradients silently."""
    structure = hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Coulomb())
    cost = hc.HammersteinCost(coulomb_record(400), structure)
    beta = np.array([4.0, 2.0, 1.0, 0.3, -0.5])
    with pytest.raises(HammersteinError):
        cost.normal_equations(beta, steps=np.ones(6))
    with pytest.raises(HammersteinError):
        cost.normal_equations(beta, steps=np.zeros(5))


def test_lm_does_not_claim_convergence_at_a_rejected_unstable_start(emps_dir):
    """reject_unstable makes every residual of an unstable point (and of its neighbours) 1e150: the
    Jacobian is zero there, and LM stopped at once with 'gtol termination condition is satisfied',
    success=True, at a point the cost scores inf (before bf7386c it walked to J = 0.2085)."""
    p = presets.emps(path=emps_dir, reject_unstable=True)
    res = minimize(p.cost, p.x0, method="lm")
    if not np.isfinite(p.cost(res.x)):
        assert not res.success, res.message
        assert "gtol" not in res.message


def _piecewise_record(N, hold="foh"):
    rng = np.random.default_rng(0)
    u = np.repeat(rng.uniform(-2, 2, N // 30 + 1), 30)[:N]
    t = np.arange(N) * 0.01
    return hc.IOData(u, 0.01 * (np.sin(t) + 0.3), dt=0.01, intersample=hold)


def test_normal_equations_of_a_finite_point_with_a_nonfinite_neighbour_keep_its_value():
    """Tanh with d1 = inf: g = d0 sign(u) and J is finite (cost 0.0163), but its neighbour d1 + h is NaN.
    The kernel poisoned f when ANY lane's last signal was non-finite, and normal_equations booked the
    point as inf instead of cost(x)."""
    cost = HammersteinCost(_piecewise_record(7), hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh()))
    x = np.array([1.0, 2.0, 3.0, 1.5, np.inf])
    J = cost(x)
    assert np.isfinite(J)
    assert cost.normal_equations(x).fun == pytest.approx(J, rel=1e-12)


def test_normal_factor_of_a_finite_point_with_a_nonfinite_neighbour_keeps_its_value():
    """Saturation with limit = inf is linear (cost finite); normal_factor says inf (one NaN lane makes R all NaN)."""
    cost = HammersteinCost(_piecewise_record(8193), hc.WienerStructure(hc.LinearStructure(1, 2), hc.Saturation()))
    x = np.array([1.0, 2.0, 3.0, 1.2, np.inf])
    J = cost(x)
    assert np.isfinite(J) and cost.normal_equations(x).fun == pytest.approx(J, rel=1e-12)
    assert cost.normal_factor(x).fun == pytest.approx(J, rel=1e-12)


@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_normal_factor_of_a_nonfinite_point_does_not_raise(value):
    """normal_equations(x) answers at a NaN / inf parameter; normal_factor raised ParameterError
    ('steps must be 5 finite, non-zero numbers'): its fallback passes the point's non-finite steps on."""
    cost = HammersteinCost(_piecewise_record(8193), hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh()))
    x = np.array([value, 2.0, 3.0, 1.5, 0.7])
    ne = cost.normal_equations(x)
    qr = cost.normal_factor(x)
    assert qr.fun == ne.fun or not np.isfinite(qr.fun)


def test_normal_factor_of_a_record_shorter_than_its_parameters():
    """Residual fallback (custom output map) on 3 samples, 4 parameters: np.linalg.qr gives a 3 x 5 R and
    from_factor raised ValueError('a factor of shape (3, 5) does not fit 4 steps')."""
    cubic = hc.CustomNonlinearity(lambda v, p: p[0] * v + p[1] * v ** 3, n_params=2)
    cost = HammersteinCost(_piecewise_record(3), hc.WienerStructure(hc.LinearStructure(0, 2), cubic))
    x = np.array([2.0, 3.0, 1.5, 0.1])
    ne = cost.normal_equations(x)
    qr = cost.normal_factor(x)
    assert qr.fun == pytest.approx(ne.fun, rel=1e-12)
    np.testing.assert_allclose(qr.gram, ne.gram, rtol=1e-8, atol=1e-12 * np.abs(ne.gram).max())


def test_lm_past_minpack_max_bytes_takes_the_factor_route(emps_case, monkeypatch):
    """From EMPS's x0 the Gram matrix is ill-conditioned: past MINPACK_MAX_BYTES the passes must be
    normal_factor's, not MINPACK's (reaching the optimum alone would not show which route was taken)."""
    calls = []
    original = HammersteinCost.normal_factor
    monkeypatch.setattr(HammersteinCost, "normal_factor", lambda self, *a: calls.append(1) or original(self, *a))
    monkeypatch.setattr(ls, "MINPACK_MAX_BYTES", 0)
    res = levenberg_marquardt(emps_case.cost, emps_case.x0)
    assert calls and res.success
    assert "MINPACK" not in res.message


DT = 0.01
KNOTS = np.linspace(-0.9, 0.9, 11)


def _pwl_structure():
    """17 lanes (16 parameters), 11 basis signals: past one compiled pass on both counts."""
    return hc.HammersteinStructure(hc.LinearStructure(1, 3), hc.PiecewiseLinear(KNOTS), offset=True)


def _long_enough(lanes):
    """A record just long enough that ``lanes`` candidates' outputs pass GROUPS_MIN_BYTES (no monkeypatch)."""
    n = simulate.GROUPS_MIN_BYTES // (8 * lanes) + 1000
    t = DT * np.arange(n)
    return hc.IOData(np.sin(0.3 * t) + 0.5 * np.sin(3.3 * t), np.cos(t), dt=DT)


def _stable_pwl_point(structure):
    x = np.random.default_rng(1).uniform(0.5, 2.0, structure.n_params)
    x[:4] = [1.0, 1.0, 3.0, 3.0]                    # H = 1 / (p + 1)^3, stable
    return x


@pytest.mark.parametrize("index, value, method", [
    (8, np.inf, "normal_equations"),      # default steps are NaN there: inf - inf in _LaneGroups.prepare
    (8, np.inf, "normal_factor"),
    (13, 1.5e308, "normal_factor"),       # row 0's signal overflows in _LaneGroups.output_blocks
])
def test_lane_groups_leak_no_numpy_warning_at_a_nonfinite_point(index, value, method):
    """A g parameter at inf or 1.5e308 (the cost is inf) on a record just long enough for lane groups.
    numpy's warnings escaped from two lines of _LaneGroups that ran outside any errstate: 'invalid value
    encountered in subtract' (``Pg - P[0, cols]`` in ``prepare``, a neighbour's NaN step moving a column
    that is inf) and 'overflow encountered in matmul' (``reference = self.P[0] @ part`` in
    ``output_blocks``; ``normal_pass`` hid that one only because ``_sum_blocks`` wraps the generator in an
    errstate, ``factor_of_blocks`` did not).  Under the project's warning filter the call then raises
    instead of returning fun = inf as the single pass does."""
    structure = _pwl_structure()
    cost = HammersteinCost(_long_enough(structure.n_params + 1), structure)
    x = _stable_pwl_point(structure)
    x[index] = value
    assert cost(x) == np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        ne = getattr(cost, method)(x)
    assert ne.fun == np.inf


def test_normal_factor_of_an_overflowing_point_leaks_no_numpy_warning():
    """A g parameter at 1.5e308 (cost inf) on a short record (stored residuals, no groups): ``from_factor``
    divided the factor by the steps outside its errstate and numpy's 'overflow encountered in divide'
    escaped (normal_equations.py, ``RJ = R[:p, :p] / steps``)."""
    t = DT * np.arange(3000)
    data = hc.IOData(np.sin(t) + 0.5 * np.sin(3.3 * t), np.cos(t), dt=DT)
    structure = hc.HammersteinStructure(
        hc.LinearStructure(1, 3),
        hc.CustomNonlinearity(lambda u, p: sum(p[k] * np.sin((k + 1) * u) for k in range(10)), 10),
        offset=True)
    cost = HammersteinCost(data, structure)
    x = _stable_pwl_point(structure)
    x[5] = 1.5e308
    assert cost(x) == np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        qr = cost.normal_factor(x)
    assert not np.isfinite(qr.fun)


def test_normal_pass_with_an_empty_basis_on_a_long_record_gives_no_index_error():
    """``normal_pass`` (public) with a basis of no signals (P of shape (3, 0)) returns None on a short
    record; on a record long enough for lane groups ``_group_signals`` picked column 0 of an empty
    P (``np.arange(1)``) and numpy's IndexError escapes.  Either None (the pass does not apply) or a
    clear HammersteinError is acceptable."""
    n = simulate.GROUPS_MIN_BYTES // (8 * 3) + 1000
    y = np.zeros(n)
    try:
        ne = simulate.normal_pass([[1.0]], [[1.0, 2.0, 1.0]], DT, y, np.zeros((3, 0)), [np.zeros((0, n))],
                                  [1e-6, 1e-6])
    except HammersteinError:
        return
    assert ne is None


def test_normal_factor_runs_its_small_qr_factorisations_in_one_blas_thread(monkeypatch):
    """The public ``normal_factor`` (any route; lane groups make it wider) reduces blocks of 8192 x (p + 1)
    differences (with LAPACK's geqrf when this was found), but only identify / minimize / levenberg_marquardt held
    BLAS to one thread.
    Called directly (as its own docstring does), OpenBLAS threaded each small QR: measured on this 2-core
    machine at 1e6 samples, 17 lanes, 2 to 12 s instead of 0.2 to 0.26 s (the project's rule: small dense
    linear algebra in single-threaded BLAS, threadpool_limits(1) around the entry points)."""
    from threadpoolctl import threadpool_info

    if max(info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas") < 2:
        pytest.skip("BLAS runs one thread here anyway")
    structure = _pwl_structure()
    cost = HammersteinCost(_long_enough(structure.n_params + 1), structure)
    threads = []
    triangle = streamed_lstsq._triangle         # the QR of each block (the C library's now), inside the limit

    def spy(*args, **kwargs):
        if not threads:                             # threadpool_info is slow: look once
            threads.append(max(info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"))
        return triangle(*args, **kwargs)
    monkeypatch.setattr(streamed_lstsq, "_triangle", spy)
    qr = cost.normal_factor(_stable_pwl_point(structure))
    assert np.isfinite(qr.fun)
    assert threads == [1]


@pytest.mark.parametrize("case", ["unstable point, reject_unstable", "b0 = inf"])
def test_normal_equations_of_a_point_scored_inf_store_no_residual_vectors(case):
    """At a point the cost scores inf -- unstable under reject_unstable=True, or a linear parameter at inf
    (no clean discretisation, so neither one pass nor the groups apply) -- the p + 1 residual vectors were
    simulated and stored whole (the single pass did the same), undoing lane groups' bounded memory: measured
    392 to 414 B/sample at 1e6 samples, 17 lanes, three times the 8 (p + 1) = 136 B of the vectors themselves
    (4 GB at 1e7 samples), for a point no solver can use.  With b0 = inf the result was not even scored inf
    (fun = 1e306 while cost(x) = inf)."""
    structure = _pwl_structure()
    lanes = structure.n_params + 1
    data = _long_enough(lanes)
    n = 4 * data.u.size                             # p + 1 residual vectors: 4 x GROUPS_MIN_BYTES = 64 MB
    t = DT * np.arange(n)
    data = hc.IOData(np.sin(0.3 * t) + 0.5 * np.sin(3.3 * t), np.cos(t), dt=DT)
    x = _stable_pwl_point(structure)
    if case == "b0 = inf":
        cost = HammersteinCost(data, structure)
        x[0] = np.inf
    else:
        cost = HammersteinCost(data, structure, reject_unstable=True)
        x[3] = -1e-12                               # a2 < 0: a pole in the right half-plane
    assert cost(x) == np.inf
    tracemalloc.start()
    try:
        ne = cost.normal_equations(x)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert ne.fun == np.inf
    assert peak < 8 * lanes * n / 2, peak / n       # well under p + 1 stored residual vectors


@pytest.mark.parametrize("maxfev", [41, 44])
def test_lm_stopped_by_maxfev_counts_the_step_whose_trial_point_it_returns(emps_case, maxfev):
    """On exhaustion, nit leaves out the step whose trial point was evaluated (and is returned as x).

    From the N-SPSA vector the unlimited run takes 8 steps in 45 evaluations (5 per pass).  With 41-44
    evaluations the 8th step's pass is cut short after its trial point (row 0) and some neighbours: that
    trial point is evaluated, is the best point, and is returned as x, bit for bit the unlimited run's
    x; but nit said 7, because _iterate counted a step only after its whole pass.  The rule
    ("nit counts the steps whose trial point was evaluated") and the MINPACK/trf routes (a trial counts
    as soon as its residual vector is evaluated) give 8.
    """
    beta = np.asarray(emps_case.paper["nspsa"]["beta"])
    full = levenberg_marquardt(emps_case.cost, beta)
    assert full.status == COMPLETED and full.nfev == 45 and full.nit == 8
    r = levenberg_marquardt(emps_case.cost, beta, maxfev=maxfev)
    assert r.status == BUDGET_EXHAUSTED and r.nfev == maxfev
    assert np.array_equal(r.x, full.x)                       # the 8th step's trial point
    assert r.nit == full.nit, f"x is the point of step {full.nit}, nit says {r.nit}"


def test_auto_with_no_budget_for_a_refinement_reports_budget_exhausted(trs_case):
    """auto stopped by maxfev before any refinement says SOLVER_FAILED (4): no solver ran or failed.

    With maxfev = 30 the starts' scan spends its share (15) and the 15 left are below a refinement's
    minimum: the message says "raise maxfev", the status table says 4 is "a solver stopped
    without converging" and 5 "ran out of maxfev first".  auto with maxfev = 60 (one refinement cut
    short) already says 5, and 800 converges (status 0).
    """
    assert auto_minimize(trs_case.cost, maxfev=60, seed=0).status == BUDGET_EXHAUSTED
    r = auto_minimize(trs_case.cost, maxfev=30, seed=0)
    assert not r.success and r.nit == 0 and "raise maxfev" in r.message
    assert r.status == BUDGET_EXHAUSTED, (r.status, r.message)


def _polynomial_cost(hold="foh", N=400, seed=0):
    """A plain Hammerstein cost ((p + b0) / (p^2 + a1 p + a0), a cubic-free polynomial g): 5 parameters."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-2.0, 2.0, N // 20), 20)
    y = np.sin(np.arange(N) * 0.01) + 0.1 * rng.normal(size=N)
    data = hc.IOData(u, y, dt=0.01, intersample=hold, name="syn")
    return HammersteinCost(data, hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Polynomial(2)))


def test_the_compiled_loop_refuses_arrays_that_do_not_fit_before_the_c_code_reads_them():
    """normal_lm._loop hands sizes to C: a point of another length, logs too short for the evaluations left, a log
    already written, or a pass whose block does not match its kernel's order are a ValueError, never a read or
    write past an array; the arrays _Passes.loop makes pass."""
    from hammerstein_ctrl._kernels import normal_kernel_number
    from hammerstein_ctrl.optimize._normal_equations import FD_REL_STEP

    cost = _polynomial_cost()
    d = cost.direct_pass()
    p = d.n_params
    number = normal_kernel_number(d.n, d.hold, p + 1, d.K, d.direct)

    def run(x=None, counts=(0, 10, 3 * (p + 1), 0), rows=3, d=d):
        x = np.array([0.5, 2.0, 3.0, 0.3, 1.2] if x is None else x)
        logs = np.empty((rows, p)), np.empty((rows, p)), np.empty((rows, p + 1))
        settings = np.array([1e-8, 1e-8, 0.0, normal_lm.ILL_CONDITIONED, d.dt, d.max_norm, FD_REL_STEP,
                             normal_lm.MAX_DAMPING, normal_lm.DAMPING_DECREASE_LIMIT])
        return normal_lm._loop(number, x, np.array([np.nan, 1e-3, 2.0]), np.empty(p), np.empty((p, p)),
                               np.empty(p), np.empty(p), np.array(counts, dtype=np.int64), settings, True, d, logs)

    assert run() in normal_lm.MESSAGES or run() in (normal_lm.HAND_BACK, normal_lm.HAND_BACK_ALONE)
    for bad in ({"x": [0.5, 2.0, 3.0, 0.3]}, {"rows": 2}, {"counts": (0, 10, 3 * (p + 1), 1)},
                {"counts": (0, 10, 0, 0)}, {"d": d._replace(n=d.n + 1)}):
        with pytest.raises(ValueError, match="do not fit"):
            run(**bad)


def _python_loop(monkeypatch):
    """Hide the compiled loop: LM then runs its loop in Python around the same pass."""
    monkeypatch.setattr(HammersteinCost, "direct_pass", lambda self: None)


@pytest.mark.parametrize("hide", [True, False], ids=["python loop", "compiled loop"])
def test_lm_refuses_a_start_of_the_wrong_length_in_the_compiled_and_the_python_loop(hide, monkeypatch):
    """A start one entry longer than the cost's parameters: the Python loop refuses it (ParameterError,
    naming the parameters); the compiled loop ran the pass kernel with 7 lanes on a 5-parameter
    structure (the sixth entry moving nothing) and, with a gtol any start meets, reported success with
    a 6-vector for a 5-parameter model.  (Shorter starts have the compiled loop read past the end of
    its arrays: not run here.)"""
    cost = _polynomial_cost()
    x0 = np.r_[0.5, 2.0, 3.0, 0.3, 1.2, 0.7]
    if hide:
        _python_loop(monkeypatch)
    with pytest.raises(ParameterError, match="beta must have 5 entries"):
        levenberg_marquardt(cost, x0, gtol=1.0)


def test_the_compiled_loop_runs_from_a_first_fit_and_the_setting_chooses_it(tmp_path):
    """lm.compiled_loop = "auto" runs the compiled loop from the first fit in a fresh process (it is C in the
    compiled core, built at install). "never" runs the Python loop; another value is refused."""
    import subprocess
    import sys

    from hammerstein_ctrl import config
    from hammerstein_ctrl.optimize import _normal_lm as normal_lm

    code = ("import numpy as np, hammerstein_ctrl as hc; from hammerstein_ctrl.optimize import _normal_lm as lm\n"
            "from hammerstein_ctrl.fit import HammersteinCost\n"
            "t = np.arange(600) * 0.01; u = np.sin(1.3 * t) + 0.5 * np.sign(np.sin(0.4 * t))\n"
            "y = np.convolve(u ** 3, np.exp(-t[:80]), mode='full')[:t.size] * 0.01\n"
            "cost = HammersteinCost(hc.IOData(u, y, dt=0.01), hc.HammersteinStructure(hc.LinearStructure(0, 2), "
            "hc.Polynomial(3)))\n"
            "passes = lm._Passes(cost, None); print(passes.direct is not None)\n"
            "print(hc.optimize.levenberg_marquardt(cost, [2.0, 3.0, 1.0, 0.5, 0.2]).success)\n")
    env = {**os.environ, "HAMMERSTEIN_CTRL_COMPILED_LOOP": "auto"}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["True", "True"]
    try:
        config.set_defaults("lm", compiled_loop="auto")
        assert normal_lm.compiled_loop_wanted()
        config.set_defaults("lm", compiled_loop="never")
        assert not normal_lm.compiled_loop_wanted()
    finally:
        config.set_defaults("lm", compiled_loop="always")
    with pytest.raises(hc.ParameterError, match=r"lm.compiled_loop must be one of \['auto', 'always', 'never'\]"):
        config.set_defaults("lm", compiled_loop="sometimes")
