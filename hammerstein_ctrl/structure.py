"""Model structures: how the paper's parameter vector beta maps to a model.

beta follows the paper's Eq. (14): the free numerator coefficients
``b0, b1, ...`` (ascending powers), then the free denominator coefficients
``a0, a1, ...`` (ascending powers; the denominator is monic), then the
parameters of the nonlinearity.  Coefficients fixed by the structure (the
monic numerator of Assumption 3, or e.g. EMPS's ``a0 = 0``) are not in beta.

Examples
--------
The EMPS structure, ``H(p) = 1/(p^2 + a1 p)`` and a Coulomb nonlinearity:

>>> from hammerstein_ctrl.structure import LinearStructure, HammersteinStructure
>>> from hammerstein_ctrl.nonlinearities import Coulomb
>>> s = HammersteinStructure(LinearStructure(0, 2, fixed={"a0": 0.0}), Coulomb())
>>> s.param_names
('a1', 'd0', 'd1', 'd2')
>>> H = s.linear.transfer_function([3.0])
>>> H.num[0][0], H.den[0][0]
(array([1.]), array([1., 3., 0.]))
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .exceptions import ParameterError
from .nonlinearities import Nonlinearity

__all__ = ["LinearStructure", "HammersteinStructure"]


class LinearStructure:
    """Parameterisation of a continuous-time transfer function ``B(p)/A(p)``.

    Parameters
    ----------
    num_order : int
        Degree ``l`` of the numerator ``B(p) = b_l p^l + ... + b0``.
    den_order : int
        Degree ``m >= 1`` of the monic denominator ``A(p) = p^m + a_{m-1} p^{m-1} + ... + a0``.
    monic_numerator : bool, default True
        Fix ``b_l = 1`` (paper Assumption 3: the gain then lives in the
        nonlinearity, which makes the split between the blocks unique).
    fixed : mapping of str to float, optional
        Further coefficients held at a given value, by name (``"a0"``, ``"b1"``, ...).

    Examples
    --------
    >>> s = LinearStructure(1, 2)            # (p + b0)/(p^2 + a1 p + a0), the TRS
    >>> s.param_names
    ('b0', 'a0', 'a1')
    >>> s.coefficients([-1.8, 0.1, 4.8])
    (array([[ 1. , -1.8]]), array([[1. , 4.8, 0.1]]))
    """

    def __init__(
        self,
        num_order: int,
        den_order: int,
        *,
        monic_numerator: bool = True,
        fixed: Mapping[str, float] | None = None,
    ):
        for label, val in (("num_order", num_order), ("den_order", den_order)):
            if int(val) != val or val < 0:
                raise ParameterError(f"{label} must be a non-negative integer, got {val!r}")
        num_order, den_order = int(num_order), int(den_order)
        if den_order < 1:
            raise ParameterError("den_order must be >= 1 (a dynamic linear block)")
        if num_order > den_order:
            raise ParameterError(
                f"improper structure: num_order {num_order} exceeds den_order {den_order}"
            )
        self.num_order = num_order
        self.den_order = den_order
        self.monic_numerator = bool(monic_numerator)

        known = [f"b{i}" for i in range(num_order + 1)] + [f"a{i}" for i in range(den_order)]
        fixed = dict(fixed or {})
        for name, value in fixed.items():
            if name not in known:
                raise ParameterError(
                    f"cannot fix unknown coefficient {name!r}; this structure has {known}"
                )
            if not np.isfinite(value):
                raise ParameterError(f"fixed coefficient {name} must be finite, got {value!r}")
        lead = f"b{num_order}"
        if self.monic_numerator:
            if lead in fixed and fixed[lead] != 1.0:
                raise ParameterError(f"{lead} is fixed to 1 by monic_numerator=True")
            fixed[lead] = 1.0
        self.fixed = {k: float(v) for k, v in fixed.items()}

        # Base coefficient arrays (descending powers) and where free parameters go.
        self._num0 = np.zeros(num_order + 1)
        self._den0 = np.zeros(den_order + 1)
        self._den0[0] = 1.0
        names, num_pos, den_pos = [], [], []
        for i in range(num_order + 1):
            name = f"b{i}"
            if name in self.fixed:
                self._num0[num_order - i] = self.fixed[name]
            else:
                names.append(name)
                num_pos.append(num_order - i)
        for i in range(den_order):
            name = f"a{i}"
            if name in self.fixed:
                self._den0[den_order - i] = self.fixed[name]
            else:
                names.append(name)
                den_pos.append(den_order - i)
        self.param_names: tuple[str, ...] = tuple(names)
        self._num_pos = np.array(num_pos, dtype=int)
        self._den_pos = np.array(den_pos, dtype=int)

    @property
    def n_params(self) -> int:
        """Number of free coefficients."""
        return len(self.param_names)

    def coefficients(self, theta):
        """Numerator and denominator coefficients (descending powers), batched.

        Parameters
        ----------
        theta : array_like, shape (n_params,) or (B, n_params)

        Returns
        -------
        num : ndarray, shape (B, num_order + 1)
        den : ndarray, shape (B, den_order + 1)
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        if theta.ndim != 2 or theta.shape[-1] != self.n_params:
            raise ParameterError(
                f"linear block takes {self.n_params} parameter(s) {list(self.param_names)}, "
                f"got {theta.shape[-1]}"
            )
        return self._coefficients(theta)

    def _coefficients(self, theta: np.ndarray):
        """:meth:`coefficients` for a validated ``(B, n_params)`` float array."""
        batch = theta.shape[0]
        num = np.repeat(self._num0[None, :], batch, axis=0)
        den = np.repeat(self._den0[None, :], batch, axis=0)
        k = self._num_pos.size
        num[:, self._num_pos] = theta[:, :k]
        den[:, self._den_pos] = theta[:, k:]
        return num, den

    def free_parameters(self, num, den) -> np.ndarray:
        """The free coefficients of ``num/den`` (descending powers), fixed ones ignored.

        The denominator is made monic first; the numerator is padded to
        ``num_order + 1`` coefficients.  Unlike :meth:`parameters` this does not
        check the fixed coefficients: it projects any block onto the structure.

        Examples
        --------
        >>> LinearStructure(0, 2, fixed={"a0": 0.0}).free_parameters([1.0], [1.0, 3.0, 2.0])
        array([3.])
        """
        num = np.atleast_1d(np.asarray(num, dtype=float))
        den = np.atleast_1d(np.asarray(den, dtype=float))
        if den.size != self.den_order + 1 or num.size > self.num_order + 1:
            raise ParameterError(
                f"coefficients of degree {num.size - 1}/{den.size - 1} do not fit "
                f"{self.num_order}/{self.den_order}")
        num, den = num / den[0], den / den[0]
        num = np.concatenate([np.zeros(self.num_order + 1 - num.size), num])
        return np.concatenate([num[self._num_pos], den[self._den_pos]])

    def transfer_function(self, theta, **kwargs):
        """The :class:`control.TransferFunction` for one parameter vector.

        ``kwargs`` (``inputs``, ``outputs``, ``name``) go to :func:`control.tf`.
        """
        import control

        theta = np.asarray(theta, dtype=float)
        if theta.ndim != 1:
            raise ParameterError("transfer_function takes a single parameter vector")
        num, den = self.coefficients(theta)
        return control.tf(num[0], den[0], **kwargs)

    def parameters(self, linear, *, rtol: float = 1e-9) -> np.ndarray:
        """Inverse of :meth:`transfer_function`: the free coefficients of ``linear``.

        The denominator is normalised to be monic first.

        Raises
        ------
        ParameterError
            If the orders do not match or a fixed coefficient (including a monic
            numerator) differs from its value in the structure.
        """
        import control

        if not isinstance(linear, control.TransferFunction):
            linear = control.tf(linear)
        if linear.ninputs != 1 or linear.noutputs != 1:
            raise ParameterError("only SISO linear blocks are supported")
        num = np.trim_zeros(np.atleast_1d(np.asarray(linear.num[0][0], dtype=float)), "f")
        den = np.trim_zeros(np.atleast_1d(np.asarray(linear.den[0][0], dtype=float)), "f")
        if den.size - 1 != self.den_order:
            raise ParameterError(
                f"denominator has degree {den.size - 1}, the structure expects {self.den_order}"
            )
        if num.size - 1 > self.num_order:
            raise ParameterError(
                f"numerator has degree {num.size - 1}, the structure allows {self.num_order}"
            )
        num, den = num / den[0], den / den[0]
        num = np.concatenate([np.zeros(self.num_order + 1 - num.size), num])
        for name, value in self.fixed.items():
            kind, i = name[0], int(name[1:])
            actual = num[self.num_order - i] if kind == "b" else den[self.den_order - i]
            if not np.isclose(actual, value, rtol=rtol, atol=rtol):
                hint = (
                    " (monic numerator: move the gain into the nonlinearity)"
                    if name == f"b{self.num_order}" and self.monic_numerator
                    else ""
                )
                raise ParameterError(
                    f"coefficient {name} = {actual:.6g} but the structure fixes it to {value:g}{hint}"
                )
        return np.concatenate([num[self._num_pos], den[self._den_pos]])

    def describe(self) -> str:
        """The structure as a formula, e.g. ``(p + b0)/(p^2 + a1 p + a0)``."""

        def poly(order, prefix):
            terms = []
            for i in range(order, -1, -1):
                name = f"{prefix}{i}"
                power = "" if i == 0 else ("p" if i == 1 else f"p^{i}")
                if prefix == "a" and i == order:
                    terms.append(power or "1")
                    continue
                coef = self.fixed.get(name)
                if coef is None:
                    terms.append(f"{name} {power}".strip())
                elif coef == 0:
                    continue
                elif coef == 1 and power:
                    terms.append(power)
                else:
                    terms.append(f"{coef:g} {power}".strip())
            return " + ".join(terms) or "0"

        return f"({poly(self.num_order, 'b')})/({poly(self.den_order, 'a')})"

    def __repr__(self):
        fixed = {k: v for k, v in self.fixed.items() if not (self.monic_numerator and k == f"b{self.num_order}")}
        extra = f", fixed={fixed}" if fixed else ""
        mon = "" if self.monic_numerator else ", monic_numerator=False"
        return f"LinearStructure({self.num_order}, {self.den_order}{mon}{extra})"


