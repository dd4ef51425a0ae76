"""Figures for judging identified models (the paper's figures 2-3, 6, 8-12, 14, 16-18).

Every helper returns a :class:`matplotlib.figure.Figure` built *without* pyplot,
so a notebook cell ending in a plot call shows the figure once (Jupyter renders
the returned Figure, see :func:`~hammerstein_ctrl.data._display.register_figure_formatter`;
nothing is left registered with pyplot to be shown again), and none calls
``plt.show()``.  In a script, write them with ``fig.savefig(path)``.  Helpers
that draw one axes also accept ``ax`` (then they draw into your figure).

Wherever a model is expected you may pass one model, a list, a dict
``{label: model}`` or an :class:`~hammerstein_ctrl.fit._identify.IdentificationResult`
(see :func:`hammerstein_ctrl.data._inputs.as_models`); wherever a record is expected,
an :class:`~hammerstein_ctrl.data.IOData` or a ``nonlinear_benchmarks``
record (see :func:`hammerstein_ctrl.data._inputs.as_iodata`).

Examples
--------
>>> import hammerstein_ctrl as hc
>>> from hammerstein_ctrl.plotting import _figures as plots
>>> case = hc.presets.trs()
>>> fig = plots.time_response(case.data, case.structure.model(case.true_beta), zoom=(100, 150))
>>> [(ax.get_title(), ax.get_ylabel()) for ax in fig.axes]   # the zoom shares the y axis
[('full record', 'pitch y (rad)'), ('zoom 100-150 s', '')]
>>> fig.savefig("response.png")                              # doctest: +SKIP
"""

from __future__ import annotations


import numpy as np

from ..data._display import register_figure_formatter
from ..data._inputs import as_iodata, as_models
from ..exceptions import ParameterError

__all__ = ["time_response", "error_response", "MIN_PEAK_BINS", "PEAK_PROMINENCE", "SMOOTH_BINS", "LOG_SPAN"]

#: Default lower edge of the PSD peak search, in Welch resolution widths (keeps the DC end out).
MIN_PEAK_BINS = 3
#: A PSD peak must stand out by this many decades above the valleys around it.
PEAK_PROMINENCE = 0.5
#: Bins over which the log-PSD is averaged before the peak search.
SMOOTH_BINS = 5
#: Welch segment length (samples) used by default.
NPERSEG = 1024
#: Ratio of largest to smallest final J above which final_cost uses a log scale.
LOG_SPAN = 10.0
#: Samples shown in the zoom panel of the study's input figure.
INPUT_ZOOM_SAMPLES = 200
#: Resolution of the saved study figures (dots per inch).
FIGURE_DPI = 110
_ROW_HEIGHT = 2.2
_WIDTH = 9.5
_MEASURED = dict(color="k", lw=1.0)


def _label(name: str, unit: str) -> str:
    return f"{name} ({unit})" if unit else name


def _new_figure(nrows=1, ncols=1, figsize=(_WIDTH, 4), **kwargs):
    """A Figure not registered with pyplot (so Jupyter shows it once) and its 2-D axes array."""
    from matplotlib.figure import Figure

    register_figure_formatter()
    fig = Figure(figsize=figsize, layout="constrained")
    return fig, fig.subplots(nrows, ncols, squeeze=False, **kwargs)


def _single_axes(ax, figsize=(_WIDTH, 4)):
    if ax is not None:
        return ax.figure, ax
    fig, axes = _new_figure(figsize=figsize)
    return fig, axes[0, 0]


def _finish(a, *, xlabel=None, ylabel=None, title=None, legend=True, grid="major"):
    if xlabel:
        a.set_xlabel(xlabel)
    if ylabel:
        a.set_ylabel(ylabel)
    if title:
        a.set_title(title, fontsize="medium")
    if legend and a.get_legend_handles_labels()[0]:
        a.legend(loc="best", fontsize="small")
    a.grid(True, which=grid, alpha=0.3)


def _outputs(data, models) -> tuple[dict, list]:
    """Simulate each model on the record; returns ``({label: y}, [labels with non-finite output])``."""
    ys, bad = {}, []
    for label, m in models.items():
        if isinstance(m, np.ndarray):
            if m.shape != data.y.shape:
                raise ParameterError(f"output for {label!r} has shape {m.shape}, the record {data.y.shape}")
            y = m
        else:
            if (getattr(m, "n_inputs", 1), getattr(m, "n_outputs", 1)) != (data.n_inputs, data.n_outputs):
                raise ParameterError(f"model {label!r} has {getattr(m, 'n_inputs', 1)} input(s) and "
                                     f"{getattr(m, 'n_outputs', 1)} output(s); record {data.name!r} has "
                                     f"{data.n_inputs} and {data.n_outputs}")
            with np.errstate(all="ignore"):
                y = np.asarray(m.simulate(data), dtype=float)
        if np.all(np.isfinite(y)):
            ys[label] = y
        else:
            bad.append(label)
    return ys, bad


def _siso_record(data):
    """A record for a figure of one input and one output (a MIMO record: a one-line error naming the way out)."""
    return as_iodata(data).require_siso("this figure", mimo_hint="draw every channel with plots.compare or "
                                        "result.plot()")


def _mark_unusable(a, bad):
    for label in bad:
        a.plot([], [], " ", label=f"{label}: non-finite output (not drawn)")


