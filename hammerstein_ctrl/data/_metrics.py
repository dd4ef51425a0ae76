"""Goodness-of-fit measures between a measured and a simulated output.

``sse`` is the paper's objective J (Eq. 4/13).  ``nrmse`` and ``fit_percent``
follow MATLAB's System Identification Toolbox (``goodnessOfFit`` with 'NRMSE'
and ``compare``): ``fit = 100 (1 - ||y - yhat|| / ||y - mean(y)||)``.

Examples
--------
>>> import numpy as np
>>> y = np.array([0.0, 1.0, 2.0, 3.0]); yhat = np.array([0.0, 1.0, 2.0, 2.0])
>>> sse(y, yhat), rmse(y, yhat)
(1.0, 0.5)
>>> round(fit_percent(y, yhat), 3)
55.279
"""

from __future__ import annotations

import numpy as np

from .._checks import as_signal
from ..exceptions import DataError

__all__ = ["sse", "rmse", "nrmse", "fit_percent", "fit_report", "channel_report"]


def _pair(y, yhat):
    y = as_signal(y, "y")
    yhat = as_signal(yhat, "yhat")
    if y.size != yhat.size:
        raise DataError(f"length mismatch: y has {y.size} samples but yhat has {yhat.size}")
    return y, yhat


def sse(y, yhat) -> float:
    """Sum of squared errors ``J = sum (y - yhat)^2`` (the paper's equation 13).

    Examples
    --------
    >>> sse([0.0, 1.0], [0.5, 2.0])
    1.25
    """
    y, yhat = _pair(y, yhat)
    with np.errstate(over="ignore"):        # a diverging model: inf, without numpy's warning
        return float(np.sum((y - yhat) ** 2))


def rmse(y, yhat) -> float:
    """Root-mean-square error.

    Examples
    --------
    >>> rmse([0.0, 1.0], [0.0, 2.0])
    0.7071067811865476
    """
    y, yhat = _pair(y, yhat)
    with np.errstate(over="ignore"):
        return float(np.sqrt(np.mean((y - yhat) ** 2)))


def nrmse(y, yhat) -> float:
    """Normalised RMSE ``||y - yhat|| / ||y - mean(y)||`` (0 is perfect).

    Raises
    ------
    DataError
        If ``y`` is constant (the normalisation is undefined).

    Examples
    --------
    >>> round(nrmse([0.0, 1.0, 2.0], [0.0, 1.0, 2.5]), 6)          # 0.5 / sqrt(2)
    0.353553
    """
    y, yhat = _pair(y, yhat)
    scale = np.linalg.norm(y - y.mean())
    if scale == 0:
        raise DataError("y is constant: NRMSE and fit % are undefined")
    with np.errstate(over="ignore"):
        return float(np.linalg.norm(y - yhat) / scale)


def fit_percent(y, yhat) -> float:
    """Fit in percent, ``100 (1 - nrmse)`` (100 is perfect, can be negative).

    Examples
    --------
    >>> round(fit_percent([0.0, 1.0, 2.0], [0.0, 1.0, 2.5]), 4)
    64.6447
    """
    return 100.0 * (1.0 - nrmse(y, yhat))


def fit_report(y, yhat) -> dict:
    """All measures at once: ``{"sse", "rmse", "nrmse", "fit_percent"}``.

    Examples
    --------
    >>> {k: round(v, 4) for k, v in fit_report([0.0, 1.0, 2.0], [0.0, 1.0, 2.5]).items()}
    {'sse': 0.25, 'rmse': 0.2887, 'nrmse': 0.3536, 'fit_percent': 64.6447}
    """
    return {
        "sse": sse(y, yhat),
        "rmse": rmse(y, yhat),
        "nrmse": nrmse(y, yhat),
        "fit_percent": fit_percent(y, yhat),
    }


def channel_report(Y, Yhat, names) -> dict:
    """:func:`fit_report` of several output channels (columns): ``sse`` and ``rmse`` over every sample,
    ``nrmse`` and ``fit_percent`` the channels' means, and ``outputs``, each channel's own report by name.

    Examples
    --------
    >>> import numpy as np
    >>> Y = np.column_stack([np.sin(np.arange(50.0)), np.arange(50.0)])
    >>> r = channel_report(Y, Y + [0.0, 1.0], ["a", "b"])
    >>> round(r["outputs"]["a"]["fit_percent"], 6), round(r["sse"], 6)
    (100.0, 50.0)
    """
    Y, Yhat = np.asarray(Y, dtype=float), np.asarray(Yhat, dtype=float)
    reports = {name: fit_report(Y[:, i], Yhat[:, i]) for i, name in enumerate(names)}
    E = Y - Yhat
    return {"sse": float(np.sum(E * E)), "rmse": float(np.sqrt(np.mean(E * E))),
            "nrmse": float(np.mean([r["nrmse"] for r in reports.values()])),
            "fit_percent": float(np.mean([r["fit_percent"] for r in reports.values()])), "outputs": reports}
