"""Model structures: how the paper's parameter vector beta maps to a model.

beta follows the paper's Eq. (14): the free numerator coefficients
``b0, b1, ...`` (ascending powers), then the free denominator coefficients
``a0, a1, ...`` (ascending powers; the denominator is monic), then the
parameters of the nonlinearity.  Coefficients fixed by the structure (the
monic numerator of Assumption 3, or e.g. EMPS's ``a0 = 0``) are not in beta.

Examples
--------
The EMPS structure, ``H(p) = 1/(p^2 + a1 p)`` and a Coulomb nonlinearity:

>>> from hammerstein_ctrl.blocks import LinearStructure, HammersteinStructure
>>> from hammerstein_ctrl.blocks import Coulomb
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

from .._checks import ESTIMATE, MAX_ORDER, as_count, as_real_array, check_delay
from .._linalg import fill_coefficients, filled_coefficients
from ..exceptions import ParameterError
from ._nonlinearities import Nonlinearity

__all__ = ["LinearStructure", "BlockStructure", "HammersteinStructure", "WienerStructure",
           "HammersteinWienerStructure", "INITIAL_STATES", "fill_coefficients", "checked_beta",
           "nuisance_names"]


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
    delay : float or "estimate", optional
        Input dead time ``tau`` in seconds: the block is ``B(p)/A(p) e^{-tau p}``.
        A number fixes it; ``"estimate"`` makes it a parameter named
        ``delay`` (after the other block parameters of a structure), estimated
        as a continuous value, not a multiple of the sample time
        (:mod:`~hammerstein_ctrl.simulate._delay`).  Default: no dead time.

    Examples
    --------
    >>> s = LinearStructure(1, 2)            # (p + b0)/(p^2 + a1 p + a0), the TRS
    >>> s.param_names
    ('b0', 'a0', 'a1')
    >>> s.coefficients([-1.8, 0.1, 4.8])
    (array([[ 1. , -1.8]]), array([[1. , 4.8, 0.1]]))
    >>> LinearStructure(0, 1, delay="estimate").delay
    'estimate'
    """

    def __init__(
        self,
        num_order: int,
        den_order: int,
        *,
        monic_numerator: bool = True,
        fixed: Mapping[str, float] | None = None,
        delay=None,
    ):
        self.delay = check_delay(delay)
        num_order, den_order = as_count(num_order, "num_order"), as_count(den_order, "den_order")
        if den_order < 1:
            raise ParameterError("den_order must be >= 1 (a dynamic linear block)")
        if den_order > MAX_ORDER:
            raise ParameterError(f"den_order {den_order} exceeds MAX_ORDER = {MAX_ORDER} (orders 1..{MAX_ORDER})")
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
            arr = as_real_array(value, f"fixed coefficient {name}")
            if arr.ndim != 0:
                raise ParameterError(f"fixed coefficient {name} must be one number, got {value!r}")
            fixed[name] = value = float(arr)
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
        self._num_pos = np.array(num_pos, dtype=np.int64)
        self._den_pos = np.array(den_pos, dtype=np.int64)
        for template in self._template:         # read by the compiled core unchecked on every evaluation
            template.flags.writeable = False

    @property
    def _template(self) -> tuple:
        """``(num0, den0, num_pos, den_pos)``, made and checked here once: what every evaluation fills in."""
        return self._num0, self._den0, self._num_pos, self._den_pos

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

    def coefficient_template(self):
        """``(num0, den0, num_pos, den_pos)``: the coefficients with the fixed ones in, and where the free ones go.

        Row ``b`` of :meth:`coefficients` is ``num0``/``den0`` with ``theta[b, j]``
        written at ``num_pos[j]`` (then ``den_pos``), as :func:`fill_coefficients` does.

        Examples
        --------
        >>> LinearStructure(0, 2, fixed={"a0": 0.0}).coefficient_template()
        (array([1.]), array([1., 0., 0.]), array([], dtype=int64), array([1]))
        """
        return self._template

    def _coefficients(self, theta: np.ndarray):
        """:meth:`coefficients` for a validated ``(B, n_params)`` float array."""
        return filled_coefficients(np.ascontiguousarray(theta), *self._template)

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

        dead = ("" if not self.delay else " e^{-delay p}" if self.estimates_delay
                else f" e^{{-{self.delay:g} p}}")
        return f"({poly(self.num_order, 'b')})/({poly(self.den_order, 'a')}){dead}"

    def __repr__(self):
        fixed = {k: v for k, v in self.fixed.items() if not (self.monic_numerator and k == f"b{self.num_order}")}
        extra = f", fixed={fixed}" if fixed else ""
        mon = "" if self.monic_numerator else ", monic_numerator=False"
        dead = f", delay={self.delay!r}" if self.delay else ""
        return f"LinearStructure({self.num_order}, {self.den_order}{mon}{extra}{dead})"

    def with_delay(self, delay) -> "LinearStructure":
        """The same coefficients with another dead time (``None``: none, a number, or ``"estimate"``)."""
        fixed = {k: v for k, v in self.fixed.items() if not (self.monic_numerator and k == f"b{self.num_order}")}
        return LinearStructure(self.num_order, self.den_order, monic_numerator=self.monic_numerator, fixed=fixed,
                               delay=delay)

    @property
    def estimates_delay(self) -> bool:
        """Whether the dead time is a parameter (``delay="estimate"``)."""
        return self.delay == ESTIMATE


