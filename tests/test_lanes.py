"""The lanes kernel (candidates across SIMD lanes, basis formed in the pass) against the interleaved kernel and
python-control."""

import control
import numpy as np
import pytest

from hammerstein_ctrl import presets
from hammerstein_ctrl._kernels import LANE_MIN, LANE_WIDTHS
from hammerstein_ctrl.simulate import sse_basis_batch, sse_batch


def _stable_batch(rng, batch, n, proper):
    """Random stable transfer functions: poles in the left half-plane, numerator degree n (or n-1)."""
    poles = -rng.uniform(0.5, 20.0, size=(batch, n))
    den = np.array([np.poly(p) for p in poles])
    num = rng.normal(size=(batch, n + 1 if proper else n))
    return num, den


@pytest.mark.parametrize("n, hold", [(1, "zoh"), (2, "foh"), (3, "foh"), (3, "zoh")])
def test_bit_identical_to_interleaved_kernel(n, hold):
    rng = np.random.default_rng(n)
    N, K = 500, 3
    for batch in (LANE_MIN, 8, 17, 35):    # padded groups, one narrow group, wide groups and a rest
        num, den = _stable_batch(rng, batch, n, proper=bool(n % 2))
        basis = rng.normal(size=(K, N))
        P = rng.normal(size=(batch, K))
        y = rng.normal(size=N)
        x0, offset = rng.normal(size=(batch, n)), rng.normal(size=batch)
        for kwargs in ({}, {"x0": x0, "offset": offset}):
            J = sse_basis_batch(num, den, P, basis, 0.01, y, intersample=hold, **kwargs)
            ref = sse_batch(num, den, _combined(P, basis), 0.01, y, intersample=hold, **kwargs)
            np.testing.assert_array_equal(J, ref)


def _combined(P, basis):
    """``P @ basis`` summed basis row by basis row (the cost's order), independent of BLAS."""
    V = P[:, :1] * basis[0]
    for k in range(1, basis.shape[0]):
        V = V + P[:, k:k + 1] * basis[k]
    return V


def test_against_forced_response():
    rng = np.random.default_rng(7)
    t = np.arange(0, 3, 0.005)
    u = np.sin(2 * t) + 0.3 * rng.normal(size=t.size)
    basis = np.vstack([u, np.abs(u), u ** 3])
    num, den = _stable_batch(rng, 9, 2, proper=False)
    P = rng.normal(size=(9, 3))
    y = np.cos(t)
    J = sse_basis_batch(num, den, P, basis, 0.005, y)
    for b in range(9):
        yhat = control.forced_response(control.tf(num[b], den[b]), t, P[b] @ basis).outputs
        assert J[b] == pytest.approx(np.sum((y - yhat) ** 2), rel=1e-10)


def test_overflow_and_unstable_candidates():
    rng = np.random.default_rng(3)
    N = 3000
    basis, y = rng.normal(size=(1, N)), rng.normal(size=N)
    num = np.ones((LANE_WIDTHS[-1] + 1, 1))
    den = np.tile([1.0, 1.0], (num.shape[0], 1))
    den[2] = [1.0, -2000.0]                   # grows like exp(2000 t): overflows within the record
    den[5] = [1.0, -0.5]                      # unstable but finite
    P = np.ones((num.shape[0], 1))
    J = sse_basis_batch(num, den, P, basis, 0.01, y)
    assert np.isinf(J[2]) and np.isfinite(np.delete(J, 2)).all()
    ref = sse_batch(num, den, basis[0], 0.01, y)
    np.testing.assert_array_equal(J, ref)
    rejected = sse_basis_batch(num, den, P, basis, 0.01, y, reject_unstable=True)
    assert np.isinf(rejected[[2, 5]]).all() and np.isfinite(np.delete(rejected, [2, 5])).all()


def test_cost_batch_matches_single_evaluations(emps_dir):
    case = presets.emps(path=emps_dir)
    x = np.asarray(case.paper["nspsa"]["beta"], float)
    betas = x * (1 + 0.05 * np.random.default_rng(0).normal(size=(50, x.size)))
    J = case.cost.batch(betas)
    np.testing.assert_array_equal(J, [case.cost(b) for b in betas])


def test_inapplicable_sizes_return_none():
    basis = np.ones((9, 10))
    assert sse_basis_batch(np.ones((3, 1)), np.tile([1.0, 1.0], (3, 1)), np.ones((3, 9)), basis, 0.1,
                           np.ones(10)) is None


