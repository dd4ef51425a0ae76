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


import numpy as np

from .._checks import as_real_array
from ..exceptions import ParameterError

__all__ = ["constant_level", "Nonlinearity"]


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
        >>> from hammerstein_ctrl import Coulomb, Tanh
        >>> Tanh().compiled_map
        'tanh'
        """
        if getattr(type(self), "_registered", None) is not type(self):      # set by the registry of families
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
        >>> from hammerstein_ctrl import Coulomb, Tanh
        >>> Coulomb().basis([-2.0, 3.0])
        array([[-2.,  3.],
               [-1.,  1.],
               [ 1.,  1.]])
        >>> from hammerstein_ctrl import Coulomb, Tanh
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
        >>> from hammerstein_ctrl import Coulomb, Tanh
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
        >>> from hammerstein_ctrl import Coulomb, Tanh
        >>> Coulomb().unexcited([1.0, 0.0, 0.0], [0.7, 0.7, 0.7])  # doctest: +NORMALIZE_WHITESPACE
        {0: 'the signal is constant (0.7): only the value g(0.7) is seen',
         1: 'the signal is constant (0.7): only the value g(0.7) is seen',
         2: 'the signal is constant (0.7): only the value g(0.7) is seen'}
        >>> from hammerstein_ctrl import Coulomb, Tanh
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


