"""The compiled core's simulation kernels against plain-Python references of the documented arithmetic.

Each reference is written the slow and obvious way, sample by sample in Python floats (IEEE doubles, no fused
multiply-add), in the order the kernels document their sums: so a kernel must give its bits exactly, on random
inputs with NaN, infinities, signed zeros, huge and subnormal entries.  python-control's own simulation is the
oracle of the semantics elsewhere (test_simulate, test_lanes).
"""

import math

import numpy as np
import pytest

from hammerstein_ctrl import _core
from hammerstein_ctrl import _kernels as kernels
from hammerstein_ctrl.blocks import NONLINEARITIES, PiecewiseLinear, Polynomial

OVERFLOW = 1.7e308


def _array(rng, *shape, scale=1.0):
    """Random entries, one array in eight holding one of NaN, an infinity, a huge, a signed zero or a subnormal."""
    a = rng.standard_normal(shape) * scale
    if a.size and rng.random() < 0.125:
        a.flat[rng.integers(a.size)] = rng.choice([np.nan, np.inf, -np.inf, -0.0, 0.0, 1e300, 5e-310])
    return a


def _stable_blocks(rng, B, n, dt=0.05):
    """``E[b] = expm([[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]])`` of random stable blocks (scipy's exponential)."""
    import scipy.linalg

    E = np.empty((B, n + 2, n + 2))
    for b in range(B):
        M = np.zeros((n + 2, n + 2))
        M[:n, :n] = (rng.standard_normal((n, n)) * 0.4 - 1.5 * np.eye(n)) * dt
        M[:n, n] = rng.standard_normal(n) * dt
        M[n, n + 1] = 1.0
        E[b] = scipy.linalg.expm(M)
    return E


def _same_bits(a, b) -> bool:
    """Every entry the same bits (signed zeros told apart), or NaN in both."""
    a, b = np.ascontiguousarray(a, dtype=float), np.ascontiguousarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all((a.view(np.int64) == b.view(np.int64)) | (np.isnan(a) & np.isnan(b))))


def _py_map(name, z, p, x):
    """A built-in family's formula for one sample, in Python floats (math's tanh: the C library's)."""
    def sign(v):
        return 1.0 if v > 0 else (-1.0 if v < 0 else v)

    def minimum(a, b):
        return a if math.isnan(a) else (b if math.isnan(b) else (b if b < a else a))

    def maximum(a, b):
        return a if math.isnan(a) else (b if math.isnan(b) else (b if b > a else a))

    if name == "tanh":
        return p[0] * math.tanh(p[1] * z)
    if name == "coulomb":
        return p[0] * z + p[1] * sign(z) + p[2]
    if name == "polynomial":
        acc = p[-1]
        for c in reversed(p[:-1]):
            acc = acc * z + c
        return acc * z
    if name in ("saturation", "deadzone"):
        a = abs(p[1])
        clipped = minimum(maximum(z, -a), a)
        return p[0] * clipped if name == "saturation" else p[0] * (z - clipped)
    if name == "sigmoid":
        return p[0] * 0.5 * (1.0 + math.tanh(0.5 * p[1] * (z - p[2])))
    if name == "friction":
        return abs(p[0]) * sign(z) + p[1]
    lo, hi = 0, len(x) - 1                              # piecewise linear: the last breakpoint <= z, clipped
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if x[mid] <= z else (lo, mid)
    k = min(lo, len(x) - 2)
    w = (z - x[k]) / (x[k + 1] - x[k])
    return p[k] * (1.0 - w) + p[k + 1] * w


