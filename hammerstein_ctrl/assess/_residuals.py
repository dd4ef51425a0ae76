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

import numpy as np

from .. import _core
from .. import config
from ..exceptions import ParameterError
from ._uncertainty import COLOURED_RATIO, fit_noise_model
from ._input_tests import GROUPS, _Segments, _coherence, _named_first, _regressor_segments, causal_test, level_test

__all__ = ["ResidualAnalysis", "residual_analysis", "RESID_LEVEL", "COLOURED_RATIO"]

#: Level of the correlation bounds (MATLAB ``resid``'s 99 %).
RESID_LEVEL = 0.99


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
