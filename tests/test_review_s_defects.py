"""Defects found by an independent review (review-s) of e386eb2..6191862; each test failed on 6191862."""

import numpy as np
import pytest

from hammerstein_ctrl import identify, minimize, presets
from hammerstein_ctrl._linalg import symmetric_eigenvalues
from hammerstein_ctrl.auto import MIN_REFINE_BUDGET


def test_lm_does_not_claim_convergence_at_a_rejected_unstable_start(emps_dir):
    """reject_unstable makes every residual of an unstable point (and of its neighbours) 1e150: the
    Jacobian is zero there, and LM stopped at once with 'gtol termination condition is satisfied',
    success=True, at a point the cost scores inf (before bf7386c it walked to J = 0.2085)."""
    p = presets.emps(path=emps_dir, reject_unstable=True)
    res = minimize(p.cost, p.x0, method="lm")
    if not np.isfinite(p.cost(res.x)):
        assert not res.success, res.message
        assert "gtol" not in res.message


def test_symmetric_eigenvalues_of_large_entries():
    """The skip test |a_pq| <= eps sqrt(|a_pp a_qq|) overflows past 1e154: no rotation, diagonal returned."""
    for S in (np.array([[1e200, 1e200], [1e200, 1e200]]), np.array([[1e160, 0.9e160], [0.9e160, 1e160]])):
        w = np.linalg.eigvalsh(S)
        np.testing.assert_allclose(symmetric_eigenvalues(S), w, rtol=0, atol=1e-13 * np.abs(w).max())


_TWO_THREADS = """
import json, threading
import scipy.linalg  # both BLAS libraries (numpy's, scipy's) loaded before the first count
import threadpoolctl
from hammerstein_ctrl._linalg import single_threaded_blas

def threads():
    return [lib["num_threads"] for lib in threadpoolctl.threadpool_info()]

before = threads()
a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()

def first():
    with single_threaded_blas():
        a_in.set()
        b_in.wait(10)
    a_out.set()

def second():
    a_in.wait(10)
    with single_threaded_blas():
        b_in.set()
        a_out.wait(10)

workers = [threading.Thread(target=first), threading.Thread(target=second)]
for w in workers:
    w.start()
for w in workers:
    w.join()
print(json.dumps({"before": before, "after": threads()}))
"""


def test_single_threaded_blas_restores_the_limits_after_two_threads():
    """Limits are process-wide but the bookkeeping is per thread: with thread A in, thread B in, A out,
    B out, B restores what it saw on entry (A's limit of 1) and the process stays single-threaded.

    Run in a child process with two BLAS threads (threadpoolctl gives OpenBLAS to one controlling
    thread at a time, so the scenario must not share this process's state)."""
    import json
    import os
    import subprocess
    import sys

    pytest.importorskip("threadpoolctl")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="2", OMP_NUM_THREADS="2")
    out = subprocess.run([sys.executable, "-c", _TWO_THREADS], capture_output=True, text=True, env=env,
                         check=True, timeout=300).stdout.strip().splitlines()[-1]
    r = json.loads(out)
    if not r["before"] or set(r["before"]) <= {1}:
        pytest.skip("no BLAS pool with more than one thread in the child")
    assert r["after"] == r["before"]


_FIRST_BLOCK_BEFORE_SCIPY = ("""
import json, sys
import numpy as np
from hammerstein_ctrl._linalg import single_threaded_blas
loaded = "scipy.linalg" in sys.modules
with single_threaded_blas():
    import threadpoolctl
    inside = {lib["filepath"]: lib["num_threads"] for lib in threadpoolctl.threadpool_info() """
                             """if lib["user_api"] == "blas"}
after = {lib["filepath"]: lib["num_threads"] for lib in threadpoolctl.threadpool_info() if lib["user_api"] == "blas"}
print(json.dumps({"loaded": loaded, "inside": inside, "after": after}))
""")


def test_the_first_block_before_scipy_linalg_also_holds_scipys_blas():
    """numpy and scipy wheels each bring their own OpenBLAS; a block opened before scipy.linalg was
    imported must still hold both (scipy's serves expm, lstsq and MINPACK's neighbours), and restore both."""
    import json
    import os
    import subprocess
    import sys

    pytest.importorskip("threadpoolctl")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="2", OMP_NUM_THREADS="2")
    r = json.loads(subprocess.run([sys.executable, "-c", _FIRST_BLOCK_BEFORE_SCIPY], capture_output=True, text=True,
                                  env=env, check=True, timeout=300).stdout.strip().splitlines()[-1])
    assert not r["loaded"]
    if set(r["after"].values()) <= {1}:
        pytest.skip("no BLAS pool with more than one thread in the child")
    assert len(r["inside"]) >= 2 and set(r["inside"].values()) == {1}, r
    assert r["after"] == {k: 2 for k in r["inside"]}, r


def test_auto_does_not_say_the_budget_ran_out_with_half_of_it_left(trs_case):
    """maxfev=60 on TRS: the start search spends its half (30), no start is found, and the result says
    'evaluation budget of 60 exhausted' with 30 evaluations unspent (EMPS: maxfev=30 gives a model,
    maxfev=40 none, with 18 spent)."""
    r = identify(trs_case.data, "trs", method="auto", maxfev=60, seed=0)
    if r.model is None and "exhausted" in r.message:
        assert r.nfev > 60 - MIN_REFINE_BUDGET, r.message