#: Choices for the initial state of the linear block.
INITIAL_STATES = ("zero", "estimate")
#: Name of the output-offset parameter.
OFFSET_NAME = "y0"
#: Name of the dead-time parameter (``LinearStructure(..., delay="estimate")``), the last block parameter.
DELAY_NAME = "delay"
#: Prefix of the initial-state parameters ``xi0, xi1, ...`` (the state ``x(0)``
#: of the controllable canonical realisation of ``H``).
STATE_PREFIX = "xi"


def nuisance_names(offset: bool, initial_state: str, n_states: int) -> tuple[str, ...]:
    """The real-data parameters that follow a structure's blocks in beta: the output offset ``y0`` and the initial
    state ``xi0 ...`` of ``n_states`` states, each where asked for.

    Examples
    --------
    >>> nuisance_names(True, "estimate", 2)
    ('y0', 'xi0', 'xi1')
    """
    return ((OFFSET_NAME,) if offset else ()) + (
        tuple(f"{STATE_PREFIX}{i}" for i in range(n_states)) if initial_state == "estimate" else ())


def checked_beta(beta, names) -> np.ndarray:
    """``beta`` as a float array ``(n,)`` or ``(B, n)`` for the parameter ``names`` of a structure.

    Raises
    ------
    ParameterError
        On a wrong length, naming the expected parameters, or values that are not real numbers.

    Examples
    --------
    >>> checked_beta([1, 2], ("a0", "d1")).tolist()
    [1.0, 2.0]
    """
    b = beta if type(beta) is np.ndarray and beta.dtype == np.float64 else as_real_array(beta, "beta")
    if b.ndim not in (1, 2) or b.shape[-1] != len(names):
        got = b.shape[-1] if b.ndim else "a scalar"
        raise ParameterError(f"beta must have {len(names)} entries {list(names)}, got {got}"
                             + (f" (array of shape {b.shape})" if b.ndim != 1 else ""))
    return b


def _check_nonlinearity(value, label: str):
    if not isinstance(value, Nonlinearity):
        raise ParameterError(f"{label} must be a Nonlinearity, got {type(value).__name__}")
    return value


