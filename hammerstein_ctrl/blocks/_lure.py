"""Lur'e models: a linear block with friction fed back on one of its signals (friction where it acts).

A Hammerstein model puts a nonlinearity on the input; a sliding mass feels
its friction as a function of its **velocity**, inside the loop:

.. code-block:: text

    w = u - g(z)            the input force less the friction force
    y = B(p)/A(p) w         the linear block (force to position)
    z = y' ("velocity")  or  z = y ("output")

with ``g`` the :class:`~hammerstein_ctrl.blocks.Friction` map
``|fc| sign(z) + c`` (Coulomb friction and a constant force) or
:class:`~hammerstein_ctrl.blocks.Coulomb` (``d0 z + |d1| sign(z) + d2``,
a viscous term as well; on velocity it duplicates the block's damping).  For
a mass ``m`` with viscous friction ``fv`` driven by ``u`` through a gain
``k``: ``B/A = (k/m) / (p^2 + (fv/m) p)`` and ``g`` in input units.

The linear block carries the gain (``LinearStructure(..., monic_numerator=False)``):
the friction enters the same channel as ``u``, so nothing is ambiguous.  ``z``
must be driven directly by ``w`` (relative degree 2 of ``B/A`` on velocity,
1 on the output), so that the loop is well posed at ``z = 0``.

The simulation is exact at the sample instants (:mod:`~hammerstein_ctrl.simulate._lure_sim`):
between sign changes of ``z`` the loop is linear, a crossing inside a sample
is located, and the mass **sticks** (``z = 0``) while the force on it is
within the Coulomb level, slipping again where it exceeds it.

Examples
--------
>>> import numpy as np, hammerstein_ctrl as hc
>>> s = LureStructure(hc.LinearStructure(0, 2, monic_numerator=False, fixed={"a0": 0.0}), hc.Friction())
>>> s.param_names
('b0', 'a1', 'fc', 'c')
>>> m = s.model([0.385, 2.13, 0.61, -0.09])
>>> t = np.arange(2000) * 0.01
>>> y = m.simulate(t, np.sin(0.5 * t))
>>> bool(np.all(y[:20] == 0.0))         # the force stays below the friction at first: stuck
True
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._checks import as_real_array, check_intersample
from ..simulate._discretize import companion_realization
from ..simulate._lure_map import loop_setup, map_slope, run
from ..simulate._lure_sim import FEEDBACK_CODES, lure_run, lure_setup
from ..exceptions import ParameterError
from ._nonlinearities import Nonlinearity
from ._families import Coulomb, Friction
from ..simulate._simulate import _check_pair, unstable
from ._model import _check_linear, _finite_scalar, _state_vector
from ._structure import INITIAL_STATES, LinearStructure, nuisance_names

__all__ = ["LureStructure", "LureModel", "LoopParts", "lure_structure", "simulate_parts", "sign_map", "FEEDBACKS",
           "FEEDBACK_FAMILIES", "DERIVATIVES", "MAX_SUBSTEPS"]

#: Most substeps per sample of a loop with a map that is not sign-type.
MAX_SUBSTEPS = 64

#: Signals the friction may act on, and the relative degree of ``B/A`` each needs.
FEEDBACKS = {"velocity": 2, "output": 1}
#: The signals any map may act on, as the derivative of the output each is (``B/A`` needs a higher relative degree).
DERIVATIVES = {"output": 0, "velocity": 1, "acceleration": 2}
#: Feedback families simulated exactly through sticking: each maps to ``(slope, Coulomb level, constant)`` of ``g``
#: from its parameters.  Any other map is simulated by :mod:`~hammerstein_ctrl.simulate._lure_map`.
FEEDBACK_FAMILIES = (Friction, Coulomb)


def sign_map(nonlinearity) -> bool:
    """Whether a map is a sign-type friction map (simulated exactly through sticking)."""
    return isinstance(nonlinearity, FEEDBACK_FAMILIES)


def _affine_parts(nonlinearity: Nonlinearity, P: np.ndarray):
    """``(slope, fc, c)`` columns of ``g(z) = slope z + fc sign(z) + c`` for rows of parameters ``P``."""
    if isinstance(nonlinearity, Friction):
        return np.zeros(P.shape[0]), np.abs(P[:, 0]), P[:, 1]
    return P[:, 0], np.abs(P[:, 1]), P[:, 2]


def _numerator_degree(linear: LinearStructure) -> int:
    """The numerator's degree once its leading coefficients fixed at 0 are dropped."""
    top = linear.num_order
    while top > 0 and getattr(linear, "fixed", {}).get(f"b{top}") == 0.0:
        top -= 1
    return top


