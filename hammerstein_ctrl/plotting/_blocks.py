"""Figures of the blocks: Bode plots of the linear block (with confidence bands) and the static maps over an input
range."""

from __future__ import annotations

import numpy as np
from ..data._inputs import as_models, is_identification_result, labelled
from ..exceptions import ParameterError
from ._figures import _WIDTH, _finish, _label, _new_figure, _single_axes

__all__ = ["bode", "nonlinearity"]


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