def _py_pass(Eb, c, d, x0, o, v, hold, direct=True, offset=True, outmap=None):
    """One candidate's outputs, sample by sample: ``x[k] = (Ad x)_r + (Bd0_r v[k-1] + Bd1_r v[k])`` (zoh:
    ``+ Gamma_r v[k-1]``), ``y = ((C x) + d v)`` mapped, ``+ o``; every sum left to right."""
    n = len(x0)
    c, d, o, v = [float(s) for s in c], float(d), float(o), [float(s) for s in v]
    a = [[float(Eb[r, k]) for k in range(n)] for r in range(n)]
    q = [0.0 if hold == "zoh" else float(Eb[r, n + 1]) for r in range(n)]
    p = [float(Eb[r, n]) if hold == "zoh" else float(Eb[r, n]) - q[r] for r in range(n)]
    x, out = [float(s) for s in x0], []
    for i, vi in enumerate(v):
        if i > 0:
            vp = v[i - 1]
            nxt = []
            for r in range(n):
                s = a[r][0] * x[0]
                for k in range(1, n):
                    s += a[r][k] * x[k]
                nxt.append(s + p[r] * vp if hold == "zoh" else s + (p[r] * vp + q[r] * vi))
            x = nxt
        z = c[0] * x[0]
        for r in range(1, n):
            z += c[r] * x[r]
        if direct:
            z = z + d * vi
        if outmap is not None:
            z = _py_map(outmap[0], z, outmap[1], outmap[2])
        out.append(z + o if offset else z)
    return out


def _py_sse(y, yh):
    J = 0.0
    for yi, h in zip(map(float, y), yh):
        e = yi - h
        J += e * e
    return J if J <= OVERFLOW else math.inf


def _py_signal(P, Phi):
    """``P[0] Phi[0] + P[1] Phi[1] + ...`` sample by sample."""
    P, Phi, out = [float(c) for c in P], Phi.tolist(), []
    for i in range(len(Phi[0])):
        v = P[0] * Phi[0][i]
        for k in range(1, len(P)):
            v += P[k] * Phi[k][i]
        out.append(v)
    return out


@pytest.mark.parametrize("n", range(1, 11))
@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_a_recursion_kernel_gives_the_references_bits(n, hold):
    """Outputs and sums of squares of every order, one to several candidates (pairs, three, singles), from random
    states, offsets and direct terms, over records of 1 to 300 samples."""
    rng = np.random.default_rng(n + 20 * (hold == "zoh"))
    for _ in range(6):
        B, N = int(rng.integers(1, 6)), int(rng.integers(1, 300))
        E, C, D, X0, Y0, V, y = (_stable_blocks(rng, B, n), _array(rng, B, n), _array(rng, B),
                                 _array(rng, B, n, scale=0.1), _array(rng, B), _array(rng, B, N), _array(rng, N))
        out, J = np.empty((B, N)), np.empty(B)
        kernels.get_kernel(n, "outputs", hold)(E, C, D, X0, Y0, V, out)
        kernels.get_kernel(n, "sse", hold)(E, C, D, X0, Y0, V, y, J)
        expected = [_py_pass(E[b], C[b], D[b], X0[b], Y0[b], list(V[b]), hold) for b in range(B)]
        assert _same_bits(out, expected)
        assert _same_bits(J, [_py_sse(y, e) for e in expected])


@pytest.mark.parametrize("family", sorted(NONLINEARITIES))
def test_an_output_map_in_the_pass_gives_the_references_bits(family):
    """Wiener kernels apply the family's map to each sample in the pass (tanh from the C library, a loop over a
    polynomial's coefficients, numpy's minimum, maximum and sign, a piecewise-linear search)."""
    rng = np.random.default_rng(len(family))
    m = {"tanh": 2, "coulomb": 3, "polynomial": 4, "saturation": 2, "deadzone": 2, "piecewise_linear": 4,
         "sigmoid": 3, "friction": 2}[family]
    for n, hold in [(1, "foh"), (2, "zoh"), (5, "foh")]:
        B, N = int(rng.integers(1, 4)), int(rng.integers(1, 200))
        E, C, D, X0, Y0, V, y = (_stable_blocks(rng, B, n), _array(rng, B, n), _array(rng, B),
                                 _array(rng, B, n, scale=0.1), _array(rng, B), _array(rng, B, N), _array(rng, N))
        HP = rng.standard_normal((B, m))
        HX = np.sort(rng.standard_normal(4)) if family == "piecewise_linear" else np.zeros(0)
        out, J = np.empty((B, N)), np.empty(B)
        kernels.get_kernel(n, "outputs", hold, family)(E, C, D, X0, Y0, V, HP, HX, out)
        kernels.get_kernel(n, "sse", hold, family)(E, C, D, X0, Y0, V, HP, HX, y, J)
        expected = [_py_pass(E[b], C[b], D[b], X0[b], Y0[b], list(V[b]), hold,
                             outmap=(family, HP[b].tolist(), HX.tolist())) for b in range(B)]
        assert _same_bits(out, expected)
        assert _same_bits(J, [_py_sse(y, e) for e in expected])
    with pytest.raises(ValueError, match="the output map's parameters"):       # fewer than the map reads
        kernels.get_kernel(5, "sse", "foh", family)(E, C, D, X0, Y0, V, np.zeros((B, 0)), HX, y, J)


