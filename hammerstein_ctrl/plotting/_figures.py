"""Figures for judging identified models (the paper's Figs. 2-3, 6, 8-12, 14, 16-18).

Every helper returns a :class:`matplotlib.figure.Figure` built *without* pyplot,
so a notebook cell ending in a plot call shows the figure once (Jupyter renders
the returned Figure, see :func:`~hammerstein_ctrl.data._display.register_figure_formatter`;
nothing is left registered with pyplot to be shown again), and none calls
``plt.show()``.  In a script, write them with ``fig.savefig(path)``.  Helpers
that draw one axes also accept ``ax`` (then they draw into your figure).

Wherever a model is expected you may pass one model, a list, a dict
``{label: model}`` or an :class:`~hammerstein_ctrl.fit._identify.IdentificationResult`
(see :func:`hammerstein_ctrl.data._display.as_models`); wherever a record is expected,
an :class:`~hammerstein_ctrl.data.IOData` or a ``nonlinear_benchmarks``
record (see :func:`hammerstein_ctrl.data._display.as_iodata`).

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

import warnings
from pathlib import Path

import numpy as np

from ..data._display import (as_iodata, as_models, is_identification_result, labelled, method_label,
                             register_figure_formatter)
from ..exceptions import ParameterError

__all__ = [
    "time_response", "error_response", "psd", "dominant_frequency", "spectral_peak", "input_signal",
    "bode", "convergence", "nonlinearity", "final_cost", "compare", "compare_fits", "result_figure",
    "study_figure_set", "study_figures", "residual_figure", "MIN_PEAK_BINS", "PEAK_PROMINENCE", "SMOOTH_BINS",
    "LOG_SPAN",
]

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
    """Measured output and model outputs over time (Figs. 8, 16), with an optional zoom (Figs. 9, 17).

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
    """Output error ``y - yhat`` of each model (Figs. 10-11, 18): one row of panels per model.

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


# -- spectra -------------------------------------------------------------------
def _welch(y, dt, nperseg):
    from scipy.signal import welch

    return welch(y, fs=1.0 / dt, nperseg=min(nperseg, y.size))


def spectral_peak(f, p, *, fmin: float, prominence: float = PEAK_PROMINENCE) -> float:
    """Frequency of the highest local maximum of a PSD above ``fmin``, or NaN if there is none.

    The search runs on ``log10 p`` smoothed over :data:`SMOOTH_BINS` bins, and a
    maximum counts only when it stands ``prominence`` decades above the valleys
    around it (scipy's peak prominence), so the ripple of a Welch estimate, a
    falling spectrum and the DC end are not reported as peaks.  The frequency
    returned is the raw spectrum's largest bin within the smoothing window.

    Examples
    --------
    >>> import numpy as np
    >>> f = np.linspace(0, 5, 501)
    >>> p = 1 / ((1 - (f / 2) ** 2) ** 2 + (0.05 * f) ** 2) + 1 / (f + 0.01)
    >>> float(spectral_peak(f, p, fmin=0.1))   # resonance at 1.995 Hz, bins 0.01 Hz apart
    1.99
    """
    from scipy.ndimage import uniform_filter1d
    from scipy.signal import find_peaks

    f, p = np.asarray(f, float), np.asarray(p, float)
    keep = np.flatnonzero(f >= fmin)
    if keep.size < SMOOTH_BINS:
        return float("nan")
    logp = np.log10(np.maximum(p[keep], np.finfo(float).tiny))
    smooth = uniform_filter1d(logp, SMOOTH_BINS, mode="nearest")
    idx, _ = find_peaks(smooth, prominence=prominence)
    if idx.size == 0:
        return float("nan")
    best = idx[np.argmax(smooth[idx])]
    lo, hi = max(best - SMOOTH_BINS // 2, 0), best + SMOOTH_BINS // 2 + 1
    return float(f[keep][lo + np.argmax(logp[lo:hi])])


def _resolution(data, nperseg) -> float:
    return 1.0 / (min(nperseg, len(data)) * data.dt)


def dominant_frequency(data, models=None, *, nperseg: int = NPERSEG, fmin: float | None = None,
                       prominence: float = PEAK_PROMINENCE) -> dict:
    """PSD peak (Hz) of the measured and each model's output, searched away from the DC end.

    Parameters
    ----------
    data : IOData or benchmark record
    models : model, list, dict or IdentificationResult, optional
    nperseg : int
        Welch segment length; the frequency resolution is ``1/(nperseg dt)``.
    fmin : float, optional
        Lowest frequency searched; default :data:`MIN_PEAK_BINS` resolution widths.
    prominence : float
        See :func:`spectral_peak`.

    Returns
    -------
    dict
        ``{"measured": f, label: f, ..., "resolution": Hz, "fmin": Hz}``; NaN
        where a spectrum has no peak above ``fmin``.
    """
    data = _siso_record(data)
    ys, _ = _outputs(data, as_models(models, arrays=True, allow_empty=True))
    df = _resolution(data, nperseg)
    fmin = MIN_PEAK_BINS * df if fmin is None else float(fmin)
    out = {}
    for label, y in {"measured": data.y, **ys}.items():
        f, p = _welch(y, data.dt, nperseg)
        out[label] = spectral_peak(f, p, fmin=fmin, prominence=prominence)
    out.update(resolution=df, fmin=fmin)
    return out


def _peak_text(f_peak, fmin):
    return f"peak {f_peak:.3g} Hz" if np.isfinite(f_peak) else f"no peak above {fmin:.2g} Hz"


def psd(data, models=None, *, nperseg: int = NPERSEG, fmin: float | None = None, logx: bool = False,
        title=None, ax=None):
    """Welch power spectral density of the measured and simulated outputs (Fig. 12).

    Each curve's peak (:func:`dominant_frequency`, searched above ``fmin``) is
    marked and given in the legend; the title states the frequency resolution.
    ``logx`` puts frequency on a log axis (for spectra spanning decades).
    """
    data = _siso_record(data)
    ys, bad = _outputs(data, as_models(models, arrays=True, allow_empty=True))
    peaks = dominant_frequency(data, ys, nperseg=nperseg, fmin=fmin)
    fig, a = _single_axes(ax)
    for label, y in {"measured": data.y, **ys}.items():
        f, p = _welch(y, data.dt, nperseg)
        style = _MEASURED if label == "measured" else dict(lw=1.0)
        (line,) = a.semilogy(f[1:], p[1:], label=f"{label} ({_peak_text(peaks[label], peaks['fmin'])})", **style)
        if np.isfinite(peaks[label]):
            a.plot(peaks[label], p[np.argmin(abs(f - peaks[label]))], "v", color=line.get_color(), ms=7)
    _mark_unusable(a, bad)
    a.axvspan(peaks["resolution"] if logx else 0.0, peaks["fmin"], color="0.9", zorder=0,
              label=f"below {peaks['fmin']:.2g} Hz: not searched")
    if logx:
        a.set_xscale("log")
    unit = f"{data.output_unit}²/Hz" if data.output_unit else "1/Hz"
    n = min(nperseg, len(data))
    _finish(a, xlabel="frequency (Hz)", ylabel=f"PSD of {data.output_name} ({unit})", grid="both",
            title=(title or f"{data.name}: output PSD")
            + f"\nWelch, {n}-sample segments, resolution {peaks['resolution']:.3g} Hz")
    return fig


def input_signal(data, *, zoom=None, nperseg: int = NPERSEG, bins: int = 40, title=None):
    """The excitation (like the paper's Figs. 6 and 14): ``u(t)`` (and a zoom), its histogram and Welch PSD."""
    data = _siso_record(data)
    if int(bins) != bins or bins < 2:
        raise ParameterError(f"bins must be an integer >= 2, got {bins!r}")
    fig, axes = _new_figure(2, 2, figsize=(_WIDTH + 2, 6.5))
    ulabel = _label(data.input_name, data.input_unit)
    if zoom is None:
        grid = axes[0, 0].get_gridspec()
        for a in axes[0]:
            a.remove()
        panels = [(fig.add_subplot(grid[0, :]), np.ones(len(data), bool), "full record")]
    else:
        panels = [(axes[0, 0], np.ones(len(data), bool), "full record"),
                  (axes[0, 1], _window(data, zoom), f"zoom {zoom[0]:g}-{zoom[1]:g} s")]
        axes[0, 0].axvspan(*zoom, color="0.88", zorder=0)
    for a, sel, what in panels:
        a.plot(data.t[sel], data.u[sel], lw=0.7, color="C0", label=f"{data.input_name}: {sel.sum()} samples")
        _finish(a, xlabel="time (s)", ylabel=ulabel, title=what)
    fig.suptitle(title or f"{data.name}: input signal (dt = {data.dt:g} s, {len(data)} samples)")
    ah, ap = axes[1]
    ah.hist(data.u, bins=int(bins), color="C0", alpha=0.8, label=f"{int(bins)} bins")
    _finish(ah, xlabel=ulabel, ylabel="samples (count)", title="amplitude distribution")
    f, p = _welch(data.u, data.dt, nperseg)
    unit = f"{data.input_unit}²/Hz" if data.input_unit else "1/Hz"
    ap.semilogy(f[1:], p[1:], color="C0", lw=1.0, label=f"resolution {_resolution(data, nperseg):.3g} Hz")
    _finish(ap, xlabel="frequency (Hz)", ylabel=f"PSD ({unit})", title="power spectral density (Welch)",
            grid="both")
    return fig


# -- linear blocks and nonlinearities ------------------------------------------
def bode(models, *, omega=None, u0: float | None = None, title=None, confidence: float | None = None,
         method: str = "linear", seed=None):
    """Bode plot of the identified linear blocks, overlaid (``control.bode_plot``), with confidence bands.

    Parameters
    ----------
    models : model, list, dict, IdentificationResult or control.TransferFunction
    omega : array_like, optional
        Frequencies (rad/s); by default python-control's choice for the systems.
    u0 : float, optional
        Plot the plant's small-signal transfer function ``g'(u0) H(p)``
        (:meth:`HammersteinModel.linearize`) instead of ``H(p)``, whose gain
        is only defined up to the scale carried by ``g``.
    confidence : float, optional
        Shade the ``confidence`` band (e.g. 0.95) of magnitude and phase of
        every result that carries a covariance, propagated from it
        (:meth:`IdentificationResult.propagate`, ``method`` "linear" or seeded
        "sampling").

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> case = hc.presets.trs()
    >>> res = hc.identify(case.data, case.structure)
    >>> fig = bode(res, confidence=0.95)
    >>> len(fig.axes[0].collections)          # the shaded band on the magnitude
    1
    """
    import control

    items = labelled(models)
    models = as_models(models, systems=True, need=("linear",))
    systems, labels = [], []
    for label, m in models.items():
        if u0 is not None and hasattr(m, "linearize"):
            systems.append(m.linearize(float(u0)))
            labels.append(f"{label}: g'({float(u0):.3g})·H(p)")
        else:
            # a dead time is drawn as the model's Pade form, as linearize() gives it
            systems.append(m.linear_block() if hasattr(m, "linear_block") else m.linear if hasattr(m, "linear") else m)
            labels.append(label)
    default = ("Bode plot of the identified linear blocks H(p)" if u0 is None else
               f"Small-signal plant g'(u0)·H(p) at u0 = {float(u0):.3g}")
    fig, axes = _new_figure(2, 1, figsize=(_WIDTH, 6), sharex=True)
    control.bode_plot(systems, omega, ax=axes, label=labels, dB=True, title=False)
    fig.suptitle(title or default)
    mag, phase = axes[0, 0], axes[1, 0]
    if confidence is not None:
        for k, (_, obj) in enumerate(items.items()):
            if getattr(obj, "covariance", None) is not None and hasattr(obj, "propagate"):
                _bode_band(mag, phase, obj, mag.get_lines()[k], u0, confidence, method, seed)
    mag.set_ylabel("magnitude (dB)")
    phase.set_ylabel("phase (deg)")
    phase.set_xlabel("frequency (rad/s)")
    if mag.get_legend() is None:
        mag.legend(loc="best", fontsize="small")
    return fig


def _bode_band(mag, phase, result, line, u0, level, method, seed):
    """Shade the ``level`` band of a result's magnitude (dB) and phase (deg) at the frequencies of ``line``."""
    w = np.asarray(line.get_xdata(), dtype=float)
    s = 1j * w

    def response(model):
        sys = model.linearize(float(u0)) if u0 is not None else model.linear
        h = np.polyval(np.asarray(sys.num[0][0], float), s) / np.polyval(np.asarray(sys.den[0][0], float), s)
        return np.r_[20 * np.log10(np.abs(h)), np.degrees(np.unwrap(np.angle(h)))]

    with np.errstate(all="ignore"):
        p = result.propagate(response, level=level, method=method, seed=seed)
    n = w.size
    color = line.get_color()
    mag.fill_between(w, p.low[:n], p.high[:n], color=color, alpha=0.2, lw=0,
                     label=f"{100 * level:g} % band")
    plotted = phase.get_lines()[mag.get_lines().index(line)].get_ydata()
    shift = 360.0 * np.round(np.nanmedian((np.asarray(plotted) - p.value[n:]) / 360.0))   # python-control's wrap
    phase.fill_between(w, p.low[n:] + shift, p.high[n:] + shift, color=color, alpha=0.2, lw=0)


#: Per static block: evaluating method, x-axis name, y-axis label.
_BLOCKS = {"input": ("g", "input u", "g(u) (input of H)"),
           "output": ("h", "output of H, z", "h(z) (model output before the offset)"),
           "middle": ("f", "middle signal x = G1 u", "f(x) (input of G2)")}


def _has_block(model, block: str) -> bool:
    """Whether ``model`` has that static block (models without the attribute are Hammerstein-like; only a
    Wiener-Hammerstein model has a middle one)."""
    if block == "middle":
        return getattr(model, "kind", "") == "wiener-hammerstein"
    return getattr(model, f"{block}_nonlinearity", block == "input") is not None


def _linear_output(model, data) -> np.ndarray:
    """``z = H(p) g(u)`` on the record: the signal entering the output nonlinearity."""
    return model.linear_output(data)


def _block_range(models, u_range, block):
    if u_range is None:
        ranges = []
        for r in _results(models):
            x = (r.data.u if block == "input" else r.model.middle(r.data) if block == "middle"
                 else _linear_output(r.model, r.data))
            ranges.append((float(np.nanmin(x)), float(np.nanmax(x))))
        if not ranges:
            raise ParameterError("give u_range=(low, high) (it defaults to the record of an IdentificationResult)")
        return min(r[0] for r in ranges), max(r[1] for r in ranges)
    try:
        lo, hi = (float(v) for v in u_range)
    except (TypeError, ValueError):
        raise ParameterError(f"u_range must be a (low, high) pair, got {u_range!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise ParameterError(f"u_range must be finite with low < high, got {u_range!r}")
    return lo, hi


def _results(models):
    if is_identification_result(models):
        return [models]
    items = models.values() if isinstance(models, dict) else models if isinstance(models, (list, tuple)) else []
    return [m for m in items if is_identification_result(m)]


def nonlinearity(models, u_range=None, *, block: str = "input", unit_in: str = "", title=None, ax=None,
                 n: int = 400, confidence: float | None = None, method: str = "linear", seed=None):
    """The identified static nonlinearities over a range of their input, with confidence bands.

    Parameters
    ----------
    models : model, list, dict or IdentificationResult
    u_range : (float, float), optional
        Range of the block's input; defaults to the range seen on the records
        of the IdentificationResults passed.
    block : {"input", "output", "middle"}
        ``g(u)`` before the linear block (Hammerstein), ``h(z)`` after it (Wiener), or
        ``f(x)`` between the two blocks of a Wiener-Hammerstein model.
    confidence : float, optional
        Shade the ``confidence`` band (e.g. 0.95) of every result that carries
        a covariance (propagated from it; ``method`` "linear" or seeded "sampling").

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> case = hc.presets.trs()
    >>> fig = nonlinearity(hc.identify(case.data, case.structure), confidence=0.95)
    >>> len(fig.axes[0].collections)
    1
    """
    if block not in _BLOCKS:
        raise ParameterError(f"block must be one of {sorted(_BLOCKS)}, got {block!r}")
    attr, xname, ylabel = _BLOCKS[block]
    items = labelled(models)
    for label, obj in items.items():
        m = obj.model if is_identification_result(obj) else obj
        if not _has_block(m, block):
            raise ParameterError(f"model {label!r} has no {block} nonlinearity")
    lo, hi = _block_range(models, u_range, block)
    models = as_models(models, need=(attr,))
    x = np.linspace(lo, hi, int(n))
    fig, a = _single_axes(ax)
    for label, m in models.items():
        line, = a.plot(x, getattr(m, attr)(x), lw=1.2, label=label)
        obj = items[label]
        if confidence is not None and getattr(obj, "covariance", None) is not None and hasattr(obj, "propagate"):
            with np.errstate(all="ignore"):
                p = obj.propagate(lambda model: getattr(model, attr)(x), level=confidence, method=method, seed=seed)
            a.fill_between(x, p.low, p.high, color=line.get_color(), alpha=0.2, lw=0,
                           label=f"{100 * confidence:g} % band")
    _finish(a, xlabel=_label(xname, unit_in), ylabel=ylabel, title=title or "Identified static nonlinearities")
    return fig


# -- optimisation runs ---------------------------------------------------------
_QUANTITIES = {"estimate": "J at the current estimate", "best": "best J evaluated so far",
               "fun": "J of the iteration"}


def _run_curves(source, quantity: str) -> dict:
    """``{label: [(nfev, values, diverged), ...]}`` from a StudyResult, results or a mapping of runs."""
    from ..optimize import DIVERGED

    def pick(nfev, values, diverged):
        nfev, values = np.asarray(nfev, float), np.asarray([float(v) for v in values])
        keep = ~np.isnan(values)
        return nfev[keep], values[keep], bool(diverged)

    if _is_study(source):
        out = {}
        for r in source.records:
            c = r["curve"]
            out.setdefault(method_label(r["method"]), []).append(pick(c["nfev"], c[quantity], r["diverged"]))
        return out
    if not isinstance(source, dict):
        runs = list(source) if isinstance(source, (list, tuple)) else [source]
        if all(hasattr(r, "optimize_result") for r in runs):  # IdentificationResults: grouped by method
            source = {}
            for r in runs:
                source.setdefault(method_label(r.method), []).append(r)
        else:
            source = {"runs": runs}
    out = {}
    for label, runs in source.items():
        runs = list(runs) if isinstance(runs, (list, tuple)) else [runs]
        runs = [getattr(r, "optimize_result", r) for r in runs]
        if not all(hasattr(r, "history") for r in runs):
            raise ParameterError(f"convergence needs OptimizeResults with a history (or a StudyResult); "
                                 f"{label!r} holds {type(runs[0]).__name__}")
        out[label] = [pick(r.history["nfev"], r.history[quantity], r.status == DIVERGED) for r in runs]
    return out


def _step_interp(grid, nfev, values):
    """Latest value at each grid NFE (NaN before the first one; inf is kept out of the scale)."""
    values = np.where(np.isfinite(values), values, np.nan)
    idx = np.searchsorted(nfev, grid, side="right") - 1
    return np.where(idx >= 0, values[np.clip(idx, 0, None)], np.nan)


def _median_band(a, label, runs, band, color):
    grid = np.unique(np.concatenate([n for n, _ in runs]))
    stack = np.array([_step_interp(grid, n, v) for n, v in runs])
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns before a run's first value
        med = np.nanmedian(stack, axis=0)
        a.plot(grid, med, lw=1.4, color=color, label=label)
        if band and len(runs) > 1:
            lo, hi = np.nanpercentile(stack, [25, 75], axis=0)
            a.fill_between(grid, lo, hi, color=color, alpha=0.2, lw=0)


def convergence(source, *, quantity: str = "estimate", title=None, ax=None, band: bool = True, ylabel=None):
    """Objective versus NFE: median and inter-quartile band over runs (Figs. 2-3).

    Diverged runs are left out of the medians and of the axis scaling; they are
    counted in the legend and drawn, each on its own, in a lower panel.

    Parameters
    ----------
    source : StudyResult, dict, list or IdentificationResult
        A study, ``{label: OptimizeResult or IdentificationResult, or a list of them}``,
        or a list of runs.
    quantity : {"estimate", "best", "fun"}
        ``"estimate"`` (default): J at each method's current estimate -- the
        iterate theta(k) for the SPSA family (run with ``monitor``), the best
        point for population and least-squares methods.  ``"best"``: the best
        value evaluated so far; for the SPSA family that is a perturbed point
        theta ± c(k) Delta, which can be far worse than theta(k).
        ``"fun"``: each iteration's own value.
    band : bool, default True
        Shade the inter-quartile range.
    ax : matplotlib Axes, optional
        Draw the non-diverged runs there (no lower panel).
    """
    if quantity not in _QUANTITIES:
        raise ParameterError(f"quantity must be one of {sorted(_QUANTITIES)}, got {quantity!r}")
    curves = _run_curves(source, quantity)
    ok = {k: [(n, v) for n, v, d in runs if not d and _usable(v)] for k, runs in curves.items()}
    diverged = {k: [(n, v) for n, v, d in runs if d and _usable(v)] for k, runs in curves.items()}
    n_div = {k: sum(d for _, _, d in runs) for k, runs in curves.items()}
    # diverged runs get their own panel when there is a scale to protect; if nothing else is drawn, the main one
    where = "none" if not any(diverged.values()) else "main" if not any(ok.values()) else \
        "lower" if ax is None else "none"
    if ax is None:
        fig, axes = _new_figure(2 if where == "lower" else 1, 1, figsize=(_WIDTH, 6.5 if where == "lower" else 4.5),
                                sharex=True, **({"height_ratios": [3, 1.4]} if where == "lower" else {}))
        a = axes[0, 0]
    else:
        fig, a = ax.figure, ax
    target = {"main": a, "lower": axes[-1, 0] if ax is None else None}.get(where)
    for i, (label, runs) in enumerate(curves.items()):
        color = _colors()[i % len(_colors())]
        text = _convergence_label(label, len(ok[label]), n_div[label], len(runs), where == "lower")
        if ok[label]:
            _median_band(a, text, ok[label], band, color)
        elif where != "main":
            a.plot([], [], " ", label=text)
        if target is not None and diverged[label]:
            _draw_diverged(target, diverged[label], color, f"{label}: {n_div[label]} diverged runs"
                           + (f" ({len(diverged[label])} with a finite J to draw)"
                              if len(diverged[label]) < n_div[label] else ""))
    _log_or_note(a, "no finite value to show")
    _finish(a, xlabel=None if where == "lower" else "function evaluations (NFE)",
            ylabel=ylabel or _QUANTITIES[quantity], grid="both",
            title=title or ("Convergence: median (line) and inter-quartile range (band) over trials"
                            if where != "main" else "Diverged runs, each drawn (x: last finite value)"))
    if where == "lower":
        b = axes[1, 0]
        b.set_yscale("log")
        _finish(b, xlabel="function evaluations (NFE)", ylabel="J (diverged runs)", grid="both",
                title="diverged runs, each on its own (x: last finite value); not in the medians or scale")
    return fig


def _usable(values) -> bool:
    return bool(values.size and np.isfinite(values).any())


def _log_or_note(a, note):
    """Log y scale when the axes holds data, else the note in its middle (a log axis needs data)."""
    if any(len(line.get_xdata()) for line in a.lines if line.get_transform() == a.transData) or a.collections:
        a.set_yscale("log")
    else:
        a.text(0.5, 0.5, note, ha="center", va="center", transform=a.transAxes)


def _convergence_label(label, n_ok, n_div, n, lower):
    if n_ok == 0:
        return f"{label}: all {n} runs diverged" + (" (lower panel)" if lower else "")
    if n == 1:
        return label
    text = f"{label}: median of {n_ok} " + ("non-diverged runs" if n_div else "runs")
    return text + (f"; {n_div} of {n} diverged" if n_div else "")


def _draw_diverged(b, runs, color, text):
    for j, (n, v) in enumerate(runs):
        fin = np.isfinite(v) & (v > 0)
        b.plot(n[fin], v[fin], lw=0.7, alpha=0.6, color=color, label=text if j == 0 else None)
        if fin.any():
            b.plot(n[fin][-1], v[fin][-1], "x", color=color, ms=6)


def _is_study(obj) -> bool:
    """Whether ``obj`` is a StudyResult (its trial records and method names; a fit to several records has
    ``records`` too, of IOData)."""
    return hasattr(obj, "records") and hasattr(obj, "methods") and not is_identification_result(obj)


def final_cost(study, *, title=None, ax=None):
    """Box plot with the individual trials of the final J per method.

    Diverged trials are not in the boxes or the axis scaling: each method's
    tick label counts them, and ``^`` marks at the top edge show them.  The
    y axis is logarithmic when the values span more than :data:`LOG_SPAN`.
    """
    if not _is_study(study):
        raise ParameterError(f"final_cost needs a StudyResult, got {type(study).__name__}")
    fig, a = _single_axes(ax)
    rng = np.random.default_rng(0)
    ticks, n_trials, finite = [], 0, []
    for i, m in enumerate(study.methods, start=1):
        recs = [r for r in study.records if r["method"] == m]
        n_trials = max(n_trials, len(recs))
        J = np.array([float(r["fun"]) for r in recs])
        div = np.array([bool(r["diverged"]) for r in recs]) | ~np.isfinite(J)
        ok = J[~div]
        finite.extend(ok.tolist())
        if ok.size:
            a.boxplot([ok], positions=[i], showfliers=False, widths=0.5)
            a.plot(i + rng.uniform(-0.12, 0.12, ok.size), ok, "o", ms=3, alpha=0.6, color="C0",
                   label=None if "trials" in a.get_legend_handles_labels()[1] else "trials")
        if div.any():
            a.plot(i + rng.uniform(-0.12, 0.12, div.sum()), np.full(div.sum(), 0.97), "^", color="firebrick",
                   ms=5, transform=a.get_xaxis_transform(), clip_on=False,
                   label=None if "diverged (off scale)" in a.get_legend_handles_labels()[1] else "diverged (off scale)")
        ticks.append(f"{method_label(m)}\n{int(div.sum())}/{len(recs)} diverged" if div.any() else method_label(m))
    a.set_xticks(range(1, len(ticks) + 1), ticks)
    a.set_xlim(0.4, len(ticks) + 0.6)
    if finite and max(finite) > LOG_SPAN * min(finite):
        a.set_yscale("log")
    elif not finite:
        a.text(0.5, 0.5, "every trial diverged: no final J to show", ha="center", va="center", transform=a.transAxes)
    _finish(a, ylabel="final J (sum of squared output errors)", xlabel="method", grid="both",
            title=title or f"{study.case.name.upper()}: final J over {n_trials} trials per method")
    return fig


# -- one result, several records -----------------------------------------------
def _records(records):
    if records is None:
        raise ParameterError("give at least one record")
    items = list(records) if isinstance(records, (list, tuple)) else [records]
    if not items:
        raise ParameterError("give at least one record")
    return [as_iodata(r) for r in items]


def compare_fits(records, models) -> dict:
    """Fit % (``100 (1 - ||y - yhat|| / ||y - mean y||)``) of each model on each record.

    Returns ``{record name: {label: fit %}}`` (``-inf`` for a non-finite simulation).
    """
    from ..data._metrics import fit_percent

    models = as_models(models)
    out = {}
    for data in _records(records):
        ys, bad = _outputs(data, models)
        out[data.name] = {label: (fit_percent(data.y, ys[label]) if label in ys else -np.inf)
                          for label in models}
    return out


def compare(records, models, *, title=None, paired: bool = False):
    """Measured against simulated output on each record, with fit % per model (MATLAB's ``compare``).

    Parameters
    ----------
    records : IOData, benchmark record or a list of them
        One row of the figure per record.
    models : model, list, dict or IdentificationResult
        Every model on every record; with ``paired=True`` a list of one model
        per record (a fit to several records: each with its own offset and state).
    """
    from ..data._metrics import fit_percent

    records = _records(records)
    if paired and (not isinstance(models, (list, tuple)) or len(models) != len(records)):
        raise ParameterError(f"paired=True needs one model per record ({len(records)}), got {models!r}")
    if any(not getattr(d, "is_siso", True) for d in records):
        return _compare_channels(records, models, title=title, paired=paired)
    if paired:
        rows = [(data, as_models(m)) for data, m in zip(records, models)]
    else:
        rows = [(data, as_models(models)) for data in records]
    fig, axes = _new_figure(len(records), 1, figsize=(_WIDTH, 1.2 + 2.6 * len(records)))
    for a, (data, row_models) in zip(axes[:, 0], rows):
        ys, bad = _outputs(data, row_models)
        a.plot(data.t, data.y, label="measured", **_MEASURED)
        for label in row_models:
            if label in ys:
                a.plot(data.t, ys[label], lw=1.0, label=f"{label}: fit {fit_percent(data.y, ys[label]):.1f} %")
        _mark_unusable(a, bad)
        _finish(a, xlabel="time (s)", ylabel=_label(data.output_name, data.output_unit),
                title=f"{data.name}" if len(records) > 1 or title is None else None)
    if title:
        fig.suptitle(title)
    return fig


def _compare_channels(records, models, *, title=None, paired=False):
    """:func:`compare` for records with several outputs: one row per output of each record."""
    from ..data._metrics import fit_percent

    rows = [(data, as_models(m, siso=False)) for data, m in zip(records, models)] if paired else [
        (data, as_models(models, siso=False)) for data in records]
    simulated = [_outputs(data, ms) for data, ms in rows]               # once per record and model
    panels = [(data, ms, sim, i) for (data, ms), sim in zip(rows, simulated) for i in range(data.n_outputs)]
    fig, axes = _new_figure(len(panels), 1, figsize=(_WIDTH, 1.2 + 2.4 * len(panels)))
    for a, (data, row_models, (ys, bad), i) in zip(axes[:, 0], panels):
        y = data.outputs[:, i]
        a.plot(data.t, y, label="measured", **_MEASURED)
        for label in row_models:
            if label in ys:
                a.plot(data.t, ys[label][:, i], lw=1.0, label=f"{label}: fit {fit_percent(y, ys[label][:, i]):.1f} %")
        _mark_unusable(a, bad)
        _finish(a, xlabel="time (s)", ylabel=_label(data.output_names[i], data.output_units[i]),
                title=f"{data.name}: {data.output_names[i]}")
    if title:
        fig.suptitle(title)
    return fig


def mimo_figure(result, *, zoom=None):
    """Overview of a MIMO identification: per output, measured vs simulated and the residual; then each
    channel's static nonlinearity over the range the record shows (what ``result.plot()`` draws for a MIMO fit).

    Parameters
    ----------
    result : IdentificationResult
        A fit of a MIMO structure, with its record.
    zoom : (start, stop), optional
        A time window (s) of the time panels.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels per output, then one per nonlinearity.
    """
    from ..data._metrics import fit_percent

    data, model, label = result.data, result.model, method_label(result.method)
    with np.errstate(all="ignore"):
        Y = np.asarray(model.simulate(data), dtype=float)
    sel = np.ones(len(data), bool) if zoom is None else _window(data, zoom)
    statics = [("g", j, nl, q, data.inputs[:, j], data.input_names[j])
               for j, (nl, q) in enumerate(zip(model.input_nonlinearities or (), model.input_params or ()))]
    Z = model.h_input(data) if model.output_nonlinearities is not None else None
    statics += [("h", i, nl, q, Z[:, i], f"linear output {i}")
                for i, (nl, q) in enumerate(zip(model.output_nonlinearities or (), model.output_params or ()))]
    p = data.n_outputs
    fig, axes = _new_figure(2 * p + len(statics), 1, figsize=(_WIDTH, 2.0 + 2.3 * (2 * p + len(statics))))
    for i in range(p):
        a, b = axes[2 * i, 0], axes[2 * i + 1, 0]
        y, yhat, name, unit = data.outputs[:, i], Y[:, i], data.output_names[i], data.output_units[i]
        a.plot(data.t[sel], y[sel], label="measured", **_MEASURED)
        if np.all(np.isfinite(yhat)):
            a.plot(data.t[sel], yhat[sel], lw=1.0, label=f"{label}: fit {fit_percent(y, yhat):.1f} %")
            b.plot(data.t[sel], (y - yhat)[sel], lw=0.8, color="C1", label=f"RMS {_rms(y - yhat):.3g}")
        else:
            _mark_unusable(a, [label])
        b.axhline(0.0, color="k", lw=0.6)
        _finish(a, xlabel="time (s)", ylabel=_label(name, unit),
                title=f"{name}: {label} on {data.name}" + ("" if result.success else " [FAILED]"))
        _finish(b, xlabel="time (s)", ylabel=_label(f"residual in {name}", unit))
    for c, (kind, k, nl, q, signal, where) in zip(axes[2 * p:, 0], statics):
        grid = np.linspace(np.min(signal), np.max(signal), 400)
        c.plot(grid, nl(grid, q), lw=1.2, label=nl.describe(q))
        _finish(c, xlabel=where, ylabel=f"{kind}{k}", title=f"{kind}{k}: static nonlinearity over the range seen")
    return fig


def _feedback_panel(ax, model, data, yhat) -> None:
    """A Lur'e loop's feedback map ``g(z)`` over the range its simulated feedback signal covers."""
    z = yhat if model.feedback == "output" else np.gradient(yhat, data.dt)
    z = z[np.isfinite(z)]
    span = float(np.max(np.abs(z))) if z.size else 1.0
    grid = np.linspace(-span, span, 801)
    ax.plot(grid, model.g(grid), lw=1.2, label=model.nonlinearity.describe(model.params))
    _finish(ax, xlabel=f"{model.feedback} (simulated range)", ylabel=f"g({model.feedback}) (input units)",
            title=f"feedback map: the force opposing the {model.feedback}")
    ax.legend(loc="best", fontsize="small")


def result_figure(result, *, zoom=None):
    """Overview of one IdentificationResult: measured vs simulated, the residual, and ``g(u)`` / ``h(z)``."""
    if not is_identification_result(result):
        raise ParameterError(f"result_figure needs an IdentificationResult, got {type(result).__name__}")
    if getattr(result.model, "n_outputs", 1) * getattr(result.model, "n_inputs", 1) > 1:
        return mimo_figure(result, zoom=zoom)
    data, model, label = result.data, result.model, method_label(result.method)
    with np.errstate(all="ignore"):
        yhat = np.asarray(model.simulate(data), dtype=float)
    fit, J, where = result.fit_percent, result.fun, data.name
    if getattr(result, "records", ()):      # a joint fit: this record's own figures, not the fit's over all records
        from ..data._metrics import fit_percent

        with np.errstate(all="ignore"):
            fit, J = fit_percent(data.y, yhat), float(np.sum((data.y - yhat) ** 2))
        where = f"{data.name} (record 1 of {len(result.records)})"
    blocks = [b for b in ("input", "output", "middle") if _has_block(model, b)]
    if getattr(model, "feedback", None) is not None:        # a Lur'e loop: its feedback map instead
        blocks = ["feedback"]
    fig, axes = _new_figure(2 + len(blocks), 1, figsize=(_WIDTH, 3.0 + 2.8 * (len(blocks) + 1)))
    (a, b), static = axes[:2, 0], axes[2:, 0]
    sel = np.ones(len(data), bool) if zoom is None else _window(data, zoom)
    ylabel = _label(data.output_name, data.output_unit)
    a.plot(data.t[sel], data.y[sel], label="measured", **_MEASURED)
    if np.all(np.isfinite(yhat)):
        a.plot(data.t[sel], yhat[sel], lw=1.0, label=f"{label}: fit {fit:.1f} %")
        unit = f" {data.output_unit}" if data.output_unit else ""
        b.plot(data.t[sel], (data.y - yhat)[sel], lw=0.8, color="C1", label=f"RMS {_rms(data.y - yhat):.3g}{unit}")
    else:
        _mark_unusable(a, [label])
    b.axhline(0.0, color="k", lw=0.6)
    _finish(a, xlabel="time (s)", ylabel=ylabel,
            title=f"{label} on {where}: J = {J:.6g}, NFE = {result.nfev}"
                  + ("" if result.success else " [FAILED]"))
    _finish(b, xlabel="time (s)", ylabel=_label(f"residual in {data.output_name}", data.output_unit),
            title="residual y - yhat")
    for c, block in zip(static, blocks):
        if block == "feedback":
            _feedback_panel(c, model, data, yhat)
            continue
        nonlinearity(result, block=block, ax=c, unit_in=data.input_unit if block == "input" else "",
                     title=f"static {block} nonlinearity over the range seen on the record")
        c.get_lines()[-1].set_label(_describe_block(model, block))
        c.legend(loc="best", fontsize="small")
    return fig


def residual_figure(analysis, *, title=None):
    """A :class:`~hammerstein_ctrl.assess.ResidualAnalysis` drawn as MATLAB's ``resid`` does.

    Top: the residuals' autocorrelation at lags 0..M; bottom: their
    cross-correlation with the input at lags -M..M (positive: the input
    leads); each with its 99 % bound shaded, and the verdict in the title.
    """
    fig, axes = _new_figure(2, 1, figsize=(_WIDTH, 5.5))
    a, b = axes[:, 0]
    lag_s = analysis.dt
    for ax, lags, values, bound, what in (
            (a, analysis.lags, analysis.autocorrelation, analysis.autocorrelation_bound, "autocorrelation of e"),
            (b, analysis.cross_lags, analysis.cross_correlation, analysis.cross_correlation_bound,
             "cross-correlation of u and e")):
        ax.axhspan(-bound, bound, color="C0", alpha=0.15, lw=0, label="99 % bound")
        ax.vlines(lags * lag_s, 0.0, values, color="k", lw=1.2)
        ax.plot(lags * lag_s, values, "o", color="k", ms=3)
        outside = np.abs(values) > bound
        if lags.size and outside.any():
            ax.plot(lags[outside] * lag_s, values[outside], "o", color="firebrick", ms=4, label="outside the bound")
        ax.axhline(0.0, color="k", lw=0.6)
        _finish(ax, xlabel="lag (s)", ylabel="correlation", title=what)
    verdict = ("passed" if analysis.passed else "the input still explains part of the residuals" if analysis.findings
               else "strongly coloured residuals: mostly a signal the model misses")
    fig.suptitle(title or f"Residual analysis{' of ' + analysis.name if analysis.name else ''}: {verdict}")
    return fig


def _describe_block(model, block: str) -> str:
    nl = getattr(model, f"{block}_nonlinearity", None) or model.nonlinearity
    params = getattr(model, f"{block}_params", None)
    return nl.describe(model.params if params is None else params)


# -- study reports -------------------------------------------------------------
def _zoom_window(data) -> tuple[float, float]:
    """A tenth of the record, a quarter of the way in, on round numbers."""
    width = float(f"{0.1 * data.duration:.2g}")
    start = float(f"{data.t[0] + 0.25 * data.duration:.2g}")
    return (start, start + width)


def _placeholder(title, message):
    fig, axes = _new_figure(figsize=(_WIDTH, 3))
    a = axes[0, 0]
    a.text(0.5, 0.5, message, ha="center", va="center", transform=a.transAxes)
    a.set_axis_off()
    a.set_title(title)
    return fig


def _study_models(study):
    summary = study.summary()
    shown, dropped = {}, []
    for m in study.methods:
        if summary[m]["diverged"] == summary[m]["n"]:
            dropped.append(method_label(m))
        else:
            shown[method_label(m)] = study.best_model(m)
    note = f" ({', '.join(dropped)} diverged: not shown)" if dropped else ""
    return shown, note


def _model_figures(study, shown, note, validation, u0):
    """Figures of the best models; with none (every method diverged) the measurement alone, no Bode plot."""
    case, data = study.case, study.case.data
    zoom = _zoom_window(data)
    none = f"every trial of every method diverged{note}: no model to show"
    figures = {
        "time_response": time_response(data, shown, zoom=zoom,
                                       title=f"{data.name}: measured and best identified outputs{note}"),
        "psd": psd(data, shown, logx=True, title=f"{data.name}: output PSD{note}"),
    }
    if shown:
        figures["error"] = error_response(data, shown, zoom=zoom,
                                          title=f"{data.name}: output error of each best model{note}")
        figures["bode"] = bode(shown, u0=u0, title=f"{case.name.upper()}: small-signal plant g'(u0)·H(p) "
                                                   f"at u0 = {u0:.3g} {data.input_unit}{note}")
        figures["nonlinearity"] = nonlinearity(shown, (float(data.u.min()), float(data.u.max())),
                                               unit_in=data.input_unit,
                                               title=f"{case.name.upper()}: identified static nonlinearities{note}")
    else:
        figures["error"] = _placeholder(f"{data.name}: output error", none)
        figures["nonlinearity"] = _placeholder(f"{case.name.upper()}: identified static nonlinearities", none)
    if validation is not None:
        figures["validation"] = time_response(validation, shown, zoom=_zoom_window(validation),
                                              title=f"{validation.name}: best models on the validation record{note}")
    return figures


def study_figure_set(study, *, validation=None, u0: float | None = None) -> dict:
    """The paper's figures for a study's best models, as ``{name: Figure}``.

    Methods whose every trial diverged are left out of the model figures (their
    outputs would swamp the scale) and named in the titles; if every method
    diverged, the time response and PSD show the measurement alone, the error
    and nonlinearity figures say so, and there is no Bode plot.  ``u0``
    (default: the median input) is the operating point of the small-signal Bode plot.
    """
    data = study.case.data
    shown, note = _study_models(study)
    u0 = float(np.median(data.u)) if u0 is None else float(u0)
    figures = _model_figures(study, shown, note, as_iodata(validation) if validation is not None else None, u0)
    start = _zoom_window(data)[0]
    figures["input"] = input_signal(data, zoom=(start, float(f"{start + INPUT_ZOOM_SAMPLES * data.dt:.3g}")))
    figures["convergence"] = convergence(study, title=f"{study.case.name.upper()}: convergence over trials")
    figures["final_cost"] = final_cost(study)
    return figures


def study_figures(study, out_dir, *, formats=("png",), validation=None, dpi: int = FIGURE_DPI) -> list[Path]:
    """Write :func:`study_figure_set` into ``out_dir`` (one file per figure and format); return the paths."""
    from .._safe_io import UnsafePathError, save_figure

    out_dir = Path(out_dir)
    if out_dir.is_symlink():
        raise UnsafePathError(f"{out_dir} is a symbolic link: refusing to write figures through it")
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fig in study_figure_set(study, validation=validation).items():
        for fmt in formats:
            path = out_dir / f"{name}.{fmt}"
            save_figure(fig, path, root=out_dir, dpi=dpi)      # never through a planted link
            paths.append(path)
    return paths
