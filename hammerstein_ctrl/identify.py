"""Fit a Hammerstein model to a record in one call.

``identify(data, structure)`` needs nothing else: the default method
``"auto"`` (:mod:`hammerstein_ctrl.auto`) starts from points computed from the
data and refines them by least squares.  The paper's methods remain available
by name with their own settings.

Every result says honestly whether it can be trusted: ``success`` is False,
with a specific ``message``, when the budget ran out before a least-squares
method converged, when the model is unstable (unless ``allow_unstable``), when
it fits no better than the best static affine gain ``y = k u + c`` (fit %
<= 0 included), or when a search stalled at its starting value.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> case = hc.presets.trs()
>>> res = hc.identify(case.data, case.structure)
>>> bool(res.fun < 178.5), res.success, res.method
(True, True, 'auto')
>>> res = hc.identify(case.data, case.structure, method="nspsa", x0=case.x0, seed=0,
...                   **{k: v for k, v in case.minimize_kwargs("nspsa").items() if k != "method"})
>>> round(res.fun, 1), res.nfev, type(res.model.linear).__name__
(178.5, 2001, 'TransferFunction')
>>> round(res.fit_percent)   # the reconstruction's noise floor: the true system scores 31 % too
31
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ._linalg import single_threaded_blas
from .datasets import IOData
from .exceptions import ParameterError
from .initialize import static_affine_sse
from .metrics import fit_report
from .model import BlockModel
from .objective import HammersteinCost
from .optimize import DIVERGED, SCIPY_METHODS, canonical_method, minimize
from .simulate import unstable
from .structure import BlockStructure

__all__ = ["identify", "IdentificationResult", "AUTO"]

#: Name of the default method (see :mod:`hammerstein_ctrl.auto`).
AUTO = "auto"
#: Methods that stop on a convergence test (running out of budget is then a failure).
_CONVERGING = ("lm",) + SCIPY_METHODS


@dataclass
class IdentificationResult:
    """The outcome of :func:`identify`.

    Attributes
    ----------
    model : BlockModel
        The fitted model (a HammersteinModel, WienerModel or
        HammersteinWienerModel); ``model.linear`` is a ``control.TransferFunction``.
    x : ndarray
        The fitted beta.
    fun : float
        J at ``x`` (sum of squared output errors on the estimation data).
    nfev : int
        Objective evaluations used.
    fit_percent, rmse, nrmse : float
        Goodness of fit on the estimation data.
    method : str
    success : bool
    message : str
    history : dict
        The optimiser's per-iteration record (``nit, nfev, fun, best``).
    elapsed : float
        Wall time in seconds.
    structure : BlockStructure
    data : IOData
    optimize_result : scipy.optimize.OptimizeResult
        The optimiser's full result.
    """

    model: BlockModel
    x: np.ndarray
    fun: float
    nfev: int
    fit_percent: float
    rmse: float
    nrmse: float
    method: str
    success: bool
    message: str
    history: dict
    elapsed: float
    structure: BlockStructure = field(repr=False)
    data: IOData = field(repr=False)
    optimize_result: object = field(repr=False)

    @property
    def params(self) -> dict:
        """The fitted parameters by name."""
        return dict(zip(self.structure.param_names, self.x.tolist()))

    @property
    def status(self) -> int:
        """The optimiser's termination code (the table in :mod:`hammerstein_ctrl.optimize`; 5: the budget ran out first)."""
        return int(self.optimize_result.status)

    def validate(self, data: IOData, *, initial_state: str | None = None) -> dict:
        """Goodness of fit (``sse``, ``rmse``, ``nrmse``, ``fit_percent``) on another record.

        Parameters
        ----------
        data : IOData
        initial_state : {"zero", "estimate"}, optional
            Start the model from rest, or estimate its initial state on
            ``data`` by least squares (as MATLAB's ``compare`` does).  Default:
            ``"estimate"`` if the identification estimated it, else ``"zero"``.
        """
        from .display import as_iodata
        from .initialize import estimate_initial_state

        if self.model is None:
            raise ParameterError(f"this identification produced no model, so there is nothing to validate "
                                 f"({self.message})")
        data = as_iodata(data)
        mode = initial_state or self.structure.initial_state
        if mode not in ("zero", "estimate"):
            raise ParameterError(f"initial_state must be 'zero' or 'estimate', got {initial_state!r}")
        with np.errstate(all="ignore"):
            x0 = estimate_initial_state(self.model, data) if mode == "estimate" else np.zeros(self.model.order)
            yhat = self.model.simulate(data, initial_state=x0)
        if not np.all(np.isfinite(yhat)):
            return {"sse": np.inf, "rmse": np.inf, "nrmse": np.inf, "fit_percent": -np.inf}
        return fit_report(data.y, yhat)

    def summary(self) -> str:
        """A short human-readable report."""
        names = ", ".join(f"{k} = {v:.6g}" for k, v in self.params.items())
        status = "ok" if self.success else "FAILED"
        return (
            f"{self.method} on {self.data.name!r}: J = {self.fun:.6g}, fit = {self.fit_percent:.2f} %, "
            f"RMSE = {self.rmse:.4g}, nfev = {self.nfev}, {self.elapsed:.2f} s [{status}: {self.message}]\n"
            f"  {self.structure.describe()}\n  {names}\n  model: {self.model!r}"
        )

    def to_dict(self) -> dict:
        """JSON-serialisable description of the fitted model and the run."""
        num = np.asarray(self.model.linear.num[0][0], dtype=float).tolist()
        den = np.asarray(self.model.linear.den[0][0], dtype=float).tolist()
        return {
            "method": self.method, "data": self.data.name, "structure": self.structure.describe(),
            "params": self.params, "beta": self.x.tolist(), "J": self.fun, "nfev": self.nfev,
            "fit_percent": self.fit_percent, "rmse": self.rmse, "nrmse": self.nrmse,
            "success": self.success, "status": self.status, "message": self.message, "elapsed_s": self.elapsed,
            "linear": {"num": num, "den": den},
            **{key: {"name": nl.name, "params": dict(zip(nl.param_names, np.asarray(p).tolist()))}
               for key, nl, p in (("nonlinearity", self.model.input_nonlinearity, self.model.input_params),
                                  ("output_nonlinearity", self.model.output_nonlinearity,
                                   self.model.output_params)) if nl is not None},
        }

    # -- notebook display (logic in display.py / plots.py) ---------------------
    def _repr_html_(self) -> str:
        from .display import result_html
        return result_html(self)

    def _repr_pretty_(self, printer, cycle):  # IPython's text view: the summary, not the dataclass fields
        printer.text(self.summary())

    def plot(self, **kwargs):
        """Measured vs simulated output, residual and g(u) (:func:`hammerstein_ctrl.plots.result_figure`)."""
        from .plots import result_figure
        return result_figure(self, **kwargs)

    def compare(self, *records, **kwargs):
        """Fit % of this model on each record, one figure (:func:`hammerstein_ctrl.plots.compare`)."""
        from .plots import compare
        return compare(list(records) or [self.data], self, **kwargs)

    def to_frame(self):
        """Parameters (``value``, ``stderr``) as a pandas DataFrame (:func:`hammerstein_ctrl.display.result_frame`)."""
        from .display import result_frame
        return result_frame(self)


