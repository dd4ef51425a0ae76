"""Wiener and Hammerstein-Wiener structures (issue 13) against independent oracles.

Every record and every reference output is generated without the package's
simulator: the static blocks are plain numpy, the linear block is simulated by
``control.forced_response`` (first-order hold) or
``scipy.signal.lsim(..., interp=False)`` (zero-order hold) on the controllable
canonical realisation written out in ``tests/_truths.py``.
"""

from __future__ import annotations

import control as ct
import numpy as np
import pytest
import scipy.signal

from hammerstein_ctrl import (Coulomb, CustomNonlinearity, DeadZone, HammersteinWienerModel, HammersteinWienerStructure,
                              IOData, LinearStructure, ParameterError, Polynomial, Saturation, Tanh, WienerModel,
                              WienerStructure, identify, load_result, read_record,)
from hammerstein_ctrl.cli import main
from hammerstein_ctrl.exceptions import HammersteinError
from hammerstein_ctrl.fit import HammersteinCost

from _truths import DT, J_SLACK, K_SIGMA, companion, multilevel_prbs, multisine, standard_errors

#: Relative agreement of the simulators with python-control / scipy.
SIM_RTOL = 1e-9


def saturation(z, gain, limit):
    return gain * np.clip(z, -limit, limit)


def dead_zone(u, width):
    return u - np.clip(u, -width, width)


def oracle(num, den, v, hold="foh", x0=None):
    """``H v`` on the grid ``k DT`` from the written-out realisation (python-control / scipy)."""
    A, B, C, D = companion(num, den)
    t = np.arange(v.size) * DT
    x0 = np.zeros(A.shape[0]) if x0 is None else np.asarray(x0, float)
    if hold == "zoh":
        return scipy.signal.lsim((A, B, C, D), v, t, X0=x0, interp=False)[1]
    return ct.forced_response(ct.ss(A, B, C, D), t, v, X0=x0).outputs


# -- known truth: name -> structure, true beta, y = f(u) in numpy, input, noise ---------------
#: Wiener: H = 1/(p^2 + 1.5 p + 2), a sensor that clips at |z| = 0.35 with gain 2.
WIENER_TRUTH = dict(
    structure=WienerStructure(LinearStructure(0, 2), Saturation()), beta=[2.0, 1.5, 2.0, 0.35],
    num=[1.0], den=[1.0, 1.5, 2.0], g=lambda u: u, h=lambda z: saturation(z, 2.0, 0.35),
    u=lambda r: multisine(r, 1.5), noise=0.01)
#: Hammerstein-Wiener: dead zone of width 0.3 (gain 1 by convention), H = 1/(p^2 + 2 p + 4),
#: output saturation of gain 3 at |z| = 0.25.
HW_TRUTH = dict(
    structure=HammersteinWienerStructure(LinearStructure(0, 2), DeadZone(), Saturation()),
    beta=[4.0, 2.0, 0.3, 3.0, 0.25], num=[1.0], den=[1.0, 2.0, 4.0], g=lambda u: dead_zone(u, 0.3),
    h=lambda z: saturation(z, 3.0, 0.25), u=lambda r: multilevel_prbs(r, 2.0), noise=0.01)
TRUTHS = {"wiener_sensor_limit": WIENER_TRUTH, "hw_deadzone_saturation": HW_TRUTH}


def make_record(spec, seed=0, name="truth"):
    rng = np.random.default_rng(seed)
    u = spec["u"](rng)
    y = spec["h"](oracle(spec["num"], spec["den"], spec["g"](u)))
    y = y + spec["noise"] * np.std(y) * rng.standard_normal(y.size)
    return IOData(u, y, dt=DT, name=name)


@pytest.fixture(scope="module")
def fits():
    """One identification per known-truth system, shared by the tests below."""
    out = {}
    for name, spec in TRUTHS.items():
        data = make_record(spec, name=name)
        out[name] = (data, identify(data, spec["structure"]))
    return out


def parameter_errors(name, fits):
    """``(|estimate - truth|, standard errors, cost, truth)`` of one known-truth fit."""
    spec = TRUTHS[name]
    data, res = fits[name]
    cost = HammersteinCost(data, spec["structure"])
    truth = spec["structure"].normalize(np.array(spec["beta"], float))
    return np.abs(res.x - truth), standard_errors(cost, res.x), cost, truth


