"""Wiener-Hammerstein models: a linear block, a static map, a second linear block (``G1 -> f -> G2``).

.. code-block:: text

    x = G1(p) u          the first linear block (static gain 1)
    w = f(x)             the static nonlinearity (it carries the gain)
    y = G2(p) w + y0     the second linear block (static gain 1)

**Gain convention.**  A gain moves freely between the three blocks, so two of
them are fixed: both linear blocks have static gain 1, written
``G(p) = (1 + b1 p + ... + bl p^l) / (1 + a1 p + ... + an p^n)``
(:class:`UnitGainBlock`), and the map ``f`` carries the whole gain.  A block
therefore has no integrator and no zero at ``p = 0``.  With this convention the
signal ``x`` has the input's units and size, so ``f``'s parameters are those of
a map of the input; and a zero that a fit does not need leaves to infinity
through a coefficient of 0 rather than one growing without bound (a pole
cannot: the highest denominator coefficient must stay non-zero).

**Intersample behaviour.**  ``G1`` is simulated exactly at the sample instants
for the input's hold (first-order hold, ``"foh"``, or zero-order hold,
``"zoh"``).  Its output ``x(t)``, and so ``w(t) = f(x(t))``, is not piecewise
linear between samples, so ``G2`` cannot be simulated exactly from samples of
``w``; it is simulated with ``w`` taken as linear between the instants where it
is computed (a first-order hold of ``w``).  ``substeps=m`` computes ``w`` at
``m`` instants per sample (the input interpolated by its own hold, which is
exact), which divides the error of that approximation by about ``m**2``:
against an ODE solver at ``rtol=1e-10``, a tanh middle with poles near the
sampling rate's tenth gives 3e-3 of the output range at ``m = 1`` and 6e-7 at
``m = 64`` (:data:`MAX_SUBSTEPS`).  On records sampled well above the blocks'
bandwidth (such as the Wiener-Hammerstein benchmark) ``m = 1`` and ``m = 4``
give fits equal to three digits.

Examples
--------
>>> import numpy as np, hammerstein_ctrl as hc
>>> s = WienerHammersteinStructure((0, 1), hc.Polynomial(3), (0, 2), time_unit=1.0)  # G1 = 1/(1 + a1 p)
>>> s.param_names
('g1_a1', 'g2_a1', 'g2_a2', 'd1', 'd2', 'd3')
>>> m = s.model([0.5, 1.0, 0.25, 1.0, 0.0, -0.2])
>>> t = np.arange(500) * 0.05
>>> y = m.simulate(t, np.ones(500))
>>> round(float(y[-1]), 6)                    # static gain: f(1) = 1 - 0.2
0.8
"""

from __future__ import annotations

import functools

import numpy as np

from ..simulate._batch import simulate_batch
from .._checks import MAX_ORDER, check_delay, check_intersample
from ..simulate._discretize import companion_realization
from ..exceptions import ParameterError
from ._model import _check_block as _check_map, _check_linear, _finite_scalar, _state_vector
from ._nonlinearities import Nonlinearity
from ..simulate._simulate import _check_pair, unstable
from ._structure import INITIAL_STATES, LinearStructure, checked_beta, nuisance_names
from ._unit_gain import MAX_SUBSTEPS, UnitGainBlock, WHParts, _check_block, simulate_wh

__all__ = ["WienerHammersteinStructure", "WienerHammersteinModel", "wiener_hammerstein_structure", "BLOCK_PREFIXES"]

