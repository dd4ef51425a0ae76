"""The result of an identification: one type for a fit just made and for one read back from a file.

:func:`hammerstein_ctrl.fit` returns an :class:`IdentificationResult`;
:func:`hammerstein_ctrl.load_result` reads one back, with the record's
description in place of its samples.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ParameterError
from ..data._iodata import IOData
from ..data._metrics import channel_report, fit_report
from ..blocks._model import BlockModel
from ..assess._residuals import ResidualAnalysis, residual_analysis
from ..blocks._structure import BlockStructure
from ..assess._uncertainty import ParameterUncertainty, Propagated
from ..assess._propagation import UncertainParameters

__all__ = ["IdentificationResult"]


@dataclass
class IdentificationResult(UncertainParameters):
    """The outcome of :func:`identify`.

    Attributes
    ----------
    model : BlockModel
        The fitted model (a HammersteinModel, WienerModel or
        HammersteinWienerModel); ``model.linear`` is a ``control.TransferFunction``.
        After a fit to several records: with the first record's offset and initial state.
    x : ndarray
        The fitted beta (after a fit to several records: the block parameters, then
        each record's offset and initial state, as ``structure.param_names`` says).
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
    structure : BlockStructure or RecordsStructure
        The structure fitted (:class:`~hammerstein_ctrl.fit.RecordsStructure` for several records).
    data : IOData
        The estimation record (the first one of several).
    optimize_result : hammerstein_ctrl.optimize.OptimizeResult
        The optimiser's full result.
    covariance : ndarray or None
        Covariance of ``x`` (aligned with it; ``inf`` on the diagonal of a
        parameter the record does not determine); ``None`` when not computed.
    warnings : list of str
        Every verdict's message (failures and warnings), in order.
    verdicts : list of Verdict
        The findings behind ``warnings`` and ``success``
        (:class:`~hammerstein_ctrl.assess.Verdict`).
    uncertainty : ParameterUncertainty or None
        The covariance with the noise model and degrees of freedom it came from.
    saved : dict
        For a result read from a file (:func:`hammerstein_ctrl.load_result`):
        the optimiser's ``status`` and the residuals' ``dof`` as saved; such a
        result has ``data`` as a description of the record (a dict: name,
        dt, n_samples, labels, units, intersample), no ``optimize_result``
        and no ``history``, and the methods that need the samples take the
        record as an argument.
    records : tuple of IOData
        After a fit to several records, all of them (``fun``, the fit figures,
        the covariance and the residual analysis cover them all); else empty.
    models : tuple of BlockModel
        After a fit to several records, each record's model: the shared blocks
        with that record's offset and initial state; else empty.
    output_fits : dict
        After a MIMO fit (:mod:`~hammerstein_ctrl.blocks`), the fit % of each
        output by name (``fit_percent`` is their mean, ``rmse`` over every
        output's samples); else empty.

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Polynomial(1))
    >>> t = np.arange(500) * 0.05
    >>> u = np.sin(0.7 * t)
    >>> y = s.model([2.0, 3.0]).simulate(t, u) + 0.01 * np.random.default_rng(0).standard_normal(500)
    >>> res = hc.identify(hc.IOData(u, y, dt=0.05), s)
    >>> isinstance(res, IdentificationResult), res.success, sorted(res.params)
    (True, True, ['a0', 'd1'])
    """

    #: Lets the display and plotting layers recognise a result without importing this module.
    is_identification_result = True
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
    covariance: np.ndarray | None = field(default=None, repr=False)
    warnings: list = field(default_factory=list)
    verdicts: list = field(default_factory=list, repr=False)
    uncertainty: ParameterUncertainty | None = field(default=None, repr=False)
    analysis: ResidualAnalysis | None = field(default=None, repr=False)
    records: tuple = field(default=(), repr=False)
    models: tuple = field(default=(), repr=False)
    output_fits: dict = field(default_factory=dict)
    saved: dict = field(default_factory=dict, repr=False)

    @property
    def params(self) -> dict:
        """The fitted parameters by name."""
        return dict(zip(self.structure.param_names, self.x.tolist()))

    @property
    def dof(self) -> int | None:
        """Degrees of freedom of the residuals, ``N - p`` (``N`` over all records of a joint fit)."""
        if "dof" in self.saved:
            return self.saved["dof"]
        n = sum(len(r) for r in self.records) if self.records else len(self.data) * self.data.n_outputs
        return n - len(self.x)

    @property
    def status(self) -> int | None:
        """The optimiser's termination code (the table in :mod:`hammerstein_ctrl.optimize`; 5: the budget ran out
        first); ``None`` for a result read from a file that does not say."""
        if self.optimize_result is None:
            return self.saved.get("status")
        return int(self.optimize_result.status)

    @property
    def record_name(self) -> str:
        """Name of the estimation record (also of a result read from a file)."""
        return str(self.data["name"] if isinstance(self.data, dict) else self.data.name)

    def _record(self):
        """The estimation record's samples, which a result read from a file does not have."""
        if isinstance(self.data, dict):
            raise ParameterError(f"this result was read from a file, which keeps only a description of its record "
                                 f"{self.record_name!r}: pass the record itself (data=...)")
        return self.data

    def validate(self, data, *, initial_state: str | None = None, offset: str = "model"):
        """Goodness of fit (``sse``, ``rmse``, ``nrmse``, ``fit_percent``) on another record, or on each of a list.

        Parameters
        ----------
        data : IOData or list of IOData
            A list gives a list of reports, one per record. After a fit to
            several records, each of those records is simulated with its own
            offset and initial state (:attr:`models`); any other record with
            :attr:`model` (the first record's).
        initial_state : {"zero", "estimate"}, optional
            Start the model from rest, or estimate its initial state on
            ``data`` by least squares through the whole model, output map and
            feedback included (as MATLAB's ``compare`` does;
            :func:`~hammerstein_ctrl.fit._baselines.estimate_initial_state`).
            Default: ``"estimate"`` if the identification estimated it, else
            ``"zero"``.
        offset : {"model", "estimate"}, default "model"
            Keep the model's output offset, or re-estimate it on ``data`` with
            the initial state (a new experiment at another operating point;
            the report then has ``offset``, the value used).

        Examples
        --------
        >>> import numpy as np, hammerstein_ctrl as hc
        >>> rng = np.random.default_rng(0); u = rng.uniform(-1, 1, 400)
        >>> truth = hc.HammersteinModel(([1.0], [1.0, 1.2]), hc.Tanh(), [2.0, 1.5], offset=0.5)
        >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Tanh(), offset=True)
        >>> res = hc.identify(hc.IOData(u, truth.simulate(np.arange(400) * 0.05, u), dt=0.05), s)
        >>> new = hc.IOData(u, truth.simulate(np.arange(400) * 0.05, u) - 1.5, dt=0.05)  # another operating point
        >>> round(res.validate(new)["fit_percent"]) < 0, round(res.validate(new, offset="estimate")["fit_percent"], 3)
        (True, 100.0)
        """
        from ..data._inputs import as_iodata

        if self.model is None:
            raise ParameterError(f"this identification produced no model, so there is nothing to validate "
                                 f"({self.message})")
        if isinstance(data, (list, tuple)) and data and all(hasattr(d, "u") for d in data):
            return [self.validate(d, initial_state=initial_state, offset=offset) for d in data]
        data = as_iodata(data)
        if offset not in ("model", "estimate"):
            raise ParameterError(f"offset must be 'model' or 'estimate', got {offset!r}")
        if self.is_mimo:
            if offset != "model":
                raise ParameterError("a MIMO model is validated with its own offsets (offset='model')")
            return self._validate_channels(data, initial_state)
        yhat, c = self._simulated_on(self._model_for(data), data, initial_state, offset == "estimate")
        report = (fit_report(data.y, yhat) if np.all(np.isfinite(yhat))
                  else {"sse": np.inf, "rmse": np.inf, "nrmse": np.inf, "fit_percent": -np.inf})
        return report if c is None else {**report, "offset": c}

    def _simulated_on(self, model, data, initial_state, offset: bool):
        """``(simulated output, re-estimated offset or None)`` of ``model`` on ``data``."""
        from ._baselines import estimate_initial_state

        mode = initial_state or self.structure.initial_state
        if mode not in ("zero", "estimate"):
            raise ParameterError(f"initial_state must be 'zero' or 'estimate', got {initial_state!r}")
        if offset and not hasattr(model, "offset"):
            raise ParameterError(f"a {type(model).__name__} has no output offset to re-estimate")
        with np.errstate(all="ignore"):
            if mode == "zero" and not offset:
                return model.simulate(data, initial_state=np.zeros(model.order)), None
            if mode == "zero":   # the offset alone: the mean of what the model leaves
                rest = model.simulate(data, initial_state=np.zeros(model.order)) - model.offset
                c = float(np.mean(np.asarray(data.y, dtype=float) - rest))
                return rest + c, c
            found = estimate_initial_state(model, data, offset=offset)
            x0, c = found if offset else (found, None)
            y = model.simulate(data, initial_state=x0)
            return (y, None) if c is None else (y - model.offset + c, c)

    @property
    def is_mimo(self) -> bool:
        """Whether the fit is of a MIMO structure (:mod:`~hammerstein_ctrl.blocks`)."""
        return str(getattr(self.structure, "kind", "")).startswith("mimo")

    def _validate_channels(self, data, initial_state):
        """:meth:`validate` of a MIMO model: the overall figures and ``outputs``, each output's own."""
        if initial_state not in (None, "zero"):
            raise ParameterError("a MIMO model is simulated from rest (initial_state='zero')")
        model = self.model
        if (data.n_inputs, data.n_outputs) != (model.n_inputs, model.n_outputs):
            raise ParameterError(f"record {data.name!r} has {data.n_inputs} input(s) and {data.n_outputs} "
                                 f"output(s); the model has {model.n_inputs} and {model.n_outputs}")
        with np.errstate(all="ignore"):
            Y = model.simulate(data)
        if not np.all(np.isfinite(Y)):
            return {"sse": np.inf, "rmse": np.inf, "nrmse": np.inf, "fit_percent": -np.inf, "outputs": {}}
        return channel_report(data.outputs, Y, data.output_names)

    def _model_for(self, data):
        """The model of ``data`` if it is one of a joint fit's records (for a result read from a file: the record
        of that name, length and sampling time), else :attr:`model`."""
        for record, model in zip(self.records, self.models):
            if record is data:
                return model
        alike = [m for r, m in zip(self.records, self.models) if isinstance(r, dict) and r["name"] == data.name
                 and r["n_samples"] == len(data) and r["dt"] == data.dt]
        if len(alike) > 1:
            raise ParameterError(f"{len(alike)} records of this fit are named {data.name!r} with the same length and "
                                 "sampling time: give the records distinct names to validate one with its own offset "
                                 "and initial state")
        return alike[0] if alike else self.model

    def residual_analysis(self, data=None, *, lags: int | None = None, initial_state: str | None = None,
                          output=0, input=0) -> ResidualAnalysis:
        """Residual analysis (MATLAB ``resid``) on the estimation record or on ``data``.

        Parameters
        ----------
        data : IOData, optional
            Another record (default: the estimation record, as analysed when
            the result was made).
        lags : int, optional
            Default ``config.defaults["residual_analysis.lags"]``.
        initial_state : {"zero", "estimate"}, optional
            For another record, as :meth:`validate` (default: as identified).
        output, input : int or str, default 0
            For a MIMO fit: the output whose residuals are analysed, against which input.

        Returns
        -------
        ResidualAnalysis
            Its ``plot()`` draws the correlations with their 99 % bounds.
        """
        if self.model is None:
            raise ParameterError(f"this identification produced no model to analyse ({self.message})")
        from ..data._inputs import as_iodata

        if self.is_mimo:
            if initial_state not in (None, "zero"):
                raise ParameterError("a MIMO model is simulated from rest (initial_state='zero')")
            record = (self._record() if data is None else as_iodata(data)).channel()
            if not (isinstance(output, (str, int, np.integer)) and isinstance(input, (str, int, np.integer))):
                raise ParameterError(f"output and input must each be one channel (a name or an index), got "
                                     f"{output!r} and {input!r}")
            o = record._channel_index(output, record.output_names, "output")[0]
            i = record._channel_index(input, record.input_names, "input")[0]
            with np.errstate(all="ignore"):
                yhat = self.model.simulate(record)[:, o]
            return residual_analysis(record.outputs[:, o] - yhat, record.inputs[:, i], dt=record.dt, simulated=yhat,
                                     lags=lags, name=f"{record.name}: {record.output_names[o]} against "
                                                     f"{record.input_names[i]}")
        if data is None and self.analysis is not None and lags in (None, self.analysis.lags[-1]):
            return self.analysis
        record = self._record() if data is None else as_iodata(data)
        yhat = self._simulated(record, initial_state)
        if not np.all(np.isfinite(yhat)):
            raise ParameterError(f"the model cannot be simulated on {record.name!r} (its output is not finite)")
        return residual_analysis(record.y - yhat, record.u, dt=record.dt, simulated=yhat, lags=lags,
                                 name=record.name)

    def _simulated(self, record, initial_state):
        if record is self.data and initial_state is None:
            with np.errstate(all="ignore"):
                return self.model.simulate(record)
        return self._simulated_on(self.model, record, initial_state, False)[0]

    def propagate(self, fun, *, level: float | None = None, method: str = "linear", samples: int = 2000,
                  seed=None) -> Propagated:
        """The uncertainty of any quantity computed from the fitted model.

        Parameters
        ----------
        fun : callable
            ``fun(model) -> array_like`` of real numbers, e.g.
            ``lambda m: m.linear.dcgain()``.
        level, method, samples, seed
            As :func:`hammerstein_ctrl.assess.propagate` (``"linear"``
            or seeded ``"sampling"`` from the covariance).

        Returns
        -------
        Propagated
            ``value``, ``stderr``, ``low``, ``high``.
        """
        from ..assess._propagation import propagate

        if self.covariance is None:
            raise ParameterError("this result carries no covariance (identify(..., uncertainty=False), or no model)")
        hold = self.data["intersample"] if isinstance(self.data, dict) else self.data.intersample
        structure = self.structure
        names = {} if not self.is_mimo or self.model is None else {
            "input_names": self.model.input_names, "output_names": self.model.output_names}
        return propagate(lambda b: fun(structure.model(b, intersample=hold, **names)), self.x, self.covariance,
                         level=level, dof=self.dof, method=method, samples=samples, seed=seed)

    def characteristics(self, level: float | None = None):
        """Poles, zeros, time constants, natural frequencies, damping and the DC gain of ``H``, with their uncertainty.

        Returns
        -------
        CharacteristicsTable
            Rows ``(quantity, value, stderr, low, high)``; renders in Jupyter,
            ``to_frame()`` gives a DataFrame.
        """
        from ..assess._propagation import linear_characteristics, row_characteristics

        if self.covariance is None:
            raise ParameterError("this result carries no covariance (identify(..., uncertainty=False), or no model)")
        if self.is_mimo:
            return row_characteristics(self.structure, self.x, self.covariance, level=level, dof=self.dof,
                                       names=(self.model.input_names, self.model.output_names))
        return linear_characteristics(self.structure, self.x, self.covariance, level=level, dof=self.dof)

    @property
    def minima(self) -> np.ndarray:
        """The different J values at which the automatic method's refinements ended (ascending; empty for other
        methods): more than one means the starts found different local minima, and :attr:`fun` is the lowest."""
        found = None if self.optimize_result is None else self.optimize_result.get("minima")
        return np.asarray([] if found is None else found, dtype=float)

    def summary(self) -> str:
        """A short human-readable report: figures, parameters with standard errors, warnings, and the spread of the
        minima the starts ended in (when they ended in more than one)."""
        se = self.stderr if self.covariance is not None else {}
        names = ", ".join(f"{k} = {v:.6g}" + (f" ± {se[k]:.2g}" if k in se else "") for k, v in self.params.items())
        status = "ok" if self.success else "FAILED"
        warned = "".join(f"\n  warning: {w}" for w in self.warnings if w not in self.message)
        minima = self.minima
        spread = (f"\n  starts: {minima.size} different minima, J = {minima[0]:.6g} (kept) to {minima[-1]:.6g}"
                  if minima.size > 1 else "")
        return (
            f"{self.method} on {self.record_name!r}: J = {self.fun:.6g}, fit = {self.fit_percent:.2f} %, "
            f"RMSE = {self.rmse:.4g}, nfev = {self.nfev}, {self.elapsed:.2f} s [{status}: {self.message}]\n"
            f"  {self.structure.describe()}\n  {names}\n  model: {self.model!r}{warned}{spread}"
        )

    def to_dict(self) -> dict:
        """JSON-serialisable description of the fitted model and the run."""
        if self.is_mimo:
            from ..blocks._json import json_safe, model_to_dict

            return json_safe({
                "method": self.method, "data": self.record_name, "structure": self.structure.describe(),
                "params": self.params, "beta": self.x.tolist(), "J": self.fun, "nfev": self.nfev,
                "fit_percent": self.fit_percent, "output_fits": dict(self.output_fits), "rmse": self.rmse,
                "nrmse": self.nrmse, "success": self.success, "status": self.status, "message": self.message,
                "elapsed_s": self.elapsed, "stderr": None if self.covariance is None else list(self.stderr.values()),
                "warnings": list(self.warnings), "model": model_to_dict(self.model)})
        num = np.asarray(self.model.linear.num[0][0], dtype=float).tolist()
        den = np.asarray(self.model.linear.den[0][0], dtype=float).tolist()
        return {
            "method": self.method, "data": self.record_name, "structure": self.structure.describe(),
            "params": self.params, "beta": self.x.tolist(), "J": self.fun, "nfev": self.nfev,
            "fit_percent": self.fit_percent, "rmse": self.rmse, "nrmse": self.nrmse,
            "success": self.success, "status": self.status, "message": self.message, "elapsed_s": self.elapsed,
            "stderr": None if self.covariance is None else list(self.stderr.values()), "warnings": list(self.warnings),
            "linear": {"num": num, "den": den},
            **{key: {"name": nl.name, "params": dict(zip(nl.param_names, np.asarray(p).tolist()))}
               for key, nl, p in (("nonlinearity", self.model.input_nonlinearity, self.model.input_params),
                                  ("output_nonlinearity", self.model.output_nonlinearity,
                                   self.model.output_params)) if nl is not None},
        }

    # -- notebook display (logic in display.py / plots.py) ---------------------
    def _repr_html_(self) -> str:
        from ..data._display import result_html
        return result_html(self)

    def _repr_pretty_(self, printer, cycle):  # IPython's text view: the summary, not the dataclass fields
        printer.text(self.summary())

    def plot(self, data=None, **kwargs):
        """Measured vs simulated output, residual and g(u) (:func:`hammerstein_ctrl.plotting.result_figure`).

        ``data`` is the estimation record, for a result read from a file (which keeps only its description)."""
        import dataclasses

        from ..data._inputs import as_iodata
        from ..plotting._results import result_figure

        result = self if data is None else dataclasses.replace(self, data=as_iodata(data))
        result._record()
        return result_figure(result, **kwargs)

    def compare(self, *records, **kwargs):
        """Fit % of this model on each record, one figure (:func:`hammerstein_ctrl.plotting.compare`).

        Without records: the estimation record, or every record of a joint fit.
        """
        from ..plotting._results import compare
        if not records and self.records and not isinstance(self.data, dict):
            return compare(list(self.records), list(self.models), paired=True, **kwargs)
        return compare(list(records) or [self._record()], self, **kwargs)

    def to_frame(self):
        """Parameters (``value``, ``stderr``) as a pandas DataFrame
        (:func:`hammerstein_ctrl.data._display.result_frame`)."""
        from ..data._display import result_frame
        return result_frame(self)
