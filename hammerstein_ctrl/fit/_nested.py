"""The simpler models nested in a fit, fitted and tested: is the fit worth its parameters?

Every identification is compared with three simpler models of the same
record (:mod:`~hammerstein_ctrl.assess._significance` for the test):

* a **constant** (the output's mean);
* a **static affine gain** ``y = k u + c``;
* the **linear model of the same order**: the structure's linear block with
  its nonlinearities replaced by a gain (``HammersteinStructure(linear,
  Polynomial(1))`` with the same offset, initial state and dead time),
  fitted by ``auto``.

A fit that does not beat one of them significantly fails, and so does a fit
that the linear model nested in it beats outright (a poor local minimum:
the fit could have reached the linear model and did not).  The dead time's
scan over whole-sample candidates is a search the F-distribution does not
see; its p-values are multiplied by the number of candidates scanned
(Bonferroni).

The test takes the residuals for noise (whitened by their autoregressive
model).  When they are mostly a predictable signal (their power more than
:data:`~hammerstein_ctrl.assess._uncertainty.COLOURED_RATIO` times their
unpredictable part), both models miss something systematic and the test
compares model errors: a fit that lowers J by more than
:data:`SYSTEMATIC_GAIN` is then not called insignificant, and the colour
warning of the residual analysis says what seems missing.

Examples
--------
>>> import numpy as np, hammerstein_ctrl as hc
>>> rng = np.random.default_rng(0)
>>> noise = hc.IOData(rng.standard_normal(600), rng.standard_normal(600), dt=0.05)
>>> r = hc.identify(noise, hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Tanh()), seed=0)  # doctest: +SKIP
>>> r.success, r.verdicts[0].code                                                                 # doctest: +SKIP
(False, 'not-significant')
"""

from __future__ import annotations

import numpy as np

from .. import config
from ._delay_fit import DelayedCost
from ..assess._diagnostics import FAILURE, Verdict
from ._experiments import RecordsCost
from ._baselines import affine_coefficients
from ._lure_fit import LureCost
from ._wh_fit import WienerHammersteinCost
from ..blocks._families import Polynomial
from ._initialize import points_for
from ..optimize import Budget, BudgetExhausted, levenberg_marquardt

from ._objective import HammersteinCost
from ._routes import route
from ..assess._significance import NestedTest, nested_f_test, rounding_sse
from ..blocks._structure import HammersteinStructure, LinearStructure
from ..assess._uncertainty import COLOURED_RATIO, fit_noise_model

__all__ = ["nested_linear_structure", "nested_tests", "significance_verdicts", "delay_scan_count"]

#: Records longer than this fit the nested linear model from the fit's own block (bounded memory), not by auto.
NESTED_AUTO_SAMPLES = 200_000
#: Relative margin by which the nested linear model must beat a fit for the fit to be a poor optimum.
WORSE_MARGIN = 1e-6
#: Residuals mostly a systematic error (:data:`~hammerstein_ctrl.assess._uncertainty.COLOURED_RATIO`) make the
#: whitened test compare model errors, not noise; a fit that lowers J by more than this share is then not
#: called insignificant (the residuals' colour warning says what is missing).
SYSTEMATIC_GAIN = 0.01
#: Evaluation budget of the nested linear model's ``auto`` fit (measured: every known-truth record of the test
#: suite and the TRS record reach the J of a 2000-evaluation fit to 8 digits within 600; past that ``auto``
#: only restarts from an optimum it already has).
NESTED_MAXFEV = 800


def nested_linear_structure(structure):
    """The linear model of the same order nested in ``structure`` (``None`` when it is linear itself).

    Examples
    --------
    >>> from hammerstein_ctrl import LinearStructure, WienerStructure, Tanh
    >>> nested_linear_structure(WienerStructure(LinearStructure(1, 2), Tanh(), offset=True)).param_names
    ('b0', 'a0', 'a1', 'd1', 'y0')
    """
    base = getattr(structure, "base", structure)          # a joint fit of several records: its blocks
    if getattr(base, "kind", "") != "lure":
        return base.linear_counterpart()
    linear = LinearStructure(base.linear.num_order, base.linear.den_order, delay=base.linear.delay)
    return HammersteinStructure(linear, Polynomial(1), offset=base.offset, initial_state=base.initial_state)