def identify(
    data: IOData,
    structure,
    method: str = AUTO,
    x0=None,
    maxfev: int | None = None,
    seed=None,
    options: dict | None = None,
    bounds=None,
    *,
    maxiter: int | None = None,
    callback=None,
    reject_unstable: bool = False,
    offset: bool | None = None,
    initial_state: str | None = None,
    allow_unstable: bool = False,
) -> IdentificationResult:
    """Identify a Hammerstein model from an input/output record.

    Parameters
    ----------
    data : IOData
        Estimation record; its ``intersample`` ("foh"/"zoh") is honoured.  A
        ``nonlinear_benchmarks`` record (``u``, ``y``, ``sampling_time``) works too.
    structure : HammersteinStructure, WienerStructure, HammersteinWienerStructure or {"trs", "emps"}
        The model structure (a preset name uses that case's structure and,
        for the paper's methods when ``x0`` is omitted, its initial point).
    method : str, default "auto"
        ``"auto"`` (data-driven starts, least-squares refinement, restarts;
        needs no ``x0`` or tuning), or any method of
        :func:`hammerstein_ctrl.minimize` (``"nspsa"``, ``"nlspsa"``,
        ``"spsa"``, ``"amvo-sca"``, ``"lm"``, or a scipy method).
    x0 : array_like, optional
        Initial beta.  Optional for ``"auto"`` (then one more start; the
        offset and initial state may be left out) and with finite ``bounds``
        (the centre of the box); required otherwise.
    maxfev, maxiter, seed, options, bounds, callback
        Passed to :func:`hammerstein_ctrl.minimize` (``auto`` uses ``maxfev``,
        ``seed`` and ``callback``).
    reject_unstable : bool, default False
        Score unstable candidates as ``inf`` (see :class:`HammersteinCost`).
    offset : bool, optional
        Estimate a constant output offset ``y0`` (overrides the structure's setting).
    initial_state : {"zero", "estimate"}, optional
        Start ``H`` from rest or estimate ``x(0)`` (overrides the structure's setting).
    allow_unstable : bool, default False
        Accept a final model with a right-half-plane pole as a success.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    ParameterError, UnknownNameError, DataError
        On a bad structure, method, initial point or record.
    """
    started = time.perf_counter()
    data = _as_record(data)
    structure, x0 = _resolve_structure(data, structure, method, x0)
    if offset is not None or initial_state is not None:
        structure = structure.with_options(offset=offset, initial_state=initial_state)
    data.check_identifiable(structure.n_params)
    key = AUTO if str(method).strip().lower() == AUTO else canonical_method(method)
    cost = HammersteinCost(data, structure, reject_unstable=reject_unstable)
    with single_threaded_blas():
        if key == AUTO:
            res = _run_auto(cost, x0, maxfev, seed, options, bounds, maxiter, callback, allow_unstable)
        else:
            x0 = _starting_point(structure, x0, bounds)
            res = minimize(cost, x0, method=key, maxfev=maxfev, maxiter=maxiter, seed=seed,
                           options=options, callback=callback, bounds=bounds)
        return _result(cost, res, key, x0, allow_unstable, started)