#: Prefixes of the two linear blocks' parameter names.
BLOCK_PREFIXES = ("g1_", "g2_")
class WienerHammersteinStructure:
    """A Wiener-Hammerstein model to identify: ``y = G2(p) f(G1(p) u) + y0``.

    Parameters
    ----------
    first, second : (num_order, den_order), UnitGainBlock or LinearStructure
        ``G1`` and ``G2``, each with static gain 1 (:class:`UnitGainBlock`:
        a ``LinearStructure`` gives its orders only).  Their parameters are
        prefixed ``g1_`` and ``g2_`` in beta.
    nonlinearity : Nonlinearity
        The static map ``f`` between them (any family, custom maps included);
        it carries the gain.
    offset : bool, default False
        Estimate a constant output offset ``y0``.
    initial_state : {"zero", "estimate"}, default "zero"
        Start both blocks at rest, or estimate their initial states
        (``xi0 ...`` of ``G1``'s then ``G2``'s companion realisation).
    substeps : int, default 1
        Instants per sample at which the middle signal is computed (module docstring).
    delay : float, optional
        A fixed dead time (seconds) at the chain's input (a ``LinearStructure``
        block's own ``delay`` is taken too; an estimated one is not supported).
    time_unit : float, optional
        The unit of time of the blocks' coefficients (:class:`UnitGainBlock`),
        in seconds; by default the sample time of the record it is fitted to
        (``identify`` sets it; :meth:`model` needs it set).

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> s = WienerHammersteinStructure((0, 2), hc.Tanh(), (1, 2), offset=True)
    >>> s.param_names
    ('g1_a1', 'g1_a2', 'g2_b1', 'g2_a1', 'g2_a2', 'd0', 'd1', 'y0')
    """

    kind = "wiener-hammerstein"
    input_nonlinearity = None
    output_nonlinearity = None
    _fixed_gain = None

    def __init__(self, first, nonlinearity: Nonlinearity, second, *,
                 offset: bool = False, initial_state: str = "zero", substeps: int = 1, time_unit: float | None = None,
                 delay: float | None = None):
        if time_unit is not None:
            time_unit = _finite_scalar(time_unit, "time_unit")
            if not time_unit > 0:
                raise ParameterError(f"time_unit must be > 0 (seconds), got {time_unit!r}")
        self.time_unit = time_unit
        for label, block in (("first", first), ("second", second)):
            if isinstance(block, UnitGainBlock) and block.time_unit != 1.0 and block.time_unit != time_unit:
                raise ParameterError(f"the {label} block's time_unit {block.time_unit!r} differs from the "
                                     f"structure's {time_unit!r}: give time_unit=... to the structure (the blocks "
                                     "share it)")
        self.first = _check_block(first, "first", 1.0 if time_unit is None else time_unit)
        self.second = _check_block(second, "second", 1.0 if time_unit is None else time_unit)
        # a dead time anywhere in the chain is one at its input (the map commutes with a delay)
        self.delay = float(sum(getattr(b, "delay", None) or 0.0 for b in (first, second)) if delay is None
                           else check_delay(delay, estimate=False))
        if self.first.den_order + self.second.den_order > MAX_ORDER:
            raise ParameterError(f"G1 and G2 have {self.first.den_order + self.second.den_order} poles together; at "
                                 f"most {MAX_ORDER} (the linear model of the whole order starts the fit)")
        if not isinstance(nonlinearity, Nonlinearity):
            raise ParameterError(f"nonlinearity must be a Nonlinearity, got {type(nonlinearity).__name__}")
        if not isinstance(offset, (bool, np.bool_)):
            raise ParameterError(f"offset must be True or False, got {offset!r}")
        if initial_state not in INITIAL_STATES:
            raise ParameterError(f"initial_state must be one of {INITIAL_STATES}, got {initial_state!r}")
        if isinstance(substeps, bool) or int(substeps) != substeps or not 1 <= substeps <= MAX_SUBSTEPS:
            raise ParameterError(f"substeps must be an integer from 1 to {MAX_SUBSTEPS}, got {substeps!r}")
        self.nonlinearity, self.offset, self.initial_state = nonlinearity, bool(offset), initial_state
        self.substeps = int(substeps)
        n1, n2 = self.first.den_order, self.second.den_order
        self.core_names: tuple[str, ...] = (
            tuple(BLOCK_PREFIXES[0] + n for n in self.first.param_names)
            + tuple(BLOCK_PREFIXES[1] + n for n in self.second.param_names) + tuple(nonlinearity.param_names))
        self.param_names: tuple[str, ...] = self.core_names + nuisance_names(self.offset, initial_state, n1 + n2)
        if len(set(self.param_names)) != len(self.param_names):
            raise ParameterError(f"parameter names clash: {list(self.param_names)}")

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @property
    def n_core(self) -> int:
        """Parameters of the blocks (without offset and initial state)."""
        return len(self.core_names)

    @property
    def linear_blocks(self) -> tuple[UnitGainBlock, UnitGainBlock]:
        return (self.first, self.second)

    @property
    def block_layout(self) -> tuple[tuple[UnitGainBlock, int], ...]:
        """``(linear block, index of its first parameter in beta)`` of each linear block."""
        return ((self.first, 0), (self.second, self.first.n_params))

    def unstable(self, betas) -> np.ndarray:
        """Whether each row of ``betas`` has a pole in the open right half-plane (in either block)."""
        _, den1, _, den2 = self.coefficients(betas)
        return unstable(den1) | unstable(den2)

    def linear_counterpart(self):
        """The linear model of the same orders (``G1 G2`` with a gain, as a Hammerstein structure with
        ``Polynomial(1)``), same offset, initial-state option and dead time; ``None`` with a custom map.

        Examples
        --------
        >>> import hammerstein_ctrl as hc
        >>> wiener_hammerstein_structure((0, 1), None, (1, 2)).linear_counterpart().param_names
        ('b0', 'a0', 'a1', 'a2', 'd1')
        """
        from ._families import CustomNonlinearity, Polynomial
        from ._structure import HammersteinStructure

        if isinstance(self.nonlinearity, CustomNonlinearity):
            return None
        f, s = self.first, self.second
        return HammersteinStructure(LinearStructure(f.num_order + s.num_order, f.den_order + s.den_order,
                                                    delay=self.delay or None),
                                    Polynomial(1), offset=self.offset, initial_state=self.initial_state)

    def linear_theta(self, beta) -> np.ndarray:
        """The coefficients of :meth:`linear_counterpart`'s block for ``G1 G2`` at ``beta`` (monic numerator)."""
        num1, den1, num2, den2 = self.coefficients(beta)
        num = np.convolve(np.trim_zeros(num1[0], "f"), np.trim_zeros(num2[0], "f"))
        return self.linear_counterpart().linear.free_parameters(num / num[0], np.convolve(den1[0], den2[0]))

    def static_blocks(self, model, data) -> list:
        """The static map as the verdicts see it: ``[(map, its parameters, its signal (a function), label, its beta
        names)]``; the signal is the middle signal ``x = G1 u`` of ``model`` on ``data``."""
        names = list(self.param_names[self._slices()[2]])
        signal = functools.cache(lambda: model.middle(data))
        return [(self.nonlinearity, model.params, signal, "signal x = G1 u", names)]

    def _slices(self) -> tuple[slice, slice, slice]:
        k1, k2 = self.first.n_params, self.second.n_params
        return slice(0, k1), slice(k1, k1 + k2), slice(k1 + k2, self.n_core)

    def with_options(self, *, offset: bool | None = None, initial_state: str | None = None,
                     substeps: int | None = None, time_unit: float | None = None) -> "WienerHammersteinStructure":
        """The same blocks with other options (``None`` keeps the current one)."""
        return WienerHammersteinStructure(
            self.first, self.nonlinearity, self.second, offset=self.offset if offset is None else offset,
            initial_state=self.initial_state if initial_state is None else initial_state,
            substeps=self.substeps if substeps is None else substeps,
            time_unit=self.time_unit if time_unit is None else time_unit, delay=self.delay)

    def for_record(self, dt: float) -> "WienerHammersteinStructure":
        """This structure with its time unit set: the record's sample time ``dt`` when none was given."""
        return self if self.time_unit is not None else self.with_options(time_unit=dt)

    def _resolved(self) -> None:
        if self.time_unit is None:
            raise ParameterError("this Wiener-Hammerstein structure has no time unit yet (the unit of its blocks' "
                                 "coefficients): give time_unit=..., or use the structure of an identification "
                                 "result (identify sets it to the record's sample time)")

    def check_beta(self, beta) -> np.ndarray:
        """``beta`` as a float array ``(n_params,)`` or ``(B, n_params)``; a wrong length is refused."""
        return checked_beta(beta, self.param_names)

    def block_params(self, beta):
        """``(G1's parameters, G2's parameters, f's parameters)`` of a beta or batch."""
        b = self.check_beta(beta)
        return tuple(b[..., s] for s in self._slices())

    def map_params(self, beta) -> np.ndarray:
        return self.block_params(beta)[2]

    def coefficients(self, beta):
        """``(num1, den1, num2, den2)`` rows of the blocks of a beta or batch (monic denominators, static gain 1)."""
        self._resolved()
        B = np.atleast_2d(self.check_beta(beta))
        p1, p2, _ = self.block_params(B)
        return self.first.monic(p1) + self.second.monic(p2)

    def parts(self, betas) -> WHParts:
        """Everything :func:`simulate_wh` needs for rows ``betas``."""
        B = np.atleast_2d(self.check_beta(betas))
        num1, den1, num2, den2 = self.coefficients(B)
        at = self.n_core
        y0 = B[:, at] if self.offset else np.zeros(B.shape[0])
        at += self.offset
        n1, n2 = self.first.den_order, self.second.den_order
        if self.initial_state == "estimate":
            x1, x2 = B[:, at:at + n1], B[:, at + n1:at + n1 + n2]
        else:
            x1, x2 = np.zeros((B.shape[0], n1)), np.zeros((B.shape[0], n2))
        return WHParts(num1, den1, np.ascontiguousarray(B[:, self._slices()[2]]), num2, den2,
                       np.ascontiguousarray(y0), np.ascontiguousarray(x1), np.ascontiguousarray(x2))

    def normalize(self, beta) -> np.ndarray:
        """beta with the map's parameters in their canonical form (the model is unchanged)."""
        b = np.array(self.check_beta(beta), dtype=float)
        s = self._slices()[2]
        b[..., s] = self.nonlinearity.normalize(b[..., s])
        return b

    def model(self, beta, *, intersample: str = "foh", name: str | None = None) -> "WienerHammersteinModel":
        """The :class:`WienerHammersteinModel` at ``beta``."""
        b = self.normalize(beta)
        if b.ndim != 1:
            raise ParameterError("model() takes one beta vector")
        p = self.parts(b)
        return WienerHammersteinModel(
            (p.num1[0], p.den1[0]), self.nonlinearity, p.map_params[0], (p.num2[0], p.den2[0]),
            offset=float(p.y0[0]), initial_state=(p.x1[0], p.x2[0]) if self.initial_state == "estimate" else None,
            intersample=intersample, substeps=self.substeps, name=name, delay=self.delay)

    def beta(self, model: "WienerHammersteinModel") -> np.ndarray:
        """The beta vector of a model that has this structure."""
        if not isinstance(model, WienerHammersteinModel) or type(model.nonlinearity) is not type(self.nonlinearity):
            raise ParameterError(f"the model {model!r} does not have this structure {self!r}")
        self._resolved()
        if tuple(model.nonlinearity.param_names) != tuple(self.nonlinearity.param_names):
            raise ParameterError(f"the model's map {model.nonlinearity!r} does not match {self.nonlinearity!r}")
        parts = []
        for label, lin, (num, den) in zip(("G1", "G2"), self.linear_blocks, model._blocks):
            num = np.trim_zeros(num, "f")
            if num.size - 1 > lin.num_order or den.size - 1 != lin.den_order:
                raise ParameterError(f"the model's {label} has orders {num.size - 1}/{den.size - 1}, the structure's "
                                     f"{lin.num_order}/{lin.den_order}")
            with np.errstate(all="ignore"):
                gain = num[-1] / den[-1]
            if not (np.isfinite(gain) and abs(gain - 1.0) <= 1e-9):
                raise ParameterError(f"the model's {label} has static gain {gain:.6g}: a Wiener-Hammerstein structure "
                                     "writes both blocks with static gain 1 (move the gain into the map)")
            parts.append(lin.free_parameters(num, den))
        parts.append(model.params)
        if self.offset:
            parts.append([model.offset])
        elif model.offset != 0.0:
            raise ParameterError(f"the model has an offset {model.offset:.6g}; the structure none (offset=True)")
        states = model.initial_state
        if self.initial_state == "estimate":
            parts += list(states or (np.zeros(self.first.den_order), np.zeros(self.second.den_order)))
        elif states is not None and any(np.any(x) for x in states):
            raise ParameterError("the model has an initial state; the structure starts at rest "
                                 "(initial_state='estimate')")
        return np.concatenate(parts)

    def describe(self) -> str:
        extra = (" + y0" if self.offset else "") + ("; x(0) estimated" if self.initial_state == "estimate" else "") + (
            f"; dead time {self.delay:.6g} s" if self.delay else "")
        return (f"G1(p) = {self.first.describe()}; f = {self.nonlinearity.name}"
                f"({', '.join(self.nonlinearity.param_names)}); G2(p) = {self.second.describe()}{extra}")

    def __repr__(self):
        opts = (", offset=True" if self.offset else "") + (
            f", initial_state={self.initial_state!r}" if self.initial_state != "zero" else "") + (
            f", substeps={self.substeps}" if self.substeps != 1 else "") + (
            f", time_unit={self.time_unit!r}" if self.time_unit is not None else "") + (
            f", delay={self.delay!r}" if self.delay else "")
        return f"WienerHammersteinStructure({self.first!r}, {self.nonlinearity!r}, {self.second!r}{opts})"