def delay_scan_count(structure, n_samples: int) -> int:
    """Whole-sample dead times the ``auto`` scan compares when ``structure`` estimates one (else 1)."""
    base = getattr(structure, "base", structure)
    if not getattr(getattr(base, "linear", None), "estimates_delay", False):
        return 1
    return min(config.get("delay.max_samples"), max(0, n_samples // 4)) + 1


def _nested_route(cost, nested):
    """The route of the nested structure on the fit's record(s), and its cost there."""
    records = cost.records if isinstance(cost, RecordsCost) else (cost.data,)
    way = route(nested, records)
    return way, way.make(records, nested)


def _linear_fit(cost, seed, x=None):
    """``(residuals, n_params)`` of the nested linear model fitted by ``auto`` (``None`` when there is none); on a
    record past :data:`NESTED_AUTO_SAMPLES` (one record, no dead time) by Levenberg-Marquardt from the fit's own
    linear block ``x`` instead, whose passes run in bounded memory where ``auto``'s start scan holds its
    candidates' responses whole."""
    nested = nested_linear_structure(cost.structure)
    if nested is None:
        return None
    way, ncost = _nested_route(cost, nested)
    with np.errstate(all="ignore"):
        try:
            if x is not None and type(ncost) is HammersteinCost and len(ncost.data) > NESTED_AUTO_SAMPLES:
                x = np.asarray(x, dtype=float)
                theta = (cost.structure.linear_theta(x) if hasattr(cost.structure, "linear_theta")
                         else x[:nested.linear.n_params])
                res = _warm_linear_fit(ncost, theta)
            else:
                res = way.auto(ncost, seed=seed, maxfev=NESTED_MAXFEV)
        except BudgetExhausted:          # a start that needs more than the whole budget: no linear test
            return None
        if res is None or not np.all(np.isfinite(res.x)):
            return None
        r = ncost.residuals(res.x)
    return (r, ncost.n_params) if np.all(np.isfinite(r)) else None


def _warm_linear_fit(ncost, theta):
    """Levenberg-Marquardt on the nested linear model from the linear block ``theta`` (its gain, offset and state
    by least squares), or ``None`` when that start cannot be formed."""
    budget = Budget(NESTED_MAXFEV)
    starts = points_for(ncost.data, ncost.structure, [theta], budget)
    if not starts or budget.remaining < 2:
        return None
    return levenberg_marquardt(ncost, starts[0], maxfev=int(budget.remaining))


def nested_tests(cost, residuals, *, noise=None, seed=None, linear: bool = True, x=None) -> list[NestedTest]:
    """The F-tests of a fit (``residuals`` at the fitted parameters, their ``noise`` model) against its nested
    models, in order: constant, static affine gain, and (``linear``) the linear model of the same order."""
    data, p = cost.data, cost.n_params
    y, u = np.asarray(data.y, dtype=float).reshape(-1), np.asarray(data.u, dtype=float).reshape(-1)
    r = np.asarray(residuals, dtype=float).reshape(-1)
    n, out = r.size, []
    if p > 1:
        mean = float(np.mean(y))
        out.append(nested_f_test(r, lambda a, b: y[a:b] - mean, n, p, 1, noise=noise, nested="a constant"))
    if p > 2:
        k, c = affine_coefficients(u, y)
        out.append(nested_f_test(r, lambda a, b: y[a:b] - (k * u[a:b] + c), n, p, 2, noise=noise,
                                 nested="the static affine gain y = k u + c"))
    fitted = _linear_fit(cost, seed, x) if linear and isinstance(cost, (HammersteinCost, DelayedCost, RecordsCost,
                                                                      LureCost, WienerHammersteinCost)) else None
    if fitted is not None:
        rl, pl = fitted
        name = "the linear model of the same order"
        if pl < p:
            out.append(nested_f_test(r, rl, n, p, pl, noise=noise, nested=name))
        elif pl == p and rl @ rl < r @ r:
            out.append(NestedTest(name, float(r @ r), float(rl @ rl), -np.inf, (0, n - p), 1.0,
                                  config.get("verdicts.significance"), "white"))
    return out


def _adjusted(test: NestedTest, scans: int) -> NestedTest:
    return test if scans <= 1 else test._replace(p_value=min(1.0, test.p_value * scans))


def significance_verdicts(cost, residuals, *, noise=None, seed=None, linear: bool = True, x=None
                          ) -> tuple[list[Verdict], list]:
    """``(verdicts, tests)``: a failure for the first nested model the fit does not beat significantly, or that
    beats the fit outright (:func:`nested_tests`; p-values Bonferroni-adjusted for a dead-time scan).  Nothing
    when ``config.defaults["verdicts.nested_tests"]`` is False."""
    if not config.get("verdicts.nested_tests"):
        return [], []
    scans = delay_scan_count(cost.structure, len(cost.data))
    r = np.asarray(residuals, dtype=float).reshape(-1)
    noise = fit_noise_model(r, cost.n_params) if noise is None else noise
    systematic = noise.predictability(r) > COLOURED_RATIO
    tests = [_adjusted(t, scans) for t in nested_tests(cost, r, noise=noise, seed=seed, linear=linear, x=x)]
    exact = rounding_sse(cost.data.y)
    for t in tests:
        if t.nested_sse <= exact:       # the nested model is exact: nothing is left to be significant, and the
            return [Verdict("not-significant", FAILURE, _not_significant(t, scans))], tests   # fit's rounding
        if t.nested_sse < t.sse * (1.0 - WORSE_MARGIN) and t.nested.startswith("the linear"):
            return [Verdict("worse-than-nested", FAILURE,
                            f"a poor optimum: {t.nested}, which this structure contains, fits better (J = "
                            f"{t.nested_sse:.6g} against {t.sse:.6g}): the search stopped short of it, in a local "
                            f"minimum or drifting toward the nonlinearity's linear limit (as when the family cannot "
                            f"take the shape the data need); try another family or structure, or start from the "
                            f"linear model's fit")], tests
        if not t.significant and not (systematic and t.sse < t.nested_sse * (1.0 - SYSTEMATIC_GAIN)):
            return [Verdict("not-significant", FAILURE, _not_significant(t, scans, systematic))], tests
    return [], tests


def _not_significant(t: NestedTest, scans: int, systematic: bool = False) -> str:
    why = (f"{t.describe()}{f', adjusted for {scans} dead times scanned' if scans > 1 else ''}; "
           f"J = {t.sse:.6g} against {t.nested_sse:.6g}")
    if t.nested.startswith("the linear") and systematic:
        return (f"the nonlinearity as fitted adds nothing: {t.nested} fits as well ({why}), and both miss a "
                f"predictable part of the output (the residuals are mostly a signal, not noise): this family or its "
                f"place seems wrong, or the search stopped short; try another family or structure")
    if t.nested.startswith("the linear"):
        return (f"the nonlinearity is not significant: {t.nested} fits as well ({why}): use the linear model, or "
                "a record that drives the nonlinearity harder")
    return (f"not significantly better than {t.nested} ({why}): the output does not seem to depend on the input as "
            "this structure describes; check that the output is the response to this input and that the input "
            "excites the plant, or try another structure")