def _as_record(data) -> IOData:
    """An IOData from an IOData or a ``nonlinear_benchmarks``-style record (``u, y, sampling_time``)."""
    from .display import as_iodata

    try:
        return as_iodata(data)
    except ParameterError:
        raise ParameterError(f"data must be an IOData record (or an object with u, y and sampling_time), "
                             f"got {type(data).__name__}") from None


def _resolve_structure(data, structure, method, x0):
    if isinstance(structure, str):
        from . import presets

        if structure.lower() not in presets.PRESETS:
            raise ParameterError(
                f"unknown structure {structure!r}: give a HammersteinStructure or one of {sorted(presets.PRESETS)}"
            )
        if x0 is None and str(method).strip().lower() != AUTO:
            x0 = presets.X0[structure.lower()]
        structure = presets.STRUCTURES[structure.lower()]()
    if not isinstance(structure, BlockStructure):
        raise ParameterError("structure must be a HammersteinStructure, WienerStructure or "
                             f"HammersteinWienerStructure, got {type(structure).__name__}")
    return structure, x0


def _starting_point(structure, x0, bounds):
    if x0 is None:
        if bounds is None:
            raise ParameterError(
                f"give an initial point x0 = [{', '.join(structure.param_names)}] (or bounds), "
                "or use method='auto', which needs none"
            )
        from .optimize._common import as_bounds

        lo, hi = as_bounds(bounds, structure.n_params)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ParameterError("x0 can only default to the centre of finite bounds")
        x0 = 0.5 * (lo + hi)
    x0 = structure.check_beta(x0)
    if x0.ndim != 1:
        raise ParameterError("x0 must be one beta vector")
    return x0


def _run_auto(cost, x0, maxfev, seed, options, bounds, maxiter, callback, allow_unstable):
    from .auto import auto_minimize

    unused = [name for name, value in (("options", options), ("bounds", bounds), ("maxiter", maxiter))
              if value is not None]
    if unused:
        raise ParameterError(f"method 'auto' does not take {', '.join(unused)}; use maxfev (and x0, seed)")
    if x0 is not None:
        x = np.asarray(x0, dtype=float).reshape(-1)
        if x.size not in (cost.structure.n_core, cost.structure.n_params):
            cost.structure.check_beta(x)
    return auto_minimize(cost, x0, maxfev=maxfev, seed=seed, allow_unstable=allow_unstable, callback=callback)


def _assess(cost, res, key: str, x0, report: dict, allow_unstable: bool) -> tuple[bool, str]:
    """``(success, message)`` after the checks that make a result trustworthy."""
    problems = []
    message = str(res.message)
    x = np.asarray(res.x, dtype=float)
    _, den = cost.structure.linear.coefficients(x[:cost.structure.linear.n_params])
    if not allow_unstable and np.all(np.isfinite(x)) and unstable(den)[0]:
        problems.append("the model is unstable (a pole in the right half-plane); pass allow_unstable=True "
                        "to accept it")
    if not np.all(np.isfinite(x)):
        problems.append("no model: the optimiser returned no finite parameters")
    elif not np.isfinite(res.fun):
        problems.append("the final model cannot be simulated (non-finite output)")
    elif report["fit_percent"] <= 0:
        problems.append(f"fit {report['fit_percent']:.1f} % is no better than a constant")
    elif res.fun >= static_affine_sse(cost.data):
        problems.append(f"J = {res.fun:.6g} is no better than the best static affine gain y = k u + c")
    if key not in _CONVERGING and key != AUTO and x0 is not None and res.status != DIVERGED:
        f0 = cost(x0)
        if np.isfinite(f0) and res.fun >= f0:
            problems.append(f"stalled: no improvement on the initial point (J = {f0:.6g})")
    success = bool(res.success) and not problems
    if problems:
        message = "; ".join(problems) + f" [{message}]"
    return success, message


def _result(cost, res, key, x0, allow_unstable, started) -> IdentificationResult:
    structure, data = cost.structure, cost.data
    x = np.asarray(res.x, dtype=float)
    with np.errstate(all="ignore"):
        yhat = cost.simulate(x) if np.all(np.isfinite(x)) else np.full(len(data), np.nan)
    if np.all(np.isfinite(yhat)):
        report = fit_report(data.y, yhat)
    else:
        report = {"fit_percent": -np.inf, "rmse": np.inf, "nrmse": np.inf}
    success, message = _assess(cost, res, key, x0, report, allow_unstable)
    model = structure.model(x, intersample=data.intersample) if np.all(np.isfinite(x)) else None
    return IdentificationResult(
        model=model, x=x, fun=float(res.fun), nfev=int(res.nfev), fit_percent=report["fit_percent"],
        rmse=report["rmse"], nrmse=report["nrmse"], method=key, success=success,
        message=message, history=res.history, elapsed=time.perf_counter() - started,
        structure=structure, data=data, optimize_result=res,
    )
