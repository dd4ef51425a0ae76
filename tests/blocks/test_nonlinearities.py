import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import (Coulomb, CustomNonlinearity, DeadZone, ParameterError, PiecewiseLinear, Polynomial,
                              Saturation, Tanh, UnknownNameError, nonlinearity_from_name,)
from hammerstein_ctrl.blocks import NONLINEARITIES, Friction, Sigmoid

U = np.linspace(-2.0, 2.0, 41)

CASES = [
    (Tanh(), [-4.7, 0.12], lambda u: -4.7 * np.tanh(0.12 * u)),
    (Coulomb(), [0.54, -0.4, 0.045], lambda u: 0.54 * u - 0.4 * np.sign(u) + 0.045),
    (Polynomial(3), [1.0, -0.5, 0.25], lambda u: u - 0.5 * u**2 + 0.25 * u**3),
    (Saturation(), [2.0, 1.5], lambda u: 2.0 * np.clip(u, -1.5, 1.5)),
    (DeadZone(), [3.0, 0.5], lambda u: 3.0 * np.where(np.abs(u) > 0.5, u - 0.5 * np.sign(u), 0.0)),
    (PiecewiseLinear([-1.0, 0.0, 1.0]), [-2.0, 0.0, 1.0],
     lambda u: np.where(u < 0, 2.0 * u, u)),
    (Sigmoid(), [2.0, 3.0, 0.3], lambda u: 2.0 / (1.0 + np.exp(-3.0 * (u - 0.3)))),
    (Friction(), [-0.4, 0.05], lambda u: 0.4 * np.sign(u) + 0.05),
]


@pytest.mark.parametrize("g, p, ref", CASES, ids=lambda c: getattr(c, "name", None))
def test_values_match_closed_form(g, p, ref):
    np.testing.assert_allclose(g(U, p), ref(U), rtol=1e-14, atol=1e-14)


def test_every_registered_family_has_a_case_here():
    assert {type(g) for g, _, _ in CASES} == set(NONLINEARITIES.values())


@pytest.mark.parametrize("g, p, ref", CASES, ids=lambda c: getattr(c, "name", None))
def test_the_compiled_map_is_the_familys_formula(g, p, ref, rng):
    """The compiled core's map of a family (what the Wiener kernels and the loop simulators apply) gives the family's
    values, and NaN for NaN."""
    from hammerstein_ctrl import _core
    from hammerstein_ctrl._kernels import MAP_CODES

    z = np.r_[U, rng.normal(scale=3.0, size=50), np.nan]
    P = np.ascontiguousarray(np.atleast_2d(p), dtype=float)
    extra = np.ascontiguousarray(g.map_extra(), dtype=float)
    got = np.empty((1, z.size))
    assert _core.hc_map_rows(MAP_CODES[g.compiled_map], z, z.size, P, 1, P.shape[1], extra, extra.size, got) == 0
    np.testing.assert_allclose(got[0, :-1], g(z[:-1], p), rtol=1e-13, atol=1e-14)
    assert np.isnan(got[0, -1])