@pytest.mark.parametrize("name", sorted(TRUTHS))
def test_known_truth_recovered_without_x0(name, fits):
    _, res = fits[name]
    err, se, cost, truth = parameter_errors(name, fits)
    assert res.success, res.message
    assert res.fun <= cost(truth) * (1 + J_SLACK), (res.fun, cost(truth))
    names = TRUTHS[name]["structure"].param_names
    assert np.all(err <= K_SIGMA * se + 1e-9), dict(zip(names, (err / se).round(2)))


def test_the_truths_exercise_their_nonlinearities():
    """Guard the oracles: the output limit and the dead zone are active on a good share of the samples."""
    for spec, threshold in ((WIENER_TRUTH, 0.35), (HW_TRUTH, 0.25)):
        u = spec["u"](np.random.default_rng(0))
        z = oracle(spec["num"], spec["den"], spec["g"](u))
        assert 0.1 < np.mean(np.abs(z) > threshold) < 0.6
    u = HW_TRUTH["u"](np.random.default_rng(0))
    assert 0.05 < np.mean(np.abs(u) <= 0.3) < 0.5


# -- simulation agreement --------------------------------------------------------------------
def wiener_model(**kw):
    return WienerModel(ct.tf([1.0, 0.7], [1.0, 1.5, 2.0]), Tanh(), [1.3, 0.9], **kw)


def hw_model(**kw):
    return HammersteinWienerModel(ct.tf([1.0], [1.0, 2.0, 4.0]), DeadZone(), [1.0, 0.3], Saturation(), [3.0, 0.25],
                                  **kw)


@pytest.mark.parametrize("hold", ["foh", "zoh"])
@pytest.mark.parametrize("which", ["wiener", "hw"])
def test_simulate_equals_forced_response_then_h(which, hold):
    rng = np.random.default_rng(3)
    u = multisine(rng, 1.8)
    if which == "wiener":
        model, g, h = wiener_model(), (lambda u: u), (lambda z: 1.3 * np.tanh(0.9 * z))
        num, den = [1.0, 0.7], [1.0, 1.5, 2.0]
    else:
        model, g, h = hw_model(), (lambda u: dead_zone(u, 0.3)), (lambda z: saturation(z, 3.0, 0.25))
        num, den = [1.0], [1.0, 2.0, 4.0]
    t = np.arange(u.size) * DT
    if hold == "foh":  # python-control's own transfer function path as well
        z_ct = ct.forced_response(ct.tf(num, den), t, g(u)).outputs
        np.testing.assert_allclose(z_ct, oracle(num, den, g(u)), rtol=0, atol=1e-12 * np.max(np.abs(z_ct)))
    expected = h(oracle(num, den, g(u), hold))
    y = model.simulate(t, u, intersample=hold)
    assert np.max(np.abs(y - expected)) <= SIM_RTOL * np.max(np.abs(expected))


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_cost_batch_matches_single_evaluations_and_the_oracle(hold):
    spec = HW_TRUTH
    rng = np.random.default_rng(1)
    u = spec["u"](rng)
    y = spec["h"](oracle(spec["num"], spec["den"], spec["g"](u), hold)) + 0.01 * rng.standard_normal(u.size)
    data = IOData(u, y, dt=DT, intersample=hold)
    cost = HammersteinCost(data, spec["structure"])
    betas = np.array(spec["beta"]) * (1 + 0.1 * rng.standard_normal((7, 5)))
    batch = cost.batch(betas)
    singles = np.array([cost(b) for b in betas])
    np.testing.assert_allclose(batch, singles, rtol=1e-12)
    for b, j in zip(betas, batch):  # each candidate against python-control / scipy
        yhat = saturation(oracle([1.0], [1.0, b[1], b[0]], dead_zone(u, b[2]), hold), b[3], b[4])
        assert abs(j - np.sum((y - yhat) ** 2)) <= 1e-8 * j


# -- gain convention -------------------------------------------------------------------------
def test_identified_hw_model_respects_the_gain_convention(fits):
    _, res = fits["hw_deadzone_saturation"]
    model, structure = res.model, HW_TRUTH["structure"]
    assert isinstance(model, HammersteinWienerModel)
    assert model.input_params[model.input_nonlinearity.gain_index] == 1.0
    num = np.trim_zeros(np.asarray(model.linear.num[0][0], float), "f")
    den = np.trim_zeros(np.asarray(model.linear.den[0][0], float), "f")
    assert num[0] / den[0] == 1.0
    np.testing.assert_array_equal(structure.beta(model), res.x)
    np.testing.assert_array_equal(structure.beta(structure.model(res.x)), res.x)


