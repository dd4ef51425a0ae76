"""Streamed least squares (blocks of samples, tree-merged QR) against dense solves of the whole regression.

The oracle is always the regression formed whole (``numpy.column_stack``) and
solved by ``numpy.linalg.lstsq`` / ``scipy.linalg.lstsq``; the streamed code
runs with a block size (37, a prime) far below the record length, so blocks
end at arbitrary samples and the merge tree has several levels.
"""

import tracemalloc

import control as ct
import numpy as np
import pytest
import scipy.linalg

from hammerstein_ctrl import (Coulomb, HammersteinStructure, IOData, LinearStructure, PiecewiseLinear, Polynomial,
                              Saturation, Tanh, identify)
from hammerstein_ctrl.optimize import _streamed_lstsq as streamed_lstsq
from hammerstein_ctrl.fit import _initialize as initialize
from hammerstein_ctrl.fit import _linear_starts as linear_starts
from hammerstein_ctrl.fit import _baselines as baselines
from hammerstein_ctrl.exceptions import DataError
from hammerstein_ctrl.fit._initialize import Budget, initial_points
from hammerstein_ctrl.optimize._streamed_lstsq import (column_blocks, constant_column, factor_of_columns,
                                                       factor_of_rows, factor_sse, orthogonal_part, rank_tolerance,
                                                       residual, residual_of_columns, solve_minimum_norm, solve_scaled,
                                                       triangular_factor)

SMALL_BLOCK = 37


@pytest.fixture
def small_blocks(monkeypatch):
    monkeypatch.setattr(streamed_lstsq, "BLOCK_SAMPLES", SMALL_BLOCK)


def regression(n=1000, seed=0):
    """Columns in the three accepted forms (2-D rows, 1-D, broadcast constant), the dense matrix and y."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 10.0, n)
    rows = np.stack([np.sin(1.3 * t), np.exp(-0.4 * t)])
    ramp = t ** 1.5
    columns = [rows, ramp, constant_column(n)]
    X = np.column_stack([rows.T, ramp, np.ones(n)])
    y = X @ np.array([1.5, -2.0, 0.25, 3.0]) + 0.1 * rng.standard_normal(n)
    return columns, X, y


@pytest.mark.parametrize("n", [1000, SMALL_BLOCK * 8, SMALL_BLOCK * 5 + 3])
def test_streamed_fit_equals_dense_lstsq(small_blocks, n):
    columns, X, y = regression(n)
    R = triangular_factor(columns, y)
    assert R.shape == (5, 5) and np.allclose(R, np.triu(R))
    w = solve_scaled(R, n)
    ref, res, *_ = np.linalg.lstsq(X, y, rcond=None)
    np.testing.assert_allclose(w, ref, rtol=1e-11)
    np.testing.assert_allclose(solve_minimum_norm(R, n), ref, rtol=1e-11)
    r = residual(columns, w, y)
    np.testing.assert_allclose(r, y - X @ ref, rtol=1e-9, atol=1e-12)
    assert factor_sse(R, w) == pytest.approx(float(res[0]), rel=1e-10)
    # R is the factor of [X y]: R^T R = [X y]^T [X y]
    Xy = np.column_stack([X, y])
    np.testing.assert_allclose(R.T @ R, Xy.T @ Xy, rtol=1e-11, atol=1e-9 * np.abs(Xy.T @ Xy).max())


def test_block_size_does_not_change_the_result(monkeypatch):
    columns, X, y = regression(2000, seed=3)
    whole = solve_scaled(triangular_factor(columns, y), 2000)
    for block in (SMALL_BLOCK, 1, 1999, 4096):
        monkeypatch.setattr(streamed_lstsq, "BLOCK_SAMPLES", block)
        np.testing.assert_allclose(solve_scaled(triangular_factor(columns, y), 2000), whole, rtol=1e-11)
        np.testing.assert_allclose(residual(columns, whole, y), y - X @ whole, rtol=1e-9, atol=1e-12)


def test_rank_deficient_regression_gives_the_dense_minimum_norm_solution(small_blocks):
    """A repeated column: the dense solvers' minimum-norm answers (scaled for gelsy, as before)."""
    columns, X, y = regression(800, seed=1)
    X2 = np.column_stack([X, X[:, 1]])
    columns2 = columns + [X[:, 1].copy()]
    R = triangular_factor(columns2, y)
    np.testing.assert_allclose(solve_minimum_norm(R, 800), np.linalg.lstsq(X2, y, rcond=None)[0], rtol=1e-9)
    scale = np.linalg.norm(X2, axis=0)
    dense = scipy.linalg.lstsq(X2 / scale, y, cond=rank_tolerance(800), lapack_driver="gelsy")[0] / scale
    w = solve_scaled(R, 800)
    np.testing.assert_allclose(w, dense, rtol=1e-8)
    assert w[1] == pytest.approx(w[-1], rel=1e-8)  # the weight is split evenly between the copies
    assert factor_sse(R, w) == pytest.approx(float(np.sum((y - X2 @ w) ** 2)), rel=1e-10)


def test_fewer_samples_than_columns(small_blocks):
    X = np.array([[1.0, 2.0, 0.5], [0.0, 1.0, 4.0]])
    y = np.array([1.0, -1.0])
    R = triangular_factor([X.T], y)
    np.testing.assert_allclose(solve_minimum_norm(R, 2), np.linalg.lstsq(X, y, rcond=None)[0], rtol=1e-12)
    assert factor_sse(R, solve_minimum_norm(R, 2)) == pytest.approx(0.0, abs=1e-24)


def test_non_finite_column_gives_no_solution(small_blocks):
    columns, X, y = regression(500)
    bad = columns[1].copy()
    bad[300] = np.inf
    R = triangular_factor([columns[0], bad, columns[2]], y)
    assert np.all(np.isnan(R)) and solve_scaled(R, 500) is None


