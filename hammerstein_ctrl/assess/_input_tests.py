"""What the input still explains in the residuals: coherence with groups of input signals, the residuals' level
against a signal's level, and in closed loop the past inputs (causal test)."""

from __future__ import annotations

from typing import NamedTuple
import numpy as np
from ..exceptions import ParameterError
from ._uncertainty import fit_noise_model

__all__ = ["CoherenceFinding", "coherence_test", "level_test", "causal_test", "ADEQUACY_Z", "COHERENCE_SEGMENTS",
           "SEGMENT_MAX", "GROUPS", "NAMED_SHARE", "LEVEL_BINS", "LEVEL_GROUPS", "CAUSAL_P"]


#: Standard deviations above the shifted pairings' mean at which an explained fraction is a finding.
ADEQUACY_Z = 4.0
#: Segments of the coherence test (fewer on short records; none below :data:`MIN_SEGMENTS`).
COHERENCE_SEGMENTS = 32
#: Fewest segments and samples per segment of the coherence test.
MIN_SEGMENTS, MIN_SEGMENT = 8, 16
#: Longest segment: longer records are tested on evenly spread segments of this length (bounded memory).
SEGMENT_MAX = 4096
#: The nested regressor sets of the coherence test: (name, regressors, what seems missing when it explains).
GROUPS = (
    ("dynamics", ("u",), "linear dynamics seem missing: the order may be too low, or a delay missing"),
    ("input nonlinearity", ("u", "u^2", "u^3"),
     "the input nonlinearity seems wrong: try another family, or another structure for it"),
    ("output nonlinearity", ("u", "u^2", "u^3", "y^2", "y^3"),
     "an output nonlinearity seems missing or wrong: try a Wiener or Hammerstein-Wiener structure"),
)


#: Quantile bins of the level test.
LEVEL_BINS = 10
#: The level test's signals: (name, signal, what seems missing when the residuals' mean depends on it).
LEVEL_GROUPS = (
    ("input level", "u", "the residuals' mean depends on the input's level in a way the model's input map does not "
                         "take: try another input family, or a Hammerstein-Wiener structure"),
    ("output level", "the simulated output",
     "the residuals' mean depends on the simulated output's level: an output nonlinearity seems missing or of the "
     "wrong shape: try a Wiener or Hammerstein-Wiener structure, or another output family"),
)
#: p-value below which a set of past-input regressors explains the whitened residuals (the closed-loop test;
#: that of :data:`ADEQUACY_Z` standard deviations of a normal).
CAUSAL_P = 3e-5
class CoherenceFinding(NamedTuple):
    """The coherence test of one regressor set (see the module notes).

    ``fraction`` is the share of the residual's power the regressors explain;
    ``chance_mean``, ``chance_std``, ``chance_max`` describe the shares of the
    segment-shifted pairings; ``found`` whether the share is a finding.
    """

    group: str
    regressors: tuple
    fraction: float
    chance_mean: float
    chance_std: float
    chance_max: float
    found: bool
    advice: str

    @property
    def beyond_chance(self) -> float:
        """The share explained beyond what chance explains on average."""
        return self.fraction - self.chance_mean

    def describe(self) -> str:
        """One line: the regressors, the share explained and the share by chance."""
        return (f"{100 * self.fraction:.0f} % of the residuals' power is explained by {', '.join(self.regressors)} "
                f"(by chance: {100 * self.chance_mean:.0f} ± {100 * self.chance_std:.0f} %, at most "
                f"{100 * self.chance_max:.0f} %)")


def _smooth_length(n: int) -> int:
    """The largest length at most ``n`` whose only prime factors are 2, 3 and 5 (fast FFTs)."""
    for m in range(n, 0, -1):
        k = m
        for f in (2, 3, 5):
            while k % f == 0:
                k //= f
        if k == 1:
            return m
    return 1


