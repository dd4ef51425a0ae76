"""The compiled small dense linear algebra of :mod:`hammerstein_ctrl._linalg` against numpy and scipy."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import scipy.linalg

from hammerstein_ctrl._linalg import expm_batch, solve_in_place, symmetric_eigenvalues


def _grams(rng, count):
    """Scaled Gram matrices of random Jacobians with columns of very different sizes, some nearly dependent."""
    for _ in range(count):
        p = int(rng.integers(1, 10))
        J = rng.standard_normal((40, p)) * 10.0 ** rng.uniform(-6, 6, p)
        if p > 1 and rng.random() < 0.4:
            J[:, -1] = J[:, 0] * (1.0 + 1e-9 * rng.standard_normal())
        G = J.T @ J
        d = np.sqrt(np.diag(G))
        yield G / np.outer(d, d)


def test_symmetric_eigenvalues_match_lapack():
    rng = np.random.default_rng(11)
    for A in _grams(rng, 300):
        w = np.linalg.eigvalsh(A)
        assert np.max(np.abs(symmetric_eigenvalues(A) - w)) <= 1e-13 * np.max(np.abs(w))
    for _ in range(300):
        p = int(rng.integers(1, 9))
        S = rng.standard_normal((p, p))
        S = S + S.T
        w = np.linalg.eigvalsh(S)
        assert np.max(np.abs(symmetric_eigenvalues(S) - w)) <= 1e-13 * np.max(np.abs(w))


def test_symmetric_eigenvalues_keep_small_ones_of_a_graded_definite_matrix():
    # diag(1, 1e-8, 1e-16) in a rotated basis with graded scaling: the smallest is still found to a few digits
    D = np.diag([1.0, 1e-8, 1e-16])
    w = symmetric_eigenvalues(D)
    assert w.tolist() == [1e-16, 1e-8, 1.0]
    S = np.array([[4.0, 2.0], [2.0, 1.0 + 1e-12]])       # eigenvalues 5 and 2e-13/(5) to first order
    w = symmetric_eigenvalues(S)
    assert w[0] == pytest.approx(1e-12 * 4.0 / 5.0, rel=1e-3) and w[1] == pytest.approx(5.0, rel=1e-12)


def test_solve_in_place_matches_numpy_and_flags_singular():
    rng = np.random.default_rng(12)
    for _ in range(300):
        n, m = int(rng.integers(1, 9)), int(rng.integers(1, 4))
        A, B = rng.standard_normal((n, n)), rng.standard_normal((n, m))
        X = B.copy()
        solve_in_place(A.copy(), X)
        np.testing.assert_allclose(X, np.linalg.solve(A, B), rtol=1e-9, atol=1e-11)
    X = np.ones((2, 1))
    solve_in_place(np.array([[1.0, 2.0], [2.0, 4.0]]), X)
    assert not np.isfinite(X).all()


def test_expm_matches_scipy_across_scalings():
    rng = np.random.default_rng(13)
    for _ in range(100):
        n = int(rng.integers(1, 7))
        M = rng.standard_normal((n, n)) * 10.0 ** rng.uniform(-3, 1.5)
        np.testing.assert_allclose(expm_batch(M[None])[0], scipy.linalg.expm(M), rtol=1e-10,
                                   atol=1e-12 * np.abs(scipy.linalg.expm(M)).max())


def test_single_threaded_blas_nests_and_restores():
    threadpoolctl = pytest.importorskip("threadpoolctl")
    from hammerstein_ctrl._linalg import single_threaded_blas

    def threads():
        return [lib["num_threads"] for lib in threadpoolctl.threadpool_info()]

    before = threads()
    with single_threaded_blas():
        assert set(threads()) <= {1}
        with single_threaded_blas():
            assert set(threads()) <= {1}
        assert set(threads()) <= {1}            # the inner block leaves the outer limit in place
    assert threads() == before
    with pytest.raises(RuntimeError):
        with single_threaded_blas():
            raise RuntimeError("inside")
    assert threads() == before                  # restored after an exception too
    with single_threaded_blas():
        assert set(threads()) <= {1}            # and the depth count was reset


def test_strings_are_not_numbers():
    from hammerstein_ctrl._checks import as_real_array
    from hammerstein_ctrl.exceptions import ParameterError

    with pytest.raises(ParameterError, match="text"):
        as_real_array(["1.5"], "beta")
    assert as_real_array(np.array([1, None, 2.0], dtype=object)[[0, 2]], "beta").tolist() == [1.0, 2.0]


def test_symmetric_eigenvalues_of_large_entries():
    """The skip test |a_pq| <= eps sqrt(|a_pp a_qq|) overflows past 1e154: no rotation, diagonal returned."""
    for S in (np.array([[1e200, 1e200], [1e200, 1e200]]), np.array([[1e160, 0.9e160], [0.9e160, 1e160]])):
        w = np.linalg.eigvalsh(S)
        np.testing.assert_allclose(symmetric_eigenvalues(S), w, rtol=0, atol=1e-13 * np.abs(w).max())


_TWO_THREADS = """
import json, threading
import scipy.linalg  # both BLAS libraries (numpy's, scipy's) loaded before the first count
import threadpoolctl
from hammerstein_ctrl._linalg import single_threaded_blas

def threads():
    return [lib["num_threads"] for lib in threadpoolctl.threadpool_info()]

before = threads()
a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()

def first():
    with single_threaded_blas():
        a_in.set()
        b_in.wait(10)
    a_out.set()

def second():
    a_in.wait(10)
    with single_threaded_blas():
        b_in.set()
        a_out.wait(10)

workers = [threading.Thread(target=first), threading.Thread(target=second)]
for w in workers:
    w.start()