class BlockStructure:
    """Base of the block-oriented structures: ``u -> [g] -> H -> [h] -> y``.

    beta is ``[linear coefficients, free parameters of g, parameters of h]``
    (paper Eq. 14 for the Hammerstein case), followed by the optional
    real-data parameters: the output offset ``y0`` (``offset=True``) and the
    initial state ``xi0 .. xi{n-1}`` of ``H``'s controllable canonical
    realisation (``initial_state="estimate"``).

    **Gain convention.**  A gain can move freely between blocks; fixing it
    makes the parameters unique.  The linear block keeps a monic numerator
    (paper Assumption 3), so ``H``'s gain is fixed and the static blocks carry
    it.  With both an input and an output nonlinearity (Hammerstein-Wiener),
    the input nonlinearity's gain parameter
    (:attr:`~hammerstein_ctrl.blocks.Nonlinearity.gain_index`) is
    fixed to 1 as well and is not part of beta.

    When the two nonlinearities share a parameter name, all their names
    are prefixed ``g_`` and ``h_`` (e.g. ``g_d1``, ``h_d1``).

    Subclasses: :class:`HammersteinStructure`, :class:`WienerStructure`,
    :class:`HammersteinWienerStructure`; a new structure is a new subclass.

    Examples
    --------
    >>> from hammerstein_ctrl import HammersteinWienerStructure, LinearStructure, Tanh, Saturation
    >>> s = HammersteinWienerStructure(LinearStructure(0, 1), Tanh(), Saturation(), offset=True)
    >>> isinstance(s, BlockStructure), s.param_names
    (True, ('a0', 'd1', 'gain', 'limit', 'y0'))
    """

    #: Short name of the structure family.
    kind = "block"

    def __init__(self, linear: LinearStructure, input_nonlinearity=None, output_nonlinearity=None, *,
                 offset: bool = False, initial_state: str = "zero"):
        if not isinstance(linear, LinearStructure):
            raise ParameterError(f"linear must be a LinearStructure, got {type(linear).__name__}")
        if initial_state not in INITIAL_STATES:
            raise ParameterError(f"initial_state must be one of {INITIAL_STATES}, got {initial_state!r}")
        self.linear = linear
        self.input_nonlinearity = input_nonlinearity
        self.output_nonlinearity = output_nonlinearity
        self.offset = bool(offset)
        self.initial_state = initial_state
        self._fixed_gain = None
        if input_nonlinearity is not None and output_nonlinearity is not None:
            self._fixed_gain = input_nonlinearity.gain_index
            if self._fixed_gain is None:
                raise ParameterError(
                    f"the input nonlinearity {input_nonlinearity.name!r} of a Hammerstein-Wiener structure needs a "
                    "gain parameter to fix to 1 (a scale parameter, or parameters it is linear in)")
        g_names = () if input_nonlinearity is None else tuple(
            n for i, n in enumerate(input_nonlinearity.param_names) if i != self._fixed_gain)
        h_names = () if output_nonlinearity is None else output_nonlinearity.param_names
        if set(g_names) & set(h_names):  # e.g. Coulomb in, polynomial out: g_d1, ... and h_d1, ...
            g_names = tuple(f"g_{n}" for n in g_names)
            h_names = tuple(f"h_{n}" for n in h_names)
        self._n_g, self._n_h = len(g_names), len(h_names)
        self.core_names: tuple[str, ...] = linear.param_names + g_names + h_names + (
            (DELAY_NAME,) if linear.estimates_delay else ())
        self.param_names: tuple[str, ...] = self.core_names + nuisance_names(self.offset, initial_state,
                                                                             linear.den_order)
        if len(set(self.param_names)) != len(self.param_names):
            raise ParameterError(f"parameter names clash: {list(self.param_names)}")

    # -- sizes and options --------------------------------------------------
    @property
    def n_params(self) -> int:
        """Length of beta."""
        return len(self.param_names)

    @property
    def n_core(self) -> int:
        """Number of parameters of the blocks themselves (without offset and initial state)."""
        return len(self.core_names)

    def _block_args(self) -> tuple:
        """Positional constructor arguments of the subclass (its blocks)."""
        raise NotImplementedError

    def with_options(self, *, offset: bool | None = None, initial_state: str | None = None):
        """The same blocks with other real-data options (``None`` keeps the current one)."""
        return type(self)(*self._block_args(), offset=self.offset if offset is None else offset,
                          initial_state=self.initial_state if initial_state is None else initial_state)

    def with_delay(self, delay):
        """The same blocks and options with another dead time of the linear block (see :class:`LinearStructure`)."""
        return type(self)(self.linear.with_delay(delay), *self._block_args()[1:], offset=self.offset,
                          initial_state=self.initial_state)

    def with_linear(self, linear: "LinearStructure"):
        """The same static blocks and options around another linear block."""
        return type(self)(linear, *self._block_args()[1:], offset=self.offset, initial_state=self.initial_state)

    def linear_counterpart(self):
        """The linear model of the same order: the static blocks replaced by a gain (``Polynomial(1)`` on the
        input), same offset, initial state and dead time; ``None`` for a structure that is linear already, or
        with a custom map (which need not contain a gain).

        Examples
        --------
        >>> from hammerstein_ctrl import LinearStructure, WienerStructure, Tanh
        >>> WienerStructure(LinearStructure(1, 2), Tanh(), offset=True).linear_counterpart().param_names
        ('b0', 'a0', 'a1', 'd1', 'y0')
        """
        from ._families import CustomNonlinearity, Polynomial

        g, h = self.input_nonlinearity, self.output_nonlinearity
        if h is None and (g is None or (isinstance(g, Polynomial) and g.n_params == 1)):
            return None
        if isinstance(g, CustomNonlinearity) or isinstance(h, CustomNonlinearity):
            return None                 # a map of the user's may not contain a gain: no linear model is nested
        return HammersteinStructure(self.linear, Polynomial(1), offset=self.offset,
                                    initial_state=self.initial_state)

    # -- beta <-> blocks ----------------------------------------------------
    def check_beta(self, beta) -> np.ndarray:
        """Return beta as a float array of shape ``(n,)`` or ``(B, n)``.

        Raises
        ------
        ParameterError
            On a wrong length, naming the expected parameters, or values that are not real numbers.
        """
        return checked_beta(beta, self.param_names)

    def linear_params(self, beta) -> np.ndarray:
        """The free coefficients of ``H``."""
        return self.check_beta(beta)[..., :self.linear.n_params]

    def input_params(self, beta):
        """The full parameter vector(s) of ``g`` (its fixed gain inserted), or ``None``."""
        if self.input_nonlinearity is None:
            return None
        b = self.check_beta(beta)
        k = self.linear.n_params
        free = b[..., k:k + self._n_g]
        if self._fixed_gain is None:
            return free
        return np.insert(free, self._fixed_gain, 1.0, axis=-1)

    def output_params(self, beta):
        """The parameter vector(s) of ``h``, or ``None``."""
        if self.output_nonlinearity is None:
            return None
        k = self.linear.n_params + self._n_g
        return self.check_beta(beta)[..., k:k + self._n_h]

    def nuisance(self, beta):
        """``(offset, initial_state)`` of a beta or batch (``None`` where not estimated)."""
        b = self.check_beta(beta)
        i = self.n_core
        offset = None
        if self.offset:
            offset, i = b[..., i], i + 1
        state = b[..., i:] if self.initial_state == "estimate" else None
        return offset, state

    def _free_input(self, params) -> np.ndarray:
        p = np.asarray(params, dtype=float)
        if self._fixed_gain is None:
            return p
        if not np.isclose(p[self._fixed_gain], 1.0):
            raise ParameterError(f"the input nonlinearity's gain "
                                 f"{self.input_nonlinearity.param_names[self._fixed_gain]}"
                                 f" must be 1 in a {self.kind} structure (move the gain to the output block)")
        return np.delete(p, self._fixed_gain)

    def model(self, beta, **kwargs):
        """The model for one beta (``kwargs``: ``intersample``, ``name``)."""
        from ._model import BlockModel

        b = self.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("model() takes a single beta vector, not a batch")
        offset, state = self.nuisance(b)
        num, den = self.linear.coefficients(self.linear_params(b))
        return BlockModel.build(
            (num[0], den[0]),                       # the transfer function is made when first asked for
            input_nonlinearity=self.input_nonlinearity, input_params=self.input_params(b),
            output_nonlinearity=self.output_nonlinearity, output_params=self.output_params(b),
            offset=0.0 if offset is None else float(offset), initial_state=state,
            delay=float(self.delay(b)), **kwargs)

    def delay(self, beta):
        """The dead time of a beta or batch: its ``delay`` entry, or the fixed one (0 without a dead time)."""
        if self.linear.estimates_delay:
            return self.check_beta(beta)[..., self.n_core - 1]
        return self.linear.delay

    def beta(self, model) -> np.ndarray:
        """The beta vector of a model that has this structure."""
        for label, mine, theirs in (("input", self.input_nonlinearity, model.input_nonlinearity),
                                    ("output", self.output_nonlinearity, model.output_nonlinearity)):
            if (mine is None) != (theirs is None) or (mine is not None and (
                    type(mine) is not type(theirs) or mine.param_names != theirs.param_names)):
                raise ParameterError(f"model's {label} nonlinearity {theirs!r} does not match {mine!r}")
        parts = [self.linear.parameters(model.linear)]
        if self.input_nonlinearity is not None:
            parts.append(self._free_input(model.input_params))
        if self.output_nonlinearity is not None:
            parts.append(model.output_params)
        if self.linear.estimates_delay:
            parts.append([model.delay])
        if self.offset:
            parts.append([model.offset])
        if self.initial_state == "estimate":
            parts.append(model.state0())
        return np.concatenate(parts)

    def normalize(self, beta) -> np.ndarray:
        """beta with the nonlinearities' parameters in their canonical form (see
        :meth:`~hammerstein_ctrl.blocks.Nonlinearity.normalize`); the model is unchanged."""
        b = np.array(self.check_beta(beta), dtype=float)
        k = self.linear.n_params
        if self.input_nonlinearity is not None and self._fixed_gain is None:
            b[..., k:k + self._n_g] = self.input_nonlinearity.normalize(b[..., k:k + self._n_g])
        if self.output_nonlinearity is not None:
            j = k + self._n_g
            b[..., j:j + self._n_h] = self.output_nonlinearity.normalize(b[..., j:j + self._n_h])
        return b

    def describe(self) -> str:
        """One-line description, e.g. ``H(p) = (p + b0)/(p^2 + a1 p + a0); g = tanh(d0, d1)``."""
        parts = [f"H(p) = {self.linear.describe()}"]
        for label, nl in (("g", self.input_nonlinearity), ("h", self.output_nonlinearity)):
            if nl is not None:
                parts.append(f"{label} = {nl.name}({', '.join(nl.param_names)})")
        extra = (" + y0" if self.offset else "") + ("; x(0) estimated" if self.initial_state == "estimate" else "")
        return "; ".join(parts) + extra

    def __repr__(self):
        opts = (", offset=True" if self.offset else "") + (
            f", initial_state={self.initial_state!r}" if self.initial_state != "zero" else "")
        args = ", ".join(repr(a) for a in self._block_args())
        return f"{type(self).__name__}({args}{opts})"