#: Choices for the initial state of the linear block.
INITIAL_STATES = ("zero", "estimate")
#: Name of the output-offset parameter.
OFFSET_NAME = "y0"
#: Prefix of the initial-state parameters ``xi0, xi1, ...`` (the state ``x(0)``
#: of the controllable canonical realisation of ``H``).
STATE_PREFIX = "xi"


class HammersteinStructure:
    """A linear structure and a nonlinearity family: the full beta <-> model map.

    beta is ``[linear coefficients, nonlinearity parameters]`` (paper Eq. 14),
    followed by the optional real-data parameters: the output offset ``y0``
    (``offset=True``) and the initial state ``xi0 .. xi{n-1}`` of ``H``'s
    controllable canonical realisation (``initial_state="estimate"``).

    Parameters
    ----------
    linear : LinearStructure
    nonlinearity : Nonlinearity
    offset : bool, default False
        Estimate a constant ``y0`` added to the output.
    initial_state : {"zero", "estimate"}, default "zero"
        Start ``H`` from rest (the paper's semantics) or estimate ``x(0)``.

    Examples
    --------
    >>> from hammerstein_ctrl.nonlinearities import Tanh
    >>> s = HammersteinStructure(LinearStructure(1, 2), Tanh())
    >>> s.param_names
    ('b0', 'a0', 'a1', 'd0', 'd1')
    >>> m = s.model([-1.816, 0.118, 4.7681, -4.7132, 0.1229])
    >>> s.beta(m).round(4).tolist()
    [-1.816, 0.118, 4.7681, -4.7132, 0.1229]
    >>> s.with_options(offset=True, initial_state="estimate").param_names[-3:]
    ('y0', 'xi0', 'xi1')
    """

    def __init__(self, linear: LinearStructure, nonlinearity: Nonlinearity, *, offset: bool = False,
                 initial_state: str = "zero"):
        if not isinstance(linear, LinearStructure):
            raise ParameterError(f"linear must be a LinearStructure, got {type(linear).__name__}")
        if not isinstance(nonlinearity, Nonlinearity):
            raise ParameterError(
                f"nonlinearity must be a Nonlinearity, got {type(nonlinearity).__name__}"
            )
        if initial_state not in INITIAL_STATES:
            raise ParameterError(f"initial_state must be one of {INITIAL_STATES}, got {initial_state!r}")
        self.linear = linear
        self.nonlinearity = nonlinearity
        self.offset = bool(offset)
        self.initial_state = initial_state
        self.core_names: tuple[str, ...] = linear.param_names + nonlinearity.param_names
        extra = ((OFFSET_NAME,) if self.offset else ()) + (
            tuple(f"{STATE_PREFIX}{i}" for i in range(linear.den_order)) if initial_state == "estimate" else ())
        self.param_names: tuple[str, ...] = self.core_names + extra

    @property
    def n_params(self) -> int:
        """Length of beta."""
        return len(self.param_names)

    @property
    def n_core(self) -> int:
        """Number of parameters of the blocks themselves (without offset and initial state)."""
        return len(self.core_names)

    def with_options(self, *, offset: bool | None = None, initial_state: str | None = None):
        """The same blocks with other real-data options (``None`` keeps the current one)."""
        return type(self)(self.linear, self.nonlinearity,
                          offset=self.offset if offset is None else offset,
                          initial_state=self.initial_state if initial_state is None else initial_state)

    def check_beta(self, beta) -> np.ndarray:
        """Return beta as a float array of shape ``(n,)`` or ``(B, n)``.

        Raises
        ------
        ParameterError
            On a wrong length, naming the expected parameters.
        """
        b = np.asarray(beta, dtype=float)
        if b.ndim not in (1, 2) or b.shape[-1] != self.n_params:
            got = b.shape[-1] if b.ndim else "a scalar"
            raise ParameterError(
                f"beta must have {self.n_params} entries {list(self.param_names)}, got {got}"
                + (f" (array of shape {b.shape})" if b.ndim != 1 else "")
            )
        return b

    def split(self, beta):
        """Split beta into (linear parameters, nonlinearity parameters)."""
        b = self.check_beta(beta)
        k = self.linear.n_params
        return b[..., :k], b[..., k:self.n_core]

    def nuisance(self, beta):
        """``(offset, initial_state)`` of a beta or batch (``None`` where not estimated)."""
        b = self.check_beta(beta)
        i = self.n_core
        offset = None
        if self.offset:
            offset, i = b[..., i], i + 1
        state = b[..., i:] if self.initial_state == "estimate" else None
        return offset, state

    def model(self, beta, **kwargs):
        """The :class:`~hammerstein_ctrl.model.HammersteinModel` for one beta.

        ``kwargs`` (``intersample``, ``name``) go to the model.
        """
        from .model import HammersteinModel

        b = self.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("model() takes a single beta vector, not a batch")
        lin, nl = self.split(b)
        offset, state = self.nuisance(b)
        return HammersteinModel(self.linear.transfer_function(lin), self.nonlinearity, nl,
                                offset=0.0 if offset is None else float(offset), initial_state=state,
                                **kwargs)

    def beta(self, model) -> np.ndarray:
        """The beta vector of a model that has this structure."""
        if model.nonlinearity.param_names != self.nonlinearity.param_names or type(
            model.nonlinearity
        ) is not type(self.nonlinearity):
            raise ParameterError(
                f"model's nonlinearity {model.nonlinearity!r} does not match {self.nonlinearity!r}"
            )
        parts = [self.linear.parameters(model.linear), model.params]
        if self.offset:
            parts.append([model.offset])
        if self.initial_state == "estimate":
            parts.append(model.state0())
        return np.concatenate(parts)

    def normalize(self, beta) -> np.ndarray:
        """beta with the nonlinearity's parameters in their canonical form (see
        :meth:`~hammerstein_ctrl.nonlinearities.Nonlinearity.normalize`); the model is unchanged."""
        b = np.array(self.check_beta(beta), dtype=float)
        k = self.linear.n_params
        b[..., k:self.n_core] = self.nonlinearity.normalize(b[..., k:self.n_core])
        return b

    def describe(self) -> str:
        """One-line description, e.g. ``H(p) = (p + b0)/(p^2 + a1 p + a0); g = tanh(d0, d1)``."""
        names = ", ".join(self.nonlinearity.param_names)
        extra = (" + y0" if self.offset else "") + ("; x(0) estimated" if self.initial_state == "estimate" else "")
        return f"H(p) = {self.linear.describe()}; g = {self.nonlinearity.name}({names}){extra}"

    def __repr__(self):
        opts = (", offset=True" if self.offset else "") + (
            f", initial_state={self.initial_state!r}" if self.initial_state != "zero" else "")
        return f"HammersteinStructure({self.linear!r}, {self.nonlinearity!r}{opts})"
