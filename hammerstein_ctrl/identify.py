"""Fit a Hammerstein model to a record in one call.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> case = hc.presets.trs()
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

from .datasets import IOData
from .exceptions import ParameterError
from .metrics import fit_report
from .model import HammersteinModel
from .objective import HammersteinCost
from .optimize import canonical_method, minimize
from .structure import HammersteinStructure

__all__ = ["identify", "IdentificationResult"]


@dataclass
class IdentificationResult:
    """The outcome of :func:`identify`.

    Attributes
    ----------
    model : HammersteinModel
        The fitted model; ``model.linear`` is a ``control.TransferFunction``.
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
    structure : HammersteinStructure
    data : IOData
    optimize_result : scipy.optimize.OptimizeResult
        The optimiser's full result.
    """

    model: HammersteinModel
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
    structure: HammersteinStructure = field(repr=False)
    data: IOData = field(repr=False)
    optimize_result: object = field(repr=False)

    @property
    def params(self) -> dict:
        """The fitted parameters by name."""
        return dict(zip(self.structure.param_names, self.x.tolist()))

    def validate(self, data: IOData) -> dict:
        """Goodness of fit (``sse``, ``rmse``, ``nrmse``, ``fit_percent``) on another record."""
        if not isinstance(data, IOData):
            raise ParameterError(f"validate() needs an IOData record, got {type(data).__name__}")
        with np.errstate(all="ignore"):
            yhat = self.model.simulate(data)
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
            "success": self.success, "message": self.message, "elapsed_s": self.elapsed,
            "linear": {"num": num, "den": den},
            "nonlinearity": {"name": self.model.nonlinearity.name,
                             "params": dict(zip(self.model.nonlinearity.param_names,
                                                self.model.params.tolist()))},
        }

    # -- notebook display (logic in display.py / plots.py) ---------------------
    def _repr_html_(self) -> str:
        from .display import result_html
        return result_html(self)

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
    method: str = "nspsa",
    x0=None,
    maxfev: int | None = None,
    seed=None,
    options: dict | None = None,
    bounds=None,
    *,
    maxiter: int | None = None,
    callback=None,
    reject_unstable: bool = False,
) -> IdentificationResult:
    """Identify a Hammerstein model from an input/output record.

    Parameters
    ----------
    data : IOData
        Estimation record.
    structure : HammersteinStructure or {"trs", "emps"}
        The model structure (a preset name uses that case's structure and,
        when ``x0`` is omitted, its initial point).
    method : str, default "nspsa"
        Any method of :func:`hammerstein_ctrl.minimize` (``"nspsa"``,
        ``"nlspsa"``, ``"spsa"``, ``"amvo-sca"``, ``"lm"``, or a scipy method).
    x0 : array_like, optional
        Initial beta.  Required unless ``structure`` is a preset name or
        ``bounds`` are given (then the centre of the box is used).
    maxfev, maxiter, seed, options, bounds, callback
        Passed to :func:`hammerstein_ctrl.minimize`.
    reject_unstable : bool, default False
        Score unstable candidates as ``inf`` (see :class:`HammersteinCost`).

    Returns
    -------
    IdentificationResult

    Raises
    ------
    ParameterError, UnknownNameError, DataError
        On a bad structure, method, initial point or record.
    """
    started = time.perf_counter()
    if not isinstance(data, IOData):
        raise ParameterError(f"data must be an IOData record, got {type(data).__name__}")
    if isinstance(structure, str):
        from . import presets

        if structure.lower() not in presets.PRESETS:
            raise ParameterError(
                f"unknown structure {structure!r}: give a HammersteinStructure or one of {sorted(presets.PRESETS)}"
            )
        if x0 is None:
            x0 = presets.X0[structure.lower()]
        structure = presets.STRUCTURES[structure.lower()]()
    if not isinstance(structure, HammersteinStructure):
        raise ParameterError(f"structure must be a HammersteinStructure, got {type(structure).__name__}")
    key = canonical_method(method)
    if x0 is None:
        if bounds is None:
            raise ParameterError(
                f"give an initial point x0 = [{', '.join(structure.param_names)}] (or bounds)"
            )
        from .optimize._common import as_bounds

        lo, hi = as_bounds(bounds, structure.n_params)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ParameterError("x0 can only default to the centre of finite bounds")
        x0 = 0.5 * (lo + hi)
    x0 = structure.check_beta(x0)
    if x0.ndim != 1:
        raise ParameterError("x0 must be one beta vector")
    cost = HammersteinCost(data, structure, reject_unstable=reject_unstable)
    res = minimize(cost, x0, method=key, maxfev=maxfev, maxiter=maxiter, seed=seed,
                   options=options, callback=callback, bounds=bounds)
    x = np.asarray(res.x, dtype=float)
    model = structure.model(x)
    with np.errstate(all="ignore"):
        yhat = cost.simulate(x)
    if np.all(np.isfinite(yhat)):
        report = fit_report(data.y, yhat)
    else:
        report = {"fit_percent": -np.inf, "rmse": np.inf, "nrmse": np.inf}
    return IdentificationResult(
        model=model, x=x, fun=float(res.fun), nfev=int(res.nfev), fit_percent=report["fit_percent"],
        rmse=report["rmse"], nrmse=report["nrmse"], method=key, success=bool(res.success),
        message=str(res.message), history=res.history, elapsed=time.perf_counter() - started,
        structure=structure, data=data, optimize_result=res,
    )
