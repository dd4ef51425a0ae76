"""The built-in families of static maps (tanh, Coulomb, polynomial, saturation, dead zone, piecewise-linear,
sigmoid, friction), the user's own maps, and the lookup by name."""

from __future__ import annotations

from typing import Callable, Sequence
import numpy as np
from ..exceptions import ParameterError, UnknownNameError
from ._nonlinearities import Nonlinearity, SCAN_POINTS, _input_quantiles

__all__ = ["Tanh", "Coulomb", "Polynomial", "Saturation", "DeadZone", "PiecewiseLinear", "Sigmoid", "Friction",
           "CustomNonlinearity", "nonlinearity_from_name", "NONLINEARITIES"]


class Tanh(Nonlinearity):
    r"""Hyperbolic tangent, the TRS nonlinearity (the paper's equation 17).

    .. math:: g(u) = \delta_0 \tanh(\delta_1 u)

    Examples
    --------
    >>> Tanh()([0.0, 1.0], [2.0, 0.5]).round(4)
    array([0.    , 0.9242])
    """

    name = "tanh"
    param_names = ("d0", "d1")
    scale_index = 0
    #: Range of ``d1 * max|u|`` scanned by :meth:`shape_grid` (almost linear to hard switching).
    SCAN_RANGE = (0.05, 5.0)

    def normalize(self, params):
        """Make ``d1 >= 0`` (``d0 tanh(d1 u) = (-d0) tanh(-d1 u)``)."""
        p = super().normalize(params)
        flip = p[..., 1] < 0
        p[..., :2] = np.where(flip[..., None], -p[..., :2], p[..., :2])
        return p

    def shape_grid(self, u):
        top = float(np.max(np.abs(u))) or 1.0
        d1 = np.geomspace(*self.SCAN_RANGE, SCAN_POINTS) / top
        return np.column_stack([np.ones_like(d1), d1])

    @staticmethod
    def formula(z, p, extra):
        return p[0] * np.tanh(p[1] * z)

    def _unexcited(self, p, u):
        """Linear or saturated on the whole signal.

        >>> Tanh().unexcited([2.0, 1e-3], [-1.0, 1.0])[1]
        'tanh(d1 u) is linear on the signal (|d1 u| <= 0.001): only the product d0 d1 is seen'
        """
        reach = np.abs(p[1] * u)
        if reach.max() <= 0.05:
            why = f"tanh(d1 u) is linear on the signal (|d1 u| <= {reach.max():.2g}): only the product d0 d1 is seen"
            return {0: why, 1: why}
        bending = float(np.mean(reach < 2.0))
        if bending < 0.01:
            return {1: f"tanh(d1 u) is saturated (+-1) on {100 * (1 - bending):.0f} % of the signal: it acts as "
                       "a sign function, whose steepness d1 the record cannot show"}
        return {}

    def _derivative(self, u, p):
        d0, d1 = self._columns(p)
        return d0 * d1 / np.cosh(d1 * u) ** 2


class Coulomb(Nonlinearity):
    r"""Linear gain plus Coulomb friction plus offset, the EMPS nonlinearity (equation 19).

    .. math:: g(u) = \delta_0 u + \delta_1 \operatorname{sign}(u) + \delta_2

    ``sign(0) = 0``, as in numpy and MATLAB.

    Examples
    --------
    >>> Coulomb()([-2.0, 0.0, 2.0], [0.5, -0.4, 0.05])
    array([-0.55,  0.05,  0.65])
    """

    name = "coulomb"
    param_names = ("d0", "d1", "d2")

    @staticmethod
    def formula(z, p, extra):
        return p[0] * z + p[1] * np.sign(z) + p[2]

    def _derivative(self, u, p):
        return np.full(np.shape(u), p[0], dtype=float)

    def _unexcited(self, p, u):
        """A signal that never changes sign.

        >>> sorted(Coulomb().unexcited([1.0, 0.5, 0.0], [0.2, 0.9]))
        [1, 2]
        """
        if np.all(u > 0) or np.all(u < 0):
            why = "the signal never changes sign, so sign(u) is constant and d1, d2 merge into one offset"
            return {1: why, 2: why}
        return {}

    def basis(self, u):
        u = np.asarray(u, dtype=float)
        return np.stack([u, np.sign(u), np.ones_like(u)])