@pytest.mark.parametrize("g, p, ref", CASES, ids=lambda c: getattr(c, "name", None))
def test_closed_loop_simulator_uses_the_same_formula(g, p, ref):
    """The compiled loop (P control of g -> 1/(s + 1) under ZOH) against the same loop stepped in Python."""
    import control as ct

    from hammerstein_ctrl.simulate import simulate_loops

    model = hc.HammersteinModel(ct.tf([1.0], [1.0, 1.0]), g, p, intersample="zoh")
    dt, kp = 0.05, 0.8
    r = 1.5 * np.sin(np.arange(200) * dt)
    Y, U_ = simulate_loops(model, [[kp, 0.0, 0.0, 0.0]], r, dt)
    a, b = np.exp(-dt), 1.0 - np.exp(-dt)
    x, y_ref = 0.0, []
    for k in range(r.size):
        y_ref.append(x)
        x = a * x + b * float(g(np.array([kp * (r[k] - x)]), p)[0])
    np.testing.assert_allclose(Y[0], y_ref, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("g, p, ref", CASES, ids=lambda c: getattr(c, "name", None))
def test_batch_equals_rows(g, p, ref, rng):
    P = np.asarray(p) + 0.1 * rng.standard_normal((4, len(p)))
    out = g(U, P)
    assert out.shape == (4, U.size)
    for row, pr in zip(out, P):
        np.testing.assert_allclose(row, g(U, pr), rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("g, p, ref", CASES, ids=lambda c: getattr(c, "name", None))
def test_wrong_parameter_count_is_named(g, p, ref):
    with pytest.raises(ParameterError, match=f"takes {g.n_params} parameter"):
        g(U, list(p) + [1.0])
    with pytest.raises(ParameterError):
        g(U, 3.0)


@pytest.mark.parametrize("g, p, ref", CASES[:3], ids=lambda c: getattr(c, "name", None))
def test_derivative_matches_finite_difference(g, p, ref):
    u = np.array([-1.3, -0.4, 0.7, 1.9])
    h = 1e-6
    fd = (g(u + h, p) - g(u - h, p)) / (2 * h)
    np.testing.assert_allclose(g.derivative(u, p), fd, rtol=1e-6)


def test_polynomial_has_no_constant_term():
    g = Polynomial(4)
    assert g.param_names == ("d1", "d2", "d3", "d4")
    assert g(0.0, [1.0, 2.0, 3.0, 4.0]) == 0.0
    with pytest.raises(ParameterError):
        Polynomial(0)


def test_piecewise_linear_extrapolates_and_validates():
    g = PiecewiseLinear([0.0, 1.0])
    np.testing.assert_allclose(g([-1.0, 2.0], [1.0, 3.0]), [-1.0, 5.0])
    with pytest.raises(ParameterError, match="strictly increasing"):
        PiecewiseLinear([1.0, 0.0])


def test_custom_callable_scalar_and_vectorised():
    def f(u, p):
        return p[0] * u + p[1] * u**3

    g = CustomNonlinearity(f, n_params=2, param_names=["k", "c"])
    assert g.param_names == ("k", "c")
    P = np.array([[1.0, 0.5], [2.0, 0.0]])
    np.testing.assert_allclose(g(U, P), np.stack([f(U, P[0]), f(U, P[1])]))
    gv = CustomNonlinearity(lambda u, p: p[..., :1] * u, n_params=1, vectorized=True)
    assert gv(U, [[1.0], [2.0]]).shape == (2, U.size)
    with pytest.raises(ParameterError, match="takes 2 parameter"):
        g(U, [1.0])
    bad = CustomNonlinearity(lambda u, p: np.ones(3), n_params=1)
    with pytest.raises(ParameterError, match="returned shape"):
        bad(U, [1.0])


def test_lookup_by_name():
    assert isinstance(nonlinearity_from_name("TANH"), Tanh)
    assert nonlinearity_from_name("dead-zone").name == "deadzone"
    assert nonlinearity_from_name("polynomial", degree=2).n_params == 2
    with pytest.raises(UnknownNameError, match="unknown nonlinearity 'cubic'.*known: coulomb"):
        nonlinearity_from_name("cubic")


@pytest.mark.parametrize("g, p, ref", CASES, ids=lambda c: getattr(c, "name", None))
def test_basis_reproduces_evaluation_when_linear_in_parameters(g, p, ref, rng):
    phi = g.basis(U)
    if g.name in ("tanh", "saturation", "deadzone", "sigmoid", "friction"):
        assert phi is None
        return
    assert phi.shape == (g.n_params, U.size)
    P = np.asarray(p) + rng.standard_normal((3, len(p)))
    np.testing.assert_allclose(P @ phi, g(U, P), rtol=1e-13, atol=1e-13)


class _ShortBasis(hc.Polynomial):
    """A custom family whose basis leaves out its last row (the compiled passes read one row per parameter)."""

    def basis(self, u):
        return super().basis(u)[:-1]


class _ObjectBasis(hc.Polynomial):
    def basis(self, u):
        return np.array([[object()] * np.size(u)] * self.degree)


@pytest.mark.parametrize("family", [_ShortBasis(2), _ObjectBasis(2)])
def test_a_basis_of_the_wrong_shape_is_refused_before_any_pass(family):
    """A basis that is not one real row per parameter would be read past its rows by the compiled
    passes: the cost refuses it when built, naming the family and the shape it needs; identify too.
    (Found by the review of the compiled LM loop, predating it.)"""
    from hammerstein_ctrl.fit import HammersteinCost

    t = np.arange(200) * 0.01
    data = hc.IOData(np.sin(t), np.cos(t), dt=0.01, name="short basis")
    structure = hc.HammersteinStructure(hc.LinearStructure(0, 1), family)
    with pytest.raises(hc.ParameterError, match=r"basis\(u\) must give one row per parameter.*\(2, 1\)"):
        HammersteinCost(data, structure)
    with pytest.raises(hc.ParameterError, match=r"basis\(u\) must give one row per parameter"):
        hc.identify(data, structure, method="lm")
    assert hc.Polynomial(2).checked_basis(t).shape == (2, 200)


def _sigmoid_record(kind, seed):
    """A known-truth record made with python-control: sigmoid 2/(1 + e^{-3 (. - c)}) and (p + 2)/(p^2 + 1.4 p + 4)."""
    import control as ct

    rng = np.random.default_rng(seed)
    N, dt = 1500, 0.05
    t = np.arange(N) * dt
    u = np.repeat(rng.uniform(-2, 2, N // 20 + 1), 20)[:N]
    H = ct.tf([1.0, 2.0], [1.0, 1.4, 4.0])
    if kind == "hammerstein":
        y = ct.forced_response(H, t, 2.0 / (1.0 + np.exp(-3.0 * (u - 0.3)))).outputs
        truth = [2.0, 4.0, 1.4, 2.0, 3.0, 0.3]      # b0, a0, a1, d0, d1, d2
    else:
        y = 2.0 / (1.0 + np.exp(-3.0 * (ct.forced_response(H, t, u).outputs - 0.2)))
        truth = [2.0, 4.0, 1.4, 2.0, 3.0, 0.2]
    return hc.IOData(u, y + 0.01 * rng.standard_normal(N), dt=dt), np.array(truth)


@pytest.mark.parametrize("kind", ["hammerstein", "wiener"])
def test_sigmoid_family_is_identified_without_x0(kind):
    structure = (hc.HammersteinStructure if kind == "hammerstein" else hc.WienerStructure)(
        hc.LinearStructure(1, 2), Sigmoid())
    for seed in range(3):
        data, truth = _sigmoid_record(kind, seed)
        res = hc.identify(data, structure, seed=0)
        assert res.success, res.message
        se = np.sqrt(np.diag(res.covariance))
        assert np.all(np.abs(res.x - truth) <= 4 * se), (res.x, se)


def test_sigmoid_model_survives_saving(tmp_path):
    import control as ct

    m = hc.WienerModel(ct.tf([1.0], [1.0, 1.0]), Sigmoid(), [2.0, 3.0, 0.3])
    m.save(tmp_path / "m.json")
    back = hc.load_model(tmp_path / "m.json")
    t = np.arange(100) * 0.1
    np.testing.assert_array_equal(back.simulate(t, np.sin(t)), m.simulate(t, np.sin(t)))
