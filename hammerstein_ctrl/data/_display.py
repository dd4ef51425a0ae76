"""How results show themselves in Jupyter and beyond.

* :func:`result_html`, :func:`study_html` render results as HTML tables
  (``_repr_html_``); :func:`result_frame`, :func:`study_frame` return pandas
  DataFrames (pandas is the optional ``frames`` extra).
* :func:`response` wraps a simulation in python-control's
  :class:`control.TimeResponseData`.
* :func:`progress` is a ``tqdm.auto`` bar that is off under pytest and in pipes.

What users pass in is normalised by :mod:`~hammerstein_ctrl.data._inputs`.
"""

from __future__ import annotations

import html
import numbers
import os
import sys

import numpy as np

from ..exceptions import ParameterError
from ._inputs import as_iodata, method_label

__all__ = ["progress", "progress_enabled", "register_figure_formatter", "response", "result_html", "study_html",
           "result_frame", "study_frame", "require_pandas", "PROGRESS_ENV"]

#: Environment variable forcing progress bars on ("1") or off ("0").
PROGRESS_ENV = "HAMMERSTEIN_CTRL_PROGRESS"
#: Install hint shown when pandas is missing.
PANDAS_HINT = "pip install hammerstein_ctrl[frames]"
#: Significant digits in the HTML tables.
HTML_DIGITS = 6


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