class Polynomial(Nonlinearity):
    r"""Polynomial without constant term (the paper's equation 3 with ``g(0) = 0``).

    .. math:: g(u) = \sum_{i=1}^{M} d_i u^i

    Parameters
    ----------
    degree : int
        The degree ``M >= 1``.

    Examples
    --------
    >>> Polynomial(3)([1.0, 2.0], [1.0, 0.0, 0.5])
    array([1.5, 6. ])
    """

    name = "polynomial"

    def __init__(self, degree: int = 3):
        if int(degree) != degree or degree < 1:
            raise ParameterError(f"polynomial degree must be an integer >= 1, got {degree!r}")
        self.degree = int(degree)
        self.param_names = tuple(f"d{i}" for i in range(1, self.degree + 1))

    @staticmethod
    def formula(z, p, extra):
        acc = p[len(p) - 1]
        for i in range(len(p) - 2, -1, -1):
            acc = acc * z + p[i]
        return acc * z

    def _derivative(self, u, p):
        cols = self._columns(p)
        acc = self.degree * cols[-1] * np.ones_like(u)
        for i in range(self.degree - 1, 0, -1):
            acc = acc * u + i * cols[i - 1]
        return acc

    def basis(self, u):
        u = np.asarray(u, dtype=float)
        return np.stack([u**i for i in range(1, self.degree + 1)])

    def _unexcited(self, p, u):
        """Fewer distinct non-zero values than coefficients.

        >>> Polynomial(3).unexcited([1.0, 0.0, 0.0], [-1.0, 1.0, -1.0])[0]
        'the signal takes 2 distinct non-zero values, fewer than the 3 coefficients'
        """
        levels = np.unique(u[u != 0]).size
        if levels < self.degree:
            why = f"the signal takes {levels} distinct non-zero values, fewer than the {self.degree} coefficients"
            return {i: why for i in range(self.degree)}
        return {}

    def __repr__(self):
        return f"Polynomial(degree={self.degree})"


class _GainAndThreshold(Nonlinearity):
    """A gain times a symmetric clipping of ``u`` at ``|a|`` (saturation, dead zone)."""

    scale_index = 0
    #: Range of the scanned thresholds, as fractions of the input's quantiles/range.
    SCAN_FRACTIONS = (0.05, 1.0)
    #: Whether the scan includes a zero threshold.
    SCAN_ZERO = False

    def normalize(self, params):
        """Make the threshold non-negative (it enters as ``|a|``)."""
        p = super().normalize(params)
        p[..., 1] = np.abs(p[..., 1])
        return p

    def shape_grid(self, u):
        a = _input_quantiles(u, *self.SCAN_FRACTIONS)
        if self.SCAN_ZERO:
            a = np.concatenate([[0.0], a])
        return np.column_stack([np.ones_like(a), a])


class Saturation(_GainAndThreshold):
    r"""Symmetric saturation with a gain.

    .. math:: g(u) = k \, \min(\max(u, -|a|), |a|)

    Examples
    --------
    >>> Saturation()([-3.0, 0.5, 3.0], [2.0, 1.0])
    array([-2.,  1.,  2.])
    """

    name = "saturation"
    param_names = ("gain", "limit")

    @staticmethod
    def formula(z, p, extra):
        a = np.abs(p[1])
        return p[0] * np.minimum(np.maximum(z, -a), a)

    def _derivative(self, u, p):
        k, a = p
        return np.where(np.abs(u) < abs(a), k, 0.0)

    def _unexcited(self, p, u):
        """A limit never reached, or always exceeded.

        >>> Saturation().unexcited([2.0, 1.5], [-1.0, 1.0])
        {1: 'the signal never reaches the limit +-1.5 (max |u| = 1)'}
        """
        a, top, bottom = abs(p[1]), float(np.abs(u).max()), float(np.abs(u).min())
        if top <= a:
            return {1: f"the signal never reaches the limit +-{a:.4g} (max |u| = {top:.4g})"}
        if bottom >= a:
            why = f"the signal is always beyond the limit +-{a:.4g} (min |u| = {bottom:.4g}): only gain x limit is seen"
            return {0: why, 1: why}
        return {}