def _window(data, zoom):
    try:
        lo, hi = (float(v) for v in zoom)
    except (TypeError, ValueError):
        raise ParameterError(f"zoom must be a (start, stop) pair of times, got {zoom!r}") from None
    if not lo < hi:
        raise ParameterError(f"zoom window must be (start, stop) with start < stop, got {zoom}")
    return (data.t >= lo) & (data.t <= hi)


def _time_rows(data, zoom, nrows, ax, head):
    """Rows of ``(mask, axes)`` panels: the full record and, with ``zoom``, a zoom to its right.

    With a zoom the figure title is ``head`` and the columns are titled; the
    zoom panels share the rows' y axes, so they carry no label or legend.
    """
    if ax is not None:
        ax.set_title(head, fontsize="medium")
        return ax.figure, [[(np.ones(len(data), bool), ax)]]
    ncols = 1 if zoom is None else 2
    fig, axes = _new_figure(nrows, ncols, figsize=(_WIDTH if ncols == 1 else 12, 1.0 + _ROW_HEIGHT * max(nrows, 1.6)),
                            sharey=True, sharex="col")
    rows = [[(np.ones(len(data), bool), axes[r, 0])] for r in range(nrows)]
    if zoom is None:
        axes[0, 0].set_title(head, fontsize="medium")
        return fig, rows
    fig.suptitle(head)
    axes[0, 0].set_title("full record", fontsize="medium")
    axes[0, 1].set_title(f"zoom {zoom[0]:g}-{zoom[1]:g} s", fontsize="medium")
    for r in range(nrows):
        rows[r].append((_window(data, zoom), axes[r, 1]))
        axes[r, 0].axvspan(*zoom, color="0.88", zorder=0)
    return fig, rows


def time_response(data, models=None, *, zoom=None, title=None, ax=None):
    """Measured output and model outputs over time (figures 8, 16), with an optional zoom (figures 9, 17).

    Parameters
    ----------
    data : IOData or benchmark record
    models : model, list, dict or IdentificationResult, optional
        Models (or simulated output arrays in a dict) to overlay on the measurement.
    zoom : (float, float), optional
        Time window (s) shown in a panel to the right of the full record.
    title : str, optional
    ax : matplotlib Axes, optional
        Draw the full record there (no zoom panel).
    """
    data = _siso_record(data)
    models = as_models(models, arrays=True, allow_empty=True)
    if zoom is not None:
        _window(data, zoom)
    ys, bad = _outputs(data, models)
    fig, rows = _time_rows(data, zoom, 1, ax, title or f"{data.name}: measured and simulated output")
    for j, (sel, a) in enumerate(rows[0]):
        a.plot(data.t[sel], data.y[sel], label="measured", **_MEASURED)
        for label, y in ys.items():
            a.plot(data.t[sel], y[sel], lw=1.0, label=label)
        if j == 0:
            _mark_unusable(a, bad)
        _finish(a, xlabel="time (s)", ylabel=_label(data.output_name, data.output_unit) if j == 0 else None,
                legend=j == 0)
    return fig


def _rms(e):
    return float(np.sqrt(np.mean(np.square(e))))


def error_response(data, models, *, zoom=None, title=None, ax=None):
    """Output error ``y - yhat`` of each model (figures 10-11, 18): one row of panels per model.

    The rows share the y axis so the error sizes compare at a glance.  With
    ``ax`` every model is drawn into that one axes, largest RMS error first
    and semi-transparent, so the smaller errors stay visible on top.
    """
    data = _siso_record(data)
    models = as_models(models, arrays=True)
    if zoom is not None:
        _window(data, zoom)
    ys, bad = _outputs(data, models)
    errors = {label: data.y - y for label, y in ys.items()}
    unit = f" {data.output_unit}" if data.output_unit else ""
    ylabel = _label(f"error in {data.output_name}", data.output_unit)
    head = title or f"{data.name}: output error y - yhat"
    if ax is not None:
        for label, e in sorted(errors.items(), key=lambda kv: -_rms(kv[1])):
            ax.plot(data.t, e, lw=0.8, alpha=0.7, label=f"{label} (RMS {_rms(e):.3g}{unit})")
        _mark_unusable(ax, bad)
        ax.axhline(0.0, color="k", lw=0.6)
        _finish(ax, xlabel="time (s)", ylabel=ylabel, title=head)
        return ax.figure
    fig, rows = _time_rows(data, zoom, max(len(errors), 1), None, head)
    colors = _colors()
    for i, (row, (label, e)) in enumerate(zip(rows, errors.items())):
        for j, (sel, a) in enumerate(row):
            a.plot(data.t[sel], e[sel], lw=0.8, color=colors[i % len(colors)],
                   label=f"{label} (RMS {_rms(e):.3g}{unit})")
            a.axhline(0.0, color="k", lw=0.6)
            _finish(a, ylabel=ylabel if j == 0 else None, legend=j == 0)
    first = rows[0][0][1]
    if not errors:
        first.text(0.5, 0.5, "no model with a finite output", transform=first.transAxes, ha="center")
    _mark_unusable(first, bad)
    for _, a in rows[-1]:
        a.set_xlabel("time (s)")
    _finish(first, ylabel=ylabel)
    return fig


def _colors():
    import matplotlib

    return matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]


