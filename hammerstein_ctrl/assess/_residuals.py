"""Residual analysis of an identified model (MATLAB's ``resid``), and whether the residuals still hold the input.

:func:`residual_analysis` gives a :class:`ResidualAnalysis`: the
autocorrelation of the residuals ``e`` (whiteness) and their cross-correlation
with the input ``u`` at lags ``-M .. M``, each with its 99 % bound, a figure
(:meth:`ResidualAnalysis.plot`), and a verdict.

**The verdict** asks whether any part of the residuals can still be explained
from the input: if it can, the model misses something.  A correlation test
alone cannot say this on real records, whose noise is coloured and whose
inputs are smooth: both widen the spread of a sample correlation far beyond
``1/sqrt(N)``.  The test here is frequency by frequency instead.  The record
is cut into segments; at each frequency the *multiple coherence* of the
residual with a set of regressors is the fraction of the residual's power
that a linear filter of the regressors explains; summed with the residual's
power as weight it is the fraction of the residual explained by the
regressors (any linear dynamics acting on them).  Its distribution when
nothing is explained comes from the same segments paired with the
regressors of *other* segments (every cyclic shift), which keeps both spectra
and breaks any link between them.  A fraction above every shifted one and
:data:`ADEQUACY_Z` of their standard deviations above their mean is a finding.
Three nested sets of regressors say what seems missing:

* ``u``: linear dynamics (the order is too low, or a delay is missing);
* ``u, u^2, u^3``: the input nonlinearity (a wrong family, or the friction in
  the wrong place);
* ``u, u^2, u^3, y^2, y^3`` (``y`` the simulated output): an output
  nonlinearity (a Wiener or Hammerstein-Wiener structure).

The sets are nested, so a residual that the input nonlinearity explains is
also explained by the largest set; the verdict names the smallest found set
that explains :data:`NAMED_SHARE` of what the largest explains.

**Any shape, on the whole record.**  Polynomial regressors and short
segments miss a residual that is a smooth but non-polynomial function of a
slow signal (``x |x|`` behind a filter).  The *level test* therefore also
asks, on the whole record, how much of the residuals' power their mean in
each of :data:`LEVEL_BINS` quantile bins of the input, and of the simulated
output, explains (a binned conditional mean: any static function), against
the same statistic with the residuals cyclically shifted against the signal
(the shifts keep both signals' colour and break their link).

**Colour.**  Residuals much larger than their unpredictable part are mostly
something the model misses, not noise: :attr:`ResidualAnalysis.coloured`
compares their power with the innovation variance of an autoregressive model
of them (:func:`~hammerstein_ctrl.assess._uncertainty.fit_noise_model`).

**Closed loop.**  On a record measured inside a feedback loop the input
depends on past noise, so every test above can find a link that is only the
controller's.  With ``closed_loop=True`` the tests are replaced by one valid
there: the residuals, whitened by their autoregressive model (the noise's
innovations, independent of everything before them), are regressed on *past*
inputs ``u(t-1) .. u(t-M)`` (and their squares and cubes), an F-test per
set.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> u = rng.standard_normal(4000)
>>> a = residual_analysis(rng.standard_normal(4000), u, dt=0.01)          # residuals independent of u
>>> a.passed, a.whiteness
(True, True)
>>> b = residual_analysis(0.1 * rng.standard_normal(4000) + 0.5 * np.roll(u, 3), u, dt=0.01)
>>> b.passed, b.findings[0].group
(False, 'dynamics')
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from .. import _core
from .. import config
from ..exceptions import ParameterError
from ._uncertainty import COLOURED_RATIO, fit_noise_model

__all__ = ["ResidualAnalysis", "CoherenceFinding", "residual_analysis", "coherence_test", "level_test",
           "causal_test", "RESID_LEVEL", "ADEQUACY_Z", "COHERENCE_SEGMENTS", "SEGMENT_MAX", "GROUPS", "NAMED_SHARE",
           "LEVEL_BINS", "LEVEL_GROUPS", "COLOURED_RATIO", "CAUSAL_P"]

#: Level of the correlation bounds (MATLAB ``resid``'s 99 %).
RESID_LEVEL = 0.99
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


def _lagged_sums(a, b, first: int, last: int) -> np.ndarray:
    """``sum_t (a_t - mean a)(b_{t-k} - mean b)`` for ``k = first .. last`` (over the overlapping samples), in the
    compiled core: raw products, with the means' share taken out afterwards from the sums over each overlap (its
    ends differ from the whole record's by ``|k|`` samples).  ``a`` and ``b`` are C-ordered float vectors of one
    length."""
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"lagged sums take two signals of one length, got shapes {a.shape} and {b.shape}")
    if not -a.size < first <= last < a.size:
        raise ValueError(f"lags {first} to {last} reach past a record of {a.size} samples")
    out = np.empty(max(0, last - first + 1))
    _core.hc_lagged_sums(a, b, a.size, int(first), int(last), out)
    return out


def _lagged(a: np.ndarray, b: np.ndarray, lags) -> np.ndarray:
    """The normalised sums of :func:`_lagged_sums` for the consecutive lags ``lags`` (negative: ``b`` leads).

    Examples
    --------
    >>> x = np.array([1.0, 2.0, 0.0, -1.0])
    >>> np.round(_lagged(x, x, np.arange(3)), 4).tolist()     # np.correlate's, normalised
    [1.0, 0.15, -0.5]
    """
    a, b = np.ascontiguousarray(a, dtype=float), np.ascontiguousarray(b, dtype=float)
    sums = _lagged_sums(a, b, int(lags[0]), int(lags[-1]))
    norm = np.sqrt(_lagged_sums(a, a, 0, 0)[0] * _lagged_sums(b, b, 0, 0)[0])
    return sums / norm if norm > 0 else np.zeros(len(sums))


def _bartlett_bound(R, U, length: int, n: int, z: float) -> float:
    """The ``z`` bound of a sample cross-correlation of independent ``e`` and ``u``.

    Bartlett's variance ``(1/N) sum_k rho_ee(k) rho_uu(k)`` is, by Parseval,
    ``(1/N) int S_e S_u df / (var e var u)``; the spectra are the segments'
    averaged periodograms (``R``, ``U``: segment spectra of length ``length``),
    so the bound widens when both signals are coloured and costs no
    correlation over the whole record.
    """
    pe, pu = np.mean(np.abs(R) ** 2, axis=0), np.mean(np.abs(U) ** 2, axis=0)
    denominator = float(pe.sum() * pu.sum())
    if not denominator > 0:
        return z / np.sqrt(n)
    var = 0.5 * length * float(pe @ pu) / denominator / n
    return float(z * np.sqrt(max(var, 1.0 / n)))


class ResidualAnalysis:
    """Correlation analysis of residuals (MATLAB ``resid``) with a verdict.

    Attributes
    ----------
    residuals : ndarray
    dt : float
    lags : ndarray
        ``0, 1, ..., M`` for :attr:`autocorrelation`; the cross-correlation has lags ``-M, ..., M``.
    autocorrelation : ndarray, shape (M + 1,)
        Of the residuals (1 at lag 0).
    autocorrelation_bound : float
        The 99 % bound ``z / sqrt(N)`` of white residuals.
    cross_correlation : ndarray, shape (2M + 1,)
        Between ``u(t - k)`` and ``e(t)``, ``k = -M, ..., M`` (positive lags: the input leads).
    cross_correlation_bound : float
        The 99 % bound for residuals independent of the input (Bartlett's, wider when both are coloured).
    whiteness : bool
        Whether the autocorrelation stays inside its bound at lags 1..M.
    independence : bool
        Whether the cross-correlation stays inside its bound.
    findings : list of CoherenceFinding
        The sets found to explain part of the residuals, the one :meth:`verdict` names first (empty when none).
    coherence : list of CoherenceFinding
        The test of every set (with ``closed_loop``: the past-input sets of :func:`causal_test`).
    level : list of CoherenceFinding
        The level test of each signal (:func:`level_test`; none in closed loop).
    passed : bool
        No finding: nothing in the residuals can be explained from the input.
    noise : NoiseModel
        The residuals' autoregressive model.
    predictability : float
        The residuals' power over the innovation variance of ``noise`` (1 for white residuals).
    closed_loop : bool
        Whether the tests were those valid in closed loop.
    """

    def __init__(self, residuals, u, dt, *, lags: int, coherence, cross_bound: float, name: str = "", level=(),
                 noise=None, closed_loop: bool = False):
        e = np.asarray(residuals, dtype=float)
        n = e.size
        if isinstance(lags, bool) or int(lags) != lags or not 1 <= lags < n:
            raise ParameterError(f"lags must be an integer between 1 and {n - 1} (the residuals' length less one), "
                                 f"got {lags!r}")
        self.residuals, self.dt, self.name = e, float(dt), name
        self.lags = np.arange(lags + 1)
        self._u = np.asarray(u, dtype=float)
        self.autocorrelation_bound = _normal_quantile(RESID_LEVEL) / np.sqrt(n)
        self.cross_correlation_bound = cross_bound
        self.coherence, self.level, self.closed_loop = list(coherence), list(level), bool(closed_loop)
        self.findings = _named_first([f for f in self.coherence if f.found]) + [f for f in self.level if f.found]
        self.noise = fit_noise_model(e) if noise is None else noise
        self.predictability = self.noise.predictability(e)

    @functools.cached_property
    def autocorrelation(self) -> np.ndarray:
        """The residuals' autocorrelation at lags ``0 .. M`` (1 at lag 0)."""
        return _lagged(self.residuals, self.residuals, self.lags)

    @functools.cached_property
    def cross_correlation(self) -> np.ndarray:
        """The cross-correlation of ``u(t - k)`` and ``e(t)`` at lags ``k = -M .. M`` (positive: the input leads)."""
        return _lagged(self.residuals, self._u, self.cross_lags)

    @property
    def whiteness(self) -> bool:
        """Whether the autocorrelation stays inside its bound at lags 1 to M."""
        return bool(np.all(np.abs(self.autocorrelation[1:]) <= self.autocorrelation_bound))

    @property
    def independence(self) -> bool:
        """Whether the cross-correlation stays inside its bound."""
        return bool(np.all(np.abs(self.cross_correlation) <= self.cross_correlation_bound))

    @property
    def cross_lags(self) -> np.ndarray:
        """Lags ``-M .. M`` of :attr:`cross_correlation`."""
        return np.arange(-self.lags[-1], self.lags[-1] + 1)

    @property
    def passed(self) -> bool:
        """Whether nothing was found: no test explains the residuals and they are not strongly coloured."""
        return not self.findings and not self.coloured

    @property
    def coloured(self) -> bool:
        """Whether the residuals are strongly coloured: not white, and their power more than
        :data:`COLOURED_RATIO` times their unpredictable part (mostly something the model misses, not noise)."""
        return bool(self.predictability > COLOURED_RATIO and not self.whiteness)

    def verdict(self) -> str | None:
        """What seems missing, or ``None`` when nothing is: the smallest found set that explains nearly as much
        as the largest (:data:`NAMED_SHARE`)."""
        if not self.findings:
            return None
        f = self.findings[0]
        where = "past inputs" if self.closed_loop else "the input"
        loop = ("" if self.closed_loop else " (if the record was taken in a feedback loop, its input depends on past "
                "outputs and this open-loop test does not apply: identify(..., closed_loop=True))")
        return f"the residuals still depend on {where}: {f.describe()}; {f.advice}{loop}"

    def colour_verdict(self) -> str | None:
        """Why strongly coloured residuals matter and what may cause them, or ``None`` when they are not."""
        if not self.coloured:
            return None
        return (f"the residuals are strongly coloured: their power is {self.predictability:.3g} times the noise floor "
                f"that an autoregressive model of them leaves ({self.noise.describe()}), so most of what the model "
                f"misses is a predictable signal, not noise; likely causes: a nonlinearity of the wrong family or in "
                f"the wrong place (try a Wiener or Hammerstein-Wiener structure, or another family), an order too "
                f"low, or a slow disturbance or drift in the output, which an output-error model does not describe")

    def summary(self) -> str:
        """A few lines: whiteness, independence and the coherence test."""
        lines = [f"residual analysis{' of ' + self.name if self.name else ''} ({self.residuals.size} samples):",
                 f"  whiteness: {'white' if self.whiteness else 'coloured'} (max |r_ee| at lags 1-{self.lags[-1]}"
                 f" = {np.max(np.abs(self.autocorrelation[1:]), initial=0):.3g}, 99 % bound "
                 f"{self.autocorrelation_bound:.3g})",
                 f"  input correlation: max |r_eu| = {np.max(np.abs(self.cross_correlation)):.3g} (99 % bound "
                 f"{self.cross_correlation_bound:.3g})"]
        lines.append(f"  colour: residual power {self.predictability:.3g} times their unpredictable part "
                     f"({self.noise.describe()}){'; STRONGLY COLOURED' if self.coloured else ''}")
        lines += [f"  {'FOUND' if f.found else 'ok'} {f.group}: {f.describe()}" for f in self.coherence + self.level]
        lines.append(f"  verdict: {self.verdict() or 'nothing in the residuals is explained by the input'}")
        return "\n".join(lines)

    def __repr__(self):
        return f"<ResidualAnalysis {'passed' if self.passed else 'FAILED'}: {self.residuals.size} samples>"

    def _repr_pretty_(self, printer, cycle):
        printer.text(self.summary())

    def plot(self, *, title: str | None = None):
        """The autocorrelation and the input cross-correlation with their 99 % bounds (MATLAB ``resid``)."""
        from ..plotting._results import residual_figure

        return residual_figure(self, title=title)


def _normal_quantile(level: float) -> float:
    from scipy.special import ndtri

    return float(ndtri(0.5 + level / 2))


def residual_analysis(residuals, u, *, dt: float, simulated=None, output=None, lags: int | None = None,
                      name: str = "", closed_loop: bool = False, noise=None) -> ResidualAnalysis:
    """Analyse residuals ``e = y - y_sim`` against the input ``u`` (see the module notes).

    Parameters
    ----------
    residuals, u : array_like, shape (N,)
    dt : float
        Sampling interval (for the figure's lag axis).
    simulated : array_like, shape (N,), optional
        The simulated output ``y_sim``; without it (or ``output``) the output-nonlinearity set is not tested.
    output : array_like, shape (N,), optional
        The measured output ``y`` instead of ``simulated`` (``y_sim = y - e`` is then formed on the
        test's segments alone: no second record-long array).
    lags : int, optional
        Default ``config.defaults["residual_analysis.lags"]`` (25).
    name : str
        Shown in the summary and the figure.
    closed_loop : bool, default False
        The record was measured inside a feedback loop: use the tests valid there (module notes).
    noise : NoiseModel, optional
        The residuals' autoregressive model, when already fitted.
    """
    e = np.asarray(residuals, dtype=float)
    if lags is None:                        # the default, shortened for a record too short for it
        lags = max(1, min(config.get("residual_analysis.lags"), (e.size - 1) // 2))
    u = np.asarray(u, dtype=float)
    if e.ndim != 1 or u.shape != e.shape:
        raise ParameterError(f"residuals and u must be 1-D signals of one length, got {e.shape} and {u.shape}")
    if int(lags) != lags or not 1 <= lags < e.size:
        raise ParameterError(f"lags must be an integer between 1 and {e.size - 1}, got {lags!r}")
    if not (np.all(np.isfinite(e)) and np.all(np.isfinite(u))):
        raise ParameterError("residuals and u must be finite (the model cannot be simulated on this record)")
    noise = fit_noise_model(e) if noise is None else noise
    seg = _Segments(e.size)
    z = _normal_quantile(RESID_LEVEL)
    common = dict(lags=int(lags), name=name, noise=noise, closed_loop=closed_loop)
    if closed_loop:
        return ResidualAnalysis(e, u, dt, coherence=causal_test(e, u, lags=int(lags), noise=noise),
                                cross_bound=z / np.sqrt(e.size), **common)
    level = level_test(e, _level_signals(u, simulated, output, e))
    if not seg.usable:
        return ResidualAnalysis(e, u, dt, coherence=[], cross_bound=z / np.sqrt(e.size), level=level, **common)
    groups = GROUPS if simulated is not None or output is not None else GROUPS[:2]
    regressors = _regressor_segments(seg, u, simulated, output, e)
    names = list(regressors)
    spectra = seg.spectra(np.stack([seg.take(e)] + [regressors[n] for n in names]))   # one FFT call
    R, X = spectra[0], spectra[1:]
    coherence = _coherence(R, X, names, groups)
    bound = _bartlett_bound(R, X[0], seg.length, e.size, z)
    return ResidualAnalysis(e, u, dt, coherence=coherence, cross_bound=bound, level=level, **common)


def _level_signals(u, simulated, output, e) -> dict:
    """The level test's signals: the input, and the simulated output (``output - e`` formed a block at a time)."""
    out = {"u": u}
    if simulated is not None:
        out["the simulated output"] = np.asarray(simulated, dtype=float)
    elif output is not None:
        y = np.asarray(output, dtype=float).reshape(-1)
        out["the simulated output"] = lambda a, b: y[a:b] - e[a:b]
    return out
