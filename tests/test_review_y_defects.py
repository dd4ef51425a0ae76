"""Review of 197c61c (status 5, BUDGET_EXHAUSTED): one failing test per defect found.

Oracles: the unlimited run of the same deterministic optimiser (its nfev, nit and x), scipy's
own stop, the code's own output against the text committed in the README and notebook 01,
and the parent commit's results-file record (rebuilt here field by field as 8c2b3cb wrote it:
status 0, success True, nit = nfev, message "evaluation budget of N exhausted").
"""

import json
import re
from pathlib import Path

import numpy as np
import pytest

from hammerstein_ctrl.auto import auto_minimize
from hammerstein_ctrl.optimize import BUDGET_EXHAUSTED, COMPLETED, levenberg_marquardt, minimize

ROOT = Path(__file__).resolve().parents[1]


def _rosenbrock(x):
    return float(100.0 * (x[1] - x[0] ** 2) ** 2 + (1.0 - x[0]) ** 2)


@pytest.mark.parametrize("method", ["nelder-mead", "powell"])
def test_nelder_mead_and_powell_stopped_by_maxfev_report_budget_exhausted(method):
    """Nelder-Mead and Powell stopped by our maxfev say SOLVER_FAILED (4), not BUDGET_EXHAUSTED (5).

    minimize hands maxfev to scipy for these two, so scipy stops itself at the budget ("Maximum number
    of function evaluations has been exceeded.", its status 1) and _scipy_minimize maps every scipy
    failure to SOLVER_FAILED; the other scipy methods, stopped by BudgetExhausted, say 5.  Unlimited,
    both converge (status 0) on Rosenbrock from (-1.2, 1) in 159 and 607 evaluations.
    """
    x0 = np.array([-1.2, 1.0])
    full = minimize(_rosenbrock, x0, method=method)
    assert full.status == COMPLETED and full.success and full.nfev > 100
    bfgs = minimize(_rosenbrock, x0, method="bfgs", maxfev=50)
    assert bfgs.status == BUDGET_EXHAUSTED                    # the rule the commit sets for scipy's methods
    r = minimize(_rosenbrock, x0, method=method, maxfev=50)
    assert r.nfev == 50 and not r.success
    assert r.status == BUDGET_EXHAUSTED, (r.status, r.message)
    assert "exhausted before convergence" in r.message


@pytest.mark.parametrize("maxfev", [41, 44])
def test_normal_equation_lm_counts_the_step_whose_trial_point_it_returns(emps_case, maxfev):
    """On exhaustion, nit leaves out the step whose trial point was evaluated (and is returned as x).

    From the N-SPSA vector the unlimited run takes 8 steps in 45 evaluations (5 per pass).  With 41-44
    evaluations the 8th step's pass is cut short after its trial point (row 0) and some neighbours: that
    trial point is evaluated, is the best point, and is returned as x, bit for bit the unlimited run's
    x; but nit says 7, because _iterate counts a step only after its whole pass.  The commit's rule
    ("nit counts the steps whose trial point was evaluated") and the MINPACK/trf routes (a trial counts
    as soon as its residual vector is evaluated) give 8.
    """
    beta = np.asarray(emps_case.paper["nspsa"]["beta"])
    full = levenberg_marquardt(emps_case.cost, beta)
    assert full.status == COMPLETED and full.nfev == 45 and full.nit == 8
    r = levenberg_marquardt(emps_case.cost, beta, maxfev=maxfev)
    assert r.status == BUDGET_EXHAUSTED and r.nfev == maxfev
    assert np.array_equal(r.x, full.x)                       # the 8th step's trial point
    assert r.nit == full.nit, f"x is the point of step {full.nit}, nit says {r.nit}"


def test_auto_with_no_budget_for_a_refinement_reports_budget_exhausted(trs_case):
    """auto stopped by maxfev before any refinement says SOLVER_FAILED (4): no solver ran or failed.

    With maxfev = 30 the starts' scan spends its share (15) and the 15 left are below a refinement's
    minimum: the message says "raise maxfev", the commit's status table says 4 is "a solver stopped
    without converging" and 5 "ran out of maxfev first".  auto with maxfev = 60 (one refinement cut
    short) already says 5, and 800 converges (status 0).
    """
    assert auto_minimize(trs_case.cost, maxfev=60, seed=0).status == BUDGET_EXHAUSTED
    r = auto_minimize(trs_case.cost, maxfev=30, seed=0)
    assert not r.success and r.nit == 0 and "raise maxfev" in r.message
    assert r.status == BUDGET_EXHAUSTED, (r.status, r.message)