def _check_feedback(linear: LinearStructure, nonlinearity, feedback: str):
    if not isinstance(feedback, str) or feedback not in DERIVATIVES:
        raise ParameterError(f"feedback must be one of {tuple(DERIVATIVES)}, got {feedback!r}")
    if not isinstance(nonlinearity, Nonlinearity):
        raise ParameterError(f"the feedback map must be a Nonlinearity, got {type(nonlinearity).__name__}")
    top = _numerator_degree(linear)
    degree = linear.den_order - top
    zeros = (f" (b{linear.num_order} is fixed at 0, so the numerator's degree is {top})"
             if top < linear.num_order else "")
    if sign_map(nonlinearity):
        if feedback not in FEEDBACKS:
            raise ParameterError(f"friction acts on the output or the velocity, got {feedback!r}")
        need = FEEDBACKS[feedback]
        if degree != need:
            den_order = max(linear.den_order, need)
            raise ParameterError(
                f"friction on the {feedback} needs a linear block of relative degree {need} (den_order - "
                f"num_order), got {degree}{zeros}: e.g. LinearStructure({den_order - need}, {den_order}, "
                "monic_numerator=False)")
    elif degree <= DERIVATIVES[feedback]:
        need = DERIVATIVES[feedback] + 1
        raise ParameterError(
            f"a map on the {feedback} needs a linear block of relative degree at least {need} (den_order - "
            f"num_order), so that the {feedback} does not jump with the input, got {degree}{zeros}")
    if linear.monic_numerator:
        raise ParameterError("a Lur'e loop carries its gain in the linear block: use "
                             "LinearStructure(..., monic_numerator=False)")
    if linear.delay:
        raise ParameterError("a Lur'e loop with a dead time is not supported yet")


def _check_substeps(substeps) -> int:
    if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or not 1 <= substeps <= MAX_SUBSTEPS:
        raise ParameterError(f"substeps must be a whole number from 1 to {MAX_SUBSTEPS}, got {substeps!r}")
    return int(substeps)


def _map_loop_outputs(nonlinearity, num, den, P, y0, x0, u, dt, hold, substeps, feedback) -> np.ndarray:
    """Outputs ``(B, N)`` of loops with a map that is not sign-type (:mod:`~hammerstein_ctrl.simulate._lure_map`)."""
    loop = loop_setup(num, den, float(dt), substeps, nonlinearity, P, DERIVATIVES[feedback])
    return run(nonlinearity, loop, P, np.asarray(y0, dtype=float), np.asarray(x0, dtype=float), u, hold == "zoh")


