"""Figures for judging identified models (the paper's Figs. 2-3, 8-12, 16-18).

Every function returns the :class:`matplotlib.figure.Figure` (and accepts an
``ax`` where a single axes makes sense) so it can be restyled; none calls
``plt.show()``.  Models are given as a mapping ``{label: model}`` where a model
is a :class:`~hammerstein_ctrl.model.HammersteinModel` or an already simulated
output array.

Examples
--------
>>> import matplotlib
>>> matplotlib.use("Agg")
>>> import hammerstein_ctrl as hc
>>> from hammerstein_ctrl import plots
>>> case = hc.presets.trs()
>>> fig = plots.time_response(case.data, {"true": case.structure.model(case.true_beta)}, zoom=(100, 150))
>>> [ax.get_ylabel() for ax in fig.axes]
['pitch y (rad)', 'pitch y (rad)']
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = [
    "time_response", "error_response", "psd", "dominant_frequency", "bode", "convergence",
    "nonlinearity", "final_cost", "study_figure_set", "study_figures",
]


def _pyplot():
    import matplotlib.pyplot as plt

    return plt


def _label(name: str, unit: str) -> str:
    return f"{name} ({unit})" if unit else name


def _outputs(data, models) -> dict:
    """Simulate each model on the record (arrays are passed through)."""
    out = {}
    for label, m in (models or {}).items():
        if hasattr(m, "simulate"):
            with np.errstate(all="ignore"):
                y = m.simulate(data)
        else:
            y = np.asarray(m, dtype=float)
            if y.shape != data.y.shape:
                raise ValueError(f"output for {label!r} has shape {y.shape}, the record {data.y.shape}")
        out[label] = y
    return out


def _figure(ax, nrows=1, figsize=(9, 4)):
    if ax is not None:
        return ax.figure, [ax]
    fig, axes = _pyplot().subplots(nrows, 1, figsize=figsize, squeeze=False)
    return fig, list(axes[:, 0])


def _window(data, zoom):
    lo, hi = zoom
    if not lo < hi:
        raise ValueError(f"zoom window must be (start, stop) with start < stop, got {zoom}")
    return (data.t >= lo) & (data.t <= hi)


def _time_panels(data, zoom, ax, title, ylabel, draw):
    """Full-record panel plus an optional zoom panel; ``draw(axes, mask)`` adds the curves."""
    fig, axes = _figure(ax, 2 if (zoom is not None and ax is None) else 1,
                        figsize=(9, 6.5 if zoom is not None else 4))
    panels = [(axes[0], np.ones(len(data), bool), title)]
    if len(axes) > 1:
        panels.append((axes[1], _window(data, zoom), f"zoom {zoom[0]:g}-{zoom[1]:g} s"))
        axes[0].axvspan(*zoom, color="0.85", zorder=0)
    for a, sel, ttl in panels:
        draw(a, sel)
        a.set_xlabel("time (s)")
        a.set_ylabel(ylabel)
        a.set_title(ttl)
        a.legend(loc="best", fontsize="small")
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def time_response(data, models, *, zoom=None, title=None, ax=None):
    """Measured output and model outputs over time (Figs. 8, 16), optionally with a zoom (Figs. 9, 17).

    Parameters
    ----------
    data : IOData
    models : dict
        ``{label: HammersteinModel or simulated output}``.
    zoom : (float, float), optional
        Time window (s) shown in a second panel below the full record.
    title : str, optional
    ax : matplotlib Axes, optional
        Draw the full record there (no zoom panel).
    """
    ys = _outputs(data, models)

    def draw(a, sel):
        a.plot(data.t[sel], data.y[sel], color="k", lw=1.6, label="measured")
        for label, y in ys.items():
            a.plot(data.t[sel], y[sel], lw=1.0, label=label)

    return _time_panels(data, zoom, ax, title or f"{data.name}: measured and identified output",
                        _label(data.output_name, data.output_unit), draw)


def error_response(data, models, *, zoom=None, title=None, ax=None):
    """Output error ``y - yhat`` of each model over time (Figs. 10-11, 18)."""
    ys = _outputs(data, models)

    def draw(a, sel):
        for label, y in ys.items():
            a.plot(data.t[sel], (data.y - y)[sel], lw=0.9, label=label)
        a.axhline(0.0, color="k", lw=0.6)

    return _time_panels(data, zoom, ax, title or f"{data.name}: output error y - yhat",
                        _label(f"error in {data.output_name}", data.output_unit), draw)


def _welch(y, dt, nperseg):
    from scipy.signal import welch

    return welch(y, fs=1.0 / dt, nperseg=min(nperseg, y.size))


def dominant_frequency(data, models=None, *, nperseg: int = 1024, fmin: float = 0.0) -> dict:
    """Frequency (Hz) of the largest Welch PSD value of each output above ``fmin``.

    Returns ``{"measured": f, label: f, ..., "resolution": bin width in Hz}``.
    """
    series = {"measured": data.y, **_outputs(data, models)}
    out = {}
    for label, y in series.items():
        f, p = _welch(y, data.dt, nperseg)
        keep = f > fmin if fmin > 0 else np.ones(f.size, bool)
        out[label] = float(f[keep][np.argmax(p[keep])])
    out["resolution"] = float(1.0 / (min(nperseg, len(data)) * data.dt))
    return out


def psd(data, models, *, nperseg: int = 1024, fmin: float = 0.0, title=None, ax=None):
    """Welch power spectral density of measured and simulated outputs (Fig. 12).

    The legend reports each curve's dominant peak in Hz (see :func:`dominant_frequency`).
    """
    ys = {"measured": data.y, **_outputs(data, models)}
    peaks = dominant_frequency(data, models, nperseg=nperseg, fmin=fmin)
    fig, (a,) = _figure(ax)
    unit = f"{data.output_unit}²/Hz" if data.output_unit else "1/Hz"
    for label, y in ys.items():
        f, p = _welch(y, data.dt, nperseg)
        style = dict(color="k", lw=1.6) if label == "measured" else dict(lw=1.0)
        a.semilogy(f[1:], p[1:], label=f"{label} (peak {peaks[label]:.3g} Hz)", **style)
    a.set_xlabel("frequency (Hz)")
    a.set_ylabel(f"PSD of {data.output_name} ({unit})")
    a.set_title(title or f"{data.name}: output power spectral density (Welch, {min(nperseg, len(data))}-sample segments)")
    a.legend(loc="best", fontsize="small")
    a.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return fig


def bode(models, *, omega=None, title=None):
    """Bode plot of the identified linear blocks, overlaid (``control.bode_plot``).

    Parameters
    ----------
    models : dict
        ``{label: HammersteinModel or control.TransferFunction}``.
    omega : array_like, optional
        Frequencies (rad/s).
    """
    import control

    labels = list(models)
    systems = [m.linear if hasattr(m, "linear") else m for m in models.values()]
    cplt = control.bode_plot(systems, omega, label=labels, dB=True,
                             title=title or "Bode plot of the identified linear blocks H(p)")
    mag, phase = cplt.axes[0, 0], cplt.axes[1, 0]
    mag.set_ylabel("magnitude (dB)")
    phase.set_ylabel("phase (deg)")
    phase.set_xlabel("frequency (rad/s)")
    if mag.get_legend() is None:
        mag.legend(loc="best", fontsize="small")
    return cplt.figure


def _curves_from(source, quantity: str):
    """``{label: [(nfev, values), ...]}`` from a StudyResult or a mapping of runs."""
    def pick(nfev, values):
        nfev, values = np.asarray(nfev, float), np.asarray([float(v) for v in values])
        keep = ~np.isnan(values)
        return nfev[keep], values[keep]

    out = {}
    if hasattr(source, "records"):
        from .report import METHOD_LABELS

        for r in source.records:
            c = r["curve"]
            out.setdefault(METHOD_LABELS.get(r["method"], r["method"]), []).append(pick(c["nfev"], c[quantity]))
        return out
    for label, runs in source.items():
        runs = runs if isinstance(runs, (list, tuple)) else [runs]
        out[label] = [pick(r.history["nfev"], r.history[quantity]) for r in runs]
    return out


def convergence(source, *, quantity: str = "estimate", title=None, ax=None, band: bool = True,
                ylabel=None):
    """Objective versus NFE: median and inter-quartile band over runs (Figs. 2-3).

    Parameters
    ----------
    source : StudyResult or dict
        A study, or ``{label: OptimizeResult or list of them}``.
    quantity : {"estimate", "best", "fun"}
        ``"estimate"`` (default): J at each method's current estimate -- the
        iterate theta(k) for the SPSA family (run with ``monitor``), the best
        point for population and least-squares methods.  ``"best"``: the best
        value evaluated so far; for the SPSA family that is a perturbed point
        theta ± c(k) Delta, which can be far worse than theta(k).
        ``"fun"``: each iteration's own value.
    band : bool, default True
        Shade the inter-quartile range.
    """
    curves = _curves_from(source, quantity)
    if ylabel is None:
        ylabel = {"estimate": "J at the current estimate", "best": "best J evaluated so far",
                  "fun": "J of the iteration"}.get(quantity, quantity)
    fig, (a,) = _figure(ax)
    for label, runs in curves.items():
        runs = [(n, v) for n, v in runs if n.size and np.isfinite(v).any()]
        if not runs:
            a.plot([], [], " ", label=f"{label}: no finite value (diverged)")
            continue
        grid = np.unique(np.concatenate([n for n, _ in runs]))
        stack = np.array([_step_interp(grid, n, b) for n, b in runs])
        with np.errstate(all="ignore"):
            med = np.nanmedian(stack, axis=0)
        (line,) = a.plot(grid, med, lw=1.4, label=f"{label} (median of {len(runs)})" if len(runs) > 1 else label)
        if band and len(runs) > 1:
            with np.errstate(all="ignore"):
                lo, hi = np.nanpercentile(stack, [25, 75], axis=0)
            a.fill_between(grid, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
    a.set_yscale("log")
    a.set_xlabel("function evaluations (NFE)")
    a.set_ylabel(ylabel)
    a.set_title(title or "Convergence: median and inter-quartile range over trials")
    a.legend(loc="best", fontsize="small")
    a.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return fig


def _step_interp(grid, nfev, values):
    """Latest value at each grid NFE (NaN before the first one; inf is kept out of the scale)."""
    values = np.where(np.isfinite(values), values, np.nan)
    idx = np.searchsorted(nfev, grid, side="right") - 1
    return np.where(idx >= 0, values[np.clip(idx, 0, None)], np.nan)


def nonlinearity(models, u_range, *, unit_in: str = "", title=None, ax=None, n: int = 400):
    """The identified static nonlinearities ``g(u)`` over an input range."""
    lo, hi = u_range
    u = np.linspace(lo, hi, n)
    fig, (a,) = _figure(ax)
    for label, m in models.items():
        a.plot(u, m.g(u), lw=1.2, label=label)
    a.set_xlabel(_label("input u", unit_in))
    a.set_ylabel("g(u) (input of H)")
    a.set_title(title or "Identified static nonlinearities")
    a.legend(loc="best", fontsize="small")
    a.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def final_cost(study, *, title=None, ax=None):
    """Box plot with the individual trials of the final J per method."""
    from .report import METHOD_LABELS

    fig, (a,) = _figure(ax)
    rng = np.random.default_rng(0)
    labels, data = [], []
    for m in study.methods:
        J = study.values(m)
        J = J[np.isfinite(J)]
        if J.size:
            labels.append(METHOD_LABELS.get(m, m))
            data.append(J)
    a.boxplot(data, showfliers=False)
    a.set_xticks(range(1, len(labels) + 1), labels)
    for i, J in enumerate(data, start=1):
        a.plot(i + rng.uniform(-0.12, 0.12, J.size), J, "o", ms=3, alpha=0.6, label="trials" if i == 1 else None)
    a.set_yscale("log")
    a.set_ylabel("final J (sum of squared output errors)")
    a.set_xlabel("method")
    a.set_title(title or f"{study.case.name.upper()}: final J over {len(study.records) // max(len(study.methods), 1)} trials")
    a.legend(loc="best", fontsize="small")
    a.grid(True, axis="y", which="both", alpha=0.3)
    fig.tight_layout()
    return fig


def _zoom_window(data) -> tuple[float, float]:
    """A tenth of the record, a quarter of the way in, on round numbers."""
    width = float(f"{0.1 * data.duration:.2g}")
    start = float(f"{data.t[0] + 0.25 * data.duration:.2g}")
    return (start, start + width)


def study_figure_set(study, *, validation=None) -> dict:
    """The paper's figures for a study's best models, as ``{name: Figure}``.

    Methods whose every trial diverged are left out of the model figures (their
    outputs would swamp the scale) and named in the titles.
    """
    from .report import METHOD_LABELS

    case, data = study.case, study.case.data
    summary = study.summary()
    shown, dropped = {}, []
    for m in study.methods:
        if summary[m]["diverged"] == summary[m]["n"]:
            dropped.append(METHOD_LABELS.get(m, m))
        else:
            shown[METHOD_LABELS.get(m, m)] = study.best_model(m)
    note = f" ({', '.join(dropped)} diverged: not shown)" if dropped else ""
    zoom = _zoom_window(data)
    figures = {
        "time_response": time_response(data, shown, zoom=zoom,
                                       title=f"{data.name}: measured and best identified outputs{note}"),
        "error": error_response(data, shown, zoom=zoom, title=f"{data.name}: output error{note}"),
        "psd": psd(data, shown, title=f"{data.name}: output PSD{note}"),
        "nonlinearity": nonlinearity(shown, (float(data.u.min()), float(data.u.max())), unit_in=data.input_unit,
                                     title=f"{case.name.upper()}: identified static nonlinearities{note}"),
        "convergence": convergence(study, title=f"{case.name.upper()}: convergence over trials"),
        "final_cost": final_cost(study),
    }
    if shown:  # with every method diverged there is no linear block to draw (control.bode_plot needs one)
        figures["bode"] = bode(shown, title=f"{case.name.upper()}: identified linear blocks{note}")
    if validation is not None:
        figures["validation"] = time_response(validation, shown, zoom=_zoom_window(validation),
                                              title=f"{validation.name}: best models on the validation record{note}")
    return figures


def study_figures(study, out_dir, *, formats=("png",), validation=None) -> list[Path]:
    """Write :func:`study_figure_set` into ``out_dir`` (one file per figure and format); return the paths."""
    plt = _pyplot()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fig in study_figure_set(study, validation=validation).items():
        for fmt in formats:
            path = out_dir / f"{name}.{fmt}"
            fig.savefig(path, dpi=120)
            paths.append(path)
        plt.close(fig)
    return paths
