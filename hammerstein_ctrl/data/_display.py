"""Jupyter-facing glue: what users pass in, and how results show themselves.

* :func:`as_models` turns one model, a list, a dict of named models or an
  :class:`~hammerstein_ctrl.fit._identify.IdentificationResult` into the
  ``{label: model}`` mapping every plot helper works on.
* :func:`as_iodata` accepts an :class:`~hammerstein_ctrl.data.IOData` or any
  record with ``u``, ``y`` and ``sampling_time`` attributes, such as the
  ``nonlinear_benchmarks`` package's ``Input_output_data``.
* :func:`result_html`, :func:`study_html` render results as HTML tables
  (``_repr_html_``); :func:`result_frame`, :func:`study_frame` return pandas
  DataFrames (pandas is the optional ``frames`` extra).
* :func:`response` wraps a simulation in python-control's
  :class:`control.TimeResponseData`.
* :func:`progress` is a ``tqdm.auto`` bar that is off under pytest and in pipes.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> from hammerstein_ctrl.data._display import as_models
>>> case = hc.presets.trs()
>>> m = case.structure.model(case.true_beta)
>>> list(as_models(m)), list(as_models([m, m])), list(as_models({"truth": m}))
(['hammerstein'], ['model 1', 'model 2'], ['truth'])
"""

from __future__ import annotations

import html
import numbers
import os
import sys
from collections.abc import Mapping

import numpy as np

from .._checks import require_siso_model
from ..exceptions import DataError, ParameterError

__all__ = [
    "as_models", "labelled", "as_iodata", "is_identification_result",
    "progress", "progress_enabled", "register_figure_formatter", "response",
    "result_html", "study_html", "result_frame", "study_frame", "require_pandas",
    "method_label", "PROGRESS_ENV",
]

#: Environment variable forcing progress bars on ("1") or off ("0").
PROGRESS_ENV = "HAMMERSTEIN_CTRL_PROGRESS"
#: Install hint shown when pandas is missing.
PANDAS_HINT = "pip install hammerstein_ctrl[frames]"
#: Significant digits in the HTML tables.
HTML_DIGITS = 6


#: Display names of the methods (in tables, figures and reports).
METHOD_LABELS = {"spsa": "SPSA", "nlspsa": "NL-SPSA", "nspsa": "N-SPSA", "amvo-sca": "AMVO-SCA", "lm": "LM*"}


def method_label(method: str) -> str:
    """Display name of a method key (``"nspsa"`` -> ``"N-SPSA"``); unknown keys pass through."""
    return METHOD_LABELS.get(method, method)


# -- input normalisation -------------------------------------------------------
def is_identification_result(obj) -> bool:
    """Whether ``obj`` is an :class:`~hammerstein_ctrl.fit._identify.IdentificationResult` (or behaves as one).

    Checked by the class flag ``is_identification_result`` rather than by
    importing the class, so this layer never imports the identification layer above it.
    """
    return bool(getattr(type(obj), "is_identification_result", False))


def _is_system(obj) -> bool:
    import control

    return isinstance(obj, control.LTI)


def _default_label(obj, index: int | None) -> str:
    if is_identification_result(obj):
        return method_label(obj.method)
    if isinstance(obj, (np.ndarray, list, tuple)):
        return "simulated" if index is None else f"simulated {index + 1}"
    name = getattr(obj, "name", None)
    if index is None:
        return str(name or type(obj).__name__)
    default = str(getattr(obj, "kind", "hammerstein")).replace("-", "_")
    if isinstance(name, str) and name and name != default and not _is_system(obj):
        return name
    return f"model {index + 1}"