class LureStructure:
    """A Lur'e loop to identify: a linear block with a static map fed back on its output or a derivative.

    Parameters
    ----------
    linear : LinearStructure
        ``B(p)/A(p)`` from the net force ``w`` to the output, with its gain
        (``monic_numerator=False``).  Friction maps need relative degree 2 for
        ``feedback="velocity"`` and 1 for ``"output"`` exactly; any other map a
        relative degree above the derivative it reads (any degree >= 1 on the output).
    nonlinearity : Nonlinearity, default Friction()
        The feedback map ``g(z)``: :class:`~hammerstein_ctrl.blocks.Friction`
        and :class:`~hammerstein_ctrl.blocks.Coulomb` are simulated exactly
        through sticking; any other map (polynomial spring, tanh friction,
        saturation, dead zone, piecewise-linear, sigmoid, custom) by
        :mod:`~hammerstein_ctrl.simulate._lure_map`, exact for its slope at 0 and with
        ``substeps`` for the rest.
    feedback : {"output", "velocity", "acceleration"}, default "velocity"
        The signal ``z`` the map reads.
    offset : bool, default False
        Estimate a constant output offset ``y0``.
    initial_state : {"zero", "estimate"}, default "zero"
        Start at rest, or estimate ``x(0)`` of the block's companion
        realisation (parameters ``xi0``, ``xi1``, ...).
    substeps : int, default 1
        Instants per sample at which a map that is not sign-type is computed
        (the error falls with their square; ignored for friction maps, which are exact).

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> lin = hc.LinearStructure(0, 2, monic_numerator=False, fixed={"a0": 0.0})
    >>> LureStructure(lin, hc.Friction(), offset=True).param_names
    ('b0', 'a1', 'fc', 'c', 'y0')
    >>> LureStructure(lin, hc.Polynomial(3), feedback="output").param_names   # a Duffing oscillator
    ('b0', 'a1', 'd1', 'd2', 'd3')
    """

    kind = "lure"
    #: Blocks of a block-oriented structure that a Lur'e loop does not have (for the shared verdicts).
    input_nonlinearity = None
    output_nonlinearity = None
    _fixed_gain = None

    def __init__(self, linear: LinearStructure, nonlinearity: Nonlinearity | None = None, *,
                 feedback: str = "velocity", offset: bool = False, initial_state: str = "zero", substeps: int = 1):
        if not isinstance(linear, LinearStructure):
            raise ParameterError(f"linear must be a LinearStructure, got {type(linear).__name__}")
        nonlinearity = Friction() if nonlinearity is None else nonlinearity
        _check_feedback(linear, nonlinearity, feedback)
        numerator = [f"b{i}" for i in range(linear.num_order + 1)]
        if all(linear.fixed.get(b) == 0.0 for b in numerator):
            raise ParameterError(f"the numerator's coefficients {numerator} are all fixed to 0: the input cannot "
                                 f"move the loop")
        if not isinstance(offset, (bool, np.bool_)):
            raise ParameterError(f"offset must be True or False, got {offset!r}")
        if initial_state not in INITIAL_STATES:
            raise ParameterError(f"initial_state must be one of {INITIAL_STATES}, got {initial_state!r}")
        self.linear, self.nonlinearity, self.feedback = linear, nonlinearity, feedback
        self.offset, self.initial_state = bool(offset), initial_state
        self.substeps = _check_substeps(substeps)
        self.param_names: tuple[str, ...] = (linear.param_names + tuple(nonlinearity.param_names)
                                             + nuisance_names(self.offset, initial_state, linear.den_order))

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @property
    def n_core(self) -> int:
        """Parameters of the loop itself (the linear block and the map), before the offset and initial state."""
        return self.linear.n_params + self.nonlinearity.n_params

    @property
    def level_index(self) -> int:
        """Position of the Coulomb level (``fc``, or ``Coulomb``'s ``d1``) in beta (a friction map only)."""
        if not sign_map(self.nonlinearity):
            raise ParameterError(f"the map {self.nonlinearity!r} has no Coulomb level")
        return self.linear.n_params + (0 if isinstance(self.nonlinearity, Friction) else 1)

    def with_options(self, *, offset: bool | None = None, initial_state: str | None = None,
                     substeps: int | None = None) -> "LureStructure":
        """The same loop with other real-data options (``None`` keeps the current one)."""
        return LureStructure(self.linear, self.nonlinearity, feedback=self.feedback,
                             offset=self.offset if offset is None else offset,
                             initial_state=self.initial_state if initial_state is None else initial_state,
                             substeps=self.substeps if substeps is None else substeps)

    def simulate_rows(self, betas, u, dt: float, hold: str, y=None) -> np.ndarray:
        """Outputs ``(B, N)`` of the loops of rows ``betas`` driven by ``u``, or with ``y`` their SSEs ``(B,)``."""
        B = np.atleast_2d(self.check_beta(betas))
        if sign_map(self.nonlinearity):
            return simulate_parts(self.parts(B), u, dt, hold, y=y)
        num, den = self.linear.coefficients(B[:, :self.linear.n_params])
        P = self.map_params(B)
        at = self.n_core
        y0 = B[:, at] if self.offset else np.zeros(B.shape[0])
        n = self.linear.den_order
        x0 = B[:, at + self.offset:at + self.offset + n] if self.initial_state == "estimate" else np.zeros((len(B), n))
        Y = _map_loop_outputs(self.nonlinearity, num, den, P, y0, x0, u, dt, hold, self.substeps, self.feedback)
        if y is None:
            return Y
        with np.errstate(all="ignore"):
            E = Y - np.asarray(y, dtype=float)
            return np.einsum("ij,ij->i", E, E)

    def check_beta(self, beta) -> np.ndarray:
        """``beta`` as a float array ``(n_params,)`` or ``(B, n_params)``; a wrong length is refused."""
        b = as_real_array(beta, "beta")
        if b.ndim not in (1, 2) or b.shape[-1] != self.n_params:
            raise ParameterError(f"beta must have {self.n_params} entries [{', '.join(self.param_names)}], "
                                 f"got shape {b.shape}")
        return b

    def linear_params(self, beta) -> np.ndarray:
        return self.check_beta(beta)[..., :self.linear.n_params]

    def unstable(self, betas) -> np.ndarray:
        """Whether each row of ``betas`` has a linear block with a pole in the open right half-plane."""
        B = np.atleast_2d(self.check_beta(betas))
        return unstable(self.linear.coefficients(B[:, :self.linear.n_params])[1])

    def map_params(self, beta) -> np.ndarray:
        """The feedback map's parameters."""
        k = self.linear.n_params
        return self.check_beta(beta)[..., k:k + self.nonlinearity.n_params]

    def parts(self, betas):
        """Everything the compiled simulation needs for rows ``betas``:
        ``(num, den, slope, fc, c, y0, x0)``."""
        B = np.atleast_2d(self.check_beta(betas))
        num, den = self.linear.coefficients(B[:, :self.linear.n_params])
        slope, fc, c = _affine_parts(self.nonlinearity, B[:, self.linear.n_params:self.n_core])
        at = self.n_core
        y0 = B[:, at] if self.offset else np.zeros(B.shape[0])
        at += self.offset
        n = self.linear.den_order
        x0 = B[:, at:at + n] if self.initial_state == "estimate" else np.zeros((B.shape[0], n))
        return LoopParts.of(num, den, slope, fc, c, y0, x0, self.feedback)

    def normalize(self, beta) -> np.ndarray:
        """``beta`` with the map's parameters in canonical form (a Coulomb level non-negative: ``fc`` and ``-fc``
        are one model)."""
        b = np.array(self.check_beta(beta), dtype=float)
        if sign_map(self.nonlinearity):
            b[..., self.level_index] = np.abs(b[..., self.level_index])
        else:
            k = self.linear.n_params
            b[..., k:self.n_core] = self.nonlinearity.normalize(b[..., k:self.n_core])
        return b

    def beta(self, model: "LureModel") -> np.ndarray:
        """The beta vector of a model that has this structure (checked: a mismatch is refused)."""
        if not isinstance(model, LureModel) or type(model.nonlinearity) is not type(self.nonlinearity) \
                or model.feedback != self.feedback:
            raise ParameterError(f"the model {model!r} does not have this structure {self!r}")
        parts = [self.linear.parameters(model.linear), model.params]
        if self.offset:
            parts.append([model.offset])
        if self.initial_state == "estimate":
            parts.append(np.zeros(self.linear.den_order) if model.initial_state is None else model.initial_state)
        return np.concatenate(parts)

    def model(self, beta, *, intersample: str = "foh", name: str | None = None) -> "LureModel":
        """The :class:`LureModel` at ``beta``."""
        b = self.normalize(self.check_beta(beta))
        if b.ndim != 1:
            raise ParameterError("model() takes one beta vector")
        num, den = self.linear.coefficients(self.linear_params(b))
        at = self.n_core
        n = self.linear.den_order
        return LureModel((num[0], den[0]), self.nonlinearity, self.map_params(b), feedback=self.feedback,
                         offset=float(b[at]) if self.offset else 0.0,
                         initial_state=b[at + self.offset:at + self.offset + n] if self.initial_state == "estimate"
                         else None, intersample=intersample, name=name, substeps=self.substeps)

    def describe(self) -> str:
        return (f"Lur'e loop: w = u - {self.nonlinearity.name}({self.feedback}), linear block "
                f"{self.linear.describe()}; parameters [{', '.join(self.param_names)}]")

    def __repr__(self):
        return (f"LureStructure({self.linear!r}, {self.nonlinearity!r}, feedback={self.feedback!r}, "
                f"offset={self.offset}, initial_state={self.initial_state!r}"
                + (f", substeps={self.substeps})" if self.substeps != 1 else ")"))


