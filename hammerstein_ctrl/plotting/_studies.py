"""Figures of a study of repeated trials: the best model of each method on the record, and the files the command
line writes."""

from __future__ import annotations

from pathlib import Path
import numpy as np
from ..data._inputs import as_iodata, method_label
from ._figures import FIGURE_DPI, INPUT_ZOOM_SAMPLES, _WIDTH, _new_figure, error_response, time_response
from ._spectra import input_signal, psd
from ._blocks import bode, nonlinearity
from ._runs import convergence, final_cost

__all__ = ["study_figure_set", "study_figures"]


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