def wiener_hammerstein_structure(first=(0, 2), nonlinearity: Nonlinearity | None = None, second=(0, 2),
                                 **options) -> WienerHammersteinStructure:
    """A :class:`WienerHammersteinStructure` from ``(num_order, den_order)`` pairs; the map defaults to a cubic.

    Examples
    --------
    >>> wiener_hammerstein_structure((0, 1), None, (0, 1)).param_names
    ('g1_a1', 'g2_a1', 'd1', 'd2', 'd3')
    """
    from ._families import Polynomial

    return WienerHammersteinStructure(tuple(first), Polynomial(3) if nonlinearity is None else nonlinearity,
                                      tuple(second), **options)


class WienerHammersteinModel:
    """An identified (or given) Wiener-Hammerstein model ``y = G2 f(G1 u) + y0``.

    Parameters
    ----------
    first, second : control.TransferFunction or (num, den)
        ``G1`` and ``G2``, as given (the structure passes unit-gain blocks).
    nonlinearity : Nonlinearity
    params : array_like
        ``f``'s parameters.
    offset : float, default 0
    initial_state : (array_like, array_like), optional
        Initial states of ``G1``'s and ``G2``'s companion realisations (default: rest).
    intersample : {"foh", "zoh"}, default "foh"
        The input's hold.
    substeps : int, default 1
        See the module docstring.
    name : str, optional
    delay : float, default 0
        Dead time (seconds) at the input; exports carry it as a Pade
        approximant (``config.defaults["delay.pade_order"]``).

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> m = WienerHammersteinModel(([2.0], [1.0, 2.0]), hc.Tanh(), [1.0, 1.0], ([1.0], [1.0, 1.0]))
    >>> sys = m.to_iosys()
    >>> sys.ninputs, sys.noutputs, sys.nstates
    (1, 1, 2)
    """

    kind = "wiener-hammerstein"
    #: Static blocks of the other block-oriented models that this one does not have (for the shared figures).
    input_nonlinearity = None
    output_nonlinearity = None
    #: ``G1``'s state reaches the output through the map: an initial state is fitted by iteration, not in one step.
    state_enters_linearly = False

    def __init__(self, first, nonlinearity, params, second, *, offset: float = 0.0, initial_state=None,
                 intersample: str = "foh", substeps: int = 1, name: str | None = None, delay: float = 0.0):
        self.nonlinearity, self.params = _check_map(nonlinearity, params, "map")
        self.delay = float(check_delay(delay, estimate=False))
        if self.nonlinearity is None:
            raise ParameterError("a Wiener-Hammerstein model needs its map (a Nonlinearity)")
        self._blocks = tuple(_check_linear(b)[1:] for b in (first, second))
        self.offset = _finite_scalar(offset, "offset")
        self.intersample = check_intersample(intersample)
        if isinstance(substeps, bool) or int(substeps) != substeps or not 1 <= substeps <= MAX_SUBSTEPS:
            raise ParameterError(f"substeps must be an integer from 1 to {MAX_SUBSTEPS}, got {substeps!r}")
        self.substeps = int(substeps)
        self.initial_state = None
        if initial_state is not None:
            if not isinstance(initial_state, (tuple, list)) or len(initial_state) != 2:
                raise ParameterError(f"initial_state must be a pair (G1's state, G2's state), got {initial_state!r}")
            self.initial_state = tuple(_state_vector(x, den.size - 1)
                                       for x, (_, den) in zip(initial_state, self._blocks))
        self.name = "wiener_hammerstein" if name is None else str(name)

    @property
    def first(self):
        """``G1`` as a ``control.TransferFunction``."""
        import control

        return control.tf(*self._blocks[0])

    @property
    def second(self):
        """``G2`` as a ``control.TransferFunction``."""
        import control

        return control.tf(*self._blocks[1])

    @property
    def orders(self) -> tuple[int, int]:
        """The orders of ``G1`` and ``G2``."""
        return tuple(den.size - 1 for _, den in self._blocks)

    @property
    def order(self) -> int:
        """The number of states: ``G1``'s and ``G2``'s orders together."""
        return sum(self.orders)

    @property
    def linear(self):
        """The product ``G1 G2`` (static gain 1) as a ``control.TransferFunction``: the model's linear dynamics about
        an operating point, up to the map's local slope (for Bode plots)."""
        import control

        (n1, d1), (n2, d2) = self._blocks
        return control.tf(np.polymul(n1, n2), np.polymul(d1, d2))

    def linearize(self, u0: float = 0.0):
        """The model about the steady input ``u0`` as a ``control.TransferFunction``: ``f'(x0) G1 G2`` with
        ``x0 = u0`` (``G1`` has static gain 1).

        Examples
        --------
        >>> import hammerstein_ctrl as hc
        >>> m = WienerHammersteinModel(([1.0], [1.0, 1.0]), hc.Polynomial(3), [2.0, 0.0, 1.0], ([2.0], [1.0, 2.0]))
        >>> float(m.linearize(1.0).dcgain())          # f'(1) = 2 + 3
        5.0
        """
        import control

        x0 = _finite_scalar(u0, "u0")
        slope = float(self.nonlinearity.derivative(np.array([x0]), self.params)[0])
        lin = self.linear
        return control.tf(slope * np.asarray(lin.num[0][0], float), lin.den[0][0])

    def motion_model(self, u0: float = 0.0):
        """:meth:`linearize` as a :class:`~hammerstein_ctrl.blocks.HammersteinModel` (unit gain) for the linear tools
        (``tune_pid``, ``analyze_loop``): a design about ``u0``; check it on the model itself with
        :meth:`simulate`."""
        from ._model import HammersteinModel
        from ._families import Polynomial

        return HammersteinModel(self.linearize(u0), Polynomial(1), [1.0], name=self.name)

    def parts(self, initial_state=None) -> WHParts:
        """The model as one row of :class:`WHParts` (from ``initial_state``, both blocks' states together, if
        given)."""
        (num1, den1), (num2, den2) = ((n[None, :] / d[0], d[None, :] / d[0]) for n, d in self._blocks)
        if initial_state is not None:
            x = _state_vector(initial_state, self.order)
            x1, x2 = x[:self.orders[0]], x[self.orders[0]:]
        else:
            x1, x2 = self.initial_state or (np.zeros(den1.shape[1] - 1), np.zeros(den2.shape[1] - 1))
        return WHParts(num1, den1, self.params[None, :], num2, den2, np.array([self.offset]),
                       np.asarray(x1, float)[None, :], np.asarray(x2, float)[None, :])

    def f(self, x) -> np.ndarray:
        """The static map ``f(x)`` between the blocks."""
        return self.nonlinearity(x, self.params)

    def _input(self, t, u, intersample):
        from ..data._iodata import time_and_input

        t, u, hold = time_and_input(t, u, self.intersample)
        hold = check_intersample(hold if intersample is None else intersample)
        dt, u = _check_pair(t, u, "u")
        return dt, u, hold

    def middle(self, t, u=None, *, intersample: str | None = None) -> np.ndarray:
        """The signal ``x = G1 u`` between ``G1`` and ``f`` at the sample instants (exact)."""
        dt, u, hold = self._input(t, u, intersample)
        p = self.parts()
        return simulate_batch(p.num1, p.den1, u, dt, x0=p.x1, intersample=hold)[0]

    def simulate(self, t, u=None, *, initial_state=None, intersample: str | None = None) -> np.ndarray:
        """The output at the instants ``t`` (uniform grid, or a record: its ``t``, ``u`` and hold) for the input
        ``u``, from the model's initial state or ``initial_state`` (``G1``'s then ``G2``'s); see the module
        docstring for the intersample behaviour."""
        dt, u, hold = self._input(t, u, intersample)
        return simulate_wh(self.nonlinearity, self.parts(initial_state), u, dt, hold, self.substeps, self.delay)[0]

    def to_iosys(self, name: str | None = None):
        """The model as a python-control ``interconnect`` of ``G1``, ``f`` and ``G2``.

        Its input is ``u`` and its output ``y``; its states are ``G1``'s then
        ``G2``'s companion realisations (as ``initial_state``), which
        ``control.input_output_response`` takes as ``X0``; a dead time is a Pade
        approximant before ``G1``, whose states come first.
        """
        import control as ct

        p = self.parts()
        first_input = "ud" if self.delay else "u"
        blocks = []
        for num, den, label, inp, out in ((p.num1, p.den1, "G1", first_input, "x"), (p.num2, p.den2, "G2", "w", "v")):
            A, B, C, D = (m[0] for m in companion_realization(num, den))
            blocks.append(ct.ss(A, B[:, None], C[None, :], np.atleast_2d(D), inputs=inp, outputs=out, name=label))
        nl, params, y0 = self.nonlinearity, self.params.copy(), self.offset
        fmap = ct.nlsys(None, lambda t, x, u, q: np.atleast_1d(nl(u, params)), inputs="x", outputs="w", name="f")
        offset = ct.nlsys(None, lambda t, x, u, q: np.atleast_1d(u[0] + y0), inputs="v", outputs="y", name="offset")
        parts = [blocks[0], fmap, blocks[1], offset]
        if self.delay:                  # a Pade approximant of the dead time before G1
            from ._model import pade_order_of

            parts.insert(0, ct.ss(ct.tf(*ct.pade(self.delay, pade_order_of())), inputs="u", outputs="ud",
                                  name="delay"))
        return ct.interconnect(parts, inputs="u", outputs="y", name=name or self.name or "wiener_hammerstein")

    def save(self, path) -> None:
        """Write the model to a JSON model file (:func:`~hammerstein_ctrl.io.load_model` reads it)."""
        from ._json import save_model

        save_model(self, path)

    def describe(self) -> str:
        (n1, d1), (n2, d2) = self._blocks
        return (f"Wiener-Hammerstein: G1 = {n1.tolist()} / {d1.tolist()}, f = {self.nonlinearity.describe(self.params)}"
                f", G2 = {n2.tolist()} / {d2.tolist()}" + (f", y0 = {self.offset:.6g}" if self.offset else ""))

    def __repr__(self):
        return f"<WienerHammersteinModel {self.nonlinearity.name}, orders {self.orders[0]} + {self.orders[1]}>"