def lure_structure(num_order: int = 0, den_order: int = 2, nonlinearity: Nonlinearity | None = None, *,
                   feedback: str = "velocity", integrating: bool = True, **options) -> LureStructure:
    """A :class:`LureStructure` from orders: ``b0 / (p^2 + a1 p)`` with friction on velocity by default.

    ``integrating=True`` fixes ``a0 = 0`` (position of a mass: no spring).

    Examples
    --------
    >>> lure_structure().param_names
    ('b0', 'a1', 'fc', 'c')
    """
    fixed = {"a0": 0.0} if integrating else None
    return LureStructure(LinearStructure(num_order, den_order, monic_numerator=False, fixed=fixed),
                         nonlinearity, feedback=feedback, **options)


class LoopParts(NamedTuple):
    """What the compiled simulation of a batch of loops needs (rows: candidates), as contiguous float arrays."""

    num: np.ndarray
    den: np.ndarray
    slope: np.ndarray
    fc: np.ndarray
    c: np.ndarray
    y0: np.ndarray
    x0: np.ndarray
    feedback: str

    @classmethod
    def of(cls, num, den, slope, fc, c, y0, x0, feedback: str) -> "LoopParts":
        arrays = (np.ascontiguousarray(v, dtype=float) for v in (num, den, slope, fc, c, y0, x0))
        return cls(*arrays, feedback)

    def setup(self, dt: float) -> tuple:
        """The per-candidate matrices (:func:`~hammerstein_ctrl.simulate._lure_sim.lure_setup`) at the sampling
        interval."""
        return lure_setup(self.num, self.den, float(dt), self.slope, FEEDBACK_CODES[self.feedback])


