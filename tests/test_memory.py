"""Bounded memory on long records: no ``B x N`` block of signals where a chunked pass suffices.

Peak memory is measured with ``tracemalloc`` (which sees every numpy array)
while the cost and ``identify`` run on a synthetic 1e6-sample EMPS record.
A batch of ``B`` candidates formed at once would take ``8 B`` bytes per sample
for the signals alone (400 B for AMVO-SCA's 50 universes); the cost forms at
most :data:`~hammerstein_ctrl.fit._objective.CHUNK_BYTES` of them at a time.
"""

import tracemalloc

import numpy as np
import pytest

import speed as bench
from hammerstein_ctrl.fit._objective import CHUNK_BYTES, HammersteinCost
from hammerstein_ctrl.paper.presets import emps_structure

N = 10**6


@pytest.fixture(scope="module")
def record():
    return bench.synthetic_record(N)


@pytest.fixture(scope="module")
def cost(record):
    c = HammersteinCost(record, emps_structure())
    c(np.array(bench.SYNTHETIC_X0))  # compile outside the measurement
    return c


def peak_bytes_per_sample(fn):
    tracemalloc.start()
    try:
        out = fn()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return peak / N, out


def candidates(count):
    rng = np.random.default_rng(1)
    return np.asarray(bench.SYNTHETIC_BETA) * (1 + 0.05 * rng.standard_normal((count, 4)))


def test_batch_of_50_in_bounded_memory(cost):
    betas = candidates(50)
    per_sample, J = peak_bytes_per_sample(lambda: cost.batch(betas))
    # one chunk of signals (16 MiB = 16.8 B/sample here) and small change, not 50 x 8 B
    assert per_sample < 2 * CHUNK_BYTES / N + 8
    # and the same values as candidate by candidate
    np.testing.assert_allclose(J[:3], [cost(b) for b in betas[:3]], rtol=1e-12)


def test_chunked_outputs_equal_whole(cost):
    betas = candidates(5)
    Y = cost.simulate_batch(betas)
    for k in (0, 4):
        np.testing.assert_array_equal(Y[k], cost.simulate(betas[k]))
    R = cost.residuals_batch(betas)
    np.testing.assert_array_equal(R[2], cost.residuals(betas[2]))
    np.testing.assert_allclose(np.sum(R * R, axis=1), cost.batch(betas), rtol=1e-10)


def test_residuals_in_bounded_memory(cost):
    per_sample, r = peak_bytes_per_sample(lambda: cost.residuals(np.array(bench.SYNTHETIC_BETA)))
    assert r.shape == (N,)
    assert per_sample < 20  # the output and the signal, 8 B each


# N-SPSA and AMVO-SCA: the stored basis (24 B) and one chunk of signals (40 B measured); LM: the basis,
# the lanes' state and a residual vector (40 B measured; MINPACK's route held its Jacobian and ours,
# 32 B each, and scipy's least_squares route two more Jacobian copies: 216 B here).  The uncertainty after
# the fit (the residuals here are coloured) adds the whitened Jacobian in single precision, 4 B per
# parameter (16 B), and a column and its simulation (16 B): 72 B measured.  The significance tests then fit the
# linear model nested in the structure by ``auto`` while the fit's cost and residuals are held: 128 B measured
# (its starts hold their regression columns whole below STREAMED_COLUMNS_BYTES, 88 B here; past it they stream).
@pytest.mark.parametrize("method, bound", [("nspsa", 136), ("amvo-sca", 136), ("lm", 136)])
def test_identify_in_bounded_memory(record, method, bound):
    bench.identify_long_record(bench.synthetic_record(2000), method)  # compile/load outside the measurement
    per_sample, r = peak_bytes_per_sample(lambda: bench.identify_long_record(record, method))
    assert r.nfev == bench.MEMORY_BUDGETS[method] and r.covariance is not None
    assert not r.uncertainty.noise.white
    assert per_sample < bound
    bare, _ = peak_bytes_per_sample(lambda: bench.identify_long_record(record, method, uncertainty=False))
    assert bare < 60


