"""Is a fit better than the simpler models nested in it?  F-tests that hold when the noise is coloured.

A model of ``p`` parameters always fits a record at least as well as any
model nested in it (a constant, a static affine gain ``y = k u + c``, the
linear model of the same order): on pure noise it still lowers the sum of
squares by about ``p / N`` of it.  Whether the lowering is more than that
is the classical F-test of nested least-squares models,

    ``F = ((J0 - J1) / (p1 - p0)) / (J1 / (N - p1))``,

``J0, p0`` the nested model's sum of squares and parameters, ``J1, p1`` the
fit's.  Under white noise ``F`` follows Fisher's ``F(p1 - p0, N - p1)`` when
the nested model is true.  Output noise of a real rig is coloured, and then
the plain test calls far too much significant.  :func:`nested_f_test`
therefore first whitens both residual vectors by the same autoregressive
filter ``A(q)``, that of the fit's residuals
(:func:`~hammerstein_ctrl.assess._uncertainty.fit_noise_model`, order by BIC), and
applies the test to the whitened sums (generalised least squares with an
estimated noise model); white residuals give the plain test exactly.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> y = rng.standard_normal(500)
>>> t = nested_f_test(y - 0.01 * rng.standard_normal(500), y - y.mean(), 500, 6, 1)  # 6 parameters fit noise
>>> t.significant
False
>>> u = rng.standard_normal(500); y2 = 0.3 * u + rng.standard_normal(500)
>>> k, c = np.polyfit(u, y2, 1)
>>> nested_f_test(y2 - k * u - c, y2 - y2.mean(), 500, 2, 1).significant        # the gain is real
True
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import config
from ..exceptions import ParameterError
from ._uncertainty import fit_noise_model

__all__ = ["NestedTest", "nested_f_test", "whitened_sse", "ROUNDING_LEVEL", "rounding_sse"]

#: Residuals below this share of the output's spread (RMS, 180 dB) are rounding: an exact fit, whose residuals'
#: tests (and F-tests between two exact fits) say nothing of the model.
ROUNDING_LEVEL = 1e-9


def rounding_sse(y) -> float:
    """The sum of squared residuals at or below which a fit of ``y`` is exact (:data:`ROUNDING_LEVEL` of its
    spread, RMS).

    >>> e = rounding_sse(np.arange(4.0))
    >>> bool(4 * 1e-13 ** 2 <= e), bool(4 * 1e-3 ** 2 <= e)
    (True, False)
    """
    y = np.asarray(y, dtype=float).reshape(-1)
    return ROUNDING_LEVEL ** 2 * float(np.sum((y - y.mean()) ** 2))


class NestedTest(NamedTuple):
    """The F-test of a fit against a model nested in it (see the module notes).

    Attributes
    ----------
    nested : str
        What the nested model is (``"a constant"``, ...).
    sse, nested_sse : float
        The fit's and the nested model's sums of squared residuals (not whitened).
    statistic : float
        ``F`` of the whitened sums (negative when the nested model fits better).
    dof : tuple of int
        ``(p1 - p0, N - p1 - order)``.
    p_value : float
        Probability of an ``F`` this large if the nested model were true.
    level : float
        The test's level: :attr:`significant` when ``p_value < level``.
    noise : str
        The whitening noise model (``"white"``, ``"AR(3)"``, ...).
    """

    nested: str
    sse: float
    nested_sse: float
    statistic: float
    dof: tuple
    p_value: float
    level: float
    noise: str

    @property
    def significant(self) -> bool:
        """Whether the fit is significantly better than the nested model."""
        return bool(self.p_value < self.level)

    def describe(self) -> str:
        """``F = .. on (d1, d2) degrees of freedom, p = ..``."""
        return (f"F = {self.statistic:.3g} on ({self.dof[0]}, {self.dof[1]}) degrees of freedom, p = "
                f"{self.p_value:.2g}{'' if self.noise == 'white' else ', ' + self.noise + ' noise'}")


#: Samples whitened at a time (the tests hold no record-long copy).
BLOCK = 1 << 16


def whitened_sse(residual, n: int, ar) -> float:
    """``|A(q) r|^2`` over samples ``len(ar) - 1 .. n - 1`` (the first ones need samples before the record).

    ``residual(a, b)`` returns ``r[a:b]``; the sum is taken a block at a time.

    Examples
    --------
    >>> r = np.array([1.0, 2.0, 4.0, 8.0, 0.0])
    >>> whitened_sse(lambda a, b: r[a:b], 5, np.array([1.0, -2.0]))    # r_t - 2 r_{t-1}: only the last, -16
    256.0
    """
    ar = np.asarray(ar, dtype=float)
    order, total = ar.size - 1, 0.0
    for a in range(order, n, BLOCK):
        b = min(n, a + BLOCK)
        piece = np.asarray(residual(a - order, b), dtype=float)
        w = piece[order:].copy()
        for i in range(1, order + 1):
            w += ar[i] * piece[order - i:piece.size - i]
        total += float(w @ w)
    return total


def _sse(residual, n: int) -> float:
    return whitened_sse(residual, n, np.ones(1))


def nested_f_test(residual, nested_residual, n: int, n_params: int, nested_params: int, *, noise=None,
                  nested: str = "nested model", level: float | None = None) -> NestedTest:
    """F-test of a fit against a model nested in it, the noise whitened first.

    Parameters
    ----------
    residual, nested_residual : array_like, shape (N,), or callable
        Residuals of the fit and of the nested model on the same samples, or
        functions ``(a, b) -> r[a:b]`` that form them a block at a time.
    n : int
        Samples ``N``.
    n_params, nested_params : int
        Parameters each estimated (``n_params > nested_params``).
    noise : NoiseModel, optional
        The fit's residuals' noise model (default: fitted here).
    nested : str
        What the nested model is, for the messages.
    level : float, optional
        Default ``config.defaults["verdicts.significance"]``.

    Returns
    -------
    NestedTest
    """
    r1, r0 = _blocks(residual, n, "residual"), _blocks(nested_residual, n, "nested_residual")
    d1 = int(n_params) - int(nested_params)
    if d1 < 1:
        raise ParameterError(f"the nested model must have fewer parameters ({nested_params}) than the fit "
                             f"({n_params})")
    level = config.get("verdicts.significance") if level is None else float(level)
    if noise is None:
        noise = fit_noise_model(r1(0, n), n_params)
    sse1, sse0 = _sse(r1, n), _sse(r0, n)
    j1, j0 = whitened_sse(r1, n, noise.ar), whitened_sse(r0, n, noise.ar)
    d2 = n - noise.order - int(n_params)
    if d2 < 1 or not (np.isfinite(j0) and np.isfinite(j1)):
        return NestedTest(nested, sse1, sse0, np.nan, (d1, max(d2, 0)), np.nan, level, noise.describe())
    if j1 <= 0.0:                           # an exact fit: better than anything nested that is not exact
        F = np.inf if j0 > 0.0 else np.nan
    else:
        F = ((j0 - j1) / d1) / (j1 / d2)
    from scipy.special import fdtrc

    p = 1.0 if not F > 0 else (0.0 if F == np.inf else float(fdtrc(d1, d2, F)))
    return NestedTest(nested, sse1, sse0, float(F), (d1, d2), p, level, noise.describe())


def _blocks(residual, n: int, name: str):
    """``(a, b) -> r[a:b]`` of a residual given as an array or as such a function."""
    if callable(residual):
        return residual
    r = np.asarray(residual, dtype=float).reshape(-1)
    if r.size != n:
        raise ParameterError(f"{name} has {r.size} samples, not {n}")
    return lambda a, b: r[a:b]
