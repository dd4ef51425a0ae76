"""Figures of optimisation runs: the cost against evaluations (with the median and band of repeated trials) and the
final cost of each method."""

from __future__ import annotations

import warnings
import numpy as np
from ..data._inputs import is_identification_result, method_label
from ..exceptions import ParameterError
from ._figures import LOG_SPAN, _WIDTH, _colors, _finish, _new_figure, _single_axes

__all__ = ["convergence", "final_cost"]


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
    """Objective versus NFE: median and inter-quartile band over runs (figures 2-3).

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
