"""Figures of one identification: its record and simulation, several records or outputs side by side, and the
residual analysis."""

from __future__ import annotations

import numpy as np
from ..data._inputs import as_iodata, as_models, is_identification_result, method_label
from ..exceptions import ParameterError
from ._figures import _MEASURED, _WIDTH, _finish, _label, _mark_unusable, _new_figure, _outputs, _rms, _window
from ._blocks import _has_block, nonlinearity

__all__ = ["compare", "compare_fits", "result_figure", "residual_figure"]


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
