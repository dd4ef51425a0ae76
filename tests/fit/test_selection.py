"""selection.py: structure selection picks the true order and family of known-truth records, flags over-ordering."""

from __future__ import annotations

import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl.exceptions import ParameterError
from hammerstein_ctrl.fit._selection import CRITERIA, candidate_structures, information_criterion, select_structure
from _truths import make_case

#: Known-truth records (python-control) and a wrong family to offer beside the true one.
RECORDS = {
    "tanh_rhp_zero": hc.Polynomial(3),
    "saturation_first_order_10pct": hc.Polynomial(3),
    "deadzone_third_order": hc.Polynomial(3),
    "cubic_resonance_zeta005": hc.DeadZone(),
    "coulomb_integrator": hc.Tanh(),
}


def _candidates(structure, wrong):
    lin = structure.linear
    bigger = hc.LinearStructure(min(lin.num_order + 1, lin.den_order + 1), lin.den_order + 1, fixed={
        k: v for k, v in lin.fixed.items() if k != f"b{lin.num_order}"})
    families = [structure.input_nonlinearity, wrong]
    return [hc.HammersteinStructure(b, g) for b in (lin, bigger) for g in families]


@pytest.mark.parametrize("name", sorted(RECORDS))
def test_the_true_order_and_family_win_and_over_ordering_is_flagged(name):
    data, structure, _, _ = make_case(name, 0)
    sel = select_structure(data, _candidates(structure, RECORDS[name]), criterion="bic", executor="serial",
                           maxfev=1500)
    assert sel.best.structure.describe() == structure.describe()
    assert sel.table[0]["success"] and not sel.table[0]["over_ordered"]
    bigger_true = next(r for r in sel.table
                       if r["n_params"] == structure.n_params + 2
                       and structure.input_nonlinearity.name in r["structure"])
    assert bigger_true["over_ordered"] or not bigger_true["success"], bigger_true
    assert [r["rank"] for r in sel.table] == list(range(1, 5))


def test_the_criteria_are_the_textbook_formulas():
    n, p, sse = 500, 4, 3.2
    assert information_criterion("aic", sse, n, p) == pytest.approx(n * np.log(sse / n) + 2 * p)
    assert information_criterion("bic", sse, n, p) == pytest.approx(n * np.log(sse / n) + p * np.log(n))
    assert information_criterion("fpe", sse, n, p) == pytest.approx(sse / n * (n + p) / (n - p))
    assert information_criterion("aic", np.inf, n, p) == np.inf


def test_validation_ranks_by_the_fit_on_another_record_and_renders():
    data, structure, _, _ = make_case("tanh_rhp_zero", 0)
    other, _, _, _ = make_case("tanh_rhp_zero", 1)
    cands = candidate_structures([(1, 2), (0, 1)], [hc.Tanh()])
    sel = select_structure(data, cands, validation=other, criterion="validation", executor="serial")
    fits = [r["validation_fit"] for r in sel.table]
    assert fits == sorted(fits, reverse=True) and fits[0] > 95
    frame = sel.to_frame()
    assert list(frame.columns[:3]) == ["structure", "n_params", "J"] and frame.attrs["criterion"] == "validation"
    assert "<table>" in sel._repr_html_() and "ranked by validation" in sel.summary()


def test_candidates_combine_orders_families_and_kinds():
    cands = candidate_structures([(0, 1), (1, 2)], [hc.Tanh(), hc.DeadZone()],
                                 kinds=("hammerstein", "wiener", "hammerstein-wiener"),
                                 output_nonlinearities=[hc.Saturation()])
    kinds = [c.kind for c in cands]
    assert kinds.count("hammerstein") == 4 and kinds.count("wiener") == 2 and kinds.count("hammerstein-wiener") == 4


@pytest.mark.parametrize("kwargs, message", [
    ({"criterion": "r2"}, "criterion must be one of"),
    ({"criterion": "validation"}, "needs a validation record"),
])
def test_bad_arguments_are_refused(trs_case, kwargs, message):
    with pytest.raises(ParameterError, match=message):
        select_structure(trs_case.data, [trs_case.structure], **kwargs)
    with pytest.raises(ParameterError, match="non-empty sequence of structures"):
        select_structure(trs_case.data, ["tanh"])
    assert set(CRITERIA) == {"aic", "bic", "fpe", "validation"}


@pytest.mark.parametrize("name", sorted(RECORDS))
def test_validation_picks_the_true_order_and_family_as_bic_does(name):
    """The same five records as the information criteria: ranked by their fit on a second record of the
    truth (other input, other noise), the true structure wins."""
    data, structure, _, _ = make_case(name, 0)
    other, _, _, _ = make_case(name, 1)
    sel = select_structure(data, _candidates(structure, RECORDS[name]), validation=other, criterion="validation",
                           executor="serial", maxfev=1500)
    assert sel.best.structure.describe() == structure.describe(), sel.table
