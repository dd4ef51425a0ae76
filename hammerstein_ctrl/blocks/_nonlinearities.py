"""Static nonlinearities ``g(u; delta)`` of a Hammerstein model.

Each class is a *parametric family*: it knows its parameter names and count and
evaluates ``g`` for a parameter vector ``delta`` of shape ``(n_params,)`` or for a
batch of parameter vectors of shape ``(B, n_params)``.  Evaluation is vectorised
over the samples ``u`` (shape ``(N,)``) and over the batch, returning ``(N,)`` or
``(B, N)`` respectively.

Examples
--------
>>> import numpy as np
>>> from hammerstein_ctrl.blocks import Tanh, Coulomb
>>> Tanh()(np.array([0.0, 1.0]), [2.0, 0.5]).round(4)
array([0.    , 0.9242])
>>> Coulomb().param_names
('d0', 'd1', 'd2')
>>> Coulomb()(np.array([-1.0, 1.0]), [[0.5, -0.4, 0.0], [1.0, 0.0, 0.1]])
array([[-0.1,  0.1],
       [-0.9,  1.1]])
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from .._checks import as_real_array
from ..exceptions import ParameterError, UnknownNameError

__all__ = [
    "constant_level",
    "Nonlinearity",
    "Tanh",
    "Coulomb",
    "Polynomial",
    "Saturation",
    "DeadZone",
    "PiecewiseLinear",
    "Sigmoid",
    "Friction",
    "CustomNonlinearity",
    "nonlinearity_from_name",
    "NONLINEARITIES",
]


class Nonlinearity:
    """Base class of a parametric static nonlinearity ``v = g(u; delta)``.

    Subclasses set :attr:`param_names` and define the family's formula once,
    as :attr:`formula` (and, where it is known in closed form, :meth:`_derivative`).
    Everything else is derived from it: the vectorised :meth:`evaluate`.  The
    families registered in :data:`NONLINEARITIES` also have a compiled map in
    the package's compiled core (:attr:`compiled_map`), the same formula
    written for one sample, which the simulation kernels, the Lur'e and the
    closed-loop simulators apply inside their passes.  Any other family,
    :class:`CustomNonlinearity` and subclasses written in Python included, is
    evaluated with numpy outside the compiled pass (an input map before it, an
    output map after it): it runs as fast as numpy evaluates it.  A family
    whose formula cannot be written in vectorised form overrides
    :meth:`_evaluate` instead.

    Examples
    --------
    >>> import numpy as np
    >>> class Cube(Nonlinearity):
    ...     name = "cube"
    ...     param_names = ("k",)
    ...     formula = staticmethod(lambda z, p, extra: p[0] * z**3)
    >>> Cube()(np.array([1.0, 2.0]), [0.5]).tolist()
    [0.5, 4.0]
    """

    #: Short name used in reprs, the CLI and :func:`nonlinearity_from_name`.
    name: str = "nonlinearity"
    #: Names of the parameters, in the order of the parameter vector.
    param_names: tuple[str, ...] = ()
    #: Index of a parameter that scales ``g`` as a whole
    #: (``g(u; p) = p[i] g(u; p with p[i] = 1)``), or ``None``.  With it, the
    #: automatic initial point fits that parameter by linear least squares.
    scale_index: int | None = None
    #: The formula ``g(z; p)``, a plain function ``formula(z, p, extra)``
    #: (declare it with ``staticmethod``) written with numpy ufuncs and
    #: indexing of ``p`` only, so that it runs both compiled on one sample
    #: (``z`` a float, ``p`` the parameter vector, ``extra`` :meth:`map_extra`)
    #: and vectorised (``z`` an array, ``p`` the parameters as columns that
    #: broadcast over it).  ``None`` for families that override :meth:`_evaluate`.
    formula = None

    @property
    def compiled_map(self) -> str | None:
        """Name of the family's map in the compiled core (:data:`hammerstein_ctrl._kernels.MAP_CODES`), or ``None``.

        The families registered in :data:`NONLINEARITIES` have one (a subclass
        of them does not: its formula may be another); an output nonlinearity
        with a compiled map is applied inside the compiled simulation pass.

        Examples
        --------
        >>> Tanh().compiled_map
        'tanh'
        """
        if NONLINEARITIES.get(self.name) is not type(self):
            return None
        return self.name

    def map_extra(self) -> np.ndarray:
        """Fixed data passed to the compiled map (e.g. breakpoints); empty by default."""
        return np.empty(0)

    @property
    def gain_index(self) -> int | None:
        """The parameter that scales ``g`` as a whole: :attr:`scale_index`, or the first
        parameter of a family linear in its parameters (``None`` if neither).

        A Hammerstein-Wiener structure fixes this parameter of its input
        nonlinearity to 1, which removes the gain ambiguity between the blocks.
        """
        if self.scale_index is not None:
            return self.scale_index
        return 0 if self.n_params and self.basis(np.zeros(1)) is not None else None

    @property
    def n_params(self) -> int:
        """Number of parameters of the family."""
        return len(self.param_names)

    # -- parameter handling -------------------------------------------------
    def check_params(self, params) -> np.ndarray:
        """Return ``params`` as a float array of shape ``(n,)`` or ``(B, n)``.

        Raises
        ------
        ParameterError
            If the last dimension does not equal :attr:`n_params`.
        """
        p = as_real_array(params, f"{self.name} nonlinearity parameters")
        if p.ndim == 0 or p.ndim > 2 or p.shape[-1] != self.n_params:
            got = p.shape[-1] if p.ndim else "a scalar"
            raise ParameterError(
                f"{self.name} nonlinearity takes {self.n_params} parameter(s) "
                f"{list(self.param_names)}, got {got} (array of shape {p.shape})"
            )
        return p

    @staticmethod
    def _columns(p: np.ndarray) -> tuple:
        """Split a parameter array into per-parameter columns that broadcast over ``u``.

        A 1-D vector gives scalars; a ``(B, n)`` batch gives ``(B, 1)`` columns.
        """
        if p.ndim == 1:
            return tuple(p)
        return tuple(p[:, i : i + 1] for i in range(p.shape[1]))

    # -- evaluation ---------------------------------------------------------
    def __call__(self, u, params) -> np.ndarray:
        """Evaluate ``g(u; params)``; see :meth:`evaluate`."""
        return self.evaluate(u, params)

    def evaluate(self, u, params) -> np.ndarray:
        """Evaluate the nonlinearity.

        Parameters
        ----------
        u : array_like, shape (N,) or scalar
            Input samples.
        params : array_like, shape (n_params,) or (B, n_params)
            One parameter vector or a batch of them.

        Returns
        -------
        ndarray, shape (N,) or (B, N)
        """
        p = self.check_params(params)
        return self._evaluate(np.asarray(u, dtype=float), p)

    def derivative(self, u, params) -> np.ndarray:
        """Return ``dg/du`` at ``u`` for one parameter vector.

        Closed form where the family has one (away from discontinuities, where
        the classical derivative is used: e.g. the ``sign`` term of
        :class:`Coulomb` contributes nothing); otherwise a central difference.
        """
        p = self.check_params(params)
        return self._derivative(np.asarray(u, dtype=float), p)

    def basis(self, u) -> np.ndarray | None:
        """Regressors ``Phi`` with ``g(u; p) = p @ Phi`` if ``g`` is linear in its parameters.

        Returns an array of shape ``(n_params, N)``, or ``None`` for families
        that are not linear in their parameters.  The objective uses it to form
        a whole batch of signals ``g(u)`` with one matrix product.

        Examples
        --------
        >>> Coulomb().basis([-2.0, 3.0])
        array([[-2.,  3.],
               [-1.,  1.],
               [ 1.,  1.]])
        >>> Tanh().basis([1.0]) is None
        True
        """
        return None

    def checked_basis(self, u) -> np.ndarray | None:
        """:meth:`basis` checked: ``None``, or a float array of shape ``(n_params, len(u))``.

        The compiled passes read :attr:`n_params` rows of the basis, so a
        family whose :meth:`basis` gives another shape is refused here, with
        a :class:`~hammerstein_ctrl.exceptions.ParameterError`, rather than
        read past its rows.

        Examples
        --------
        >>> Coulomb().checked_basis([1.0, -2.0]).shape
        (3, 2)
        """
        phi = self.basis(u)
        if phi is None:
            return None
        expected = (self.n_params, np.size(u))
        try:
            phi = np.asarray(phi, dtype=float)
        except (TypeError, ValueError):
            phi = None
        if phi is None or phi.shape != expected:
            got = "values that are not real numbers" if phi is None else f"shape {phi.shape}"
            raise ParameterError(f"{type(self).__name__}.basis(u) must give one row per parameter and one column "
                                 f"per sample, shape {expected} here; it gave {got}")
        return phi

    def normalize(self, params) -> np.ndarray:
        """The canonical form of ``params`` among those giving the same ``g``.

        Families with a symmetry (``d0 tanh(d1 u) = (-d0) tanh(-d1 u)``, limits
        entering as ``|a|``) map every parameter vector to one representative,
        so reported parameters are unique.  The default is the identity.
        """
        return np.array(self.check_params(params), dtype=float)

    def shape_grid(self, u) -> np.ndarray | None:
        """Candidate parameter vectors for a scan of the parameters ``g`` is not linear in.

        Used by the automatic initial point for families that have a
        :attr:`scale_index` but no :meth:`basis`: each row has the scale
        parameter set to 1 and the others spread over the range of the
        input ``u``.  ``None`` where no scan is defined.
        """
        return None

    def unexcited(self, params, signal) -> dict:
        """Why a signal leaves parameters undetermined: ``{parameter index: reason}``.

        Used to explain an identification whose record does not determine
        some parameters of this block.  The default knows one case, a
        constant signal (only the single value ``g(c)`` is seen); families
        add their own (a limit never reached, a segment never entered).

        Examples
        --------
        >>> Coulomb().unexcited([1.0, 0.0, 0.0], [0.7, 0.7, 0.7])  # doctest: +NORMALIZE_WHITESPACE
        {0: 'the signal is constant (0.7): only the value g(0.7) is seen',
         1: 'the signal is constant (0.7): only the value g(0.7) is seen',
         2: 'the signal is constant (0.7): only the value g(0.7) is seen'}
        >>> Coulomb().unexcited([1.0, 0.0, 0.0], [0.7, -0.2, 0.1])
        {}
        """
        u = np.asarray(signal, dtype=float)
        u = u[np.isfinite(u)]
        if u.size == 0:
            return {}
        level = constant_level(u)
        if level is not None:
            why = f"the signal is constant ({level:.4g}): only the value g({level:.4g}) is seen"
            return {i: why for i in range(self.n_params)}
        return self._unexcited(np.asarray(self.check_params(params), dtype=float), u)

    def _unexcited(self, p: np.ndarray, u: np.ndarray) -> dict:
        """:meth:`unexcited` for a finite, non-constant signal (families override; default: nothing known)."""
        return {}

    def _evaluate(self, u: np.ndarray, p: np.ndarray) -> np.ndarray:
        formula = type(self).formula
        if formula is None:  # pragma: no cover - a family must give one or the other
            raise NotImplementedError(f"{type(self).__name__} defines neither formula nor _evaluate")
        return np.asarray(formula(u, self._columns(p), self.map_extra()), dtype=float)

    def _derivative(self, u: np.ndarray, p: np.ndarray) -> np.ndarray:
        h = 1e-6 * np.maximum(1.0, np.abs(u))
        return (self._evaluate(u + h, p) - self._evaluate(u - h, p)) / (2 * h)

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def describe(self, params) -> str:
        """Human-readable formula with the given parameter values substituted."""
        p = self.check_params(params)
        vals = ", ".join(f"{n}={v:.6g}" for n, v in zip(self.param_names, np.atleast_1d(p)))
        return f"{self.name}({vals})"


def constant_level(signal) -> float | None:
    """The value of a signal that does not change (its finite samples within 1e-12 of their largest), else None:
    a static block driven by it shows one value of its map, whatever its parameters.

    Examples
    --------
    >>> constant_level([0.7, 0.7, np.nan]), constant_level([0.7, -0.2])
    (0.7, None)
    """
    u = np.asarray(signal, dtype=float)
    u = u[np.isfinite(u)]
    if u.size == 0:
        return None
    lo, hi = float(u.min()), float(u.max())
    return hi if hi - lo <= 1e-12 * max(1.0, abs(hi)) else None


#: Points of the scans of :meth:`Nonlinearity.shape_grid`.
SCAN_POINTS = 16


def _input_quantiles(u, low: float, high: float) -> np.ndarray:
    """Distinct positive levels of ``|u|``: its quantiles between the fractions ``low`` and
    ``high``, and as many evenly spaced levels up to the same fraction of its range (a signal
    that dwells near zero has its quantiles bunched there)."""
    a = np.abs(np.asarray(u, dtype=float))
    even = np.linspace(0.0, high * float(a.max(initial=0.0)), SCAN_POINTS + 1)[1:]
    q = np.unique(np.concatenate([np.quantile(a, np.linspace(low, high, SCAN_POINTS)), even]))
    return q[q > 0] if np.any(q > 0) else np.array([1.0])


class Tanh(Nonlinearity):
    r"""Hyperbolic tangent, the TRS nonlinearity (paper Eq. 17).

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
    r"""Linear gain plus Coulomb friction plus offset, the EMPS nonlinearity (Eq. 19).

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
    r"""Polynomial without constant term (paper Eq. 3 with ``g(0) = 0``).

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