def _check_item(label, obj, *, arrays: bool, systems: bool, need: tuple, siso: bool = True):
    """One model (IdentificationResult unwrapped), array or LTI system, checked for what is needed."""
    if is_identification_result(obj):
        obj = obj.model
    if siso:
        require_siso_model(obj, f"this (model {label!r})", ", or use result.compare() and result.plot(), which draw "
                           "every channel")
    if isinstance(obj, (np.ndarray, list, tuple)) and arrays:
        return np.asarray(obj, dtype=float)
    if systems and _is_system(obj):
        return obj
    if all(hasattr(obj, attr) for attr in need):
        return obj
    kinds = "a HammersteinModel or an IdentificationResult"
    kinds += ", a control.TransferFunction" if systems else ""
    kinds += ", a simulated output array" if arrays else ""
    raise ParameterError(f"model {label!r} must be {kinds}, got {type(obj).__name__}")


def as_models(models, *, arrays: bool = False, systems: bool = False, need=("simulate",),
              allow_empty: bool = False, siso: bool = True) -> dict:
    """Normalise what a user passes as "models" to ``{label: model}``.

    Parameters
    ----------
    models : model, IdentificationResult, list/tuple of them, dict ``{label: model}`` or None
        Labels of list items are the result's method (``"N-SPSA"``), the
        model's own ``name`` when it was given one, else ``"model 1"``, ...
    arrays : bool
        Also accept simulated output arrays as dict values.
    systems : bool
        Also accept python-control LTI systems (for Bode plots).
    need : tuple of str
        Attributes a model must have (e.g. ``("g",)`` for nonlinearity plots).
    allow_empty : bool
        Accept ``None`` or an empty collection (returns ``{}``).
    siso : bool, default True
        Refuse MIMO models (naming ``model.element``) where only SISO ones make sense.

    Raises
    ------
    ParameterError
        On an unsupported type, or an empty collection when not allowed.
    """
    return {key: _check_item(key, obj, arrays=arrays, systems=systems, need=need, siso=siso)
            for key, obj in labelled(models, arrays=arrays, allow_empty=allow_empty).items()}


def labelled(models, *, arrays: bool = False, allow_empty: bool = False) -> dict:
    """``{label: object as given}``, labelled as :func:`as_models` labels them (results are not unwrapped).

    Examples
    --------
    >>> list(labelled([1.0, "x"]))
    ['model 1', 'model 2']
    """
    if models is None:
        items = []
    elif isinstance(models, Mapping):
        items = [(str(k), v) for k, v in models.items()]
    elif isinstance(models, (list, tuple)) and not (arrays and models and isinstance(models[0], numbers.Number)):
        items = [(_default_label(m, i), m) for i, m in enumerate(models)]
    else:
        items = [(_default_label(models, None), models)]
    if not items and not allow_empty:
        raise ParameterError("give at least one model (a model, a list or a dict {label: model})")
    out = {}
    for label, obj in items:
        key, k = label, 2
        while key in out:
            key, k = f"{label} ({k})", k + 1
        out[key] = obj
    return out


def as_iodata(obj):
    """Return ``obj`` as an :class:`~hammerstein_ctrl.data.IOData` record.

    Accepts an ``IOData`` (returned unchanged) or any object with ``u``, ``y``
    and ``sampling_time`` attributes and optionally ``name`` -- the
    ``nonlinear_benchmarks`` package's ``Input_output_data``.

    Raises
    ------
    ParameterError
        When ``obj`` is not a record (a list of records names how many it holds).
    DataError
        When the record has no sampling time or bad samples.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> rec = SimpleNamespace(u=[0.0, 1.0, 0.5], y=[0.0, 0.1, 0.3], sampling_time=0.01, name="train")
    >>> d = as_iodata(rec)
    >>> d.name, d.dt, len(d)
    ('train', 0.01, 3)
    """
    from ._iodata import IOData

    if isinstance(obj, IOData):
        return obj
    if isinstance(obj, (list, tuple)) and obj and all(hasattr(o, "u") for o in obj):
        raise ParameterError(f"expected one input/output record, got a {type(obj).__name__} of {len(obj)}; "
                             "pass one of them")
    if not (hasattr(obj, "u") and hasattr(obj, "y")):
        raise ParameterError(f"expected an IOData record or an object with u, y and sampling_time, "
                             f"got {type(obj).__name__}")
    dt = getattr(obj, "sampling_time", None)
    if dt is None:
        dt = getattr(obj, "dt", None)
    if dt is None:
        raise DataError(f"record {getattr(obj, 'name', '')!r} has no sampling_time: "
                        "build IOData(u, y, dt=...) yourself")
    return IOData(obj.u, obj.y, dt=float(dt), name=str(getattr(obj, "name", None) or "data"))


