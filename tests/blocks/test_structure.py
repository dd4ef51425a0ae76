import control as ct
import numpy as np
import pytest

from hammerstein_ctrl import (
    Coulomb, HammersteinStructure, LinearStructure, ParameterError, Polynomial, Tanh,
)


def test_trs_and_emps_parameter_order_follows_eq14():
    trs = HammersteinStructure(LinearStructure(1, 2), Tanh())
    emps = HammersteinStructure(LinearStructure(0, 2, fixed={"a0": 0.0}), Coulomb())
    assert trs.param_names == ("b0", "a0", "a1", "d0", "d1")
    assert emps.param_names == ("a1", "d0", "d1", "d2")
    m = trs.model([-1.816, 0.118, 4.7681, -4.7132, 0.1229])
    np.testing.assert_allclose(m.linear.num[0][0], [1.0, -1.816])
    np.testing.assert_allclose(m.linear.den[0][0], [1.0, 4.7681, 0.118])
    np.testing.assert_allclose(m.params, [-4.7132, 0.1229])
    e = emps.model([3.14, 0.54, -0.4, 0.045])
    np.testing.assert_allclose(e.linear.den[0][0], [1.0, 3.14, 0.0])


def test_round_trip_through_transfer_function(rng):
    s = HammersteinStructure(LinearStructure(2, 4, monic_numerator=False), Polynomial(2))
    beta = rng.standard_normal(s.n_params)
    np.testing.assert_allclose(s.beta(s.model(beta)), beta, rtol=1e-12)
    # a non-monic denominator is normalised on the way back
    lin = LinearStructure(1, 2)
    H = ct.tf([2.0, 4.0], [2.0, 6.0, 8.0])
    np.testing.assert_allclose(lin.parameters(H), [2.0, 4.0, 3.0])


def test_fixed_and_monic_coefficients_are_checked():
    lin = LinearStructure(0, 2, fixed={"a0": 0.0})
    with pytest.raises(ParameterError, match="a0 = 2 but the structure fixes it to 0"):
        lin.parameters(ct.tf([1], [1, 3, 2]))
    with pytest.raises(ParameterError, match="monic numerator"):
        LinearStructure(1, 2).parameters(ct.tf([2, 1], [1, 3, 2]))
    with pytest.raises(ParameterError, match="denominator has degree 3"):
        LinearStructure(1, 2).parameters(ct.tf([1, 1], [1, 3, 2, 1]))
    with pytest.raises(ParameterError, match="unknown coefficient 'a5'"):
        LinearStructure(1, 2, fixed={"a5": 1.0})
    with pytest.raises(ParameterError, match="improper"):
        LinearStructure(3, 2)


def test_wrong_beta_length_names_the_parameters():
    s = HammersteinStructure(LinearStructure(0, 2, fixed={"a0": 0.0}), Coulomb())
    with pytest.raises(ParameterError, match=r"beta must have 4 entries \['a1', 'd0', 'd1', 'd2'\], got 5"):
        s.model([1, 2, 3, 4, 5])
    with pytest.raises(ParameterError, match="got 3"):
        s.check_beta(np.zeros((2, 3)))


def test_batched_coefficients_match_single(rng):
    lin = LinearStructure(1, 3, fixed={"a1": 0.5})
    thetas = rng.standard_normal((5, lin.n_params))
    num, den = lin.coefficients(thetas)
    for k, th in enumerate(thetas):
        H = lin.transfer_function(th)
        np.testing.assert_allclose(num[k], H.num[0][0])
        np.testing.assert_allclose(den[k], H.den[0][0])
    assert den[0, 2] == 0.5


def test_describe():
    s = HammersteinStructure(LinearStructure(1, 2), Tanh())
    assert s.describe() == "H(p) = (p + b0)/(p^2 + a1 p + a0); g = tanh(d0, d1)"
    e = LinearStructure(0, 2, fixed={"a0": 0.0})
    assert e.describe() == "(1)/(p^2 + a1 p)"


@pytest.mark.parametrize("args, kwargs, message", [
    (("a", 2), {}, "num_order must be a non-negative integer, got 'a'"),
    ((True, 2), {}, "num_order must be a non-negative integer, got True"),
    ((1, 2.5), {}, "den_order must be a non-negative integer, got 2.5"),
    ((1, float("nan")), {}, "den_order must be a non-negative integer"),
    ((1, 10**400), {}, "den_order must be a non-negative integer"),
    ((0, 2), {"fixed": {"a0": "x"}}, "fixed coefficient a0 must be numbers"),
    ((0, 2), {"fixed": {"a0": [1, 2]}}, "fixed coefficient a0 must be one number"),
])
def test_linear_structure_refuses_what_is_not_an_order(args, kwargs, message):
    from hammerstein_ctrl import LinearStructure

    with pytest.raises(ParameterError, match=message):
        LinearStructure(*args, **kwargs)


def test_the_coefficient_template_is_read_only():
    """Every evaluation hands the template to the C library unchecked: it cannot be changed from outside (a
    position written past the coefficients would be a write past an array)."""
    num0, den0, num_pos, den_pos = LinearStructure(1, 2).coefficient_template()
    for template in (num0, den0, num_pos, den_pos):
        with pytest.raises(ValueError, match="read-only"):
            template[...] = 0