# ---------------------------------------------------------------------------
# the automatic starts, streamed, against the dense regression they replaced
# ---------------------------------------------------------------------------
def hammerstein_case(n=3000, offset=False, initial_state="zero", seed=5):
    """A noisy Coulomb-Hammerstein record (true offset 0.3) and the structure to fit."""
    structure = HammersteinStructure(LinearStructure(0, 2), Coulomb(), offset=offset, initial_state=initial_state)
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    u = np.repeat(rng.uniform(-1.0, 1.0, n // 50 + 1), 50)[:n]
    truth = HammersteinStructure(LinearStructure(0, 2), Coulomb()).model([4.0, 1.2, 0.8, 0.2, 0.05])
    y = truth.simulate(t, u) + 0.3 + 0.01 * rng.standard_normal(n)
    return IOData(u, y, t), structure


def dense_columns(reg, theta, drives):
    return np.column_stack([np.broadcast_to(c[:, None] if c.ndim == 1 else c.T, (reg.y.size, 1 if c.ndim == 1
                                                                                 else c.shape[0]))
                            for c in reg.columns(theta, drives)])


@pytest.fixture(params=[False, True], ids=["held", "streamed"])
def streamed(request, monkeypatch):
    """Regression columns held whole, or (streamed) formed a block of samples at a time however short the record."""
    if request.param:
        monkeypatch.setattr(initialize, "STREAMED_COLUMNS_BYTES", 0)
    return request.param


def _held_columns(reg, theta, drives):
    """The columns held whole, whichever way ``reg`` forms them."""
    held = initialize._Drives.rows(drives.array if drives.array is not None else
                                   np.hstack([p for p in drives.blocks()]))
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(initialize, "STREAMED_COLUMNS_BYTES", 1 << 62)
        return dense_columns(reg, theta, held)


@pytest.mark.parametrize("offset, initial_state", [(False, "zero"), (True, "zero"), (False, "estimate")])
def test_reduced_fit_equals_dense_lstsq(small_blocks, offset, initial_state, streamed):
    data, s = hammerstein_case(offset=offset, initial_state=initial_state)
    reg = initialize._Regression(s, data, initialize.Budget(None))
    drives = initialize._drives(s.input_nonlinearity, np.asarray(data.u), reg)
    assert (drives.array is None) == streamed
    for theta in ([4.0, 1.2], [1.0, 3.0], [9.0, 0.5]):
        Phi = _held_columns(reg, np.array(theta), drives)
        assert Phi.shape == (3000, 3 + offset + 2 * (initial_state == "estimate"))
        ref, res, rank, _ = np.linalg.lstsq(Phi, reg.y, rcond=None)
        assert rank == Phi.shape[1]
        w, sse = reg.fit(reg.columns(np.array(theta), drives))
        np.testing.assert_allclose(w, ref, rtol=1e-9)
        assert sse == pytest.approx(float(res[0]), rel=1e-9)
        r = reg.residual(reg.columns(np.array(theta), drives), w)
        np.testing.assert_allclose(r, reg.y - Phi @ ref, rtol=1e-7, atol=1e-10)


@pytest.mark.parametrize("offset, initial_state", [(False, "zero"), (True, "zero"), (False, "estimate"),
                                                   (True, "estimate")])
def test_the_scans_factor_simulated_in_place_has_the_bits_and_cost_of_the_columns_factor(
        small_blocks, offset, initial_state, streamed, monkeypatch):
    data, s = hammerstein_case(offset=offset, initial_state=initial_state)
    theirs, ours = initialize.Budget(None), initialize.Budget(None)
    in_place = []
    monkeypatch.setattr(initialize, "factor_of_rows", lambda whole: in_place.append(1) or factor_of_rows(whole))
    drives = initialize._drives(s.input_nonlinearity, np.asarray(data.u), initialize._Regression(s, data, None))
    for theta in ([4.0, 1.2], [1.0, 3.0], [-2.0, 0.5], [np.nan, 1.0]):
        R = initialize._Regression(s, data, theirs).factor(
            initialize._Regression(s, data, theirs).columns(np.array(theta), drives))
        R_at = initialize._Regression(s, data, ours).factor_at(np.array(theta), drives)
        assert R_at.tobytes() == R.tobytes()
        assert np.all(np.isfinite(R)) == np.all(np.isfinite(theta))
    assert ours.nfev == theirs.nfev > 0
    assert len(in_place) == (0 if streamed else 4)        # held drives take the in-place factor, streamed ones not


def test_arx_poles_equal_dense_equation_error_fit(small_blocks, streamed):
    data, s = hammerstein_case(n=2000)
    drives = initialize._drives(s.input_nonlinearity, np.asarray(data.u), initialize._Regression(s, data, None))
    assert (drives.array is None) == streamed
    y, m, N = np.asarray(data.y), 2, 2000
    basis = s.input_nonlinearity.basis(np.asarray(data.u))
    X = np.column_stack([-y[m - i:N - i] for i in (1, 2)] + [d[m - i:N - i] for d in basis for i in (1, 2)]
                        + [np.ones(N - m)])
    coef = np.linalg.lstsq(X, y[m:], rcond=None)[0]
    z = np.roots(np.r_[1.0, coef[:m]]).astype(complex)
    # a negative real root (an oscillation at the Nyquist rate) stands for its decay rate alone
    ref = np.sort_complex(np.where((z.imag == 0) & (z.real < 0), np.log(np.abs(z)) + 0j, np.log(z)) / data.dt)
    got = np.sort_complex(linear_starts._arx_poles(data, drives, m))
    np.testing.assert_allclose(got, ref, rtol=1e-7)
    assert np.all(got.real < 0)


def test_static_affine_sse_equals_dense(small_blocks):
    data, _ = hammerstein_case(n=1234)
    u, y = np.asarray(data.u), np.asarray(data.y)
    X = np.column_stack([u, np.ones_like(u)])
    res = np.linalg.lstsq(X, y, rcond=None)[1]
    assert baselines.static_affine_sse(data) == pytest.approx(float(res[0]), rel=1e-10)


def test_initial_points_do_not_depend_on_the_block_size(monkeypatch, streamed):
    """The whole start pipeline (scan, ARX poles, reduced LM, static fit), blocks of 37 vs one block held whole
    (streamed: the drives and their responses also formed by blocks, through the compiled lane passes)."""
    data, s = hammerstein_case(n=2000, offset=True)
    s = HammersteinStructure(LinearStructure(0, 2), Polynomial(2), offset=True)
    with monkeypatch.context() as held:
        held.setattr(initialize, "STREAMED_COLUMNS_BYTES", 1 << 62)
        whole = initialize.initial_points(data, s, initialize.Budget(600))
    monkeypatch.setattr(streamed_lstsq, "BLOCK_SAMPLES", SMALL_BLOCK)
    blocked = initialize.initial_points(data, s, initialize.Budget(600))
    assert len(whole) == len(blocked) >= 1      # (the three candidates' refinements join one optimum here)
    # the reduced refinements run up to 60 MINPACK steps: rounding of the block sums moves their end points
    # by about 1e-6 (measured 1.3e-6 on one coefficient); streamed, MINPACK differentiates the reduced residual
    # itself where the held columns give Kaufman's Jacobian
    for a, b in zip(whole, blocked):
        np.testing.assert_allclose(b, a, rtol=1e-5, atol=1e-9)


def test_auto_finds_a_plant_on_a_long_record():
    """A (1, 2) block with Coulomb friction and an offset, 2e4 samples generated by python-control.

    Its starts used to come from refinements that shared the budget evenly (about 20 reduced steps
    each, none converged): auto ended at J/N = 4.0e-3 against the noise's 1e-4 and said it had not
    converged (3.6e-3 at 1e5 samples).  Refined in turn (the best scan candidates first, up to 60
    steps each), it finds the plant.  Its scan is denser than 12 frequencies (3 per decade past four
    decades), which 1e6-sample records need.
    """
    import control

    from hammerstein_ctrl import Coulomb, IOData
    from hammerstein_ctrl import identify

    n = 20_000
    rng = np.random.default_rng(1)
    u = np.repeat(rng.uniform(-1.0, 1.0, n // 200 + 1), 200)[:n]
    t = 0.01 * np.arange(n)
    g = 0.8 * u + 0.2 * np.sign(u) + 0.05
    y = control.forced_response(control.tf([0.5, 1.0], [1.0, 1.2, 1.5]), t, g).outputs + 0.3
    y += 0.01 * rng.standard_normal(n)
    s = HammersteinStructure(LinearStructure(1, 2), Coulomb(), offset=True)
    f = linear_starts._frequencies(IOData(np.zeros(10 ** 6), np.zeros(10 ** 6), dt=0.01))   # five decades
    assert f.size >= linear_starts.SCAN_PER_DECADE * np.log10(f[-1] / f[0]) > linear_starts.SCAN_FREQUENCIES
    r = identify(IOData(u, y, t), s, seed=0)
    assert r.success, r.message
    # H = 0.5 (p + 2) / (p^2 + 1.2 p + 1.5): b0, a0, a1, then g's coefficients times 0.5, then the offset
    np.testing.assert_allclose(r.x, [2.0, 1.5, 1.2, 0.4, 0.1, 0.025, 0.3], rtol=2e-2, atol=2e-3)
    assert r.fun / n == pytest.approx(1e-4, rel=0.05)


def test_arx_poles_of_a_noisy_oversampled_record_make_a_stable_candidate():
    """Equation error on a noisy record sampled far faster than the plant gives a negative real discrete
    pole (an oscillation at the Nyquist rate).  Its log has the imaginary part pi/dt and no conjugate;
    the candidate's real polynomial was then unstable (it overflowed on 1e6 samples, and auto found no
    start for a piecewise-linear g there).  Its decay rate now stands in: the poles come in conjugate
    pairs and the candidate block is stable."""
    import control

    from hammerstein_ctrl import Coulomb, IOData
    from hammerstein_ctrl.simulate._simulate import unstable

    n = 10_000
    rng = np.random.default_rng(1)
    u = np.repeat(rng.uniform(-1.0, 1.0, n // 200 + 1), 200)[:n]
    t = 0.01 * np.arange(n)
    y = control.forced_response(control.tf([0.5, 1.0], [1.0, 1.2, 1.5]), t, 0.8 * u + 0.2 * np.sign(u)).outputs
    data = IOData(u, y + 0.3 + 0.01 * rng.standard_normal(n), t)
    s = HammersteinStructure(LinearStructure(1, 2), Coulomb(), offset=True)
    drives = initialize._drives(s.input_nonlinearity, u, initialize._Regression(s, data, None))
    poles = linear_starts._arx_poles(data, drives, 2)
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(np.conj(poles)), rtol=1e-12)
    assert np.all(poles.real < 0)
    assert not unstable(np.real(np.poly(poles)))[0]


def test_residual_of_columns_never_returns_samples_no_block_covered():
    """residual_of_columns(blocks, w, y) allocates ``np.empty(y.size)`` and writes only the samples the
    blocks cover: blocks of 3 samples with a y of 5 return 2 samples of uninitialised memory as part of
    the residual, with no error (measured: ``[0, 2, 4, 3, 4]`` whose last two are left-over memory).
    The public function must refuse blocks that do not cover ``y`` (a clear ValueError), never
    return garbage.  Reproduce: ``residual_of_columns(column_blocks([np.arange(3.0)], 3), [1.0],
    np.arange(5.0))``."""
    y = 3.0 * np.arange(5.0)
    with pytest.raises(ValueError, match="sample|block|cover|length"):
        residual_of_columns(column_blocks([np.arange(3.0)], 3), [1.0], y)


def test_factor_of_columns_checks_its_blocks_against_width_and_y():
    """factor_of_columns(blocks, y, width) neither checks ``width`` against the blocks' columns nor the
    blocks' samples against ``y``: (1) one column declared as width 3 is broadcast into all three
    columns (``part[:, :-1] = X``), and the fit of ``y = 2 t`` comes out ``[2/3, 2/3, 2/3]`` instead of
    a refusal (numpy.linalg.lstsq on the one column gives ``[2]``); (2) blocks of 3 samples with a y of
    5 silently fit the first 3 samples only (the factor's residual 0 where y's tail is not fitted).
    Both are silently wrong numbers from a public function; a clear ValueError is expected.
    Reproduce: ``factor_of_columns(column_blocks([t], 5), 2 * t, 3)``."""
    t = np.arange(5.0)
    assert np.allclose(np.linalg.lstsq(t[:, None], 2 * t, rcond=None)[0], [2.0])      # the oracle
    assert np.allclose(solve_scaled(factor_of_columns(column_blocks([t], 5), 2 * t, 1), 5), [2.0])
    with pytest.raises(ValueError, match="column|width"):
        factor_of_columns(column_blocks([t], 5), 2 * t, 3)
    with pytest.raises(ValueError, match="sample|block|cover|length"):
        factor_of_columns(column_blocks([t[:3]], 3), 3.0 * t ** 2, 1)


DT = 0.01


def _plant_record(n, num, den, g, seed=0, hold=200, noise=0.0):
    """A Hammerstein record from python-control: ``y = H g(u)`` (+ noise), ``u`` piecewise constant."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.0, 1.0, n // hold + 1), hold)[:n]
    t = DT * np.arange(n)
    y = ct.forced_response(ct.tf(list(num), list(den)), t, g(u)).outputs
    return IOData(u, y + noise * rng.standard_normal(n), t)


def _coulomb(u):
    return 0.8 * u + 0.2 * np.sign(u) + 0.05


def _hold_columns_whole(monkeypatch):
    monkeypatch.setattr(initialize, "STREAMED_COLUMNS_BYTES", 1 << 62)


def _stream_columns(monkeypatch, block=300):
    monkeypatch.setattr(initialize, "STREAMED_COLUMNS_BYTES", 0)
    monkeypatch.setattr(streamed_lstsq, "BLOCK_SAMPLES", block)


@pytest.mark.parametrize("den_order", [9, 10])
def test_streamed_starts_of_a_block_with_more_than_eight_states(monkeypatch, den_order):
    """LinearStructure allows den_order up to MAX_ORDER = 10; the compiled passes of response_blocks take
    at most MAX_UNROLLED_STATES = 8 states.  On a record long enough to stream (a Coulomb g past
    ~700 000 samples; forced here with STREAMED_COLUMNS_BYTES = 0) every regression's factor comes out
    NaN (the ParameterError of response_blocks is caught as 'a block that cannot be simulated'), no
    candidate is fitted and initial_points returns no start at all, where the held route returns 3.
    identify then says 'the search for starting points used up its share of the budget without finding
    one (219 of maxfev = 3000 evaluations spent ...); raise maxfev', which is not the reason."""
    data = _plant_record(2000, [1.0], [1.0, 2.0, 5.0], _coulomb)
    s = HammersteinStructure(LinearStructure(0, den_order), Coulomb())
    with monkeypatch.context() as mp:
        _hold_columns_whole(mp)
        held = initial_points(data, s, Budget(2000))
    assert len(held) == 3
    _stream_columns(monkeypatch)
    streamed = initial_points(data, s, Budget(2000))
    assert len(streamed) == len(held)


def test_initial_points_with_an_unlimited_budget():
    """Budget(maxfev: int | None): None is unlimited (initial_points makes one itself for an unlimited
    caller's budget).  _refine_in_turn takes REFINE_SHARE * remaining = inf as its pool and
    int(inf // k) raises 'ValueError: cannot convert float NaN to integer'.  4a8e3e1 returned the
    plant's parameters ([5, 2, 0.8, 0.2, 0.05] for H = 1 / (p^2 + 2 p + 5), g = 0.8 u + 0.2 sign u + 0.05)."""
    data = _plant_record(1000, [1.0], [1.0, 2.0, 5.0], _coulomb)
    s = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    points = initial_points(data, s, Budget(None))
    np.testing.assert_allclose(points[0], [5.0, 2.0, 0.8, 0.2, 0.05], rtol=1e-6)


def _tanh_plant_record():
    return _plant_record(3000, [1.0], [1.0, 1.0, 4.0], lambda u: 2.0 * np.tanh(1.5 * u), noise=0.01)


@pytest.mark.parametrize("maxfev", [250, 300])
def test_auto_with_a_small_budget_still_starts_a_family_without_basis(maxfev):
    """_refine_in_turn lets the first refinement take the whole REFINE_SHARE of what the scan left; a g
    without a basis (Tanh) then needs 16 shapes x (1 + 2 free responses) = 48 evaluations for its static
    fit and finds 33 left: no start, and identify reports 'no model' (J = inf).  At 4a8e3e1 (an even
    split that skipped refinements too small to run) the same calls returned a start and identify
    reached J = 0.2966 (converged at maxfev = 300)."""
    data = _tanh_plant_record()
    s = HammersteinStructure(LinearStructure(0, 2), Tanh(), initial_state="estimate")
    r = identify(data, s, maxfev=maxfev, seed=0)
    assert r.nfev <= maxfev
    assert r.fun / len(data) < 2e-4, r.message           # noise: 1e-4 per sample


@pytest.mark.parametrize("maxfev", [150, 200])
def test_initial_points_with_a_small_budget_start_a_saturation_with_an_offset(maxfev):
    """The same starvation for a (1, 2) block with a saturation and an offset: no start (4a8e3e1: one)."""
    data = _tanh_plant_record()
    s = HammersteinStructure(LinearStructure(1, 2), Saturation(), offset=True)
    assert len(initial_points(data, s, Budget(maxfev))) >= 1


def test_streaming_threshold_counts_the_regressions_columns(monkeypatch):
    """STREAMED_COLUMNS_BYTES is documented as the 'size of a regression's columns (8 N bytes each) past
    which its driving signals and their simulated responses are formed a block of samples at a time';
    _Regression.streams counts only the drives.  A Tanh g (drives [u, 1]) with a (0, 3) block and an
    estimated initial state has 2 responses + 3 free responses = 5 columns: with the threshold at the
    drives' size (16 N) one reduced fit still holds them whole: 80 B/sample here, against 4 B/sample
    streamed (blocks of 1024 samples).  Measured at 1e6 samples with the real threshold: identify takes
    112 B/sample on this structure (with the offset), 64 with the threshold at 0."""
    n = 50_000
    data = _plant_record(n, [1.0], [1.0, 3.0, 3.0, 1.0], lambda u: 2.0 * np.tanh(1.5 * u), hold=500)
    s = HammersteinStructure(LinearStructure(0, 3), Tanh(), initial_state="estimate")
    monkeypatch.setattr(initialize, "STREAMED_COLUMNS_BYTES", 2 * 8 * n)    # the two drives, not the 5 columns
    monkeypatch.setattr(streamed_lstsq, "BLOCK_SAMPLES", 1024)               # block buffers well below that
    reg = initialize._Regression(s, data, Budget(None))
    theta = np.array([1.0, 3.0, 3.0])
    u = np.asarray(data.u, dtype=float)
    initialize._reduced_sse(reg, theta, initialize._drives(s.input_nonlinearity, u, reg))     # compile outside
    tracemalloc.start()
    try:
        sse = initialize._reduced_sse(reg, theta, initialize._drives(s.input_nonlinearity, u, reg))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert np.isfinite(sse)
    assert peak < initialize.STREAMED_COLUMNS_BYTES, f"{peak / n:.1f} B/sample"


def test_auto_finds_a_lightly_damped_plant_whose_poles_lie_near_its_zeros():
    """A (2, 3) block with a lightly damped pair near its zeros, H = (p^2 + 0.5 p + 4) / ((p + 0.5)
    (p^2 + 0.6 p + 4.09)), a piecewise-linear g (11 knots) and an offset, 3e4 samples from python-control
    with noise of 1e-4 per sample.  4a8e3e1 converged to the noise (J/N = 9.85e-5; also for seeds 2 and 3,
    and at 1e5 samples: 9.9e-5..1.0e-4).  Now all three starts are near-cancelling models with
    coefficients of 1e4..1e5 and LM stays there: J/N = 3.96e-4, not converged (3.7e-4..4.0e-4 for seeds
    1..3, 3.0e-4 at 1e5 samples; still 3.96e-4 with maxfev = 8000).  The cause is the scan grid: 13
    frequencies instead of 12 at 3e4 samples (SCAN_PER_DECADE); with 12 the new refinement converges."""
    n = 30_000
    knots = np.linspace(-1.0, 1.0, 11)
    g_knots = np.sign(knots) * np.abs(knots) ** 0.5
    data = _plant_record(n, [1.0, 0.5, 4.0], np.real(np.poly([-0.5, -0.3 + 2j, -0.3 - 2j])),
                         lambda u: np.interp(u, knots, g_knots), seed=1, hold=60, noise=0.01)
    s = HammersteinStructure(LinearStructure(2, 3), PiecewiseLinear(knots), offset=True)
    r = identify(data, s, seed=0)
    assert r.fun / n < 1.5e-4, r.message


@pytest.mark.parametrize("n", [50, 20000, 300000])      # whole (one call) up to 4 MiB, in blocks past it
def test_the_whole_and_the_blocked_factor_give_the_dense_fit_and_check_lengths(n):
    rng = np.random.default_rng(n)
    X, y = rng.normal(size=(3, n)), rng.normal(size=n)
    columns = [X, constant_column(n)]
    R = triangular_factor(columns, y)
    A = np.column_stack([X.T, np.ones(n)])
    ref = np.linalg.lstsq(A, y, rcond=None)[0]
    np.testing.assert_allclose(solve_scaled(R, n), ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(R.T @ R, np.column_stack([A, y]).T @ np.column_stack([A, y]), rtol=1e-9)
    with pytest.raises(DataError, match=f"a column has {n + 1} samples where y has {n}"):
        triangular_factor([rng.normal(size=n + 1)], y)


def test_solve_scaled_calls_gelsy_as_scipy_does():
    rng = np.random.default_rng(7)
    for p in range(0, 7):
        A = rng.normal(size=(40, p + 1))
        if p > 2:
            A[:, 1] = 3.0 * A[:, 0]                     # rank-deficient
        R = np.linalg.qr(A, mode="r")
        R11 = R[:-1, :-1]
        scale = np.sqrt(np.sum(R11 * R11, axis=0))
        scale[scale == 0] = 1.0
        ref = scipy.linalg.lstsq(R11 / scale, R[:-1, -1], cond=rank_tolerance(40), lapack_driver="gelsy",
                                 check_finite=False)[0] / scale
        assert np.array_equal(solve_scaled(R, 40), ref)


# ---------------------------------------------------------------------------
# the residual, the projection and the variable-projection refinement of the starts
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(4))
def test_residual_and_orthogonal_part_equal_the_dense_projection(seed):
    columns, X, y = regression(n=700, seed=seed)
    R = triangular_factor(columns, y)
    w = solve_scaled(R, y.size)
    np.testing.assert_allclose(residual(columns, w, y), y - X @ w, rtol=0, atol=1e-12 * np.abs(y).max())
    Z = np.random.default_rng(seed).normal(size=(3, y.size)) + X[:, :3].T
    ref = Z - (X @ np.linalg.lstsq(X, Z.T, rcond=None)[0]).T
    out = orthogonal_part(columns, R, Z)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-10 * np.abs(Z).max())
    assert np.abs(out @ X).max() < 1e-9 * np.abs(Z).max() * np.abs(X).max() * y.size


def test_orthogonal_part_of_rank_deficient_columns_is_the_projection_on_their_span():
    """Two equal columns: the span is one direction, and what is left of Z is orthogonal to it."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=500)
    columns = [np.stack([a, 2.0 * a]), constant_column(500)]
    y = 3.0 * a + 1.0 + 0.1 * rng.normal(size=500)
    R = triangular_factor(columns, y)
    Z = rng.normal(size=(2, 500))
    basis = np.column_stack([a, np.ones(500)])
    ref = Z - (basis @ np.linalg.lstsq(basis, Z.T, rcond=None)[0]).T
    np.testing.assert_allclose(orthogonal_part(columns, R, Z), ref, atol=1e-10)


def _coulomb_truth(n=2000, hold="foh"):
    """A noise-free Coulomb-Hammerstein record of H = 1 / (p^2 + 2 p + 5) and its regression at the truth."""
    data = _plant_record(n, [1.0], [1.0, 2.0, 5.0], _coulomb, hold=40)
    s = HammersteinStructure(LinearStructure(0, 2), Coulomb())
    reg = initialize._Regression(s, data, Budget(None))
    drives = initialize._drives(s.input_nonlinearity, np.asarray(data.u, dtype=float), reg)
    return reg, drives, np.array([5.0, 2.0])


def test_kaufman_jacobian_of_the_reduced_residual_equals_its_central_differences_at_a_perfect_fit():
    """Where the residual vanishes Kaufman's Jacobian is the exact one: compared with central differences of
    the reduced residual itself (the linear coefficients re-fitted at every point)."""
    reg, drives, theta = _coulomb_truth()
    problem = initialize._ReducedProblem(reg, drives, 10**6)
    r = problem.residual(theta)
    assert np.abs(r).max() < 1e-9
    J = problem.jacobian(theta)
    assert J.shape == (2, reg.y.size)
    for j in range(2):
        h = np.zeros(2)
        h[j] = 1e-5 * theta[j]
        central = (problem.residual(theta + h) - problem.residual(theta - h)) / (2 * h[j])
        np.testing.assert_allclose(J[j], central, rtol=0, atol=1e-5 * np.abs(central).max())


@pytest.mark.parametrize("family", [Coulomb(), Tanh()], ids=["basis", "affine"])
def test_kaufman_jacobian_equals_the_dense_formula_with_an_offset_and_a_residual(family):
    """-(I - P_X) sum_i w_i d(H d_i)/d theta, formed densely (central differences of each column, numpy's
    projection), away from the optimum of a noisy record: with a constant column after the drives' responses."""
    data = _plant_record(1500, [1.0], [1.0, 2.0, 5.0], _coulomb, hold=40, noise=0.02)
    s = HammersteinStructure(LinearStructure(0, 2), family, offset=True)
    reg = initialize._Regression(s, data, Budget(None))
    drives = initialize._drives(s.input_nonlinearity, np.asarray(data.u, dtype=float), reg)
    theta = np.array([4.0, 1.5])
    problem = initialize._ReducedProblem(reg, drives, 10**6)
    problem.residual(theta)
    J = problem.jacobian(theta)
    X = dense_columns(reg, theta, drives)
    w = np.linalg.lstsq(X, reg.y, rcond=None)[0]
    k = drives.count
    D = np.empty((2, reg.y.size))
    for j in range(2):
        h = np.zeros(2)
        h[j] = 1e-6 * theta[j]
        up, down = dense_columns(reg, theta + h, drives), dense_columns(reg, theta - h, drives)
        D[j] = (up[:, :k] - down[:, :k]) @ w[:k] / (2 * h[j])
    ref = -(D.T - X @ np.linalg.lstsq(X, D.T, rcond=None)[0]).T
    np.testing.assert_allclose(J, ref, rtol=0, atol=1e-5 * np.abs(ref).max())


def test_reduced_refinement_reaches_the_plant_and_spends_no_more_than_its_share():
    reg, drives, theta = _coulomb_truth()
    for limit in (8, 20, 60):
        before = reg.budget.nfev
        x, sse, converged = initialize._refine_linear(reg, np.array([3.0, 1.0]), drives, limit)
        assert reg.budget.nfev - before <= limit * reg.evaluations(drives)
        if limit == 60:
            np.testing.assert_allclose(x, theta, rtol=1e-7)
            assert sse < 1e-16 * np.sum(reg.y ** 2) and converged


def test_reduced_refinement_simulates_its_start_once(monkeypatch):
    """The refinement simulates its start once (MINPACK's first residual, which its first Jacobian reuses)."""
    reg, drives, _ = _coulomb_truth()
    seen = []
    real = initialize._ReducedProblem._evaluate

    def counting(self, theta):
        seen.append(np.array(theta))
        return real(self, theta)
    monkeypatch.setattr(initialize._ReducedProblem, "_evaluate", counting)
    start = np.array([3.0, 1.0])
    initialize._refine_linear(reg, start, drives, 60)
    assert sum(np.array_equal(t, start) for t in seen) == 1


def test_a_refinement_stopped_by_its_share_does_not_drop_a_later_one(monkeypatch):
    """Only optima MINPACK converged to are joined: a first refinement cut short (4 residuals' worth) is not
    one, so the second start, near it, still runs to the plant."""
    reg, drives, theta = _coulomb_truth()
    real, known_sizes = initialize._refine_linear, []

    def first_cut_short(reg_, theta_, drives_, limit, known):
        known_sizes.append(len(known))
        return real(reg_, theta_, drives_, 4 if len(known_sizes) == 1 else limit, known)
    monkeypatch.setattr(initialize, "_refine_linear", first_cut_short)
    out = initialize._refine_in_turn(reg, [(np.array([3.0, 1.0]), 1.0), (np.array([3.2, 1.1]), 2.0)], drives)
    assert known_sizes == [0, 0] and len(out) == 2
    np.testing.assert_allclose(out[0][0], theta, rtol=1e-7)


def test_orthogonal_part_of_ill_conditioned_columns_equals_the_dense_projection():
    """Columns nearly dependent (condition number about 1e6): the coefficients of the semi-normal equations err
    by about cond^2 eps, but what is left of Z only by about cond eps (measured 4e-10)."""
    rng = np.random.default_rng(5)
    a = rng.normal(size=800)
    columns = [np.stack([a, a + 1e-6 * rng.normal(size=800), rng.normal(size=800)])]
    y = rng.normal(size=800)
    R = triangular_factor(columns, y)
    Z = np.stack([a + rng.normal(size=800), 2.0 * a - columns[0][1] + 0.5 * rng.normal(size=800)])
    X = columns[0].T
    ref = Z - (X @ np.linalg.lstsq(X, Z.T, rcond=None)[0]).T
    np.testing.assert_allclose(orthogonal_part(columns, R, Z), ref, rtol=0, atol=1e-8 * np.abs(Z).max())


def test_residual_refuses_coefficients_that_do_not_match_the_columns():
    columns, X, y = regression(n=50)
    with pytest.raises(DataError, match="5 coefficients for 4 columns"):
        residual(columns, np.ones(5), y)
    assert np.array_equal(residual([], [], y), y)


def test_a_refinement_that_reaches_an_earlier_optimum_is_dropped():
    """Two scan candidates in one basin give one start (the second stops once it comes near the first's
    optimum)."""
    reg, drives, theta = _coulomb_truth()
    starts = [(np.array([3.0, 1.0]), 1.0), (np.array([7.0, 3.0]), 2.0)]
    refined = initialize._refine_in_turn(reg, starts, drives)
    assert len(refined) == 1
    np.testing.assert_allclose(refined[0][0], theta, rtol=1e-7)
    assert initialize._refine_linear(reg, np.array([7.0, 3.0]), drives, known=[theta]) is None


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_a_non_finite_value_anywhere_in_a_whole_regression_gives_no_solution(value):
    """The whole factor checks R, not the copy of [X y]: every position of one non-finite value must reach it
    (with rows of zeros, equal columns and a zero column, where a reflector can be the identity)."""
    rng = np.random.default_rng(11)
    X = rng.normal(size=(3, 12))
    X[1, 4:] = 0.0                          # a column with zeros below some rows
    X[2] = X[0]                             # two equal columns
    y = rng.normal(size=12)
    for cols, target in [(X, y), (np.vstack([X, np.zeros(12)]), y)]:
        for j in range(cols.shape[0] + 1):
            for i in range(12):
                c, t = cols.copy(), target.copy()
                if j < c.shape[0]:
                    c[j, i] = value
                else:
                    t[i] = value
                R = triangular_factor([c], t)
                assert np.all(np.isnan(R)) and solve_scaled(R, 12) is None, (j, i)


@pytest.mark.parametrize("offset, initial_state", [(False, "zero"), (True, "estimate")])
def test_scan_candidates_are_ranked_by_the_solved_sum_of_squares(offset, initial_state):
    """R_pp^2 stands in for the solve only where the columns are independent: with an offset and free responses
    beside a Coulomb basis (its constant's response lies in their span but for rounding) R_pp^2 was up to
    half the solved value and reordered candidates."""
    data, _ = hammerstein_case(n=1500)
    s = HammersteinStructure(LinearStructure(0, 3), Coulomb(), offset=offset, initial_state=initial_state)
    reg = initialize._Regression(s, data, Budget(None))
    drives = initialize._drives(s.input_nonlinearity, np.asarray(data.u, dtype=float), reg)
    groups = linear_starts._candidate_linear(s.linear, data, drives)
    for theta in next(iter(groups.values())):
        solved = reg.fit(reg.columns(theta, drives))[1]
        np.testing.assert_allclose(initialize._reduced_sse(reg, theta, drives), solved, rtol=1e-9)


def test_columns_each_close_to_the_span_of_the_earlier_ones_are_not_independent():
    """a, a + d b, b + d c (a, b, c orthonormal, d = 3e-8): no diagonal of the factor falls below 3e-8, yet the
    columns span a plane to 1e-15.  independent() looks at the singular values; the scan's sum of squares then
    takes the solve, and the projection drops the direction as solve_scaled does."""
    rng = np.random.default_rng(2)
    a, b, c = np.linalg.qr(rng.normal(size=(2000, 3)))[0].T
    d = 3e-8
    columns = [np.stack([a, a + d * b, b + d * c])]
    y = rng.normal(size=2000)
    R = triangular_factor(columns, y)
    assert np.min(np.abs(np.diag(R)[:-1])) > 1e-8
    assert not streamed_lstsq.independent(R, 1e-8)
    assert streamed_lstsq.independent(triangular_factor([np.stack([a, b, c])], y), 1e-8)
    Z = rng.normal(size=(2, 2000))
    U, sv, _ = np.linalg.svd(columns[0].T / np.linalg.norm(columns[0], axis=1), full_matrices=False)
    kept = U[:, sv > rank_tolerance(2000) * sv[0]]
    np.testing.assert_allclose(orthogonal_part(columns, R, Z), Z - (kept @ (kept.T @ Z.T)).T, atol=1e-6)


def test_orthogonal_part_without_columns_is_z_and_checks_lengths():
    Z = np.arange(6.0).reshape(2, 3)
    assert np.array_equal(orthogonal_part([], np.zeros((1, 1)), Z), Z)
    R = triangular_factor([np.ones(4)], np.arange(4.0))
    with pytest.raises(DataError, match="a column has 4 samples where y has 3"):
        orthogonal_part([np.ones(4)], R, Z)


def test_a_start_with_no_finite_fit_is_not_a_converged_optimum():
    """A block whose simulation overflows (a fast unstable pole) has no finite fit: MINPACK sees a zero Jacobian
    and reports gtol, which must not make it an optimum later refinements join."""
    reg, drives, _ = _coulomb_truth()
    theta = np.array([5.0, -400.0])
    assert initialize._reduced_sse(reg, theta, drives) == np.inf
    x, sse, converged = initialize._refine_linear(reg, theta, drives, 60)
    assert sse == np.inf and not converged


def test_kaufman_jacobian_of_a_cancelling_polynomial_basis_equals_the_dense_formula():
    """A degree-9 polynomial basis of an input within [0.8, 1.2]: the fitted coefficients cancel by many orders,
    so H(theta) v combined from the drives' own responses differs from H(theta) v simulated whole by far more
    than a forward step moves it (that base made the Jacobian 1370 % wrong).  Reference: python-control's
    response to v at theta -/+ h (central differences), projected by numpy."""
    n, dt = 3000, 0.01
    rng = np.random.default_rng(1)
    u = np.repeat(rng.uniform(0.8, 1.2, n // 40 + 1), 40)[:n]
    t = dt * np.arange(n)
    y = ct.forced_response(ct.tf([1.0], [1.0, 2.0, 5.0]), t, np.sin(3.0 * u)).outputs + 1e-3 * rng.normal(size=n)
    s = HammersteinStructure(LinearStructure(0, 2), Polynomial(9))
    data = IOData(u, y, t)
    reg = initialize._Regression(s, data, Budget(None))
    drives = initialize._drives(s.input_nonlinearity, u, reg)
    theta = np.array([5.0, 2.0])
    problem = initialize._ReducedProblem(reg, drives, 10**6)
    problem.residual(theta)
    J = problem.jacobian(theta)
    X = dense_columns(reg, theta, drives)
    v = problem.last.w[:drives.count] @ drives.array
    D = np.empty((2, n))
    for j in range(2):
        h = np.zeros(2)
        h[j] = 1e-4 * theta[j]
        up, down = ([ct.forced_response(ct.tf(*[list(c[0]) for c in s.linear.coefficients(th)]), t, v).outputs
                     for th in (theta + h, theta - h)])
        D[j] = (up - down) / (2 * h[j])
    ref = -(D.T - X @ np.linalg.lstsq(X, D.T, rcond=None)[0]).T
    np.testing.assert_allclose(J, ref, rtol=0, atol=1e-4 * np.abs(ref).max())


@pytest.mark.parametrize("scales", [(1.0,) * 6, (1e200,) * 6, (1e-200,) * 6, (1e-310,) * 6,
                                    (1e150, 1e-150, 1.0, 1e100, 1e-100, 1.0), (0.0, 1.0, 1.0, 1.0, 1.0, 1.0)])
def test_the_factor_is_lapacks_to_rounding_at_every_scale(scales):
    """The C library's Householder factorisation against LAPACK's dgeqrf (scipy, an independent oracle): the same
    R (LAPACK's reflectors, so the same signs) to a few units of rounding of each column, for columns huge, tiny,
    subnormal, of mixed scales or zero; a value that is not finite makes R all NaN."""
    from scipy.linalg import lapack

    from hammerstein_ctrl.optimize._streamed_lstsq import factor_of_rows

    rows = np.random.default_rng(len(set(scales))).normal(size=(6, 3000)) * np.array(scales)[:, None]
    R = factor_of_rows(rows.copy())
    expected = np.triu(lapack.dgeqrf(rows.T.copy(order="F"))[0][:6])
    column = np.maximum(np.abs(expected).max(axis=0), 1e-320)
    assert np.max(np.abs(R - expected) / column) < 1e-13
    rows[2, 7] = np.nan
    assert np.isnan(factor_of_rows(rows)).all()


def test_the_factor_takes_squares_below_the_normal_range_and_any_block_it_is_given():
    """A column whose squares are subnormal but sum past the smallest normal number is normed from its scaled
    values (the plain sum of squares was 4e-13 off); read-only, integer and C-ordered blocks are factored (copied
    where they must be); a block of another width is refused."""
    from scipy.linalg import lapack

    from hammerstein_ctrl.optimize._streamed_lstsq import factor_of_blocks, factor_of_rows

    v = 1.6810375542488234e-156
    rows = np.vstack([np.r_[0.0, np.full(8192, v)], np.linspace(-1.0, 1.0, 8193)])
    R = factor_of_rows(rows.copy())
    expected = np.triu(lapack.dgeqrf(rows.T.copy(order="F"))[0][:2])
    assert abs(R[0, 0] - expected[0, 0]) <= 1e-15 * abs(expected[0, 0])
    A = np.random.default_rng(3).normal(size=(40, 3))
    frozen = np.asfortranarray(A)
    frozen.flags.writeable = False
    reference = factor_of_blocks([A.copy(order="F")], 3)
    for block in (frozen, np.ascontiguousarray(A), np.round(A * 10).astype(np.int64) / 10 * 0 + A):
        np.testing.assert_array_equal(factor_of_blocks([block], 3), reference)
    np.testing.assert_array_equal(factor_of_blocks([np.arange(12).reshape(4, 3)], 3),
                                  factor_of_blocks([np.arange(12.0).reshape(4, 3)], 3))
    with pytest.raises(ValueError, match="does not have the 3 columns"):
        factor_of_blocks([np.ones((10, 4))], 3)


def test_the_rank_check_agrees_with_the_svd_on_clear_and_borderline_factors():
    """_clear_of_rank_loss proves independence from the inverse's norm where it can and asks the SVD otherwise:
    over random unit-column triangular factors, from well conditioned to singular (condition 1e2 to 1e12, around
    the cut of 1e-8), it decides as the singular values say."""
    from hammerstein_ctrl.optimize._streamed_lstsq import _clear_of_rank_loss

    rng = np.random.default_rng(11)
    decided = []
    for _ in range(400):
        p = int(rng.integers(1, 9))
        Q = np.linalg.qr(rng.normal(size=(p, p)))[0]
        s = np.logspace(0, -rng.uniform(2, 12), p)
        T = np.linalg.qr((Q * s) @ np.linalg.qr(rng.normal(size=(p, p)))[0])[1]
        T = T / np.linalg.norm(T, axis=0)
        sigma = np.linalg.svd(T, compute_uv=False)
        expected = bool(sigma[-1] > 1e-8 * sigma[0])
        assert _clear_of_rank_loss(T, 1e-8) == expected
        decided.append(expected)
    assert 50 < sum(decided) < 350                      # both answers were exercised
    T = np.triu(np.ones((3, 3)))
    T[1, 1] = 0.0                                       # singular: the inverse is not finite, the SVD decides
    assert not _clear_of_rank_loss(T / np.linalg.norm(T, axis=0), 1e-8)