def _segments(n: int):
    """``(starts, length)`` of the coherence test's segments, or ``None`` on a record too short."""
    count = min(COHERENCE_SEGMENTS, n // MIN_SEGMENT)
    if count < MIN_SEGMENTS:
        return None
    length = _smooth_length(min(n // count, SEGMENT_MAX))
    return np.linspace(0, n - length, count).astype(np.int64), length


def _segment_spectra(S: np.ndarray, window) -> np.ndarray:
    """Windowed FFTs of the (de-meaned) segments ``S`` (one per row along the last axis), without the zero
    frequency; each signal (leading index) scaled to unit power, which the test does not see but its ridge does."""
    S = S - S.mean(axis=-1, keepdims=True)
    S *= window
    F = np.fft.rfft(S, axis=-1)[..., 1:].astype(np.complex64)     # a statistic: single precision suffices
    if F.ndim == 3:
        power = np.sqrt(np.sum(np.abs(F) ** 2, axis=(1, 2), keepdims=True))
        F /= np.where(power > 0, power, 1.0)
    return F


class _Segments:
    """The samples of the coherence test's segments of a record (at most ``COHERENCE_SEGMENTS x SEGMENT_MAX``:
    the test's memory does not grow with the record)."""

    def __init__(self, n: int):
        plan = _segments(n)
        self.usable = plan is not None
        if self.usable:
            starts, self.length = plan
            self.index = starts[:, None] + np.arange(self.length)
            self.window = np.hanning(self.length)

    def take(self, x) -> np.ndarray:
        return np.asarray(x, dtype=float)[self.index]

    def spectra(self, S) -> np.ndarray:
        return _segment_spectra(S, self.window)


def _regressor_segments(seg: _Segments, u, simulated, output=None, residuals=None) -> dict:
    """The regressors of :data:`GROUPS` on the segments (each set spans the same space however its signals are
    centred or scaled: the test is invariant to that, so they are only centred).  The simulated output is
    ``simulated``, or ``output - residuals`` formed on the segments alone."""
    us = seg.take(u)
    us -= us.mean()
    out = {"u": us, "u^2": us * us, "u^3": us * us * us}
    if simulated is not None or output is not None:
        ys = seg.take(simulated) if simulated is not None else seg.take(output) - seg.take(residuals)
        ys -= ys.mean()
        out.update({"y^2": ys * ys, "y^3": ys * ys * ys})
    return out


def coherence_test(residuals, regressors: dict, groups=GROUPS) -> list[CoherenceFinding]:
    """The share of the residuals' power explained by nested regressor sets, against chance (module notes).

    Parameters
    ----------
    residuals : array_like, shape (N,)
    regressors : dict of str to array_like, shape (N,)
        The signals named in ``groups``.
    groups : sequence of (name, regressor names, advice)
        Nested sets, smallest first.

    Returns
    -------
    list of CoherenceFinding
        Empty when the record is too short to test (fewer than
        ``MIN_SEGMENTS * MIN_SEGMENT`` samples).

    Examples
    --------
    >>> rng = np.random.default_rng(3)
    >>> u = rng.standard_normal(2000)
    >>> e = np.convolve(u, [0.0, 0.5, 0.3])[:2000] + 0.1 * rng.standard_normal(2000)   # u filtered: dynamics
    >>> [(f.group, f.found) for f in coherence_test(e, {"u": u, "u^2": u**2, "u^3": u**3}, GROUPS[:2])]
    [('dynamics', True), ('input nonlinearity', True)]
    """
    seg = _Segments(np.size(residuals))
    if not seg.usable:
        return []
    names = list(dict.fromkeys(n for _, g, _ in groups for n in g))
    spectra = seg.spectra(np.stack([seg.take(residuals)] + [seg.take(regressors[n]) for n in names]))
    return _coherence(spectra[0], spectra[1:], names, groups)


def _coherence(R, X, names, groups) -> list[CoherenceFinding]:
    """The coherence test of nested groups whose regressors are ``names`` in order (each group a prefix of them).

    With ``A = L L^H`` the regressors' spectral matrix at a frequency and
    ``b`` their cross-spectrum with the residual, the explained power is
    ``|L^-1 b|^2``; for a group of the first ``q`` regressors it is the sum of
    the first ``q`` squares (the leading block of a Cholesky factor is the
    factor of the leading block), so one factorisation serves every group.
    """
    total = float(np.sum(np.abs(R) ** 2))
    if not (total > 0 and np.isfinite(total)):
        return []
    Xf = np.ascontiguousarray(np.moveaxis(X, 2, 0), dtype=np.complex128)          # (bins, q, segments)
    A = np.matmul(Xf, np.conj(np.swapaxes(Xf, 1, 2)))                             # (bins, q, q)
    trace = np.trace(A, axis1=1, axis2=2).real
    ridge = 1e-6 * np.maximum(trace, 1e-12 * max(float(trace.max()), 1e-300)) / len(names)
    A += ridge[:, None, None] * np.eye(len(names))
    Y = np.matmul(np.linalg.inv(np.linalg.cholesky(A)), Xf)                       # whitened regressors
    # residual of segment k with the regressors of segment k + s, for every shift s (s = 0: as recorded)
    Rf = np.conj(np.fft.fft(np.asarray(R, dtype=np.complex128).T, axis=1))       # (bins, segments)
    cross = np.fft.ifft(np.fft.fft(Y, axis=2) * Rf[:, None, :], axis=2)
    shares = np.cumsum(np.sum(cross.real ** 2 + cross.imag ** 2, axis=0), axis=0).T / total   # (shifts, q)
    out = []
    for name, members, advice in groups:
        if list(members) != names[:len(members)]:
            raise ParameterError(f"coherence groups must be nested prefixes of {names}, got {members}")
        explained = shares[:, len(members) - 1]
        chance = explained[1:]
        mean, std, top = float(chance.mean()), float(chance.std()), float(chance.max())
        found = bool(explained[0] > top and explained[0] > mean + ADEQUACY_Z * std)
        out.append(CoherenceFinding(name, tuple(members), float(explained[0]), mean, std, top, found, advice))
    return out


#: A smaller regressor set is named when it explains this share of what the largest found set explains
#: (beyond chance): the larger sets' extra regressors then add little.
NAMED_SHARE = 0.85


def _named_first(findings: list) -> list:
    """The found sets, the one to name first: the smallest that explains :data:`NAMED_SHARE` of the most."""
    if not findings:
        return []
    most = max(f.beyond_chance for f in findings)
    first = next(f for f in findings if f.beyond_chance >= NAMED_SHARE * most)
    return [first] + [f for f in findings if f is not first]


#: Samples binned at a time by the level test (its memory does not grow with the record).
_LEVEL_BLOCK = 1 << 16


def _bin_index(signal_of, n: int, bins: int) -> np.ndarray:
    """The quantile bin (``0 .. bins - 1``, one byte each) of every sample of a signal given as
    ``signal_of(a, b) -> x[a:b]``; the quantiles from at most 65 536 evenly spread samples."""
    step = max(1, n // _LEVEL_BLOCK)
    sample = np.concatenate([signal_of(a, min(n, a + _LEVEL_BLOCK * step))[::step]
                             for a in range(0, n, _LEVEL_BLOCK * step)])
    edges = np.quantile(sample, np.linspace(0.0, 1.0, bins + 1)[1:-1])
    index = np.empty(n, dtype=np.uint8)
    for a in range(0, n, _LEVEL_BLOCK):
        b = min(n, a + _LEVEL_BLOCK)
        index[a:b] = np.searchsorted(edges, signal_of(a, b))
    return index


def _binned_share(e: np.ndarray, index: np.ndarray, shift: int, bins: int, total: float) -> float:
    """Share of ``|e|^2`` that the mean of ``e[(t + shift) mod N]`` per bin ``index[t]`` explains (no copy)."""
    n = e.size
    count = np.bincount(index, minlength=bins).astype(float)
    sums = (np.bincount(index[:n - shift], weights=e[shift:], minlength=bins)
            + np.bincount(index[n - shift:], weights=e[:shift], minlength=bins))
    return float(np.sum(sums * sums / np.maximum(count, 1.0)) / total)


def _scaled_chi2_tail(value: float, mean: float, std: float) -> float:
    """Upper tail at ``value`` of the scaled chi-square with the given mean and standard deviation.

    A binned share of independent residuals is ``chi2(bins - 1) / N`` for white ones; coloured ones scale it
    and change its degrees of freedom, which the shifted pairings' moments measure (``k = 2 mean^2 / var``).
    """
    from scipy.special import chdtrc

    if not (mean > 0 and std > 0):
        return 0.0 if value > mean else 1.0
    k = 2.0 * mean * mean / (std * std)
    return float(chdtrc(k, value * k / mean))


def level_test(residuals, signals: dict, groups=LEVEL_GROUPS, *, bins: int = LEVEL_BINS,
               shifts: int = COHERENCE_SEGMENTS) -> list[CoherenceFinding]:
    """How much of the residuals' power their mean per quantile bin of each signal explains, against chance.

    Parameters
    ----------
    residuals : array_like, shape (N,)
    signals : dict of str to array_like shape (N,) or callable ``(a, b) -> x[a:b]``
        The signals of ``groups`` (those missing are not tested).
    groups : sequence of (name, signal name, advice)
    bins : int
        Quantile bins of each signal.
    shifts : int
        Cyclic shifts of the residuals (``k N / shifts``, ``k = 1 .. shifts - 1``) that make the chance
        distribution: a share is a finding when it exceeds every shifted one and the upper tail of the scaled
        chi-square with their mean and spread is below :data:`CAUSAL_P` there.

    Returns
    -------
    list of CoherenceFinding
        One per tested group; empty on a record shorter than ``shifts * bins * 4`` samples.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> v = np.convolve(rng.standard_normal(4000), np.ones(40) / 40, "same")       # a slow signal
    >>> e = 0.3 * np.abs(v) + 0.02 * rng.standard_normal(4000)                   # an even function of it
    >>> [(f.group, f.found) for f in level_test(e, {"u": v}, LEVEL_GROUPS[:1])]
    [('input level', True)]
    """
    e = np.asarray(residuals, dtype=float).reshape(-1)
    n = e.size
    if n < shifts * bins * 4:
        return []
    e = e - e.mean()
    total = float(e @ e)
    if not (total > 0 and np.isfinite(total)):
        return []
    out = []
    for name, signal, advice in groups:
        if signal not in signals:
            continue
        x = signals[signal]
        index = _bin_index(x if callable(x) else _slicer(np.asarray(x, dtype=float)), n, bins)
        stats = np.array([_binned_share(e, index, (k * n) // shifts, bins, total) for k in range(shifts)])
        chance = stats[1:]
        mean, std, top = float(chance.mean()), float(chance.std()), float(chance.max())
        found = bool(stats[0] > top and _scaled_chi2_tail(stats[0], mean, std) < CAUSAL_P)
        label = f"a function of {signal}"
        out.append(CoherenceFinding(name, (label,), float(stats[0]), mean, std, top, found, advice))
    return out


def _slicer(x: np.ndarray):
    """``x`` as a function of a block ``(a, b)``, as the level test reads its signals."""
    return lambda a, b: x[a:b]


def _past_regressors(u: np.ndarray, lags: int, powers: int) -> np.ndarray:
    """Columns ``u(t-k)^j`` (``k = 1 .. lags``, ``j = 1 .. powers``, ``u`` centred and scaled) for ``t >= lags``."""
    v = (u - u.mean()) / (u.std() or 1.0)
    n = v.size
    cols = [v[lags - k:n - k] ** j for j in range(1, powers + 1) for k in range(1, lags + 1)]
    return np.column_stack(cols)


def causal_test(residuals, u, *, lags: int, noise=None) -> list[CoherenceFinding]:
    """Closed-loop test: do past inputs explain the whitened residuals?  (Module notes; an F-test per set.)

    Parameters
    ----------
    residuals, u : array_like, shape (N,)
    lags : int
        Past inputs ``u(t-1) .. u(t-lags)``.
    noise : NoiseModel, optional
        The residuals' autoregressive model (default: fitted here).

    Returns
    -------
    list of CoherenceFinding
        ``dynamics`` (past inputs) and ``input nonlinearity`` (with their squares and cubes).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(3000)
    >>> e = rng.standard_normal(3000)
    >>> [f.found for f in causal_test(e, u, lags=10)]
    [False, False]
    >>> [f.found for f in causal_test(e + 0.3 * np.roll(u, 2) ** 2, u, lags=10)]
    [False, True]
    """
    from scipy.special import fdtrc, fdtri

    e = np.asarray(residuals, dtype=float).reshape(-1)
    u = np.asarray(u, dtype=float).reshape(-1)
    noise = fit_noise_model(e) if noise is None else noise
    start = max(lags, noise.order)
    w = noise.whiten(e)[start - noise.order:]                 # the innovations at t >= start
    out = []
    for (name, members, advice), powers in zip(GROUPS[:2], (1, 3)):
        X = _past_regressors(u[start - lags:], lags, powers)
        X = np.column_stack([np.ones(len(w)), X])
        q = X.shape[1] - 1
        dof = len(w) - q - 1
        if dof < 10:
            return []
        coef, *_ = np.linalg.lstsq(X, w, rcond=None)
        r = w - X @ coef
        total = float(np.sum((w - w.mean()) ** 2))
        explained = (total - float(r @ r)) / total if total > 0 else 0.0
        F = (explained / q) / max((1.0 - explained) / dof, 1e-300)
        p = float(fdtrc(q, dof, F))
        past = tuple(f"past {m}" for m in members)
        critical = q * float(fdtri(q, dof, 1.0 - CAUSAL_P))        # the share the test needs: q F / (q F + dof)
        out.append(CoherenceFinding(name, past, explained, q / (len(w) - 1), float(np.sqrt(2.0 * q)) / len(w),
                                    critical / (critical + dof), bool(p < CAUSAL_P), advice))
    return out
