"""Review of 4c9b6bc..4a8e3e1 (lane groups: normal equations past one compiled pass).

Each test is a defect found by the review and fails at 4a8e3e1.  The lane
groups themselves gave the stored Jacobian's numbers in every case tried
(see the review report); what fails here is at their edges (leaked numpy
warnings at non-finite points, an IndexError on an empty basis), and three
defects older than these commits (marked "older") met on the way.

Oracles: the cost's own value ``cost(x)``, python-control's simulation, and the
project's rule that a RuntimeWarning leaking from hammerstein_ctrl is an error
(pyproject.toml: ``filterwarnings = ["error::RuntimeWarning:hammerstein_ctrl.*"]``).
"""

import warnings

import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl import simulate
from hammerstein_ctrl.exceptions import HammersteinError
from hammerstein_ctrl.objective import HammersteinCost

DT = 0.01
KNOTS = np.linspace(-0.9, 0.9, 11)


def _pwl_structure():
    """17 lanes (16 parameters), 11 basis signals: past one compiled pass on both counts."""
    return hc.HammersteinStructure(hc.LinearStructure(1, 3), hc.PiecewiseLinear(KNOTS), offset=True)


def _long_enough(lanes):
    """A record just long enough that ``lanes`` candidates' outputs pass GROUPS_MIN_BYTES (no monkeypatch)."""
    n = simulate.GROUPS_MIN_BYTES // (8 * lanes) + 1000
    t = DT * np.arange(n)
    return hc.IOData(np.sin(0.3 * t) + 0.5 * np.sin(3.3 * t), np.cos(t), dt=DT)


def _point(structure):
    x = np.random.default_rng(1).uniform(0.5, 2.0, structure.n_params)
    x[:4] = [1.0, 1.0, 3.0, 3.0]                    # H = 1 / (p + 1)^3, stable
    return x


@pytest.mark.parametrize("index, value, method", [
    (8, np.inf, "normal_equations"),      # default steps are NaN there: inf - inf in _LaneGroups.prepare
    (8, np.inf, "normal_factor"),
    (13, 1.5e308, "normal_factor"),       # row 0's signal overflows in _LaneGroups.output_blocks
])
def test_lane_groups_leak_no_numpy_warning_at_a_nonfinite_point(index, value, method):
    """A g parameter at inf or 1.5e308 (the cost is inf) on a record just long enough for lane groups.
    Before these commits 17 lanes took the stored residuals, silently.  Now numpy's warnings escape
    from two lines of _LaneGroups that run outside any errstate: 'invalid value encountered in
    subtract' (``Pg - P[0, cols]`` in ``prepare``, a neighbour's NaN step moving a column that is inf)
    and 'overflow encountered in matmul' (``reference = self.P[0] @ part`` in ``output_blocks``;
    ``normal_pass`` hides that one only because ``_sum_blocks`` wraps the generator in an errstate,
    ``factor_of_blocks`` does not).  Under the project's warning filter the call raises instead of
    returning fun = inf as the single pass does."""
    structure = _pwl_structure()
    cost = HammersteinCost(_long_enough(structure.n_params + 1), structure)
    x = _point(structure)
    x[index] = value
    assert cost(x) == np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        ne = getattr(cost, method)(x)
    assert ne.fun == np.inf


def test_normal_factor_of_an_overflowing_point_leaks_no_numpy_warning():
    """Older (from_factor, not these commits): a g parameter at 1.5e308 (cost inf) on a short record
    (stored residuals, no groups): ``from_factor`` divides the factor by the steps outside its errstate
    and numpy's 'overflow encountered in divide' escapes (normal_equations.py, ``RJ = R[:p, :p] / steps``)."""
    t = DT * np.arange(3000)
    data = hc.IOData(np.sin(t) + 0.5 * np.sin(3.3 * t), np.cos(t), dt=DT)
    structure = hc.HammersteinStructure(
        hc.LinearStructure(1, 3),
        hc.CustomNonlinearity(lambda u, p: sum(p[k] * np.sin((k + 1) * u) for k in range(10)), 10),
        offset=True)
    cost = HammersteinCost(data, structure)
    x = _point(structure)
    x[5] = 1.5e308
    assert cost(x) == np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        qr = cost.normal_factor(x)
    assert not np.isfinite(qr.fun)


def test_normal_pass_with_an_empty_basis_on_a_long_record_gives_no_index_error():
    """``normal_pass`` (public) with a basis of no signals (P of shape (3, 0)) returned None before these
    commits; on a record long enough for lane groups ``_group_signals`` now picks column 0 of an empty
    P (``np.arange(1)``) and numpy's IndexError escapes.  Either None (the pass does not apply) or a
    clear HammersteinError is acceptable."""
    n = simulate.GROUPS_MIN_BYTES // (8 * 3) + 1000
    y = np.zeros(n)
    try:
        ne = simulate.normal_pass([[1.0]], [[1.0, 2.0, 1.0]], DT, y, np.zeros((3, 0)), [np.zeros((0, n))],
                                  [1e-6, 1e-6])
    except HammersteinError:
        return
    assert ne is None


