import warnings

import control as ct
import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import Coulomb, HammersteinModel, ParameterError, Tanh


@pytest.fixture
def trs_model():
    return HammersteinModel(ct.tf([1, -1.816], [1, 4.7681, 0.118]), Tanh(), [-4.7132, 0.1229])


@pytest.mark.slow
def test_iosys_agrees_with_sampled_semantics_for_smooth_input(trs_model):
    """ODE view (g on the interpolated u) vs sampled view (interpolated g(u)): equal for smooth data."""
    sys = trs_model.to_iosys()
    assert isinstance(sys, ct.NonlinearIOSystem)
    assert sys.ninputs == 1 and sys.noutputs == 1 and sys.nstates == 2
    t = np.arange(0, 60, 0.05)
    u = 2.0 * np.sin(0.3 * t) + 0.5 * np.sin(1.1 * t)
    ode = ct.input_output_response(sys, t, u, solve_ivp_kwargs={"rtol": 1e-10, "atol": 1e-12}).outputs
    sampled = trs_model.simulate(t, u)
    assert np.max(np.abs(ode - sampled)) / np.max(np.abs(sampled)) < 1e-4


def test_iosys_differs_slightly_for_sign_nonlinearity():
    """Documented difference: sign(u) switches at the crossing in the ODE view, at samples otherwise."""
    m = HammersteinModel(ct.tf([1], [1, 3.0, 0.0]), Coulomb(), [0.5, -0.4, 0.05])
    t = np.arange(0, 4, 0.01)
    u = np.sin(2.0 * t)
    ode = ct.input_output_response(m.to_iosys(), t, u, solve_ivp_kwargs={"rtol": 1e-9, "atol": 1e-12,
                                                                         "max_step": 0.005}).outputs
    rel = np.max(np.abs(ode - m.simulate(t, u))) / np.max(np.abs(ode))
    assert 1e-6 < rel < 2e-2


def test_closed_loop_with_pid_matches_linearised_loop_for_small_signals():
    """The NonlinearIOSystem wires into a PID loop; small signals follow the linearised loop."""
    model = HammersteinModel(ct.tf([1], [1, 3.14, 0]), Tanh(), [2.0, 0.5])
    pid = ct.tf([1.0, 2.0, 0.5], [0.01, 1.0, 0.0], inputs="e", outputs="u")  # filtered PID
    err = ct.summing_junction(inputs=["r", "-y"], output="e")
    loop = ct.interconnect([err, pid, model.to_iosys()], inputs="r", outputs="y")
    assert loop.nstates == 4  # 2 plant + 2 controller states
    t = np.arange(0, 20, 0.01)
    r = np.full(t.size, 1e-3)
    nonlinear = ct.input_output_response(loop, t, r, solve_ivp_kwargs={"rtol": 1e-9, "atol": 1e-12}).outputs
    linear = ct.forced_response(ct.feedback(ct.tf([1.0, 2.0, 0.5], [0.01, 1.0, 0.0]) * model.linearize(0.0)),
                                t, r).outputs
    assert np.max(np.abs(nonlinear - linear)) < 1e-3 * np.max(np.abs(linear))
    assert abs(linear[-1] - 1e-3) < 1e-5  # and the loop does track


def test_linearize_is_slope_times_H(trs_model):
    for u0 in (0.0, 0.8):
        lin = trs_model.linearize(u0)
        slope = (trs_model.g(u0 + 1e-6) - trs_model.g(u0 - 1e-6)) / 2e-6
        assert isinstance(lin, ct.TransferFunction)
        np.testing.assert_allclose(ct.dcgain(lin), slope * ct.dcgain(trs_model.linear), rtol=1e-8)


def test_model_validation():
    with pytest.raises(ParameterError, match="continuous-time"):
        HammersteinModel(ct.tf([1], [1, 0.5], dt=0.1), Tanh(), [1, 1])
    with pytest.raises(ParameterError, match="tanh nonlinearity takes 2 parameter"):
        HammersteinModel(ct.tf([1], [1, 1]), Tanh(), [1, 1, 1])
    with pytest.raises(ParameterError, match="proper"):
        HammersteinModel(ct.tf([1, 0, 0], [1, 1]), Tanh(), [1, 1])
    m = HammersteinModel(ct.ss(ct.tf([1], [1, 2])), Tanh(), [1, 1])
    assert isinstance(m.linear, ct.TransferFunction) and m.is_stable()
    assert "tanh(d0=1, d1=1)" in repr(m)


# -- numerical extremes and bad arguments --------------------------------------------------------------------
def test_a_diverging_simulation_warns_where_and_why():
    from hammerstein_ctrl import SimulationWarning

    model = HammersteinModel(ct.tf([1], [1, -50, 0]), Coulomb(), [1.0, 0.0, 0.0])
    t = np.arange(0, 100, 0.01)
    with pytest.warns(SimulationWarning, match=r"not finite from sample \d+ .*unstable \(pole\(s\) 50"):
        y = model.simulate(t, np.ones_like(t))
    assert not np.isfinite(y[-1])
    stable = HammersteinModel(ct.tf([1], [1, 3, 0]), Coulomb(), [1.0, 0.0, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stable.simulate(t, np.ones_like(t))


@pytest.mark.parametrize("build, message", [
    (lambda: HammersteinModel(ct.tf([1], [1, 1]), Tanh(), [10**400, 1.0]), "too large for a float"),
    (lambda: HammersteinModel(ct.tf([1], [1, 1]), Tanh(), [1.0, 1.0], offset=10**400), "too large for a float"),
    (lambda: HammersteinModel(ct.tf([1], np.ones(12)), Tanh(), [1.0, 1.0]), "has order 11; at most 10"),
    (lambda: HammersteinModel(ct.tf([1], [1, 1]), Tanh(), ["a", 1.0]), "must be numbers"),
    (lambda: HammersteinModel(ct.tf([1], [1, 1]), Tanh(), [1.0, 1.0]).to_iosys(dt=True), "dt must be a positive"),
    (lambda: HammersteinModel(ct.tf([1], [1, 1]), Tanh(), [1.0, 1.0]).to_iosys(dt=-0.1), "dt must be a positive"),
])
def test_bad_model_arguments_raise_parameter_errors(build, message):
    with pytest.raises(ParameterError, match=message):
        build()


def test_export_refuses_a_signal_name_python_control_cannot_take():
    model = hc.HammersteinModel(([1.0], [1.0, 1.0]), hc.Tanh(), [1.0, 1.0])
    with pytest.raises(hc.ParameterError, match="input name 'motor.voltage' contains '.'.*'motor_voltage'"):
        model.to_iosys(inputs="motor.voltage")
    mimo = hc.MIMOModel([[[1.0], [2.0]]], [[1.0, 1.0]], input_names=["motor.a", "motor.b"])
    with pytest.raises(hc.ParameterError, match="input name 'motor.a' contains '.'"):
        mimo.to_iosys()
    assert model.to_iosys(inputs="motor_voltage").input_labels == ["motor_voltage"]
