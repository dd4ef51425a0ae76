"""The presets against the oracles of the paper's TRS and EMPS cases."""

import pytest

from hammerstein_ctrl import ParameterError, UnknownNameError, presets


@pytest.mark.parametrize("beta, J, tol", [
    ([3.2870, 0.59130, -0.4448, 0.0486], 0.24480, 2e-5),     # N-SPSA, Table 8
    ([3.1626, 0.5485, -0.4019, 0.0457], 0.21067, 2e-5),      # AMVO-SCA, Table 8
    ([3.1102, 0.6361, -0.5352, 0.0552], 0.30002, 2e-5),      # NL-SPSA, Table 8
    ([3.138764, 0.544501, -0.398365, 0.045066], 0.208517, 2e-6),  # least-squares optimum
])
def test_emps_cost_oracles(emps_case, beta, J, tol):
    assert emps_case.cost(beta) == pytest.approx(J, abs=tol)


def test_emps_preset_contents(emps_case):
    assert len(emps_case.data) == 12000 and emps_case.data.dt == 0.001
    assert emps_case.x0.tolist() == [-1.0, 0.5, -0.4, 0.0]
    assert emps_case.cost(emps_case.x0) == pytest.approx(3.82e11, rel=1e-3)
    assert len(emps_case.validation()) == 12000


def test_trs_preset_contents(trs_case):
    assert trs_case.x0.tolist() == [-2.0, 0.0, 5.0, -5.0, 0.0]
    assert trs_case.cost(trs_case.true_beta) == pytest.approx(178.5, abs=1e-9)
    with pytest.raises(ParameterError, match="beta must have 5 entries"):
        trs_case.cost([1.0, 2.0])


def test_get_by_name_and_method_settings(trs_case):
    assert presets.get("TRS").name == "trs"
    with pytest.raises(UnknownNameError, match="unknown case 'cstr'"):
        presets.get("cstr")
    kw = trs_case.minimize_kwargs("N-SPSA")
    assert kw["method"] == "nspsa" and kw["maxiter"] == 1000
    with pytest.raises(UnknownNameError, match="unknown method 'pso'"):
        trs_case.minimize_kwargs("pso")