@pytest.mark.parametrize("batch", [1, LANE_MIN - 1])
def test_small_batches_in_one_compiled_call_and_their_fallbacks(batch):
    """Below LANE_MIN the discretisation and the pass are one call; rows it cannot take go the general way."""
    rng = np.random.default_rng(11)
    N = 400
    basis, y = rng.normal(size=(2, N)), rng.normal(size=N)
    P = rng.normal(size=(batch, 2))
    for den_row in ([1.0, 3.0], [1.0, 1e5], [1.0, -0.5], [0.0, 1.0], [1.0, np.nan]):
        # stable, too fast for the compiled Pade (scipy's expm takes it), unstable, improper, non-finite
        num, den = np.ones((batch, 1)), np.tile(den_row, (batch, 1))
        for reject in (False, True):
            J = sse_basis_batch(num, den, P, basis, 1e-3, y, reject_unstable=reject)
            ref = sse_batch(num, den, _combined(P, basis), 1e-3, y, reject_unstable=reject)
            np.testing.assert_array_equal(J, ref)
    assert np.isinf(sse_basis_batch(num, den, P, basis, 1e-3, y)).all()


def test_a_nonfinite_last_signal_sample_scores_inf_without_a_direct_term():
    """ZOH: the last sample's signal reaches the output only through d; the lanes kernel leaves d = 0 out."""
    N = 50
    u = np.full(N, 1e-200)
    u[-1] = 1e200
    for batch in (1, LANE_MIN, 8):
        num, den, P = np.ones((batch, 1)), np.tile([1.0, 1.0], (batch, 1)), np.full((batch, 1), 1e200)
        J = sse_basis_batch(num, den, P, u[None], 0.01, np.zeros(N), intersample="zoh")
        assert np.isinf(J).all()


def test_basis_arguments_are_checked():
    from hammerstein_ctrl.exceptions import DataError, ParameterError

    rng = np.random.default_rng(0)
    u, y = rng.normal(size=300), rng.normal(size=300)
    num, den = np.ones((3, 1)), np.tile([1.0, 1.0], (3, 1))
    shared = sse_basis_batch(num, den, np.array([[1.0]]), u[None], 0.01, y)   # one row of P for every candidate
    np.testing.assert_array_equal(shared, sse_batch(num, den, u, 0.01, y))
    with pytest.raises(ParameterError, match="2 rows of basis coefficients for 3"):
        sse_basis_batch(num, den, np.ones((2, 1)), u[None], 0.01, y)
    with pytest.raises(ParameterError, match="do not match a basis"):
        sse_basis_batch(num, den, np.ones((3, 1)), np.ones((2, 300)), 0.01, y)
    with pytest.raises(DataError, match="same, non-zero, length"):
        sse_basis_batch(num, den, np.ones((3, 1)), u[None], 0.01, y[:-1])
    with pytest.raises(DataError, match="same, non-zero, length"):
        sse_batch(num, den, np.ones((3, 0)), 0.01, np.ones(0))