@pytest.mark.parametrize("family", sorted(NONLINEARITIES))
def test_a_compiled_map_is_the_familys_formula(family):
    """The core's map of each family (hc_map_rows) is its formula: the numpy form to rounding (numpy's own tanh
    differs from the C library's in the last bit), a scalar one in Python floats to the bit."""
    rng = np.random.default_rng(7)
    special = {"polynomial": lambda: Polynomial(4), "piecewise_linear": lambda: PiecewiseLinear([-1.0, -0.2, 0.5, 1.5])}
    nl = special.get(family, NONLINEARITIES[family])()
    z = np.concatenate([rng.standard_normal(300) * 2, [0.0, -0.0, np.nan, np.inf, -np.inf, 1e300]])
    P = rng.standard_normal((3, nl.n_params))
    extra = np.ascontiguousarray(nl.map_extra(), dtype=float)
    out = np.empty((3, z.size))
    assert _core.hc_map_rows(kernels.MAP_CODES[nl.compiled_map], z, z.size, P, 3, P.shape[1], extra, extra.size,
                             out) == 0
    expected = [[_py_map(family, zi, P[b].tolist(), extra.tolist()) for zi in z.tolist()] for b in range(3)]
    assert _same_bits(out, expected)
    with np.errstate(all="ignore"):
        np.testing.assert_allclose(out, nl(z, P), rtol=1e-13, atol=1e-300, equal_nan=True)


@pytest.mark.parametrize("n", range(1, 9))
def test_a_basis_signal_gives_the_references_bits_one_at_a_time_and_in_lanes(n):
    """Kernels that form each candidate's signal ``P[b] @ Phi`` in the pass (one at a time, and across vector lanes
    with or without a direct term and an offset, groups of eight padded) sum like the reference on that signal."""
    rng = np.random.default_rng(100 + n)
    for hold in ("foh", "zoh"):
        K, N = int(rng.integers(1, 9)), int(rng.integers(1, 250))
        Phi, y = _array(rng, K, N), _array(rng, N)
        for B, direct, offset in [(2, True, True), (13, False, False), (9, True, False), (3, False, True)]:
            E, C, X0, P = _stable_blocks(rng, B, n), _array(rng, B, n), _array(rng, B, n, scale=0.1), _array(rng, B, K)
            D = _array(rng, B) if direct else np.zeros(B)
            Y0 = _array(rng, B) if offset else np.zeros(B)
            expected = [_py_sse(y, _py_pass(E[b], C[b], D[b], X0[b], Y0[b], _py_signal(P[b], Phi), hold))
                        for b in range(B)]
            J, Jl = np.empty(B), np.empty(B)
            kernels.get_kernel(n, "sse", hold, None, K)(E, C, D, X0, Y0, P, Phi, y, J)
            kernels.get_lane_kernel(n, hold, K, direct, offset)(E, C, D, X0, Y0, P, Phi, y, Jl)
            assert _same_bits(J, expected)
            assert _same_bits(Jl, expected)