# -- progress bars -------------------------------------------------------------
def _ipython():
    """The running IPython shell, or None (IPython is never imported here if it is not loaded)."""
    shell = sys.modules.get("IPython")
    return shell.get_ipython() if shell is not None else None


def _in_jupyter() -> bool:
    return type(_ipython()).__name__ == "ZMQInteractiveShell"


def register_figure_formatter() -> bool:
    """In IPython, show a matplotlib ``Figure`` that ends a cell as one PNG image.

    The plot helpers build their figures without pyplot (so the inline
    backend does not show them a second time); this registers IPython's own
    PNG printer for :class:`matplotlib.figure.Figure` unless a figure format
    is already configured (``%config InlineBackend.figure_formats``).  Returns
    whether an IPython shell is running.
    """
    ip = _ipython()
    if ip is None:
        return False
    from IPython.core.pylabtools import print_figure
    from matplotlib.figure import Figure

    formatters = ip.display_formatter.formatters
    if not any(Figure in f.type_printers for f in formatters.values()):
        formatters["image/png"].for_type(Figure, lambda fig: print_figure(fig, "png", bbox_inches="tight"))
    return True


def progress_enabled() -> bool:
    """Whether progress bars show by default.

    ``$HAMMERSTEIN_CTRL_PROGRESS`` (``"0"``/``"1"``) decides when set; otherwise
    they are off under pytest and on in Jupyter or when stderr is a terminal.
    """
    forced = os.environ.get(PROGRESS_ENV, "").strip()
    if forced in ("0", "1"):
        return forced == "1"
    if "PYTEST_CURRENT_TEST" in os.environ:
        return False
    return _in_jupyter() or bool(getattr(sys.stderr, "isatty", lambda: False)())


def progress(iterable_or_total=None, *, enabled: bool | None = None, desc: str | None = None, **kwargs):
    """A ``tqdm.auto`` progress bar, silent unless :func:`progress_enabled` (or ``enabled=True``).

    Parameters
    ----------
    iterable_or_total : iterable or int
        Wrap an iterable, or give the number of steps and call ``.update()``.
    enabled : bool, optional
        Force the bar on or off.
    desc : str, optional
    **kwargs
        Passed to ``tqdm``.

    Examples
    --------
    >>> sum(progress(range(4), desc="trials"))
    6
    >>> with progress(3, enabled=False) as bar:
    ...     bar.update(3)
    """
    from tqdm.auto import tqdm

    on = progress_enabled() if enabled is None else bool(enabled)
    if isinstance(iterable_or_total, numbers.Integral):
        return tqdm(total=int(iterable_or_total), disable=not on, desc=desc, **kwargs)
    return tqdm(iterable_or_total, disable=not on, desc=desc, **kwargs)


# -- python-control time responses ---------------------------------------------
def _label(name: str, unit: str) -> str:
    return f"{name} ({unit})" if unit else name