def simulate_parts(parts: LoopParts, u, dt: float, hold: str, y=None) -> np.ndarray:
    """Outputs ``(B, N)`` of the loops ``parts`` (:meth:`LureStructure.parts`), or with ``y`` their SSEs ``(B,)``."""
    u = np.ascontiguousarray(u, dtype=float)
    want = y is None
    out = np.empty((parts.den.shape[0], u.size if want else 1))
    with np.errstate(all="ignore"):
        lure_run(*parts.setup(dt), parts.fc, parts.c, parts.x0, parts.y0, u, hold == "foh", u if want else y, out,
                 want)
    return out if want else out[:, 0]


class LureModel:
    """An identified (or given) Lur'e loop: ``y = B/A (u - g(z)) + offset``, ``z`` the output or a derivative.

    Parameters
    ----------
    linear : (num, den) or control.TransferFunction
        The linear block from the net force to the output.
    nonlinearity : Nonlinearity
        The feedback map (see :class:`LureStructure`).
    params : array_like
        The map's parameters.
    feedback : {"output", "velocity", "acceleration"}
    offset : float
    initial_state : array_like, optional
        ``x(0)`` of the companion realisation of ``num/den``.
    intersample : {"foh", "zoh"}
    name : str, optional
    substeps : int, default 1
        See :class:`LureStructure`.

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> m = LureModel(([2.0], [1.0, 0.6, 0.0]), hc.Polynomial(3), [4.0, 0.0, 3.0], feedback="output")
    >>> y = m.simulate(np.arange(2000) * 0.05, np.full(2000, 1.0))
    >>> round(float(y[-1]), 4)                           # at rest: 4 y + 3 y^3 = 1
    0.2397
    """

    kind = "lure"
    #: Static blocks of a block-oriented model that a Lur'e loop does not have (for the shared figures).
    input_nonlinearity = None
    output_nonlinearity = None

    def __init__(self, linear, nonlinearity, params, *, feedback: str = "velocity", offset: float = 0.0,
                 initial_state=None, intersample: str = "foh", name: str | None = None, substeps: int = 1):
        _, num, den = _check_linear(linear if not isinstance(linear, list) else tuple(linear))
        if not np.any(num):
            raise ParameterError("the linear block's gain is zero: the input cannot move the loop")
        self._num, self._den = num / den[0], den / den[0]
        lin = LinearStructure(self._num.size - 1, self.order, monic_numerator=False)
        _check_feedback(lin, nonlinearity, feedback)
        self.nonlinearity = nonlinearity
        self.params = nonlinearity.check_params(params).astype(float)
        if self.params.ndim != 1 or not np.all(np.isfinite(self.params)):
            raise ParameterError(f"params must be one vector of finite numbers, got {params!r}")
        self.feedback, self.offset = feedback, _finite_scalar(offset, "offset")
        self.name = "lure" if name is None else str(name)
        self.intersample = check_intersample(intersample)
        self.initial_state = _state_vector(initial_state, self.order)
        self.substeps = _check_substeps(substeps)

    @property
    def order(self) -> int:
        return len(self._den) - 1

    @property
    def linear(self):
        """The linear block as a ``control.TransferFunction``."""
        import control

        return control.tf(self._num, self._den)

    def g(self, z) -> np.ndarray:
        """The feedback map ``g(z)``."""
        return self.nonlinearity(z, self.params)

    def _parts(self, initial_state=None) -> LoopParts:
        """The model as a one-row :class:`LoopParts` (from ``initial_state`` if given, else its own)."""
        slope, fc, c = _affine_parts(self.nonlinearity, self.params[None, :])
        x0 = self.initial_state if initial_state is None else _state_vector(initial_state, self.order)
        x0 = np.zeros((1, self.order)) if x0 is None else np.reshape(x0, (1, self.order))
        return LoopParts.of(self._num[None, :], self._den[None, :], slope, fc, c, [self.offset], x0, self.feedback)

    def simulate(self, t, u=None, *, initial_state=None, intersample: str | None = None) -> np.ndarray:
        """The output at the sample instants, exact through sticking (see the module's notes).

        Parameters
        ----------
        t : array_like or IOData
            Uniform time grid, or a record (its ``t``, ``u``, ``intersample``).
        u : array_like, optional
        initial_state : array_like, optional
            Overrides the model's ``x(0)``.
        intersample : {"foh", "zoh"}, optional
        """
        from ..data._iodata import time_and_input

        t, u, hold = time_and_input(t, u, self.intersample)
        hold = check_intersample(hold if intersample is None else intersample)
        dt, u = _check_pair(t, u, "u")
        if sign_map(self.nonlinearity):
            return simulate_parts(self._parts(initial_state), u, dt, hold)[0]
        x0 = self.initial_state if initial_state is None else _state_vector(initial_state, self.order)
        x0 = np.zeros((1, self.order)) if x0 is None else np.reshape(x0, (1, self.order))
        return _map_loop_outputs(self.nonlinearity, self._num[None, :], self._den[None, :], self.params[None, :],
                                 [self.offset], x0, u, dt, hold, self.substeps, self.feedback)[0]

    def to_iosys(self, name: str | None = None):
        """The loop as a python-control ``interconnect`` of the linear block and the feedback map.

        Its input is ``u``, its output ``y``; its states are the linear
        block's (the companion realisation, as ``initial_state``), which
        ``control.input_output_response`` takes as ``X0`` (the model's own
        ``initial_state`` is not carried).  An ODE solver cannot stay on
        ``z = 0`` with a ``sign``: it chatters through sticking, so use
        :meth:`simulate` for the sampled response.
        """
        import control as ct

        A, B, C, _ = (m[0] for m in companion_realization(self._num, self._den))
        Cz = C @ np.linalg.matrix_power(A, DERIVATIVES[self.feedback])
        plant = ct.ss(A, B[:, None], np.vstack([C, Cz]), np.zeros((2, 1)), inputs="w", outputs=["ylin", "z"],
                      name="linear")
        fmap = ct.nlsys(None, lambda t, x, u, p: np.atleast_1d(self.g(u[0])), inputs="z", outputs="f",
                        name="friction")
        offset = ct.nlsys(None, lambda t, x, u, p: np.atleast_1d(u[0] + self.offset), inputs="ylin",
                          outputs="y", name="offset")
        junction = ct.summing_junction(inputs=["u", "-f"], output="w")
        return ct.interconnect([plant, fmap, offset, junction], inputs="u", outputs="y",
                               name=name or self.name or "lure")

    def linearize(self):
        """The loop in motion as a ``control.TransferFunction`` from ``u`` to ``y``.

        While ``z`` keeps its sign the friction is a constant force (an input
        disturbance of ``-(fc sign(z) + c)``), and only a viscous slope ``k``
        of the map (``Coulomb``'s ``d0``) acts on the dynamics:
        ``B / (A + k p B)`` on velocity, ``B / (A + k B)`` on the output.  At
        rest the loop sticks: no linear model describes it there.  Any other
        map acts through its slope at 0 (the loop linearised about rest).

        Examples
        --------
        >>> m = LureModel(([0.4], [1.0, 1.5, 0.0]), Coulomb(), [1.25, 0.5, 0.05])
        >>> m.linearize().den[0][0].tolist()              # p^2 + (1.5 + 0.4 * 1.25) p
        [1.0, 2.0, 0.0]
        """
        import control

        if sign_map(self.nonlinearity):
            slope = float(_affine_parts(self.nonlinearity, self.params[None, :])[0][0])
        else:
            slope = float(map_slope(self.nonlinearity, self.params[None, :])[0])
        term = np.polymul(self._num, np.eye(DERIVATIVES[self.feedback] + 1)[0])
        return control.tf(self._num, np.polyadd(self._den, slope * term))

    def motion_model(self):
        """:meth:`linearize` as a :class:`~hammerstein_ctrl.blocks.HammersteinModel` (unit gain), for the
        linear tools (``tune_pid``, ``analyze_loop``): a design for the loop in motion, in which friction is a
        constant disturbance.  Check the result against sticking with
        :class:`~hammerstein_ctrl.fit.KnownLoop` (``KnownLoop(controller, r).simulate(model)``).

        Examples
        --------
        >>> LureModel(([0.4], [1.0, 2.0, 0.0]), Friction(), [0.5, 0.05]).motion_model().params.tolist()
        [1.0]
        """
        from ._model import HammersteinModel
        from ._families import Polynomial

        return HammersteinModel(self.linearize(), Polynomial(1), [1.0], name=self.name)

    def save(self, path) -> None:
        """Write the model to a JSON model file (:func:`~hammerstein_ctrl.io.load_model` reads it)."""
        from ._json import save_model

        save_model(self, path)

    def describe(self) -> str:
        vals = ", ".join(f"{k} = {v:.6g}" for k, v in zip(self.nonlinearity.param_names, self.params))
        return (f"Lur'e loop: y = ({np.array2string(self._num, precision=6)}) / "
                f"({np.array2string(self._den, precision=6)}) (u - g({self.feedback})) + {self.offset:.6g}, "
                f"g = {self.nonlinearity.name} ({vals})")

    def __repr__(self):
        return f"<LureModel {self.describe()}>"