def _py_normal(E, C, D, X, Y0, P, Phi, HP, HX, y, hold, direct, offset, outmap, cut, block_sums):
    """Sums ``[f, sum d r, sum d d^T]`` of a point (lane 0) and its neighbours over two blocks of samples: f
    carried through both, the others carried (``block_sums`` False) or summed per block from zero and added."""
    lanes = P.shape[0]
    p = lanes - 1
    outs = []
    for g in range(lanes):
        e = g if g < E.shape[0] else 0
        mapped = None if outmap is None else (outmap, HP[g].tolist(), HX.tolist())
        outs.append(_py_pass(E[e], C[e], D[e], X[g], Y0[g], _py_signal(P[g], Phi), hold, direct, offset, mapped))
    f, g, H = 0.0, [0.0] * p, [[0.0] * p for _ in range(p)]
    for span in (range(0, cut), range(cut, len(y))):
        gb, Hb = ([0.0] * p, [[0.0] * p for _ in range(p)]) if block_sums else (g, H)
        for i in span:
            r = y[i] - outs[0][i]
            f += r * r
            d = [outs[0][i] - outs[j + 1][i] for j in range(p)]
            for j in range(p):
                gb[j] += d[j] * r
                for k in range(j + 1):
                    Hb[j][k] += d[j] * d[k]
        if block_sums:
            g = [a + b for a, b in zip(g, gb)]
            H = [[H[j][k] + Hb[j][k] if k <= j else 0.0 for k in range(p)] for j in range(p)]
    full = np.array([[H[max(j, k)][min(j, k)] for k in range(p)] for j in range(p)])
    return np.concatenate([[f], g, full.ravel()]), outs


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 8, 10])
def test_a_normal_equation_pass_gives_the_references_sums_over_blocks(n):
    """The pass of a point and its neighbours (2 to 16 lanes, fewer linear blocks than lanes, a direct term, an
    offset or an output map), fed a record in two blocks: its sums and, with the outputs option, every lane's output
    are the reference's to the bit; the lanes' states carry across the blocks."""
    rng = np.random.default_rng(200 + n)
    for rep in range(5):
        lanes, K, N = int(rng.integers(2, 17)), int(rng.integers(1, 9)), int(rng.integers(2, 150))
        R = int(rng.integers(1, lanes + 1))
        hold = ("foh", "zoh")[rep % 2]
        direct, offset = bool(rng.integers(2)), bool(rng.integers(2))
        outmap = "tanh" if n <= 8 and rep == 2 else None
        E, C = _stable_blocks(rng, R, n), rng.standard_normal((R, n))
        D = rng.standard_normal(R) if direct else np.zeros(R)
        X, Y0 = rng.standard_normal((lanes, n)) * 0.1, rng.standard_normal(lanes) if offset else np.zeros(lanes)
        P, Phi, y = rng.standard_normal((lanes, K)), rng.standard_normal((K, N)), rng.standard_normal(N)
        HP, HX = (rng.standard_normal((lanes, 2)), np.zeros(0)) if outmap else (np.zeros((lanes, 0)), np.zeros(0))
        cut = int(rng.integers(1, N))
        expected, outs = _py_normal(E, C, D, X, Y0, P, Phi, HP, HX, y, hold, direct, offset, outmap, cut,
                                    block_sums=n <= 4 and outmap is None)
        for outputs in (False, True):
            k = kernels.get_normal_kernel(n, hold, lanes, K, direct, offset, outmap, outputs)
            Xs, VP = X.copy(), np.zeros(lanes)
            acc = np.empty((N, lanes)) if outputs else np.zeros(1 + (lanes - 1) * lanes)
            for a, b in ((0, cut), (cut, N)):
                k(E, C, D, Xs, Y0, VP, P, np.ascontiguousarray(Phi[:, a:b]), HP, HX, y[a:b], a,
                  acc[a:b] if outputs else acc)
            assert _same_bits(acc, np.array(outs).T if outputs else expected)
            assert _same_bits(VP, [_py_signal(P[g], Phi[:, -1:])[0] for g in range(lanes)])