class DeadZone(_GainAndThreshold):
    r"""Symmetric dead zone with a gain.

    .. math:: g(u) = k\,(u - \min(\max(u, -|a|), |a|))

    Examples
    --------
    >>> DeadZone()([-3.0, 0.5, 3.0], [2.0, 1.0])
    array([-4.,  0.,  4.])
    """

    name = "deadzone"
    param_names = ("gain", "width")
    SCAN_FRACTIONS = (0.02, 0.8)
    SCAN_ZERO = True

    @staticmethod
    def formula(z, p, extra):
        a = np.abs(p[1])
        return p[0] * (z - np.minimum(np.maximum(z, -a), a))

    def _derivative(self, u, p):
        k, a = p
        return np.where(np.abs(u) > abs(a), k, 0.0)

    def _unexcited(self, p, u):
        """A signal that stays inside the dead zone.

        >>> DeadZone().unexcited([2.0, 1.5], [-1.0, 1.0])[0]
        'the signal stays inside the dead zone +-1.5 (max |u| = 1): the block never passes it on'
        """
        a, top = abs(p[1]), float(np.abs(u).max())
        if top <= a:
            why = f"the signal stays inside the dead zone +-{a:.4g} (max |u| = {top:.4g}): the block never passes it on"
            return {0: why, 1: why}
        return {}


class PiecewiseLinear(Nonlinearity):
    """Piecewise-linear function through fixed breakpoints.

    The parameters are the values of ``g`` at the breakpoints; between them
    ``g`` is interpolated linearly and outside them it is extrapolated with the
    slope of the first or last segment.

    Parameters
    ----------
    breakpoints : array_like
        Strictly increasing input values, at least two.

    Examples
    --------
    >>> g = PiecewiseLinear([-1.0, 0.0, 1.0])
    >>> g.param_names
    ('g0', 'g1', 'g2')
    >>> g([-2.0, -0.5, 0.5, 2.0], [-1.0, 0.0, 2.0])
    array([-2. , -0.5,  1. ,  4. ])
    """

    name = "piecewise_linear"

    @staticmethod
    def formula(z, p, extra):
        """One sample (``extra``: the breakpoints); :meth:`_evaluate` is the vectorised form, through the segments."""
        n = extra.size
        lo, hi = 0, n - 1               # the segment: the last breakpoint <= z, clipped to the first and last
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if extra[mid] <= z:
                lo = mid
            else:
                hi = mid
        k = min(lo, n - 2)
        w = (z - extra[k]) / (extra[k + 1] - extra[k])
        return p[k] * (1.0 - w) + p[k + 1] * w

    def __init__(self, breakpoints: Sequence[float]):
        bp = np.asarray(breakpoints, dtype=float)
        if bp.ndim != 1 or bp.size < 2 or not np.all(np.isfinite(bp)) or np.any(np.diff(bp) <= 0):
            raise ParameterError(
                "PiecewiseLinear needs at least two finite, strictly increasing breakpoints"
            )
        self.breakpoints = bp
        self.param_names = tuple(f"g{i}" for i in range(bp.size))

    def _segments(self, u):
        bp = self.breakpoints
        idx = np.clip(np.searchsorted(bp, u, side="right") - 1, 0, bp.size - 2)
        w = (u - bp[idx]) / (bp[idx + 1] - bp[idx])
        return idx, w

    def _evaluate(self, u, p):
        idx, w = self._segments(u)
        return p[..., idx] * (1.0 - w) + p[..., idx + 1] * w

    def _derivative(self, u, p):
        idx, _ = self._segments(u)
        bp = self.breakpoints
        return (p[idx + 1] - p[idx]) / (bp[idx + 1] - bp[idx])

    def basis(self, u):
        u = np.atleast_1d(np.asarray(u, dtype=float))
        idx, w = self._segments(u)
        phi = np.zeros((self.breakpoints.size, u.size))
        cols = np.arange(u.size)
        phi[idx, cols] = 1.0 - w
        phi[idx + 1, cols] = w
        return phi

    def map_extra(self) -> np.ndarray:
        return self.breakpoints

    def _unexcited(self, p, u):
        """Knots whose neighbouring segments the signal never enters.

        >>> PiecewiseLinear([-0.4, 0.0, 0.5, 1.0]).unexcited([0.0, 0.0, 0.5, 1.5], [0.1, 0.9])[0]
        'the signal (range 0.1 to 0.9) never enters the segments next to the breakpoint -0.4'
        """
        bp = self.breakpoints
        lo, hi = float(u.min()), float(u.max())
        out = {}
        for i, b in enumerate(bp):
            left = -np.inf if i == 0 else bp[i - 1]
            right = np.inf if i == bp.size - 1 else bp[i + 1]
            if not np.any((u > left) & (u < right)):
                out[i] = (f"the signal (range {lo:.4g} to {hi:.4g}) never enters the segments next to the "
                          f"breakpoint {b:g}")
        return out

    def __repr__(self):
        return f"PiecewiseLinear(breakpoints={self.breakpoints.tolist()})"