def test_recomputed_basis_gives_the_same_numbers(record, cost, monkeypatch):
    """Past BASIS_MAX_BYTES the basis is rebuilt block by block: same signals, same J, no stored basis."""
    from hammerstein_ctrl.fit import _objective as objective

    monkeypatch.setattr(objective, "BASIS_MAX_BYTES", 0)
    monkeypatch.setattr(objective, "BASIS_BLOCK", 7919)  # a prime: blocks end mid-level
    streamed = HammersteinCost(record, emps_structure())
    assert streamed._basis is None and cost._basis is not None
    betas = candidates(3)
    np.testing.assert_array_equal(streamed.batch(betas), cost.batch(betas))
    np.testing.assert_array_equal(streamed.residuals(betas[0]), cost.residuals(betas[0]))
    per_sample, _ = peak_bytes_per_sample(lambda: streamed.batch(betas))
    assert per_sample < 8 * 3 + 4  # the 3 signals, the basis blocks are small


def test_auto_in_bounded_memory(record):
    """``identify(data, structure)`` (method "auto") on the 1e6-sample record, as at 1e7 samples.

    The cost streams its basis here (as it does past BASIS_MAX_BYTES, e.g. at
    1e7 samples); the starts form their drives and the drives' responses a
    block of samples at a time (through the compiled lane passes) and reduce
    their regressions block by block (streamed_lstsq), so what remains is
    MINPACK's residual, Jacobian and work vectors on the reduced problem
    (25 B measured; holding the drives and their responses took 80 B, and
    forming the regressions whole 192 B/sample at 1e7 samples before).
    """
    from hammerstein_ctrl import identify
    from hammerstein_ctrl.fit import _objective as objective

    structure = emps_structure()
    budget = 300  # every stage runs: scan, reduced LM, static fits, LM refinements
    identify(bench.synthetic_record(2000), structure, maxfev=budget, seed=0)  # compile outside the measurement
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(objective, "BASIS_MAX_BYTES", 0)
        per_sample, r = peak_bytes_per_sample(lambda: identify(record, structure, maxfev=budget, seed=0))
    assert r.success and r.nfev <= budget and r.optimize_result.starts == 3
    np.testing.assert_allclose(r.x, bench.SYNTHETIC_BETA, rtol=1e-6)
    assert per_sample < 104         # 96 B measured: the nested linear fit's starts (above); the optimisation 25 B


@pytest.mark.slow
@pytest.mark.parametrize("method", ["auto"])     # LM's passes alone: test_normal_equations' lane-group tests
def test_a_wide_structure_in_bounded_memory(record, method):
    """16 parameters and an 11-signal basis (piecewise-linear g with 11 knots, a (1, 3) block, an offset).

    Past one compiled pass the normal equations run as lane groups, and the
    starts form their 11 drives and responses by blocks: 30 B/sample measured,
    where p + 1 = 17 stored residual vectors alone took 136 and auto's starts
    (which formed the whole basis to see whether there was one) 400.
    """
    from hammerstein_ctrl import HammersteinStructure, LinearStructure, PiecewiseLinear
    from hammerstein_ctrl import identify

    s = HammersteinStructure(LinearStructure(1, 3), PiecewiseLinear(np.linspace(-0.9, 0.9, 11)), offset=True)
    kwargs = {"maxfev": 300 if method == "auto" else 60, "seed": 0, "method": method}
    if method == "lm":
        kwargs["x0"] = np.r_[[1.0, 1.0, 3.0, 3.0], np.linspace(-0.9, 0.9, 11), 0.0]     # H = 1 / (p + 1)^3
    from hammerstein_ctrl.simulate import _normal_pass
    from hammerstein_ctrl.fit import _initialize as initialize

    with pytest.MonkeyPatch.context() as mp:      # compile outside the measurement, on the long records' routes
        mp.setattr(_normal_pass, "GROUPS_MIN_BYTES", 0)
        mp.setattr(initialize, "STREAMED_COLUMNS_BYTES", 0)
        identify(bench.synthetic_record(3000), s, **kwargs)
    per_sample, r = peak_bytes_per_sample(lambda: identify(record, s, **kwargs))
    assert r.nfev == kwargs["maxfev"] and np.isfinite(r.fun)
    assert per_sample < 60 + 4 * s.n_params      # the whitened Jacobian: 4 B per parameter (64 B here)


