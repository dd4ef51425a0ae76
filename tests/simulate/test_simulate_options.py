"""Zero-order hold, initial state and output offset against scipy and python-control."""

import control as ct
import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from hammerstein_ctrl import HammersteinModel, IOData, Tanh
from hammerstein_ctrl._linalg import expm_batch
from hammerstein_ctrl.simulate import companion_realization, discretize, lsim, simulate_batch, sse_batch


def rel_max_err(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize("order", [1, 2, 3, 5, 10])
def test_zoh_and_initial_state_match_scipy(order, rng):
    t = np.arange(2000) * 0.01
    for _ in range(3):
        den = np.real(np.poly(-rng.uniform(0.3, 15.0, order)))
        num = rng.standard_normal(rng.integers(1, order + 2))
        A, B, C, D = (m[0] for m in companion_realization(num, den))
        sys = (A, B[:, None], C[None, :], [[D]])
        v = np.repeat(rng.standard_normal(t.size // 10), 10)
        x0 = rng.standard_normal(order)
        _, ref, _ = scipy.signal.lsim(sys, v, t, X0=x0, interp=False)
        assert rel_max_err(lsim((num, den), t, v, x0=x0, intersample="zoh"), ref) <= 1e-9
        ref_foh = ct.forced_response(ct.ss(*sys), t, v, X0=x0).outputs
        assert rel_max_err(lsim((num, den), t, v, x0=x0), ref_foh) <= 1e-9


def test_held_signal_zoh_equals_foh_on_a_fine_staircase():
    """A DAC's staircase: ZOH on the coarse samples equals FOH on a fine grid of the same staircase."""
    H = ct.tf([1.0, 2.0], [1.0, 0.6, 9.0])
    coarse = np.arange(400) * 0.05
    v = np.sign(np.sin(0.8 * coarse)) + 0.3 * np.cos(2.1 * coarse)
    fine = np.arange(400 * 50) * 0.001
    v_fine = np.repeat(v, 50)
    y_fine = ct.forced_response(H, fine, v_fine).outputs[::50]
    y_zoh = lsim(H, coarse, v, intersample="zoh")
    assert np.max(np.abs(y_zoh - y_fine)) < 2e-2 * np.max(np.abs(y_fine))  # FOH ramps in the fine grid's last step
    assert np.max(np.abs(y_zoh - y_fine)) < 0.1 * np.max(np.abs(lsim(H, coarse, v) - y_fine))


def test_batch_options_and_sse_agree_with_outputs(rng):
    num = np.array([[1.0, 2.0], [1.0, -1.0]])
    den = np.array([[1.0, 3.0, 2.0], [1.0, 0.5, 4.0]])
    V = rng.standard_normal((2, 500))
    x0 = rng.standard_normal((2, 2))
    off = np.array([0.5, -1.0])
    y = rng.standard_normal(500)
    for hold in ("foh", "zoh"):
        Y = simulate_batch(num, den, V, 0.01, x0=x0, offset=off, intersample=hold)
        J = sse_batch(num, den, V, 0.01, y, x0=x0, offset=off, intersample=hold)
        np.testing.assert_allclose(J, np.sum((y - Y) ** 2, axis=1), rtol=1e-12)
        for b in range(2):
            ref = lsim((num[b], den[b]), np.arange(500) * 0.01, V[b], x0=x0[b], intersample=hold) + off[b]
            np.testing.assert_allclose(Y[b], ref, rtol=1e-13, atol=1e-13)


def test_model_simulate_honours_record_intersample_offset_and_state():
    m = HammersteinModel(ct.tf([1.0], [1.0, 1.0, 4.0]), Tanh(), [2.0, 0.5], offset=0.3,
                         initial_state=[0.2, -0.1])
    t = np.arange(1000) * 0.01
    u = np.repeat(np.sin(np.arange(100)), 10)
    A, B, C, D = (x[0] for x in companion_realization([1.0], [1.0, 1.0, 4.0]))
    _, ref, _ = scipy.signal.lsim((A, B[:, None], C[None, :], [[D]]), 2 * np.tanh(0.5 * u), t,
                                  X0=[0.2, -0.1], interp=False)
    y = m.simulate(IOData(u, np.zeros_like(u), t, intersample="zoh"))
    assert rel_max_err(y - 0.3, ref) <= 1e-9
    np.testing.assert_allclose(m.to_ss().A, A)
    assert m.simulate(t, u, initial_state=[0, 0])[0] == pytest.approx(0.3)


def test_discretize_zoh_matches_scipy_cont2discrete():
    A = np.array([[-0.6, -9.0], [1.0, 0.0]])
    B = np.array([1.0, 0.0])
    Ad, Bd0, Bd1 = discretize(A, B, 0.05, "zoh")
    ref = scipy.signal.cont2discrete((A, B[:, None], np.eye(2), np.zeros((2, 1))), 0.05, "zoh")
    np.testing.assert_allclose(Ad[0], ref[0], rtol=1e-13)
    np.testing.assert_allclose(Bd0[0], ref[1][:, 0], rtol=1e-13)
    assert not np.any(Bd1)


def test_compiled_expm_matches_scipy(rng):
    for m in (2, 3, 4, 6, 10):
        M = rng.standard_normal((20, m, m)) * rng.uniform(1e-4, 2.0, (20, 1, 1))
        E, R = expm_batch(M), scipy.linalg.expm(M)
        assert np.max(np.linalg.norm(E - R, axis=(1, 2)) / np.linalg.norm(R, axis=(1, 2))) < 1e-12
    assert np.all(np.isnan(expm_batch(np.full((1, 2, 2), np.inf))))