class Sigmoid(Nonlinearity):
    r"""Logistic sigmoid: a smooth switch between 0 and ``d0`` centred at ``d2`` (an actuator that opens).

    .. math:: g(u) = \frac{\delta_0}{1 + e^{-\delta_1 (u - \delta_2)}}

    Evaluated as ``d0 (1 + tanh(d1 (u - d2) / 2)) / 2``, which never overflows.

    Examples
    --------
    >>> Sigmoid()([-100.0, 0.5, 100.0], [2.0, 4.0, 0.5]).round(6)
    array([0., 1., 2.])
    """

    name = "sigmoid"
    param_names = ("d0", "d1", "d2")
    scale_index = 0

    @staticmethod
    def formula(z, p, extra):
        return p[0] * 0.5 * (1.0 + np.tanh(0.5 * p[1] * (z - p[2])))

    def shape_grid(self, u):
        """Steepness from almost linear to a hard switch over the input's range, centres at its quantiles."""
        u = np.asarray(u, dtype=float)
        span = float(np.ptp(u)) or 1.0
        steep = np.geomspace(0.5, 50.0, 8) / span
        centres = np.quantile(u, np.linspace(0.1, 0.9, 5))
        d1, d2 = np.meshgrid(steep, centres)
        return np.column_stack([np.ones(d1.size), d1.ravel(), d2.ravel()])


class Friction(Nonlinearity):
    r"""Coulomb friction and a constant force: the feedback map of a Lur'e model of a sliding mass.

    .. math:: g(v) = |f_c| \operatorname{sign}(v) + c

    The Coulomb level enters as ``|fc|`` (friction opposes motion), so ``fc``
    and ``-fc`` are one model; fits report it non-negative.  It has no viscous
    term: in a Lur'e model on velocity the linear block's damping is that term.
    ``sign(0) = 0``; a Lur'e simulation resolves ``v = 0`` itself (sticking
    while ``|force - c| <= |fc|``, :mod:`~hammerstein_ctrl.blocks`).

    Examples
    --------
    >>> Friction()([-0.1, 0.0, 0.2], [0.5, 0.1])
    array([-0.4,  0.1,  0.6])
    """

    name = "friction"
    param_names = ("fc", "c")

    @staticmethod
    def formula(z, p, extra):
        return np.abs(p[0]) * np.sign(z) + p[1]

    def _derivative(self, u, p):
        return np.zeros(np.shape(u), dtype=float)


