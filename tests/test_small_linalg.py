"""The compiled small dense linear algebra of :mod:`hammerstein_ctrl._linalg` against numpy and scipy."""

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
