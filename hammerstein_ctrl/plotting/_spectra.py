"""Spectra: Welch power spectral densities of records and simulations, their dominant frequency, and the input's
signal figure."""

from __future__ import annotations

import numpy as np
from ..data._inputs import as_models
from ..exceptions import ParameterError
from ._figures import (MIN_PEAK_BINS, NPERSEG, PEAK_PROMINENCE, SMOOTH_BINS, _MEASURED, _WIDTH, _finish, _label,
                       _mark_unusable, _new_figure, _outputs, _single_axes, _siso_record, _window)

__all__ = ["psd", "dominant_frequency", "spectral_peak", "input_signal"]


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
    """Welch power spectral density of the measured and simulated outputs (figure 12).

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
    """The excitation (like the paper's figures 6 and 14): ``u(t)`` (and a zoom), its histogram and Welch PSD."""
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