class CustomNonlinearity(Nonlinearity):
    """A user-supplied static function with a declared number of parameters.

    Parameters
    ----------
    func : callable
        ``func(u, params) -> v`` with ``u`` of shape ``(N,)`` and ``params`` of
        shape ``(n_params,)``.  With ``vectorized=True`` it is also called with a
        ``(B, n_params)`` batch and must then return ``(B, N)``.
    n_params : int
        Number of parameters.
    param_names : sequence of str, optional
        Defaults to ``p0, p1, ...``.
    vectorized : bool, default False
        Whether ``func`` accepts a batch of parameter vectors.
    name : str, default "custom"

    Examples
    --------
    >>> cubic = CustomNonlinearity(lambda u, p: p[0] * u + p[1] * u**3, n_params=2)
    >>> cubic([1.0, 2.0], [1.0, 0.5])
    array([1.5, 6. ])
    """

    def __init__(
        self,
        func: Callable,
        n_params: int,
        param_names: Sequence[str] | None = None,
        *,
        vectorized: bool = False,
        name: str = "custom",
    ):
        if not callable(func):
            raise ParameterError("CustomNonlinearity needs a callable func(u, params)")
        if int(n_params) != n_params or n_params < 0:
            raise ParameterError(f"n_params must be a non-negative integer, got {n_params!r}")
        names = tuple(param_names) if param_names is not None else tuple(f"p{i}" for i in range(int(n_params)))
        if len(names) != n_params:
            raise ParameterError(f"{len(names)} parameter names given for n_params={n_params}")
        self.func = func
        self.param_names = names
        self.vectorized = bool(vectorized)
        self.name = name

    def _evaluate(self, u, p):
        if p.ndim == 1 or self.vectorized:
            v = np.asarray(self.func(u, p), dtype=float)
        else:
            v = np.stack([np.asarray(self.func(u, row), dtype=float) for row in p])
        expected = p.shape[:-1] + np.shape(u)
        if v.shape != expected:
            try:
                v = np.broadcast_to(v, expected).copy()
            except ValueError:
                raise ParameterError(
                    f"custom nonlinearity {self.name!r} returned shape {v.shape}, expected {expected}"
                ) from None
        return v

    def __repr__(self):
        return f"CustomNonlinearity({self.name!r}, n_params={self.n_params})"


#: Nonlinearity families known by name (for the CLI and configuration files).
NONLINEARITIES: dict[str, type[Nonlinearity]] = {
    "tanh": Tanh,
    "coulomb": Coulomb,
    "polynomial": Polynomial,
    "saturation": Saturation,
    "deadzone": DeadZone,
    "piecewise_linear": PiecewiseLinear,
    "sigmoid": Sigmoid,
    "friction": Friction,
}
for _family in NONLINEARITIES.values():
    _family._registered = _family          # a registered family (not a subclass of one) has a compiled map


def nonlinearity_from_name(name: str, **kwargs) -> Nonlinearity:
    """Create a nonlinearity family from its name.

    Parameters
    ----------
    name : str
        One of ``tanh``, ``coulomb``, ``polynomial``, ``saturation``,
        ``deadzone``, ``piecewise_linear``, ``sigmoid`` (case-insensitive; ``-`` and ``_``
        are interchangeable).
    **kwargs
        Passed to the class (``degree`` for polynomial, ``breakpoints`` for
        piecewise_linear).

    Examples
    --------
    >>> nonlinearity_from_name("polynomial", degree=2).param_names
    ('d1', 'd2')
    """
    key = str(name).strip().lower().replace("-", "_").replace(" ", "_")
    key = {"dead_zone": "deadzone", "pwl": "piecewise_linear", "sign": "coulomb"}.get(key, key)
    if key not in NONLINEARITIES:
        raise UnknownNameError(
            f"unknown nonlinearity {name!r}; known: {', '.join(sorted(NONLINEARITIES))}"
        )
    try:
        return NONLINEARITIES[key](**kwargs)
    except TypeError as exc:
        raise ParameterError(f"bad arguments for nonlinearity {key!r}: {exc}") from None