def _readme_row(case: str, variant: str) -> list:
    for line in (ROOT / "README.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 9 and cells[0] == case and cells[1] == variant:
            return cells
    raise AssertionError(f"no README row {case} | {variant}")


def test_readme_table_success_count_of_lm_on_trs_matches_the_code(trs_case):
    """The README's results table says LM from the paper's TRS start succeeds 25/25 on 2 001 evaluations.

    LM from there needs 2 042 evaluations to converge (status 0); on the table's budget of 2 001 it
    now returns status 5, success False, so bench.identification_comparison counts 0 successes.  LM is
    deterministic: one run stands for the 25.
    """
    from hammerstein_ctrl.bench import identification_comparison

    cells = _readme_row("TRS", "LM from the paper's start")
    ok, runs = map(int, cells[6].split("/"))
    row = identification_comparison(trs_case, seeds=range(1), variants=("lm-paper-start",))[0]
    assert row["nfev"] == int(cells[7]) == 2001
    assert row["success"] / row["runs"] == ok / runs, f"README {cells[6]}, code {row['success']}/{row['runs']}"


def test_quickstart_notebook_shows_the_lm_message_the_code_gives(trs_case):
    """Notebook 01's committed LM output shows the message the code no longer gives.

    The cell ``lm = hc.identify(data, structure, method="lm", ..., maxfev=2000)`` is committed with
    "[FAILED: evaluation budget of 2000 exhausted before convergence [evaluation budget of 2000
    exhausted]]" (the old _assess problem plus the old optimiser message); the same call now says
    "[FAILED: evaluation budget of 2000 exhausted before convergence]".
    """
    import hammerstein_ctrl as hc

    nb = json.loads((ROOT / "notebooks" / "01_quickstart.ipynb").read_text())
    cell = next(c for c in nb["cells"]
                if c["cell_type"] == "code" and "".join(c["source"]).startswith("lm = hc.identify("))
    shown = "".join(next(o for o in cell["outputs"] if "data" in o)["data"]["text/plain"]).splitlines()[0]
    lm = hc.identify(trs_case.data, trs_case.structure, method="lm", x0=[-2.0, 0.0, 5.0, -5.0, 0.0], maxfev=2000)
    tail = re.compile(r" s (\[.*\])$")
    assert tail.search(shown).group(1) == tail.search(lm.summary().splitlines()[0]).group(1)


def test_resumed_study_does_not_mix_lm_records_of_the_old_status(trs_case, tmp_path, monkeypatch):
    """A results file written before the change is resumed as is: one LM run with two statuses.

    The fingerprint (RECORD_VERSION 3) did not change with the meaning of status/success/nit, so a
    rerun of ``reproduce`` keeps the parent commit's TRS LM trial (status 0, success True, nit = nfev
    = 2001, "evaluation budget of 2001 exhausted") beside new trials of the same deterministic run
    (status 5, success False, nit 346).  The old record is rebuilt here as 8c2b3cb wrote it, with its
    RECORD_VERSION 3 (checked against a real run of that commit: config b29493283d3cc5c2, the same
    seed and fields).
    """
    from hammerstein_ctrl import study as study_module
    from hammerstein_ctrl.study import record_digest, run_study

    path = tmp_path / "results.jsonl"
    with monkeypatch.context() as m:
        m.setattr(study_module, "RECORD_VERSION", 3)        # the parent commit's
        new = run_study(trs_case, ["lm"], trials=1, seed=0).records[0]
    assert new["status"] == BUDGET_EXHAUSTED and new["nfev"] == 2001
    old = {**new, "status": COMPLETED, "success": True, "nit": new["nfev"],
           "message": f"evaluation budget of {new['nfev']} exhausted"}
    old["digest"] = record_digest(old)
    path.write_text(json.dumps(old) + "\n")
    study = run_study(trs_case, ["lm"], trials=2, seed=0, results_path=path)
    statuses = {(r["status"], r["success"], r["nit"]) for r in study.records}
    assert len(statuses) == 1, f"one deterministic run, {study.resumed} resumed: {statuses}"
