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
that explains :data:`NAMED_SHARE` of what the largest explains.  On records
measured inside a feedback loop the input also depends on past noise, and a
finding may mean that instead.

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

from . import _core
from . import config
from .exceptions import ParameterError

__all__ = ["ResidualAnalysis", "CoherenceFinding", "residual_analysis", "coherence_test",
           "RESID_LEVEL", "ADEQUACY_Z", "COHERENCE_SEGMENTS", "SEGMENT_MAX", "GROUPS", "NAMED_SHARE"]

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
        ``0 .. M`` for :attr:`autocorrelation`; the cross-correlation has lags ``-M .. M``.
    autocorrelation : ndarray, shape (M + 1,)
        Of the residuals (1 at lag 0).
    autocorrelation_bound : float
        The 99 % bound ``z / sqrt(N)`` of white residuals.
    cross_correlation : ndarray, shape (2M + 1,)
        Between ``u(t - k)`` and ``e(t)``, ``k = -M .. M`` (positive lags: the input leads).
    cross_correlation_bound : float
        The 99 % bound for residuals independent of the input (Bartlett's, wider when both are coloured).
    whiteness : bool
        Whether the autocorrelation stays inside its bound at lags 1..M.
    independence : bool
        Whether the cross-correlation stays inside its bound.
    findings : list of CoherenceFinding
        The sets found to explain part of the residuals, the one :meth:`verdict` names first (empty when none).
    coherence : list of CoherenceFinding
        The test of every set.
    passed : bool
        No finding: nothing in the residuals can be explained from the input.
    """

    def __init__(self, residuals, u, dt, *, lags: int, coherence, cross_bound: float, name: str = ""):
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
        self.coherence = list(coherence)
        self.findings = _named_first([f for f in self.coherence if f.found])
        self.passed = not self.findings

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
        """Whether the autocorrelation stays inside its bound at lags ``1 .. M``."""
        return bool(np.all(np.abs(self.autocorrelation[1:]) <= self.autocorrelation_bound))

    @property
    def independence(self) -> bool:
        """Whether the cross-correlation stays inside its bound."""
        return bool(np.all(np.abs(self.cross_correlation) <= self.cross_correlation_bound))

    @property
    def cross_lags(self) -> np.ndarray:
        """Lags ``-M .. M`` of :attr:`cross_correlation`."""
        return np.arange(-self.lags[-1], self.lags[-1] + 1)

    def verdict(self) -> str | None:
        """What seems missing, or ``None`` when nothing is: the smallest found set that explains nearly as much
        as the largest (:data:`NAMED_SHARE`)."""
        if not self.findings:
            return None
        f = self.findings[0]
        return f"the residuals still depend on the input: {f.describe()}; {f.advice}"

    def summary(self) -> str:
        """A few lines: whiteness, independence and the coherence test."""
        lines = [f"residual analysis{' of ' + self.name if self.name else ''} ({self.residuals.size} samples):",
                 f"  whiteness: {'white' if self.whiteness else 'coloured'} (max |r_ee| at lags 1-{self.lags[-1]}"
                 f" = {np.max(np.abs(self.autocorrelation[1:]), initial=0):.3g}, 99 % bound "
                 f"{self.autocorrelation_bound:.3g})",
                 f"  input correlation: max |r_eu| = {np.max(np.abs(self.cross_correlation)):.3g} (99 % bound "
                 f"{self.cross_correlation_bound:.3g})"]
        lines += [f"  {'FOUND' if f.found else 'ok'} {f.group}: {f.describe()}" for f in self.coherence]
        lines.append(f"  verdict: {self.verdict() or 'nothing in the residuals is explained by the input'}")
        return "\n".join(lines)

    def __repr__(self):
        return f"<ResidualAnalysis {'passed' if self.passed else 'FAILED'}: {self.residuals.size} samples>"

    def _repr_pretty_(self, printer, cycle):
        printer.text(self.summary())

    def plot(self, *, title: str | None = None):
        """The autocorrelation and the input cross-correlation with their 99 % bounds (MATLAB ``resid``)."""
        from .plots import residual_figure

        return residual_figure(self, title=title)


def _normal_quantile(level: float) -> float:
    from scipy.special import ndtri

    return float(ndtri(0.5 + level / 2))


def residual_analysis(residuals, u, *, dt: float, simulated=None, output=None, lags: int | None = None,
                      name: str = "") -> ResidualAnalysis:
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
    seg = _Segments(e.size)
    z = _normal_quantile(RESID_LEVEL)
    if not seg.usable:
        return ResidualAnalysis(e, u, dt, lags=int(lags), coherence=[], cross_bound=z / np.sqrt(e.size), name=name)
    groups = GROUPS if simulated is not None or output is not None else GROUPS[:2]
    regressors = _regressor_segments(seg, u, simulated, output, e)
    names = list(regressors)
    spectra = seg.spectra(np.stack([seg.take(e)] + [regressors[n] for n in names]))   # one FFT call
    R, X = spectra[0], spectra[1:]
    coherence = _coherence(R, X, names, groups)
    bound = _bartlett_bound(R, X[0], seg.length, e.size, z)
    return ResidualAnalysis(e, u, dt, lags=int(lags), coherence=coherence, cross_bound=bound, name=name)