def response(model, data_or_t, u=None):
    """Simulate ``model`` and return python-control's :class:`control.TimeResponseData`.

    Parameters
    ----------
    model : HammersteinModel
    data_or_t : IOData, benchmark record, or array_like
        A record (its ``t`` and ``u``; signal names and units become the labels)
        or a time grid.
    u : array_like, optional
        Input samples when ``data_or_t`` is a time grid.

    Returns
    -------
    control.TimeResponseData
        ``inputs`` is ``u``, ``outputs`` the simulated ``y``; ``.plot()`` works.

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Tanh
    >>> m = HammersteinModel(ct.tf([1], [1, 1]), Tanh(), [1.0, 1.0])
    >>> r = response(m, np.linspace(0, 5, 51), np.ones(51))
    >>> r.input_labels, r.output_labels, round(float(r.outputs[-1]), 3)
    (['u'], ['y'], 0.756)
    """
    import control

    if u is None:
        if isinstance(data_or_t, np.ndarray):
            raise ParameterError("response(model, t, u) needs the input u (or pass an IOData record)")
        data = as_iodata(data_or_t)
        t, u = data.t, data.u
        labels = (_label(data.input_name, data.input_unit), _label(data.output_name, data.output_unit))
        y = model.simulate(data)
        title = f"{getattr(model, 'name', 'model')} on {data.name}"
    else:
        t, y = np.asarray(data_or_t, dtype=float), model.simulate(data_or_t, u)
        labels, title = ("u", "y"), f"{getattr(model, 'name', 'model')} response"
    return control.TimeResponseData(t, y, inputs=np.asarray(u, dtype=float), issiso=True,
                                     input_labels=[labels[0]], output_labels=[labels[1]], title=title,
                                     sysname=getattr(model, "name", None), plot_inputs=True)


# -- standard errors -----------------------------------------------------------
def _uncertainty_columns(result):
    """``(stderr, low, high)`` arrays aligned with the parameters, or ``None`` when the result has no covariance."""
    if getattr(result, "covariance", None) is None:
        return None
    se = np.array(list(result.stderr.values()))
    bounds = np.array(list(result.conf_int().values()))
    return se, bounds[:, 0], bounds[:, 1]


# -- HTML ----------------------------------------------------------------------
def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.{HTML_DIGITS}g}"
    return html.escape(str(v))


def _table(header, rows, caption: str = "") -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    cap = f"<caption style='text-align:left'>{caption}</caption>" if caption else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def result_html(result) -> str:
    """HTML for an IdentificationResult: status line, fit numbers, the parameter table with standard errors and
    95 % intervals, warnings."""
    unc = _uncertainty_columns(result)
    rows = [[html.escape(k), _fmt(v)] + ([_fmt(unc[0][i]), f"[{_fmt(unc[1][i])}, {_fmt(unc[2][i])}]"]
                                         if unc is not None else [])
            for i, (k, v) in enumerate(result.params.items())]
    header = ["parameter", "value"] + (["std. error", "95 % interval"] if unc is not None else [])
    ok = bool(result.success)
    status = (f"<b style='color:{'green' if ok else 'firebrick'}'>{'success' if ok else 'FAILED'}</b>: "
              f"{html.escape(str(result.message))}")
    data_name = getattr(getattr(result, "data", None), "name", "")
    stats = (f"fit {result.fit_percent:.2f} %, J = {result.fun:.{HTML_DIGITS}g}, RMSE = {result.rmse:.4g}, "
             f"NFE = {result.nfev}, {result.elapsed:.2f} s")
    parts = [f"<div><b>IdentificationResult</b>: {html.escape(method_label(result.method))} on "
             f"{html.escape(str(data_name))}<br>{status}<br>{stats}<br>"
             f"<code>{html.escape(repr(result.model))}</code>",
             _table(header, rows)]
    warns = list(getattr(result, "warnings", None) or [])
    if warns:
        parts.append("<ul>" + "".join(f"<li>warning: {html.escape(str(w))}</li>" for w in warns) + "</ul>")
    return "".join(parts) + "</div>"


_SUMMARY_COLUMNS = ("n", "mean", "median", "best", "worst", "std", "nfev", "diverged", "time_mean")