@pytest.mark.parametrize("intersample", ["foh", "zoh"])
def test_normal_equations_of_a_g_without_basis_stream_its_signals(record, intersample):
    """tanh has no basis: its distinct signals (the point's and one per parameter of g) are evaluated a
    block at a time inside the compiled pass, with the numbers of the stored N x p Jacobian and no p x N array."""
    from hammerstein_ctrl.paper.datasets import IOData
    from hammerstein_ctrl.blocks import Tanh
    from hammerstein_ctrl.optimize._normal_equations import forward_steps, from_residuals, neighbours
    from hammerstein_ctrl.blocks import HammersteinStructure, LinearStructure

    data = IOData(record.u, record.y, dt=record.dt, intersample=intersample)
    structure = HammersteinStructure(LinearStructure(1, 2), Tanh(), offset=True)
    cost = HammersteinCost(data, structure)
    x = np.array([2.0, 3.0, 1.5, 0.8, 0.5, 0.05])
    h = forward_steps(x)
    assert cost._fused_normal_equations(neighbours(x, h), h) is not None      # the compiled pass applies
    per_sample, ne = peak_bytes_per_sample(lambda: cost.normal_equations(x))
    assert per_sample < 8                        # p + 1 = 7 residual vectors alone would be 56 B per sample
    small = HammersteinCost(data.window(0.0, 20.0), structure)
    ref = from_residuals(small.residuals_batch(neighbours(x, h)), h)
    got = small.normal_equations(x)
    assert got.fun == pytest.approx(small(x), rel=1e-12) == pytest.approx(ref.fun, rel=1e-12)
    np.testing.assert_allclose(got.gradient, ref.gradient, rtol=1e-6, atol=1e-9 * np.abs(ref.gradient).max())
    np.testing.assert_allclose(got.gram, ref.gram, rtol=1e-6, atol=1e-9 * np.abs(ref.gram).max())
    assert np.isfinite(ne.fun)


def test_normal_factor_streams_its_blocks(cost):
    """The QR-factor form of the normal equations: lanes' outputs a block at a time, no p x N array."""
    x = np.asarray(bench.SYNTHETIC_BETA, float)
    cost.normal_factor(x)                       # compile outside the measurement (a cold kernel cache)
    per_sample, qr = peak_bytes_per_sample(lambda: cost.normal_factor(x))
    assert per_sample < 2
    ne = cost.normal_equations(x)
    assert qr.fun == pytest.approx(ne.fun, rel=1e-9)
    scale = np.sqrt(np.outer(np.diag(ne.gram), np.diag(ne.gram)))
    assert np.max(np.abs(qr.gram - ne.gram) / scale) < 1e-6
    R, qtr = qr.factor
    assert not np.tril(R, -1).any() and qtr @ qtr <= qr.fun      # triangular; Q.T r is part of r


def test_normal_equations_of_a_custom_output_map_stream_the_lanes(record):
    """A custom h (no compiled form) is applied to the lanes' outputs a block at a time: no p + 1 residuals."""
    from hammerstein_ctrl.blocks import CustomNonlinearity
    from hammerstein_ctrl.blocks import LinearStructure, WienerStructure

    cubic = CustomNonlinearity(lambda v, p: p[0] * v + p[1] * v ** 3, n_params=2)
    cost = HammersteinCost(record, WienerStructure(LinearStructure(0, 2), cubic))
    x = np.array([2.0, 3.0, 1.5, 0.1])
    cost.normal_equations(x), cost.normal_factor(x)     # compile outside the measurement (a cold kernel cache)
    per_sample, ne = peak_bytes_per_sample(lambda: cost.normal_equations(x))
    assert per_sample < 4 and np.isfinite(ne.fun)     # p + 1 = 5 stored residual vectors would be 40 B
    per_sample, qr = peak_bytes_per_sample(lambda: cost.normal_factor(x))
    assert per_sample < 4 and qr.fun == pytest.approx(ne.fun, rel=1e-9)