class HammersteinStructure(BlockStructure):
    """``y = H(p) g(u)``: a static input nonlinearity, then the linear block (the paper's model).

    Parameters
    ----------
    linear : LinearStructure
    nonlinearity : Nonlinearity
        The input nonlinearity ``g``.
    offset : bool, default False
        Estimate a constant ``y0`` added to the output.
    initial_state : {"zero", "estimate"}, default "zero"
        Start ``H`` from rest (the paper's semantics) or estimate ``x(0)``.

    Examples
    --------
    >>> from hammerstein_ctrl.blocks import Tanh
    >>> s = HammersteinStructure(LinearStructure(1, 2), Tanh())
    >>> s.param_names
    ('b0', 'a0', 'a1', 'd0', 'd1')
    >>> m = s.model([-1.816, 0.118, 4.7681, -4.7132, 0.1229])
    >>> s.beta(m).round(4).tolist()
    [-1.816, 0.118, 4.7681, -4.7132, 0.1229]
    >>> s.with_options(offset=True, initial_state="estimate").param_names[-3:]
    ('y0', 'xi0', 'xi1')
    """

    kind = "hammerstein"

    def __init__(self, linear: LinearStructure, nonlinearity: Nonlinearity, *, offset: bool = False,
                 initial_state: str = "zero"):
        super().__init__(linear, _check_nonlinearity(nonlinearity, "nonlinearity"), None, offset=offset,
                         initial_state=initial_state)

    @property
    def nonlinearity(self) -> Nonlinearity:
        """The input nonlinearity ``g``."""
        return self.input_nonlinearity

    def _block_args(self) -> tuple:
        return (self.linear, self.input_nonlinearity)

    def split(self, beta):
        """Split beta into (linear parameters, nonlinearity parameters)."""
        return self.linear_params(beta), self.input_params(beta)