def test_structure_refuses_an_input_gain_other_than_one():
    structure = HW_TRUTH["structure"]
    model = HammersteinWienerModel(ct.tf([1.0], [1.0, 2.0, 4.0]), DeadZone(), [2.0, 0.3], Saturation(), [1.5, 0.25])
    with pytest.raises(ParameterError, match="gain .*must be 1"):
        structure.beta(model)
    # the same system with the gain moved to the output block is accepted
    t = np.arange(2000) * DT
    u = multisine(np.random.default_rng(0), 2.0)[:2000]
    # h(z) = 1.5 clip(2 z', 0.25) = 3 clip(z', 0.125): both blocks describe one system
    moved = HammersteinWienerModel(ct.tf([1.0], [1.0, 2.0, 4.0]), DeadZone(), [1.0, 0.3], Saturation(),
                                   [3.0, 0.125])
    np.testing.assert_allclose(moved.simulate(t, u), model.simulate(t, u), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(structure.beta(moved), [4.0, 2.0, 0.3, 3.0, 0.125])


def test_structure_refuses_a_non_monic_numerator():
    structure = WienerStructure(LinearStructure(0, 2), Saturation())
    model = WienerModel(ct.tf([2.0], [1.0, 1.5, 2.0]), Saturation(), [2.0, 0.35])
    with pytest.raises(ParameterError, match="b0 = 2 but the structure fixes it to 1"):
        structure.beta(model)


def test_hw_parameter_names_of_coulomb_and_polynomial_do_not_clash():
    """Coulomb input (d0 fixed, d1, d2 free) with a polynomial output (d1, d2, d3) must be buildable."""
    lin = LinearStructure(0, 2, fixed={"a0": 0.0})
    s = HammersteinWienerStructure(lin, Coulomb(), Polynomial(3))
    assert s.n_params == 6 and len(set(s.param_names)) == 6
    assert s.param_names == ("a1", "g_d1", "g_d2", "h_d1", "h_d2", "h_d3")


# -- python-control exports ------------------------------------------------------------------
@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_wiener_to_iosys_dt_matches_simulate(hold):
    model = wiener_model(intersample=hold, offset=0.2, initial_state=[0.3, -0.1])
    u = multisine(np.random.default_rng(5), 1.5)[:1500]
    t = np.arange(u.size) * DT
    sys = model.to_iosys(dt=DT)
    y_io = ct.input_output_response(sys, t, u).outputs  # default X0 = 0: the model's own x(0)
    y = model.simulate(t, u)
    assert np.max(np.abs(y_io - y)) <= SIM_RTOL * np.max(np.abs(y))
    # and it is the Wiener model, not a Hammerstein one: h acts on the samples of H's output
    z = oracle([1.0, 0.7], [1.0, 1.5, 2.0], u, hold, x0=[0.3, -0.1])
    np.testing.assert_allclose(y, 1.3 * np.tanh(0.9 * z) + 0.2, rtol=0, atol=SIM_RTOL * np.max(np.abs(y)))


@pytest.mark.parametrize("u0", [0.0, 0.8])
def test_wiener_linearize_is_h_prime_times_h(u0):
    H = ct.tf([1.0, 0.7], [1.0, 1.5, 2.0])
    model = WienerModel(H, Polynomial(3), [1.0, -0.4, 0.3])
    z0 = 0.35 * u0  # steady state H(0) u0
    eps = 1e-5
    h = lambda z: z - 0.4 * z**2 + 0.3 * z**3  # noqa: E731
    slope = (h(z0 + eps) - h(z0 - eps)) / (2 * eps)
    lin = model.linearize(u0)
    for w in (0.0, 0.3, 2.0, 20.0):
        expected = slope * complex(H(1j * w))
        assert abs(complex(lin(1j * w)) - expected) <= 1e-8 * abs(expected)


def test_wiener_linearize_with_an_integrator_needs_z0():
    model = WienerModel(ct.tf([1.0], [1.0, 3.0, 0.0]), Polynomial(3), [1.0, -0.4, 0.3])
    with pytest.raises(ParameterError, match="z0"):
        model.linearize(0.5)
    eps, z0 = 1e-5, 0.2
    h = lambda z: z - 0.4 * z**2 + 0.3 * z**3  # noqa: E731
    slope = (h(z0 + eps) - h(z0 - eps)) / (2 * eps)
    lin = model.linearize(0.5, z0=z0)
    assert abs(complex(lin(2j)) - slope * complex(model.linear(2j))) <= 1e-8 * abs(slope * complex(model.linear(2j)))


# -- CLI ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, extra, model_type", [
    ("wiener_sensor_limit", [], WienerModel),
    ("hw_deadzone_saturation", ["--nonlinearity", "deadzone"], HammersteinWienerModel),
])
def test_cli_identifies_block_structures(name, extra, model_type, tmp_path, capsys):
    data = make_record(TRUTHS[name], name=name)
    csv = data.to_csv(tmp_path / f"{name}.csv")
    out = tmp_path / "result.json"
    code = main(["identify", "--data", str(csv), "--orders", "0", "2", *extra,
                 "--output-nonlinearity", "saturation", "--out", str(out)])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    saved = load_result(out)
    assert type(saved.model) is model_type
    assert saved.structure.param_names == TRUTHS[name]["structure"].param_names
    np.testing.assert_allclose(saved.structure.beta(saved.model), saved.x, rtol=1e-12)
    # the loaded model reproduces the stored fit on the record
    back = read_record(csv)
    np.testing.assert_allclose(back.y, data.y, rtol=1e-12)
    cost = HammersteinCost(back, saved.structure)
    assert cost(saved.x) == pytest.approx(saved.fun, rel=1e-9)
    yhat = saved.model.simulate(back)
    assert np.sum((back.y - yhat) ** 2) == pytest.approx(saved.fun, rel=1e-9)
    # and it is the truth to within a few per cent (the statistical test is above)
    np.testing.assert_allclose(saved.x, TRUTHS[name]["beta"], rtol=0.05)


