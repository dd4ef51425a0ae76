"""How far to trust fitted parameters: their covariance, and its propagation to what users look at.

For a least-squares fit ``beta* = argmin |r(beta)|^2`` of ``N`` samples and
``p`` parameters, the Gauss-Newton covariance is

    ``cov = G^-1 M G^-1``, with ``G = J^T J`` and ``M = J^T Sigma J``,

``J`` the Jacobian of the residuals at ``beta*`` and ``Sigma`` the covariance
of the noise.  For white noise ``Sigma = s^2 I`` with ``s^2 = |r|^2 / (N - p)``
and the formula reduces to the familiar ``s^2 (J^T J)^-1``.  Output noise of a
real rig is seldom white, and then that formula understates the spread of the
estimates several times over.  :func:`fit_noise_model` describes the
residuals by an autoregressive model ``A(q) v = e`` whose order the Bayesian
information criterion picks (order 0, the white formula exactly, when the
residuals are white); ``M`` is then ``s_e^2 |H^T J|^2`` with ``H`` the
noise's impulse-response (lower-triangular Toeplitz) matrix, computed by
filtering ``J`` backwards in time through ``1/A(q)``.

A parameter the record cannot determine has an infinite standard error: the
Gram matrix is decomposed after scaling its columns to unit norm, and the
directions whose eigenvalue falls below :data:`RANK_TOLERANCE` of the largest
get infinite variance, so every parameter that moves along them does too.

:func:`propagate` carries the covariance to any function of the parameters
(linearly, with a derivative over the parameters' own uncertainty, or by
seeded sampling); :func:`root_gradients` gives the exact first-order
sensitivity of a polynomial's roots (poles and zeros) to its coefficients.

Examples
--------
A straight line ``y = a + b t`` fitted to 200 samples with white noise: the
white formula, and the coloured one, which finds the residuals white and so
gives the same:

>>> import numpy as np
>>> t = np.linspace(0.0, 1.0, 200)
>>> J = np.column_stack([np.ones_like(t), t])
>>> r = np.random.default_rng(0).standard_normal(t.size)
>>> u = parameter_covariance(J, r, noise="white")
>>> bool(np.allclose(u.covariance, (r @ r / 198) * np.linalg.inv(J.T @ J)))
True
>>> c = parameter_covariance(J, r)
>>> c.noise.describe(), bool(np.allclose(c.covariance, u.covariance))
('white', True)
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import _core
from .. import config
from ..exceptions import ParameterError

__all__ = ["NoiseModel", "ParameterUncertainty", "Propagated", "channel_uncertainty", "fit_noise_model",
           "parameter_covariance", "residual_jacobian", "estimate_uncertainty", "t_factor", "scaled_eigen",
           "NOISE_MODELS", "MAX_NOISE_ORDER", "RANK_TOLERANCE", "JACOBIAN_MAX_BYTES"]

#: Noise descriptions for the covariance: ``"colored"`` (an autoregressive model of the residuals, order
#: picked by BIC; the white formula when they are white) or ``"white"`` (the plain Gauss-Newton formula).
NOISE_MODELS = ("colored", "white")
#: Highest order of the autoregressive noise model.
MAX_NOISE_ORDER = 30
#: Eigenvalues of the column-scaled Gram matrix below this fraction of the largest are taken as zero: the
#: record carries no information along their directions (forward differences resolve ~1e-16 here).
RANK_TOLERANCE = 1e-13
#: Largest block of residual vectors formed at once for the Jacobian; past it the columns are formed one
#: simulation at a time.
JACOBIAN_MAX_BYTES = 1 << 24


#: Residual power past this many times the innovation variance of their autoregressive model (their
#: unpredictable part, the noise floor) makes them strongly coloured (AR(1) noise of pole 0.9 gives 5.3):
#: mostly a systematic error, for which tests that take the residuals for noise say nothing.
COLOURED_RATIO = 20.0


class NoiseModel(NamedTuple):
    """An autoregressive description ``A(q) v = e`` of the residuals ``v``.

    ``ar`` is ``[1, a1, ..., an]`` (``v_t + a1 v_{t-1} + ... = e_t``), ``variance``
    the variance of the white ``e`` (degrees of freedom corrected).
    """

    order: int
    ar: np.ndarray
    variance: float

    @property
    def white(self) -> bool:
        """Whether the model is white noise (order 0)."""
        return self.order == 0

    def spectrum_at_zero(self) -> float:
        """The noise's spectral density at frequency 0 (per sample): ``variance / A(1)^2``; the
        variance of a mean of ``N`` samples is this over ``N``."""
        return float(self.variance / np.sum(self.ar) ** 2)

    def describe(self) -> str:
        """``"white"`` or ``"AR(n)"``."""
        return "white" if self.white else f"AR({self.order})"

    def predictability(self, r) -> float:
        """Power of the residuals ``r`` (about their mean) over the innovation variance: 1 for white noise;
        past :data:`COLOURED_RATIO` they are mostly a predictable signal, not noise.

        Examples
        --------
        >>> NoiseModel(0, np.array([1.0]), 2.0).predictability(np.array([1.0, -1.0, 2.0, -2.0]))
        1.25
        """
        r = np.asarray(r, dtype=float).reshape(-1)
        power = float(np.mean((r - r.mean()) ** 2)) if r.size else 0.0
        return power / self.variance if self.variance > 0 else 1.0

    def whiten(self, r) -> np.ndarray:
        """The innovations ``A(q) r`` at samples ``order .. N - 1`` (the first ones need samples before ``r``).

        Examples
        --------
        >>> NoiseModel(1, np.array([1.0, -0.5]), 1.0).whiten(np.array([2.0, 1.0, 0.5])).tolist()
        [0.0, 0.0]
        """
        r = np.asarray(r, dtype=float).reshape(-1)
        return r.copy() if self.order == 0 else np.convolve(r, self.ar)[self.order:r.size]


class ParameterUncertainty(NamedTuple):
    """The covariance of fitted parameters and what it was computed from.

    Attributes
    ----------
    covariance : ndarray, shape (p, p)
        ``inf`` on the diagonal of parameters the record does not determine.
    gram : ndarray, shape (p, p)
        ``J^T J`` (the residual Jacobian's Gram matrix).
    noise : NoiseModel
    dof : int
        ``N - p``.
    channel_noise : tuple of NoiseModel
        With several output channels, each channel's own noise model.
    """

    covariance: np.ndarray
    gram: np.ndarray
    noise: NoiseModel
    dof: int
    #: With several output channels, each channel's own noise model (``noise`` is then the noisiest one).
    channel_noise: tuple = ()

    @property
    def stderr(self) -> np.ndarray:
        """Standard errors (``inf`` where undetermined)."""
        return np.sqrt(np.abs(np.diag(self.covariance)))

    def conf_int(self, x, level: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)``: Student-t intervals ``x -/+ t se`` at ``level``."""
        k = t_factor(level, self.dof) * self.stderr
        return np.asarray(x, dtype=float) - k, np.asarray(x, dtype=float) + k

    def correlation(self) -> np.ndarray:
        """The parameters' correlation matrix (NaN where a standard error is infinite or zero)."""
        se = self.stderr
        with np.errstate(all="ignore"):
            return self.covariance / np.outer(se, se)


class Propagated(NamedTuple):
    """A quantity computed from the parameters, with its standard error and confidence interval."""

    value: np.ndarray
    stderr: np.ndarray
    low: np.ndarray
    high: np.ndarray


def t_factor(level: float, dof: int) -> float:
    """The two-sided Student-t factor of a ``level`` interval with ``dof`` degrees of freedom.

    Examples
    --------
    >>> round(t_factor(0.95, 10), 4), round(t_factor(0.95, 10**6), 4)
    (2.2281, 1.96)
    """
    level = _check_level(level)
    from scipy.special import stdtrit

    return float(stdtrit(max(int(dof), 1), 0.5 + level / 2.0))


def _check_level(level) -> float:
    if level is None:
        return config.get("uncertainty.level")
    try:
        value = float(level)
    except (TypeError, ValueError):
        raise ParameterError(f"level must be a number between 0 and 1, got {level!r}") from None
    if not 0.0 < value < 1.0:
        raise ParameterError(f"level must be between 0 and 1 (e.g. 0.95), got {level!r}")
    return value


def _check_noise(noise) -> str:
    key = str(noise).strip().lower().replace("coloured", "colored")
    if key not in NOISE_MODELS:
        raise ParameterError(f"noise must be one of {NOISE_MODELS}, got {noise!r}")
    return key


# -- the noise model -------------------------------------------------------------
def _autocovariances(r: np.ndarray, max_lag: int) -> np.ndarray:
    """``sum_t r_t r_{t+k} / N`` for ``k = 0 .. max_lag`` (about zero: the noise has no mean)."""
    n = r.size
    return np.array([r[k:] @ r[:n - k] for k in range(max_lag + 1)]) / n


def fit_noise_model(r, n_params: int = 0, *, max_order: int | None = None, white: bool = False) -> NoiseModel:
    """An autoregressive model of residuals ``r``, its order picked by BIC (Levinson-Durbin).

    Parameters
    ----------
    r : array_like, shape (N,)
        Residuals at the fitted parameters.
    n_params : int
        Parameters fitted (the innovation variance is scaled by ``N / (N - n_params)``).
    max_order : int, optional
        Highest order tried (default :data:`MAX_NOISE_ORDER`, at most ``N // 20``).
    white : bool
        Order 0 regardless (the plain formula).

    Examples
    --------
    >>> import numpy as np, scipy.signal
    >>> e = np.random.default_rng(1).standard_normal(5000)
    >>> fit_noise_model(e).order
    0
    >>> m = fit_noise_model(scipy.signal.lfilter([1.0], [1.0, -0.9], e))
    >>> m.order, round(float(m.ar[1]), 2)
    (1, -0.9)
    """
    r = np.asarray(r, dtype=float)
    n = r.size
    top = 0 if white else min(MAX_NOISE_ORDER if max_order is None else int(max_order), n // 20)
    gamma = _autocovariances(r, top)
    scale = n / max(n - int(n_params), 1)
    if not gamma[0] > 0 or not np.isfinite(gamma[0]):
        return NoiseModel(0, np.ones(1), float(gamma[0]) * scale if np.isfinite(gamma[0]) else np.inf)
    best = (n * np.log(gamma[0]), 0, np.ones(1), gamma[0])
    a, err = np.ones(1), gamma[0]
    for k in range(1, top + 1):
        reflection = -(a @ gamma[k:0:-1]) / err          # a @ [gamma_k, ..., gamma_1]
        a = np.concatenate([a, [0.0]])
        a = a + reflection * a[::-1]
        err *= 1.0 - reflection * reflection
        if not err > 0:
            break
        bic = n * np.log(err) + k * np.log(n)
        if bic < best[0]:
            best = (bic, k, a.copy(), err)
    return NoiseModel(best[1], best[2], float(best[3]) * scale)


def _backward_filter(rows, ar, out, first: int) -> None:
    """``out[:, first + c] = H^T rows[c]``: ``w_t = rows_t - sum_i ar[i] w_{t+i}``, run from the end (compiled).

    The recursion runs in double precision, the sum over ``i`` added in
    order, whatever ``out`` holds (float64 or float32); ``rows`` (q x n),
    ``ar`` and the writeable ``out`` (n x at least ``first + q``) are
    C-ordered.
    """
    rows, ar = np.ascontiguousarray(rows, dtype=float), np.ascontiguousarray(ar, dtype=float)
    q, n = rows.shape
    if ar.size < 1 or first < 0:
        raise ValueError(f"the whitening filter needs an AR polynomial [1, a1, ...] and a first column >= 0, not "
                         f"{ar.size} coefficients and column {first}")
    if out.ndim != 2 or out.shape[0] != n or out.shape[1] < first + q or out.dtype not in (np.float64, np.float32):
        raise TypeError(f"_backward_filter writes {n} x {first + q} floats, not {out.dtype} {out.shape}")
    run = _core.hc_backward_filter if out.dtype == np.float64 else _core.hc_backward_filter_single
    if run(rows, q, n, ar, ar.size - 1, out, out.shape[1], first) != 0:
        raise MemoryError(f"no memory for the whitening filter of {q} x {n} values")


def _whitening_transpose(J: np.ndarray, noise: NoiseModel) -> np.ndarray:
    """``H^T J``: each column filtered backwards in time through ``1/A(q)`` (the noise's impulse response transposed).

    Examples
    --------
    >>> import numpy as np, scipy.signal
    >>> J = np.random.default_rng(0).standard_normal((50, 2))
    >>> m = NoiseModel(1, np.array([1.0, -0.8]), 1.0)
    >>> ref = scipy.signal.lfilter([1.0], m.ar, J[::-1], axis=0)[::-1]
    >>> bool(np.allclose(_whitening_transpose(J, m), ref))
    True
    """
    out = np.empty(J.shape)
    _backward_filter(np.ascontiguousarray(np.asarray(J, dtype=float).T), noise.ar, out, 0)
    return out


# -- covariance ------------------------------------------------------------------
def scaled_eigen(gram):
    """Eigen-decomposition of the Gram matrix with its columns scaled to unit norm: ``(w, V, scale, null)``.

    ``scale`` are the column norms; ``null`` marks the eigenvalues below
    :data:`RANK_TOLERANCE` of the largest (zero columns give such an
    eigenvalue).  ``None`` when the matrix is not finite or cannot be
    decomposed (an overflowing simulation).
    """
    G = np.asarray(gram, dtype=float)
    if not np.all(np.isfinite(G)):
        return None
    d = np.sqrt(np.clip(np.diag(G), 0.0, None))
    zero = ~(d > 0)
    scale = np.where(zero, 1.0, d)
    C = G / np.outer(scale, scale)
    C[zero, :] = 0.0
    C[:, zero] = 0.0
    try:
        w, V = np.linalg.eigh(C)
    except np.linalg.LinAlgError:
        return None
    null = w <= RANK_TOLERANCE * max(float(w[-1]), 0.0) if w.size else np.zeros(0, dtype=bool)
    return w, V, scale, null


def _scaled_inverse(gram: np.ndarray):
    """``(inverse, undetermined)``: ``gram^-1`` on the subspace the columns determine, and which parameters load
    on a direction they do not (infinite variance; see :data:`RANK_TOLERANCE`)."""
    p = np.shape(gram)[0]
    eig = scaled_eigen(gram)
    if eig is None:
        return np.zeros((p, p)), np.ones(p, dtype=bool)
    w, V, scale, null = eig
    inv = (V[:, ~null] / w[~null]) @ V[:, ~null].T
    undetermined = (np.abs(V[:, null]) > 1e-6).any(axis=1)
    return inv / np.outer(scale, scale), undetermined


def parameter_covariance(J, r, *, noise: str = "colored", gram=None) -> ParameterUncertainty:
    """The covariance of least-squares parameters from the residual Jacobian ``J`` and residuals ``r``.

    Parameters
    ----------
    J : ndarray, shape (N, p), or None
        The Jacobian of the residuals (or of the simulated output: the sign
        does not matter).  May be ``None`` with ``gram`` given for white noise
        (the Jacobian itself is needed for coloured noise only).
    r : ndarray, shape (N,)
    noise : {"colored", "white"}
        See :data:`NOISE_MODELS`.
    gram : ndarray, shape (p, p), optional
        ``J^T J`` if already known.

    Returns
    -------
    ParameterUncertainty
    """
    noise = _check_noise(noise)
    r = np.asarray(r, dtype=float)
    if gram is None:
        gram = _gram(J)
    model = fit_noise_model(r, np.shape(gram)[0], white=noise == "white")
    meat = None
    if not model.white:
        if J is None:
            raise ParameterError("coloured residuals need the Jacobian J, not only its Gram matrix")
        meat = _gram(_whitening_transpose(J, model))
    return _assembled(np.asarray(gram, dtype=float), meat, model, r.size)


def _assembled(gram, meat, model: NoiseModel, n: int) -> ParameterUncertainty:
    """``s^2 G^-1`` (``meat`` None) or ``G^-1 (s_e^2 meat) G^-1``, with infinite variance where undetermined."""
    inv, undetermined = _scaled_inverse(gram)
    cov = model.variance * inv if meat is None else inv @ (model.variance * meat) @ inv
    cov = 0.5 * (cov + cov.T)
    cov[undetermined, :] = np.nan
    cov[:, undetermined] = np.nan
    cov[undetermined, undetermined] = np.inf
    return ParameterUncertainty(cov, gram, model, n - gram.shape[0])


def _gram(J) -> np.ndarray:
    """``J^T J`` in double precision, a block of rows at a time (``J`` may be single precision)."""
    J = np.asarray(J)
    if J.dtype == np.float64:
        return J.T @ J
    G = np.zeros((J.shape[1], J.shape[1]))
    for start in range(0, J.shape[0], 1 << 16):
        block = np.asarray(J[start:start + (1 << 16)], dtype=float)
        G += block.T @ block
    return G


def _jacobian_columns(cost, x, r):
    """``(j, column)`` of the residuals' forward-difference Jacobian at ``x`` (scipy's "2-point" steps), one at a time.

    The ``p + 1`` residual vectors come from one batch up to
    :data:`JACOBIAN_MAX_BYTES`, past it one simulation per column.
    """
    from ..optimize._normal_equations import forward_steps, neighbours

    h = forward_steps(x)
    X = neighbours(x, h)
    if X.shape[0] * r.size * 8 <= JACOBIAN_MAX_BYTES:
        R = np.asarray(cost.residuals_batch(X[1:]), dtype=float)
        for j in range(x.size):
            yield j, (R[j] - r) / h[j]
        return
    for j in range(x.size):
        col = np.asarray(cost.residuals(X[j + 1]), dtype=float)
        col -= r
        col /= h[j]
        yield j, col


def residual_jacobian(cost, x) -> tuple[np.ndarray, np.ndarray]:
    """``(r, J)``: the residuals at ``x`` and their forward-difference Jacobian, ``N x p`` (double precision).

    ``cost`` implements the least-squares protocol (``residuals``, ``residuals_batch``).

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> case = hc.presets.emps()                                     # doctest: +SKIP
    >>> r, J = residual_jacobian(case.cost, case.paper["nspsa"]["beta"])   # doctest: +SKIP
    """
    x = np.asarray(x, dtype=float)
    r = np.asarray(cost.residuals(x), dtype=float)
    J = np.empty((r.size, x.size))
    for j, col in _jacobian_columns(cost, x, r):
        J[:, j] = col
    return r, J


def _whitened_gram(cost, x, r, noise: NoiseModel, gram) -> tuple[np.ndarray, np.ndarray]:
    """``(J^T J, (H^T J)^T (H^T J))``: ``J^T J`` is ``gram`` when given (the compiled pass's), else formed too.

    Up to :data:`JACOBIAN_MAX_BYTES` the Jacobian's columns come from one batch
    and are filtered together; past it they are formed one simulation at a
    time and ``H^T J`` is kept in single precision (4 bytes per sample and
    parameter).
    """
    from ..optimize._normal_equations import forward_steps, neighbours

    p = x.size
    if (p + 1) * r.size * 8 <= JACOBIAN_MAX_BYTES:
        h = forward_steps(x)
        R = np.asarray(cost.residuals_batch(neighbours(x, h)[1:]), dtype=float)
        R -= r
        R /= h[:, None]                                 # the Jacobian's columns, as rows
        white = np.empty((r.size, p))
        _backward_filter(R, noise.ar, white, 0)
        return (R @ R.T if gram is None else gram), white.T @ white
    white = np.empty((r.size, p), dtype=np.float32)
    raw = None if gram is not None else np.empty((r.size, p), dtype=np.float32)
    for j, col in _jacobian_columns(cost, x, r):
        if raw is not None:
            raw[:, j] = col
        _backward_filter(col[None, :], noise.ar, white, j)
    return (gram if raw is None else _gram(raw)), _gram(white)


def estimate_uncertainty(cost, x, *, noise: str = "colored", residuals=None) -> tuple[ParameterUncertainty, np.ndarray]:
    """``(uncertainty, residuals)`` of a fit at ``x`` of a least-squares cost.

    The Gram matrix comes from the cost's compiled normal-equation pass
    where it has one (no ``N x p`` Jacobian is stored); coloured residuals
    need the whitened Jacobian ``H^T J``, formed a column at a time and kept
    in single precision.

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> case = hc.presets.trs()
    >>> res = hc.identify(case.data, case.structure, uncertainty=False)
    >>> unc, r = estimate_uncertainty(case.cost, res.x)
    >>> unc.noise.describe(), bool(np.all(np.abs(res.x - case.true_beta) < 4 * unc.stderr))
    ('white', True)
    """
    noise = _check_noise(noise)
    x = np.asarray(x, dtype=float)
    r = np.asarray(cost.residuals(x) if residuals is None else residuals, dtype=float)
    model = fit_noise_model(r, x.size, white=noise == "white")
    gram = None
    normal = getattr(cost, "normal_equations", None)
    batch = (x.size + 1) * r.size * 8 <= JACOBIAN_MAX_BYTES      # the coloured path forms J^T J itself then
    if normal is not None and (model.white or not batch):
        ne = normal(x)
        gram = ne.gram if ne.finite else None
    if model.white:
        if gram is None:
            gram = _gram(residual_jacobian(cost, x)[1])
        return _assembled(gram, None, model, r.size), r
    gram, meat = _whitened_gram(cost, x, r, model, gram)
    return _assembled(gram, meat, model, r.size), r


def channel_uncertainty(cost, x, residuals, channels: int, *, noise: str = "colored") -> ParameterUncertainty:
    """The covariance of a fit to several output channels, each with its own noise.

    The residual vector lists the channels one after the other (as
    :class:`~hammerstein_ctrl.fit.MIMOCost` does).  Each channel gets
    its own noise model (variance and, for ``noise="colored"``, AR filter:
    outputs measured by different sensors differ in both), and the
    covariance is the sandwich ``G^-1 (sum_i s_i^2 (H_i^T J_i)^T (H_i^T J_i)) G^-1``
    with ``G = J^T J``; no filter runs across the join of two channels.
    With equal white noise on every channel it is the plain formula.

    Examples
    --------
    >>> import numpy as np
    >>> class Line:            # two channels y_i = x t + noise, the second ten times noisier
    ...     t = np.linspace(0, 1, 200)
    ...     def residuals(self, x): return np.r_[self.t, self.t] * (1.0 - x[0]) + np.r_[e1, e2]
    ...     def residuals_batch(self, X): return np.array([self.residuals(x) for x in X])
    >>> rng = np.random.default_rng(0); e1, e2 = 0.01 * rng.standard_normal(200), 0.1 * rng.standard_normal(200)
    >>> unc = channel_uncertainty(Line(), np.array([1.0]), Line().residuals([1.0]), 2, noise="white")
    >>> [m.describe() for m in unc.channel_noise], round(float(unc.stderr[0]), 4)   # sqrt((s1^2 + s2^2) / (4 sum t^2))
    (['white', 'white'], 0.0063)
    """
    noise = _check_noise(noise)
    x = np.asarray(x, dtype=float)
    r = np.asarray(residuals, dtype=float)
    _, J = residual_jacobian(cost, x)
    gram = _gram(J)
    meat = np.zeros_like(gram)
    models = []
    rows = r.size // channels
    for k in range(channels):
        part = slice(k * rows, (k + 1) * rows)
        model = fit_noise_model(r[part], max(1, round(x.size / channels)), white=noise == "white")
        W = J[part] if model.white else _whitening_transpose(J[part], model)
        meat += model.variance * _gram(W)
        models.append(model)
    unc = _assembled(gram, meat, NoiseModel(0, np.ones(1), 1.0), r.size)
    return unc._replace(noise=max(models, key=lambda m: m.variance), channel_noise=tuple(models))