def study_html(study, alpha: float = 0.05) -> str:
    """HTML comparison table of a StudyResult (ours, then the paper's value in grey), with rank-sum notes."""
    s = study.summary(alpha)
    paper = getattr(study.case, "paper", {}) or {}
    header = ["method", "source", "mean", "median", "best", "worst", "std", "NFE", "diverged", "s/trial"]
    rows = []
    for m in study.methods:
        st = s[m]
        style = " style='color:firebrick'" if st["diverged"] else ""
        rows.append([f"<b>{html.escape(method_label(m))}</b>", "ours",
                     *(_fmt(st[c]) for c in ("mean", "median", "best", "worst", "std")),
                     f"{st['nfev']:.0f}", f"<span{style}>{st['diverged']}/{st['n']}</span>",
                     f"{st['time_mean']:.3f}"])
        if m in paper:
            p = paper[m]
            rows.append(["", "<i>paper</i>", _paper_cell(p, "mean"), "",
                         *(_paper_cell(p, c) for c in ("best", "worst", "std", "nfev")), "", ""])
    n = max((st["n"] for k, st in s.items() if k != "ranksum"), default=0)
    caption = (f"<b>{html.escape(study.case.name.upper())}</b>: final J = Σ(y − ŷ)² over {n} "
               f"independent trials, seed {study.seed}")
    notes = [_ranksum_note(pair, r, paper.get("ranksum"), alpha) for pair, r in s["ranksum"].items()]
    return (_table(header, rows, caption)
            + ("<ul>" + "".join(f"<li>{x}</li>" for x in notes) + "</ul>" if notes else ""))


def _paper_cell(row: dict, column: str) -> str:
    return f"<i>{_fmt(row.get(column)) or 'N/A'}</i>"


def _ranksum_note(pair: str, r: dict, ref, alpha: float) -> str:
    a, b = pair.split(" vs ")
    text = (f"Wilcoxon rank-sum {html.escape(method_label(a))} vs {html.escape(method_label(b))}: "
            f"p = {r['p']:.3g}, h = {r['h']} (α = {alpha:g})")
    if ref and set(ref.get("pair", ())) == {a, b}:
        text += f"; paper: p = {ref['p']:.3g}, h = {ref['h']}"
    return text


# -- DataFrames ----------------------------------------------------------------
def require_pandas():
    """Import pandas or raise an ImportError that says how to install it."""
    try:
        import pandas
    except ImportError as exc:
        raise ImportError(f"to_frame() needs pandas, an optional dependency: {PANDAS_HINT}") from exc
    return pandas


def result_frame(result):
    """The fitted parameters as a DataFrame (index: parameter names; ``value``, ``stderr``, ``low``, ``high``:
    the 95 % interval; NaN without a covariance).

    Run facts (method, J, fit %, NFE, success, message, warnings) are in ``frame.attrs``.
    """
    pd = require_pandas()
    names = list(result.params)
    unc = _uncertainty_columns(result)
    nan = np.full(len(names), np.nan)
    se, low, high = unc if unc is not None else (nan, nan, nan)
    frame = pd.DataFrame({"value": list(result.params.values()), "stderr": se, "low": low, "high": high},
                         index=pd.Index(names, name="parameter"))
    frame.attrs.update(method=result.method, J=float(result.fun), fit_percent=float(result.fit_percent),
                       nfev=int(result.nfev), success=bool(result.success), message=str(result.message),
                       warnings=list(getattr(result, "warnings", None) or []))
    return frame


def study_frame(study, trials: bool = False, alpha: float = 0.05):
    """A StudyResult as a DataFrame.

    ``trials=False`` (default): one row per method with ``n, mean, median,
    best, worst, std, nfev, diverged, time_mean``.  ``trials=True``: one row per
    trial with its seed, final J, NFE, status, divergence, time and parameters.
    """
    pd = require_pandas()
    if trials:
        names = list(study.case.structure.param_names)
        rows = [{"method": r["method"], "trial": r["trial"], "seed": r["seed"], "J": float(r["fun"]),
                 "nfev": r["nfev"], "status": r["status"], "diverged": bool(r["diverged"]),
                 "elapsed": r["elapsed"], **dict(zip(names, (float(v) for v in r["x"])))}
                for r in study.records]
        return pd.DataFrame(rows).set_index(["method", "trial"])
    s = study.summary(alpha)
    frame = pd.DataFrame([{c: s[m][c] for c in _SUMMARY_COLUMNS} for m in study.methods],
                         index=pd.Index(study.methods, name="method"))
    frame.attrs.update(case=study.case.name, seed=study.seed)
    return frame