@pytest.mark.parametrize("order", [2, 9])       # 2: compiled output map; 9: numpy map after the recursion
def test_wiener_with_a_nan_saturation_limit_scores_inf_on_every_route(order):
    """A NaN saturation limit gives NaN outputs in numpy (np.clip) but is ignored by the compiled
    output map (min/max drop NaN), so for n <= 8 the cost is finite (the unsaturated value)."""
    t = 0.01 * np.arange(800)
    data = IOData(np.sin(3 * t), 0.3 * np.cos(2 * t), dt=0.01)
    structure = WienerStructure(LinearStructure(0, order), Saturation())
    den = np.poly(-np.arange(1.0, order + 1))[::-1][:order]          # stable, poles -1 .. -n
    beta = np.r_[den, 2.0 * np.prod(np.arange(1.0, order + 1)), np.nan]
    cost = HammersteinCost(data, structure)
    assert cost(beta) == np.inf
    assert cost.batch(np.vstack([beta] * 3)).tolist() == [np.inf] * 3
    assert np.isnan(cost.simulate(beta)).any()


def test_wiener_with_a_parameterless_custom_output_map():
    """WienerStructure accepts a CustomNonlinearity with no parameters, but every cost evaluation then
    failed inside numpy ('cannot reshape array of size 0 into shape (0)').  Either the structure is refused
    with a clear error, or its cost is the sum of squares of y - h(H u), simulated here by python-control."""
    h = CustomNonlinearity(lambda v, p: np.tanh(v), 0)
    try:
        structure = WienerStructure(LinearStructure(0, 2), h)
    except HammersteinError:
        return
    t = 0.01 * np.arange(2000)
    u = np.sin(t) + 0.5 * np.sin(3.3 * t)
    y = np.cos(t)
    cost = HammersteinCost(IOData(u, y, dt=0.01), structure)
    x = np.array([2.0, 3.0])                        # H = 1 / (p^2 + 3 p + 2)
    assert structure.param_names == ("a0", "a1")
    expected = np.tanh(ct.forced_response(ct.tf([1.0], [1.0, 3.0, 2.0]), t, u).outputs)
    assert cost(x) == pytest.approx(float(np.sum((y - expected) ** 2)), rel=1e-6)