for w in workers:
    w.join()
print(json.dumps({"before": before, "after": threads()}))
"""


def test_single_threaded_blas_restores_the_limits_after_two_threads():
    """Limits are process-wide but the bookkeeping is per thread: with thread A in, thread B in, A out,
    B out, B restores what it saw on entry (A's limit of 1) and the process stays single-threaded.

    Run in a child process with two BLAS threads (threadpoolctl gives OpenBLAS to one controlling
    thread at a time, so the scenario must not share this process's state)."""
    pytest.importorskip("threadpoolctl")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="2", OMP_NUM_THREADS="2")
    out = subprocess.run([sys.executable, "-c", _TWO_THREADS], capture_output=True, text=True, env=env,
                         check=True, timeout=300).stdout.strip().splitlines()[-1]
    r = json.loads(out)
    if not r["before"] or set(r["before"]) <= {1}:
        pytest.skip("no BLAS pool with more than one thread in the child")
    assert r["after"] == r["before"]


_FIRST_BLOCK_BEFORE_SCIPY = ("""
import json, sys
import numpy as np
from hammerstein_ctrl._linalg import single_threaded_blas
loaded = "scipy.linalg" in sys.modules
with single_threaded_blas():
    import threadpoolctl
    inside = {lib["filepath"]: lib["num_threads"] for lib in threadpoolctl.threadpool_info() """
                             """if lib["user_api"] == "blas"}
after = {lib["filepath"]: lib["num_threads"] for lib in threadpoolctl.threadpool_info() if lib["user_api"] == "blas"}
print(json.dumps({"loaded": loaded, "inside": inside, "after": after}))
""")


def test_single_threaded_blas_opened_before_scipy_linalg_also_holds_scipys_blas():
    """numpy and scipy wheels each bring their own OpenBLAS; a block opened before scipy.linalg was
    imported must still hold both (scipy's serves expm, lstsq and MINPACK's neighbours), and restore both."""
    pytest.importorskip("threadpoolctl")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="2", OMP_NUM_THREADS="2")
    r = json.loads(subprocess.run([sys.executable, "-c", _FIRST_BLOCK_BEFORE_SCIPY], capture_output=True, text=True,
                                  env=env, check=True, timeout=300).stdout.strip().splitlines()[-1])
    assert not r["loaded"]
    if set(r["after"].values()) <= {1}:
        pytest.skip("no BLAS pool with more than one thread in the child")
    assert len(r["inside"]) >= 2 and set(r["inside"].values()) == {1}, r
    assert r["after"] == {k: 2 for k in r["inside"]}, r


def _transfer_rows(rng, rows: int, n: int):
    """Stable-ish transfer functions of ``n`` poles as (num, den) rows, and the usual odd rows: a NaN, a zero
    leading coefficient, and a pole fast enough for scipy's exponential."""
    num = rng.standard_normal((rows, n))
    den = np.hstack([np.ones((rows, 1)), np.abs(rng.standard_normal((rows, n))) + 0.1])
    num[1, 0], den[2, 0], den[3, 1] = np.nan, 0.0, 1e4
    return np.ascontiguousarray(num), np.ascontiguousarray(den)


def test_the_discretisation_gives_scipys_exponential_and_flags_the_rows_it_cannot_take():
    """The compiled core's discretisation: scipy's exponential (independent oracle) for every usable row, the
    unusable rows (NaN, a zero leading coefficient) and those past the compiled Pade flagged."""
    from hammerstein_ctrl._linalg import tf_augmented, tf_discrete

    rng = np.random.default_rng(5)
    for n in (1, 2, 4):
        num, den = _transfer_rows(rng, 6, n)
        E, C, D, ok, big, clean = tf_discrete(num, den, 0.05, 64.0)
        assert ok.tolist() == [True, False, False, True, True, True]
        assert big.tolist() == [False, False, False, True, False, False]
        assert not clean
        M = tf_augmented(num[ok], den[ok], 0.05)[0]
        np.testing.assert_allclose(E[ok & ~big], scipy.linalg.expm(M[~big[ok]]), rtol=1e-12, atol=1e-14)
        assert tf_discrete(num[[0, 4]].copy(), den[[0, 4]].copy(), 0.05, 64.0)[5]      # usable rows: clean


def test_the_python_doors_refuse_shapes_the_c_code_would_read_past():
    """The C functions take sizes beside pointers: each Python door checks the shapes it passes, so a wrong one is
    a ValueError naming the argument, never a read or write past an array."""
    from hammerstein_ctrl._linalg import expm_into, fill_coefficients, one_norm, tf_augmented

    A = np.eye(3)
    with pytest.raises(ValueError, match="B must be a matrix of 3 rows"):
        solve_in_place(A, np.ones((2, 1)))
    with pytest.raises(ValueError, match="out must have shape \\(2, 2\\)"):
        expm_into(np.eye(2), np.empty((1, 1)))
    with pytest.raises(ValueError, match="S must be a square matrix"):
        symmetric_eigenvalues(np.ones(4))
    with pytest.raises(ValueError, match="M must be a square matrix"):
        one_norm(np.ones((2, 3)))
    with pytest.raises(ValueError, match="M must be a stack of square matrices"):
        expm_batch(np.ones((2, 3)))
    with pytest.raises(ValueError, match="num and den must be rows"):
        tf_augmented(np.ones((2, 1)), np.ones((1, 2)), 0.1)
    with pytest.raises(ValueError, match="positions \\[-1\\]"):
        fill_coefficients(np.ones((1, 2)), np.zeros(1), np.ones(2), np.array([-1]), np.array([1]))