def test_a_static_block_and_a_state_space_model_of_any_order_run_the_generic_loop():
    """A static block (order 0: the output is its direct term) and a model past the written-out orders run one
    generic loop, the reference's arithmetic; a static transfer function simulates as its gain (python-control's
    answer too)."""
    import control

    from hammerstein_ctrl.simulate import lsim

    rng = np.random.default_rng(9)
    for n in (0, 12):
        B, N = 2, 60
        E, C, D, X0, Y0, V, y = (_stable_blocks(rng, B, n), _array(rng, B, n), _array(rng, B),
                                 _array(rng, B, n, scale=0.1), _array(rng, B), _array(rng, B, N), _array(rng, N))
        for hold in ("foh", "zoh"):
            out, J = np.empty((B, N)), np.empty(B)
            kernels.get_kernel(n, "outputs", hold)(E, C, D, X0, Y0, V, out)
            kernels.get_kernel(n, "sse", hold)(E, C, D, X0, Y0, V, y, J)
            expected = [_py_pass(E[b], C[b], D[b], X0[b], Y0[b], list(V[b]), hold) if n else
                        [(0.0 + float(D[b]) * float(v)) + float(Y0[b]) for v in V[b]] for b in range(B)]
            assert _same_bits(out, expected)
            assert _same_bits(J, [_py_sse(y, e) for e in expected])
    t, v = np.arange(5) * 0.1, np.array([1.0, -2.0, 0.5, 3.0, 0.0])
    np.testing.assert_array_equal(lsim(control.tf([2.0], [1.0]), t, v), 2.0 * v)
    np.testing.assert_allclose(lsim(control.tf([2.0], [1.0]), t, v),
                               control.forced_response(control.tf([2.0], [1.0]), t, v).outputs, rtol=1e-15)


def test_a_non_finite_last_signal_sample_makes_the_sums_not_finite():
    """Under zero-order hold the last signal sample reaches the output only through the direct term: without one,
    a non-finite last sample still makes the pass's sum of squares NaN and a batch's sum inf (as with d = 0)."""
    n, lanes, N = 2, 3, 40
    rng = np.random.default_rng(5)
    E, C, P = _stable_blocks(rng, 1, n), rng.standard_normal((1, n)), np.ones((lanes, 1))
    Phi = rng.standard_normal((1, N))
    Phi[0, -1] = np.inf
    acc = np.zeros(1 + (lanes - 1) * lanes)
    kernels.get_normal_kernel(n, "zoh", lanes, 1, False, False)(E, C, np.zeros(1), np.zeros((lanes, n)),
                                                                np.zeros(lanes), np.zeros(lanes), P, Phi,
                                                                np.zeros((lanes, 0)), np.zeros(0), np.zeros(N), 0, acc)
    assert np.isnan(acc[0])
    J = np.empty(lanes)
    kernels.get_lane_kernel(n, "zoh", 1, False, False)(np.repeat(E, lanes, 0), np.repeat(C, lanes, 0),
                                                       np.zeros(lanes), np.zeros((lanes, n)), np.zeros(lanes), P,
                                                       Phi, np.zeros(N), J)
    assert np.all(J == np.inf)


def test_the_door_refuses_arrays_that_do_not_fit_with_the_arguments_name():
    """A kernel's arrays are checked against one another before it runs: a mismatched size, a missing sample, the
    wrong element type, a read-only output or a missing argument each raise naming the kernel and the argument."""
    k = kernels.get_kernel(2, "sse", "foh", None, 3)
    B, N = 3, 50
    args = [np.zeros((B, 4, 4)), np.zeros((B, 2)), np.zeros(B), np.zeros((B, 2)), np.zeros(B), np.zeros((B, 3)),
            np.zeros((3, N)), np.zeros(N), np.zeros(B)]
    k(*args)
    assert args[-1].tolist() == [0.0] * B

    def refused(index, value, error, match):
        given = list(args)
        given[index] = value
        with pytest.raises(error, match=match):
            k(*given)
    refused(3, np.zeros((B + 1, 2)), ValueError,
            r"hc_kernel_n2_sse_foh_k3: X0 has shape \(4, 2\), not \(B,2\+\); B = 3")
    refused(0, np.zeros((B, 3, 3)), ValueError, r"E has shape \(3, 3, 3\), not \(B,2\+,4\+\)")
    refused(6, np.zeros((3, 0)), ValueError, r"Phi has shape \(3, 0\)")              # no sample: nothing to read
    refused(7, np.zeros(N + 1), ValueError, "y has shape")
    refused(5, np.zeros((B, 4)), ValueError, r"P has shape \(3, 4\), not \(B,3\)")
    refused(1, np.zeros((B, 2), dtype=np.float32), TypeError, "C must be a float64 array")
    refused(5, np.zeros((3, B)).T, TypeError, "P must be a C-ordered float64 array")
    frozen = np.zeros(B)
    frozen.flags.writeable = False
    refused(8, frozen, TypeError, "out must be a C-ordered, writeable float64 array")
    with pytest.raises(TypeError, match="takes 8 arguments, not 9|takes more than 8"):
        k(*args[:-1])