def test_wiener_with_a_parameterless_custom_output_map():
    """Older (simulate._output_map, not these commits): WienerStructure accepts a CustomNonlinearity with
    no parameters, but every cost evaluation then fails inside numpy ('cannot reshape array of size 0
    into shape (0)').  Either the structure is refused with a clear error, or its cost is the sum of
    squares of y - h(H u), simulated here by python-control."""
    import control

    h = hc.CustomNonlinearity(lambda v, p: np.tanh(v), 0)
    try:
        structure = hc.WienerStructure(hc.LinearStructure(0, 2), h)
    except HammersteinError:
        return
    t = DT * np.arange(2000)
    u = np.sin(t) + 0.5 * np.sin(3.3 * t)
    y = np.cos(t)
    cost = HammersteinCost(hc.IOData(u, y, dt=DT), structure)
    x = np.array([2.0, 3.0])                        # H = 1 / (p^2 + 3 p + 2)
    assert structure.param_names == ("a0", "a1")
    expected = np.tanh(control.forced_response(control.tf([1.0], [1.0, 3.0, 2.0]), t, u).outputs)
    assert cost(x) == pytest.approx(float(np.sum((y - expected) ** 2)), rel=1e-6)


def test_normal_factor_runs_its_small_qr_factorisations_in_one_blas_thread(monkeypatch):
    """Older (HammersteinCost.normal_factor, any route; lane groups make it wider): the public
    ``normal_factor`` reduces blocks of 8192 x (p + 1) differences with LAPACK's geqrf, but only
    identify / minimize / levenberg_marquardt hold BLAS to one thread.  Called directly (as its own
    docstring does), OpenBLAS threads each small QR: measured on this 2-core machine at 1e6 samples,
    17 lanes, 2 to 12 s instead of 0.2 to 0.26 s (the project's rule: small dense linear algebra in
    single-threaded BLAS, threadpool_limits(1) around the entry points)."""
    from threadpoolctl import threadpool_info

    from hammerstein_ctrl import streamed_lstsq

    if max(info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas") < 2:
        pytest.skip("BLAS runs one thread here anyway")
    structure = _pwl_structure()
    cost = HammersteinCost(_long_enough(structure.n_params + 1), structure)
    threads = []
    geqrf = streamed_lstsq._GEQRF

    def spy(*args, **kwargs):
        if not threads:                             # threadpool_info is slow: look once
            threads.append(max(info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"))
        return geqrf(*args, **kwargs)
    monkeypatch.setattr(streamed_lstsq, "_GEQRF", spy)
    qr = cost.normal_factor(_point(structure))
    assert np.isfinite(qr.fun)
    assert threads == [1]


@pytest.mark.parametrize("case", ["unstable point, reject_unstable", "b0 = inf"])
def test_normal_equations_of_a_point_scored_inf_store_no_residual_vectors(case):
    """Older (HammersteinCost.normal_equations; the single pass does the same), but it undoes lane groups'
    bounded memory: at a point the cost scores inf -- unstable under reject_unstable=True, or a linear
    parameter at inf (no clean discretisation, so neither one pass nor the groups apply) -- the p + 1
    residual vectors are simulated and stored whole: measured 392 to 414 B/sample at 1e6 samples,
    17 lanes, three times the 8 (p + 1) = 136 B of the vectors themselves (4 GB at 1e7 samples), for
    a point no solver can use.  With b0 = inf the result is not even scored inf (fun = 1e306 while
    cost(x) = inf)."""
    import tracemalloc

    structure = _pwl_structure()
    lanes = structure.n_params + 1
    data = _long_enough(lanes)
    n = 4 * data.u.size                             # p + 1 residual vectors: 4 x GROUPS_MIN_BYTES = 64 MB
    t = DT * np.arange(n)
    data = hc.IOData(np.sin(0.3 * t) + 0.5 * np.sin(3.3 * t), np.cos(t), dt=DT)
    x = _point(structure)
    if case == "b0 = inf":
        cost = HammersteinCost(data, structure)
        x[0] = np.inf
    else:
        cost = HammersteinCost(data, structure, reject_unstable=True)
        x[3] = -1e-12                               # a2 < 0: a pole in the right half-plane
    assert cost(x) == np.inf
    tracemalloc.start()
    try:
        ne = cost.normal_equations(x)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert ne.fun == np.inf
    assert peak < 8 * lanes * n / 2, peak / n       # well under p + 1 stored residual vectors