class WienerStructure(BlockStructure):
    """``y = h(H(p) u)``: the linear block, then a static output nonlinearity (e.g. a sensor limit).

    Parameters are those of :class:`HammersteinStructure`; ``nonlinearity`` is
    the output nonlinearity ``h``, which carries the gain (``H`` has a monic
    numerator).

    Examples
    --------
    >>> from hammerstein_ctrl.blocks import Saturation
    >>> s = WienerStructure(LinearStructure(0, 2), Saturation())
    >>> s.param_names, s.describe()
    (('a0', 'a1', 'gain', 'limit'), 'H(p) = (1)/(p^2 + a1 p + a0); h = saturation(gain, limit)')
    """

    kind = "wiener"

    def __init__(self, linear: LinearStructure, nonlinearity: Nonlinearity, *, offset: bool = False,
                 initial_state: str = "zero"):
        super().__init__(linear, None, _check_nonlinearity(nonlinearity, "nonlinearity"), offset=offset,
                         initial_state=initial_state)

    @property
    def nonlinearity(self) -> Nonlinearity:
        """The output nonlinearity ``h``."""
        return self.output_nonlinearity

    def _block_args(self) -> tuple:
        return (self.linear, self.output_nonlinearity)


class HammersteinWienerStructure(BlockStructure):
    """``y = h(H(p) g(u))``: input nonlinearity, linear block, output nonlinearity.

    The input nonlinearity's gain parameter is fixed to 1 (and left out of
    beta); ``h`` carries the gain.

    Examples
    --------
    >>> from hammerstein_ctrl.blocks import DeadZone, Saturation
    >>> s = HammersteinWienerStructure(LinearStructure(0, 1), DeadZone(), Saturation())
    >>> s.param_names
    ('a0', 'width', 'gain', 'limit')
    """

    kind = "hammerstein-wiener"

    def __init__(self, linear: LinearStructure, input_nonlinearity: Nonlinearity,
                 output_nonlinearity: Nonlinearity, *, offset: bool = False, initial_state: str = "zero"):
        super().__init__(linear, _check_nonlinearity(input_nonlinearity, "input_nonlinearity"),
                         _check_nonlinearity(output_nonlinearity, "output_nonlinearity"), offset=offset,
                         initial_state=initial_state)

    def _block_args(self) -> tuple:
        return (self.linear, self.input_nonlinearity, self.output_nonlinearity)
