"""Review of 2322260..e6b5ac8 (16 lanes, output maps in the normal pass, the streamed QR factor).

Each test is a defect found by the review (they fail at e6b5ac8), except the
last, which checks that the factor route is actually taken (the test in
test_normal_equations.py passes with the route switched off).
Oracle: the cost's own value ``cost(x)`` and ``normal_equations``.
"""

import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl.objective import HammersteinCost


def _record(N, hold="foh"):
    rng = np.random.default_rng(0)
    u = np.repeat(rng.uniform(-2, 2, N // 30 + 1), 30)[:N]
    t = np.arange(N) * 0.01
    return hc.IOData(u, 0.01 * (np.sin(t) + 0.3), dt=0.01, intersample=hold)


def test_a_finite_point_with_a_nonfinite_neighbour_keeps_its_value():
    """Tanh with d1 = inf: g = d0 sign(u) and J is finite (cost 0.0163), but its neighbour d1 + h is NaN.
    The kernel poisons f when ANY lane's last signal is non-finite and normal_equations now books the
    point as inf (2322260 gave cost(x))."""
    cost = HammersteinCost(_record(7), hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh()))
    x = np.array([1.0, 2.0, 3.0, 1.5, np.inf])
    J = cost(x)
    assert np.isfinite(J)
    assert cost.normal_equations(x).fun == pytest.approx(J, rel=1e-12)


def test_normal_factor_of_a_finite_point_with_a_nonfinite_neighbour_keeps_its_value():
    """Saturation with limit = inf is linear (cost finite); normal_factor says inf (one NaN lane makes R all NaN)."""
    cost = HammersteinCost(_record(8193), hc.WienerStructure(hc.LinearStructure(1, 2), hc.Saturation()))
    x = np.array([1.0, 2.0, 3.0, 1.2, np.inf])
    J = cost(x)
    assert np.isfinite(J) and cost.normal_equations(x).fun == pytest.approx(J, rel=1e-12)
    assert cost.normal_factor(x).fun == pytest.approx(J, rel=1e-12)


@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_normal_factor_of_a_nonfinite_point_does_not_raise(value):
    """normal_equations(x) answers at a NaN / inf parameter; normal_factor raised ParameterError
    ('steps must be 5 finite, non-zero numbers'): its fallback passes the point's non-finite steps on."""
    cost = HammersteinCost(_record(8193), hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Tanh()))
    x = np.array([value, 2.0, 3.0, 1.5, 0.7])
    ne = cost.normal_equations(x)
    qr = cost.normal_factor(x)
    assert qr.fun == ne.fun or not np.isfinite(qr.fun)


def test_normal_factor_of_a_record_shorter_than_its_parameters():
    """Residual fallback (custom output map) on 3 samples, 4 parameters: np.linalg.qr gives a 3 x 5 R and
    from_factor raised ValueError('a factor of shape (3, 5) does not fit 4 steps')."""
    cubic = hc.CustomNonlinearity(lambda v, p: p[0] * v + p[1] * v ** 3, n_params=2)
    cost = HammersteinCost(_record(3), hc.WienerStructure(hc.LinearStructure(0, 2), cubic))
    x = np.array([2.0, 3.0, 1.5, 0.1])
    ne = cost.normal_equations(x)
    qr = cost.normal_factor(x)
    assert qr.fun == pytest.approx(ne.fun, rel=1e-12)
    np.testing.assert_allclose(qr.gram, ne.gram, rtol=1e-8, atol=1e-12 * np.abs(ne.gram).max())


def test_lm_past_minpack_max_bytes_takes_the_factor_route(emps_case, monkeypatch):
    """From EMPS's x0 the Gram matrix is ill-conditioned: past MINPACK_MAX_BYTES the passes must be
    normal_factor's, not MINPACK's (the existing test also passes when the route is switched off)."""
    from hammerstein_ctrl.optimize import least_squares as ls
    from hammerstein_ctrl.optimize import levenberg_marquardt

    calls = []
    original = HammersteinCost.normal_factor
    monkeypatch.setattr(HammersteinCost, "normal_factor", lambda self, *a: calls.append(1) or original(self, *a))
    monkeypatch.setattr(ls, "MINPACK_MAX_BYTES", 0)
    res = levenberg_marquardt(emps_case.cost, emps_case.x0)
    assert calls and res.success
    assert "MINPACK" not in res.message
