"""The EMPS cost with a busy sibling process on the other core.

The cost does small dense linear algebra for every candidate.  Handed to
multi-threaded OpenBLAS, that made one evaluation 3x slower with one other busy
core and 12-45x slower on a loaded 2-core machine, because BLAS worker threads
spun against the other work.  Here a sibling process spins a one-thread BLAS
loop, paused and running in interleaved blocks (medians of 7 each), and the
cost's time per evaluation is compared between the two.

The default suite checks only what a busy machine cannot fake: while the
sibling runs, the process must use at most 1.2 CPU seconds per wall second
(spinning worker threads add theirs; one thread cannot; other load on the
machine only lowers the figure), and the numbers must not change.  The wall
time per evaluation (must not grow by more than 3x; sharing two cores with one
more busy process can cost up to ~1.5x on its own) depends on everything else
the machine runs, so it is asserted only under the ``timing`` marker, which
``make bench`` runs and ``make test`` leaves out.  The growth of the process's CPU time
is not bounded here: where the two cores are hyper-threads of one, a sibling
busy with vector arithmetic slows the batched kernel's own thread by up to ~1.9x
(measured on this machine), with no thread of ours spinning.
"""

import numpy as np
import pytest

import speed as bench

#: Largest accepted CPU seconds of the process per wall second while the sibling runs.
CPU_PER_WALL_BOUND = 1.2
#: Largest accepted busy/quiet ratio of wall time per evaluation.
WALL_RATIO_BOUND = 3.0
#: CPU seconds per wall second below which a one-thread product shows the cores taken by other work (a
#: second thread could not spin there, so the check that the measure sees spinning threads cannot run).
FREE_CORE_SHARE = 0.9


@pytest.fixture(scope="module")
def emps_beta(emps_case):
    return np.asarray(emps_case.paper["nspsa"]["beta"], dtype=float)


@pytest.mark.timing
def test_sibling_really_keeps_a_core_busy():
    r = bench.contention_ratio(lambda: sum(range(2000)), number=200, pairs=3)
    # on an idle machine it takes a whole core; shared by 4-5 agents on 2 cores still a fair slice
    assert r["sibling_share"] > 0.1


def _emps_cost_under_contention(emps_case, emps_beta, kind):
    cost = emps_case.cost
    if kind == "single":
        fn, number = (lambda: cost(emps_beta)), 100
    else:
        betas = emps_beta + 1e-3 * np.random.default_rng(0).standard_normal((50, emps_beta.size))
        fn, number = (lambda: cost.batch(betas)), 4
    expected = fn()
    r = bench.contention_ratio(fn, number=number)
    np.testing.assert_array_equal(fn(), expected)  # same numbers under load
    return r


@pytest.mark.parametrize("kind", ["single", "batched"])
def test_emps_cost_spins_no_threads_beside_a_busy_sibling(emps_case, emps_beta, kind):
    r = _emps_cost_under_contention(emps_case, emps_beta, kind)
    assert r["busy_cpu_per_wall"] < CPU_PER_WALL_BOUND, r


@pytest.mark.timing
@pytest.mark.parametrize("kind", ["single", "batched"])
def test_emps_cost_wall_time_unaffected_by_busy_sibling(emps_case, emps_beta, kind):
    r = _emps_cost_under_contention(emps_case, emps_beta, kind)
    assert r["busy_cpu_per_wall"] < CPU_PER_WALL_BOUND, r
    assert r["ratio"] < WALL_RATIO_BOUND, r


@pytest.mark.timing
def test_the_measure_sees_threads_spinning_against_the_sibling():
    """The bound can fail: a 300 x 300 product in two-thread OpenBLAS uses ~1.3 CPU seconds per wall second
    while the sibling runs (one thread: 1.0)."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    if max((lib["num_threads"] for lib in threadpoolctl.threadpool_info() if lib["user_api"] == "blas"),
           default=1) < 2:
        pytest.skip("BLAS runs one thread here")
    a = np.random.default_rng(0).standard_normal((300, 300))
    with threadpoolctl.threadpool_limits(1):
        one = bench.contention_ratio(lambda: a @ a, number=200)["busy_cpu_per_wall"]
    assert one < CPU_PER_WALL_BOUND
    if one < FREE_CORE_SHARE:
        pytest.skip(f"other work holds the cores (one thread gets {one:.2f} CPU s per wall s): no thread can spin")
    # a machine loaded by other work can starve the second thread: seen in one of three tries suffices
    seen = [bench.contention_ratio(lambda: a @ a, number=200)["busy_cpu_per_wall"] for _ in range(3)]
    assert max(seen) > CPU_PER_WALL_BOUND, seen