@pytest.mark.parametrize("kind", ["basis", "no g", "offset and x0", "reject unstable", "tanh", "tanh, offset and x0"])
def test_single_evaluations_give_the_bits_of_a_batch(kind):
    """cost(beta) takes one compiled call where it can; every route gives what the batch gives (a single
    candidate of a g without a basis passes its evaluated signal as a basis of one, a batch its signals whole)."""
    import hammerstein_ctrl as hc
    from hammerstein_ctrl.fit import HammersteinCost

    rng = np.random.default_rng(5)
    N = 2000
    u = np.repeat(rng.uniform(-2, 2, N // 20), 20)
    data = hc.IOData(u, np.sin(np.arange(N) * 0.01) + 0.1 * rng.normal(size=N), dt=0.01, name="syn")
    g = None if kind == "no g" else hc.Tanh() if kind.startswith("tanh") else hc.Polynomial(2)
    from hammerstein_ctrl.blocks import BlockStructure

    nuisance = kind.endswith("offset and x0")
    options = {"offset": nuisance, "initial_state": "estimate" if nuisance else "zero"}
    structure = (BlockStructure(hc.LinearStructure(1, 2), **options) if g is None      # a linear block alone
                 else hc.HammersteinStructure(hc.LinearStructure(1, 2), g, **options))
    cost = HammersteinCost(data, structure, reject_unstable=kind == "reject unstable")
    assert (cost._direct is not None) == (kind in ("basis", "no g", "reject unstable", "tanh"))
    betas = rng.uniform(0.5, 2.0, (12, structure.n_params))
    betas[3, 2] = -1.0                      # an unstable candidate
    betas[5, 0] = np.nan                    # a hostile one
    np.testing.assert_array_equal([cost(b) for b in betas], cost.batch(betas))


def test_a_single_evaluation_evaluates_g_once_whatever_the_order():
    """A candidate of a g without a basis is evaluated once per cost(beta), past the unrolled kernels' orders too
    (where its signal is read whole, not passed as a basis of one)."""
    import hammerstein_ctrl as hc
    from hammerstein_ctrl.blocks import CustomNonlinearity
    from hammerstein_ctrl.fit import HammersteinCost

    calls = []
    g = CustomNonlinearity(lambda u, p: calls.append(u.size) or p[0] * np.tanh(u), 1)
    rng = np.random.default_rng(2)
    data = hc.IOData(rng.normal(size=3000), rng.normal(size=3000), dt=0.01)
    counted = {}
    for order in (2, 9):
        cost = HammersteinCost(data, hc.HammersteinStructure(hc.LinearStructure(0, order), g, offset=True))
        calls.clear()
        assert np.isfinite(cost(np.r_[np.poly(-np.linspace(1.0, 2.0, order))[1:][::-1], 1.0, 0.1]))
        counted[order] = sum(calls)
    assert counted == {2: 3000, 9: 3000}


def test_reject_unstable_set_after_construction_and_threads_keep_their_own_buffers(emps_dir):
    """The one-call path honours reject_unstable as it is now; each thread forms its signals in its own buffer."""
    import pickle
    from concurrent.futures import ThreadPoolExecutor

    case = presets.trs()
    x = np.asarray(case.true_beta, float)
    betas = x * (1 + 0.2 * np.random.default_rng(3).normal(size=(40, x.size)))
    serial = [case.cost.batch(betas[i::4]) for i in range(4)]
    with ThreadPoolExecutor(4) as pool:
        for _ in range(5):
            threaded = list(pool.map(case.cost.batch, [betas[i::4] for i in range(4)]))
            for a, b in zip(serial, threaded):
                np.testing.assert_array_equal(a, b)
    copy = pickle.loads(pickle.dumps(case.cost))
    np.testing.assert_array_equal(copy.batch(betas), case.cost.batch(betas))

    emps = presets.emps(path=emps_dir)
    unstable = np.asarray(emps.x0, float)          # a1 = -1: a pole in the right half-plane
    assert np.isfinite(emps.cost(unstable))
    emps.cost.reject_unstable = True
    assert emps.cost(unstable) == np.inf == emps.cost.batch([unstable])[0]


def test_one_compiled_version_takes_read_only_and_writeable_arrays():
    """A record's arrays are read-only, a caller's are not: the kernels take both with one compiled version."""
    from hammerstein_ctrl._kernels import get_coefficient_kernel, get_kernel
    from hammerstein_ctrl.simulate._simulate import COMPILED_EXPM_MAX_NORM, simulate_batch

    rng = np.random.default_rng(4)
    u, y = rng.normal(size=300), rng.normal(size=300)
    num, den = np.array([[0.5, 1.0]] * 4), np.array([[1.0, 1.2, 0.8]] * 4)
    basis = np.vstack([u, u ** 3])
    P = rng.normal(size=(4, 2))

    def frozen(a):
        a = a.copy()
        a.flags.writeable = False
        return a

    results = []
    for wrap in (np.copy, frozen):
        J = sse_basis_batch(wrap(num), wrap(den), wrap(P), wrap(basis), 0.01, wrap(y), offset=wrap(np.ones(4)))
        J1 = sse_basis_batch(wrap(num[:1]), wrap(den[:1]), wrap(P[:1]), wrap(basis), 0.01, wrap(y),
                             offset=wrap(np.ones(1)), x0=wrap(np.ones((1, 2))))
        Y = simulate_batch(wrap(num[:2]), wrap(den[:2]), wrap(P[:2] @ basis), 0.01, offset=wrap(np.ones(2)),
                           x0=wrap(np.zeros((2, 2))))
        results.append((J, J1, Y))
    for a, b in zip(*results):
        assert np.array_equal(a, b)
    J2 = np.empty(1)
    assert get_coefficient_kernel(2, "foh", 2)(num[:1], den[:1], 0.01, COMPILED_EXPM_MAX_NORM, np.zeros((1, 2)),
                                               frozen(np.zeros(1)), P[:1], frozen(basis), frozen(y), J2)
    assert J2[0] == sse_basis_batch(num[:1], den[:1], P[:1], basis, 0.01, y)[0]
    with pytest.raises(TypeError, match="E must be a float64 array"):   # a wrong type is refused, never converted
        get_kernel(2, "outputs", "foh")(np.zeros((1, 4, 4), dtype=np.float32), *[np.zeros((1, 1))] * 6)
    with pytest.raises(TypeError, match="out must be a C-ordered, writeable"):
        get_kernel(2, "outputs", "foh")(*[np.zeros((1, 4, 4))] + [frozen(np.zeros(s)) for s in (
            (1, 2), 1, (1, 2), 1, (1, 3), (1, 3))])


def test_one_compiled_discretisation_and_pass_serves_every_state_dimension_and_basis():
    """Single evaluations discretise and run the pass in one call of the C library, the same for every order and
    basis (the pass is called through its address), with the bits of the batch path."""
    from hammerstein_ctrl._kernels import get_coefficient_kernel
    from hammerstein_ctrl.simulate._simulate import COMPILED_EXPM_MAX_NORM

    rng = np.random.default_rng(8)
    u, y = rng.normal(size=500), rng.normal(size=500)
    functions = set()
    for n, K in ((1, 1), (3, 2), (5, 3)):
        num, den = rng.normal(size=(1, n)), np.poly(-rng.uniform(0.5, 3.0, size=n))[None, :]
        P, basis = rng.normal(size=(1, K)), np.vstack([u ** (k + 1) for k in range(K)])
        J = np.full(1, np.nan)
        f = get_coefficient_kernel(n, "zoh", K)
        assert f(num, den, 0.02, COMPILED_EXPM_MAX_NORM, np.zeros((1, n)), np.zeros(1), P, basis, y, J)
        assert J[0] == sse_basis_batch(num, den, P, basis, 0.02, y, intersample="zoh")[0]
        functions.add((f.func, f.args[0].split("|")[0]))
    assert len({func for func, _ in functions}) == 1 and len(functions) == 3      # one door, a kernel per order
    den = np.array([[0.0, 1.0, 2.0]])                   # not a transfer function: left for the general path
    J = np.full(1, 7.0)
    assert not get_coefficient_kernel(2, "zoh", 1)(np.ones((1, 1)), den, 0.02, COMPILED_EXPM_MAX_NORM,
                                                   np.zeros((1, 2)), np.zeros(1), np.ones((1, 1)), u[None, :], y, J)
    assert J[0] == 7.0


def test_shared_rows_strided_views_and_repeated_lookups_reach_the_one_compiled_version():
    """Arrays the kernels' signatures do not take as given (read-only broadcast rows, strided views) are
    converted before the call, and asking for a kernel again does not compile (or refuse) anything."""
    from hammerstein_ctrl import HammersteinStructure, IOData, LinearStructure, Polynomial
    from hammerstein_ctrl._kernels import get_coefficient_kernel
    from hammerstein_ctrl.fit import HammersteinCost
    from hammerstein_ctrl.simulate import lsim

    rng = np.random.default_rng(5)
    u, y = rng.normal(size=400), rng.normal(size=400)
    basis = np.vstack([u, u ** 3])
    num, den = np.ones((2, 1)), np.tile([1.0, 3.0, 2.0], (2, 1))
    shared = sse_basis_batch(num, den, np.array([1.0, 0.5]), basis, 0.01, y)     # one row of P for both
    assert np.array_equal(shared, sse_basis_batch(num, den, np.array([[1.0, 0.5]] * 2), basis, 0.01, y))
    cost = HammersteinCost(IOData(u, y, dt=0.01), HammersteinStructure(LinearStructure(0, 2), Polynomial(2)))
    B = np.array([[2.0, 9.0], [3.0, 9.0], [1.0, 9.0], [0.5, 9.0]])
    assert cost(B[:, 0]) == cost(np.ascontiguousarray(B[:, 0]))                     # a column of an array
    v = np.repeat(u, 2)
    t, H = np.arange(400) * 0.01, control.tf([2.0], [1.0, 3.0, 2.0])
    assert np.array_equal(lsim(H, t, v[::2]), lsim(H, t, u))                          # a strided signal
    again, first = get_coefficient_kernel(n=2, hold="foh", K=2), get_coefficient_kernel(2, "foh", 2)
    assert (again.func, again.args) == (first.func, first.args)       # by keyword: the same compiled call