def test_a_pass_refuses_arrays_that_do_not_fit_it():
    """A pass's own size checks (lanes counted by VP, rows of X and P, basis rows, the sums' length) reach Python as
    a ValueError that says what the pass takes."""
    k = kernels.get_normal_kernel(2, "foh", 5, 3, False, False)
    with pytest.raises(ValueError, match="the pass takes 2 to 16 lanes .*3 basis rows"):
        k(np.zeros((1, 4, 4)), np.zeros((1, 2)), np.zeros(1), np.zeros((6, 2)), np.zeros(6), np.zeros(6),
          np.zeros((6, 3)), np.zeros((3, 10)), np.zeros((6, 0)), np.zeros(0), np.zeros(10), 0, np.zeros(29))
    with pytest.raises(ValueError, match="built for 2..16 lanes, not 17"):
        kernels.get_normal_kernel(2, "foh", 17, 3)


def test_the_single_evaluation_from_coefficients_checks_what_the_kernel_reads():
    """get_coefficient_kernel's call (the core's discretisation, then the kernel) checks every array against the
    kernel's order and basis before it runs: a block of another order, a short output, too few basis rows or an
    improper block are refused by name; a row the compiled path cannot take leaves out untouched."""
    from hammerstein_ctrl._linalg import tf_discrete
    from hammerstein_ctrl.simulate._simulate import COMPILED_EXPM_MAX_NORM

    f = kernels.get_coefficient_kernel(3, "foh", 1)
    num, den = np.ones((1, 1)), np.array([[1.0, 3.0, 3.0, 1.0]])
    args = [np.zeros((1, 3)), np.zeros(1), np.ones((1, 1)), np.ones((1, 40)), np.zeros(40), np.empty(1)]
    assert f(num, den, 0.1, COMPILED_EXPM_MAX_NORM, *args) and np.isfinite(args[-1][0])

    def refused(error, match, num=num, den=den, **changed):
        given = dict(zip(("X0", "Y0", "P", "Phi", "y", "out"), args), **changed)
        with pytest.raises(error, match=match):
            f(num, den, 0.1, COMPILED_EXPM_MAX_NORM, *given.values())
    refused(ValueError, r"hc_coefficient_pass_n3_k1: den has shape \(1, 3\), not \(B,4\)", den=np.ones((1, 3)))
    refused(ValueError, r"out has shape \(0\), not \(B\); B = 1", out=np.empty(0))
    refused(ValueError, r"Phi has shape \(0, 40\)", Phi=np.ones((0, 40)))
    refused(ValueError, "num has more coefficients than den", num=np.ones((1, 5)))
    out = np.full(1, 7.0)
    assert not f(num, np.array([[0.0, 3.0, 3.0, 1.0]]), 0.1, COMPILED_EXPM_MAX_NORM, *args[:-1], out)
    assert out[0] == 7.0
    E, C, D, ok, big, clean = tf_discrete(num, den, 0.1, COMPILED_EXPM_MAX_NORM)
    J = np.empty(1)
    kernels.get_kernel(3, "sse", "foh", None, 1)(E, C, D, *args[:5], J)
    assert _same_bits(J, args[-1])                 # the same pass as from the discretised block
