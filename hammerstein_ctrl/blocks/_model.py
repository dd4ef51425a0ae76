"""Block-oriented models: Hammerstein (``g`` then ``H``), Wiener (``H`` then ``h``) and both.

:class:`BlockModel` holds a linear block ``H`` (a :class:`control.TransferFunction`)
with an optional static input nonlinearity ``g`` and an optional static output
nonlinearity ``h``: ``y = h(H(p) g(u)) + offset``.  :class:`HammersteinModel`,
:class:`WienerModel` and :class:`HammersteinWienerModel` are its three shapes.

Two views of the same model exist on purpose:

* :meth:`BlockModel.simulate` uses the *sampled* semantics the paper's
  numbers depend on: ``g`` is applied to the input samples and ``g(u)`` is
  interpolated linearly between samples (exactly
  ``control.forced_response(H, t, g(u))``).  This is what identification uses.
* :meth:`BlockModel.to_iosys` returns a :class:`control.NonlinearIOSystem`
  (``control.nlsys`` for ``g`` wired to ``H`` with ``control.interconnect``) for
  closed loops and controller design.  Simulated with
  :func:`control.input_output_response`, ``g`` acts on the interpolated input
  ``u(t)`` inside an ODE solver; for smooth ``g`` and inputs the two agree
  closely, but with a discontinuous ``g`` such as ``sign(u)`` the ODE view
  switches at the zero crossing instead of at the sample, so it differs slightly.

Examples
--------
>>> import numpy as np, control as ct
>>> from hammerstein_ctrl import HammersteinModel, Tanh
>>> m = HammersteinModel(ct.tf([1, -1.816], [1, 4.7681, 0.118]), Tanh(), [-4.7132, 0.1229])
>>> t = np.arange(0, 10, 0.1)
>>> y = m.simulate(t, np.ones_like(t))
>>> m.linearize(0.0).num[0][0].round(4)
array([-0.5793,  1.0519])
"""

from __future__ import annotations


import numpy as np

from .._checks import as_count, as_signal, check_delay, check_intersample, check_transfer_function, signal_names
from ..exceptions import ParameterError
from ._nonlinearities import Nonlinearity

__all__ = ["BlockModel", "HammersteinModel", "WienerModel", "HammersteinWienerModel", "pade_order_of"]


def pade_order_of(order=None) -> int:
    """The order of the Pade approximant that stands for a dead time in python-control exports and loop analyses.

    ``order`` if given, else ``config.defaults["delay.pade_order"]`` (6: phase error under 0.1 degree
    up to ``omega tau = 6``, 1.4 degrees at 8).
    """
    from .. import config

    return config.get("delay.pade_order") if order is None else as_count(order, "pade_order", minimum=1)


def _finite_scalar(value, label: str) -> float:
    try:
        v = float(value)
    except OverflowError:
        raise ParameterError(f"{label} is too large for a float ({str(value)[:40]}...)") from None
    except (TypeError, ValueError):
        raise ParameterError(f"{label} must be a number, got {value!r}") from None
    if not np.isfinite(v):
        raise ParameterError(f"{label} must be finite, got {v!r}")
    return v


def _state_vector(value, n: int):
    """A finite initial state of length ``n`` as a read-only array (``None`` stays ``None``)."""
    if value is None:
        return None
    x = np.array(value, dtype=float).reshape(-1)
    if x.size != n or not np.all(np.isfinite(x)):
        raise ParameterError(f"initial_state must be {n} finite numbers (the order of H), got {np.shape(value)}")
    x.setflags(write=False)
    return x


def _check_block(nonlinearity, params, label: str):
    """``(nonlinearity, read-only finite parameter vector)`` or ``(None, None)``."""
    if nonlinearity is None:
        if params is not None:
            raise ParameterError(f"{label} parameters given without an {label} nonlinearity")
        return None, None
    if not isinstance(nonlinearity, Nonlinearity):
        raise ParameterError(f"{label} nonlinearity must be a Nonlinearity, got {type(nonlinearity).__name__}")
    p = nonlinearity.check_params(params)
    if p.ndim != 1:
        raise ParameterError(f"a model takes one parameter vector for its {label} nonlinearity")
    if not np.all(np.isfinite(p)):
        raise ParameterError(f"{label} nonlinearity parameters must be finite, got {p.tolist()}")
    p = p.copy()
    p.setflags(write=False)
    return nonlinearity, p


def _check_linear(linear):
    """``(transfer function or None, num, den)``: a python-control block checked, or ``(num, den)`` coefficients
    (descending powers) whose transfer function is made when first asked for (python-control's import is
    the slowest part of a first identification)."""
    if isinstance(linear, tuple) and len(linear) == 2:
        num, den = check_transfer_function(np.ravel(linear[0]), np.ravel(linear[1]), "the linear block",
                                           advice="reduce the model (e.g. control.balred)")
        return None, num, den
    import control

    if isinstance(linear, control.StateSpace):
        linear = control.ss2tf(linear)
    if not isinstance(linear, control.TransferFunction):
        raise ParameterError(f"linear must be a control.TransferFunction, got {type(linear).__name__}")
    if linear.ninputs != 1 or linear.noutputs != 1:
        raise ParameterError("the linear block must be SISO")
    if linear.isdtime(strict=True):
        raise ParameterError("the linear block must be continuous-time (dt=0)")
    num, den = check_transfer_function(linear.num[0][0], linear.den[0][0], "the linear block",
                                       advice="reduce the model (e.g. control.balred)")
    return linear, num, den


class BlockModel:
    """``y = h(H(p) g(u)) + offset`` with ``H`` a :class:`control.TransferFunction`.

    Parameters
    ----------
    linear : control.TransferFunction or control.StateSpace
        Continuous-time SISO linear block ``H(p)`` (state-space blocks are
        converted to a transfer function).
    input_nonlinearity, output_nonlinearity : Nonlinearity, optional
        The static blocks ``g`` before and ``h`` after ``H`` (identity if omitted).
    input_params, output_params : array_like, optional
        Their parameters.
    offset : float, default 0
        Constant added to the output.
    initial_state : array_like, optional
        State ``x(0)`` of ``H``'s controllable canonical realisation
        (:func:`~hammerstein_ctrl.simulate.companion_realization`, the one
        :meth:`to_ss` returns); default: at rest.
    intersample : {"foh", "zoh"}, default "foh"
        Default intersample behaviour of the input in :meth:`simulate` when it
        is given ``(t, u)`` arrays; a record's own ``intersample`` wins.
    name : str, optional
        Name used for the interconnected system.
    delay : float, default 0
        Input dead time ``tau`` in seconds (``y = h(H(p) e^{-tau p} g(u))``),
        simulated exactly (:mod:`~hammerstein_ctrl.simulate._delay`); python-control
        exports carry it as a Pade approximant of order ``pade_order``
        (:func:`pade_order_of`).

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> m = hc.HammersteinModel(([1.0], [1.0, 1.0]), hc.Tanh(), [2.0, 1.0])
    >>> isinstance(m, BlockModel), m.order
    (True, 1)
    >>> float(m.simulate(np.arange(400) * 0.05, np.ones(400))[-1]).__round__(4)      # 2 tanh(1) at rest
    1.5232
    """

    #: Short name of the structure family.
    kind = "block"

    def __init__(self, linear, *, input_nonlinearity=None, input_params=None, output_nonlinearity=None,
                 output_params=None, offset: float = 0.0, initial_state=None, intersample: str = "foh",
                 name: str | None = None, delay: float = 0.0):
        self._linear, self._num, self._den = _check_linear(linear)
        order = self._den.size - 1
        self.delay = check_delay(delay, estimate=False)
        self.input_nonlinearity, self.input_params = _check_block(input_nonlinearity, input_params, "input")
        self.output_nonlinearity, self.output_params = _check_block(output_nonlinearity, output_params, "output")
        self.offset = _finite_scalar(offset, "offset")
        self.initial_state = _state_vector(initial_state, order)
        self.intersample = check_intersample(intersample)
        self.name = name or self.kind.replace("-", "_")

    @staticmethod
    def build(linear, *, input_nonlinearity=None, input_params=None, output_nonlinearity=None,
              output_params=None, **kwargs) -> "BlockModel":
        """The model of the right shape for the blocks given (Hammerstein, Wiener or both)."""
        if input_nonlinearity is not None and output_nonlinearity is None:
            return HammersteinModel(linear, input_nonlinearity, input_params, **kwargs)
        if output_nonlinearity is not None and input_nonlinearity is None:
            return WienerModel(linear, output_nonlinearity, output_params, **kwargs)
        if input_nonlinearity is not None:
            return HammersteinWienerModel(linear, input_nonlinearity, input_params, output_nonlinearity,
                                          output_params, **kwargs)
        return BlockModel(linear, **kwargs)

    @property
    def linear(self):
        """The linear block ``H`` as a :class:`control.TransferFunction` (made on first use from the coefficients
        a structure gives)."""
        if self._linear is None:
            import control

            self._linear = control.tf(self._num, self._den)
        return self._linear

    @linear.setter
    def linear(self, value):
        """Replace the linear block (a transfer function; checked where the model is used, as before)."""
        self._linear = value
        self._num = np.trim_zeros(np.atleast_1d(np.asarray(value.num[0][0], dtype=float)), "f")
        self._den = np.trim_zeros(np.atleast_1d(np.asarray(value.den[0][0], dtype=float)), "f")

    def coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """``(num, den)`` of the linear block, descending powers (copies; python-control is not needed).

        Examples
        --------
        >>> from hammerstein_ctrl import HammersteinModel, Tanh
        >>> HammersteinModel(([1.0, 2.0], [1.0, 1.4, 4.0]), Tanh(), [1.5, 0.9]).coefficients()
        (array([1., 2.]), array([1. , 1.4, 4. ]))
        """
        return self._num.copy(), self._den.copy()

    @property
    def order(self) -> int:
        """Number of states of the linear block."""
        return self._den.size - 1

    def state0(self) -> np.ndarray:
        """The initial state ``x(0)`` (zeros when the model starts at rest)."""
        return np.zeros(self.order) if self.initial_state is None else self.initial_state.copy()

    # -- evaluation -------------------------------------------------------------
    def g(self, u) -> np.ndarray:
        """The input nonlinearity ``g(u)`` (the identity if there is none)."""
        if self.input_nonlinearity is None:
            return np.asarray(u, dtype=float)
        return self.input_nonlinearity(u, self.input_params)

    def h(self, z) -> np.ndarray:
        """The output nonlinearity ``h(z)`` (the identity if there is none)."""
        if self.output_nonlinearity is None:
            return np.asarray(z, dtype=float)
        return self.output_nonlinearity(z, self.output_params)

    def simulate(self, t, u=None, *, initial_state=None, intersample: str | None = None) -> np.ndarray:
        """Simulate the model with the sampled (identification) semantics.

        Parameters
        ----------
        t : array_like or IOData
            Uniform time grid, or a record whose ``t``, ``u`` and
            ``intersample`` are used.
        u : array_like, optional
            Input samples (required unless ``t`` is a record).
        initial_state : array_like, optional
            Overrides the model's own ``x(0)`` (e.g. zeros to start from rest).
        intersample : {"foh", "zoh"}, optional
            Overrides the record's (or the model's) intersample behaviour.

        Returns
        -------
        ndarray
            The output; at rest, with first-order hold, no offset and no
            output nonlinearity it equals ``control.forced_response(H, t, g(u)).outputs``.
        """
        from ..data._iodata import time_and_input
        from ..simulate._simulate import simulate_blocks

        t, u, hold = time_and_input(t, u, self.intersample)
        x0 = self.initial_state if initial_state is None else _state_vector(initial_state, self.order)
        hold = hold if intersample is None else intersample
        if self.delay:
            from ..simulate._delay import simulate_delayed

            y = simulate_delayed(self, t, u, x0=x0, intersample=hold)
        else:
            y = simulate_blocks(self, t, u, x0=x0, intersample=hold)
        if not np.isfinite(y).all():
            self._warn_diverged(np.asarray(t, dtype=float), y)
        return y

    def _warn_diverged(self, t: np.ndarray, y: np.ndarray) -> None:
        """Issue a :class:`SimulationWarning` naming where the output stopped being finite, and why."""
        from ..simulate._simulate import warn_diverged

        poles = np.roots(self._den)
        growing = poles[poles.real > 0]
        why = (f"the model is unstable (pole(s) {', '.join(f'{p:.4g}' for p in growing)} in the right half-plane)"
               if growing.size else "its state overflowed")
        dt = float(t[1] - t[0]) if t.size > 1 else 0.0
        warn_diverged(y, dt, self.name, why, t0=float(t[0]) if t.size else 0.0, stacklevel=4)

    def linear_output(self, t, u=None) -> np.ndarray:
        """``z = H(p) g(u)``: the linear block's output (the signal entering ``h``), from the model's ``x(0)``.

        Takes a record or ``(t, u)`` as :meth:`simulate` does.
        """
        inner = BlockModel.build((self._num, self._den), input_nonlinearity=self.input_nonlinearity,
                                 input_params=self.input_params, initial_state=self.initial_state,
                                 intersample=self.intersample, delay=self.delay)
        with np.errstate(all="ignore"):
            return inner.simulate(t, u)

    # -- python-control interop -------------------------------------------------
    def to_iosys(self, name: str | None = None, *, dt: float | None = None, inputs: str = "u",
                 outputs: str = "y", intersample: str | None = None, pade_order: int | None = None):
        """The model as a :class:`control.NonlinearIOSystem` interconnection.

        With ``dt`` given, the exact discrete-time system of
        :func:`hammerstein_ctrl.simulate.sampled_iosys` instead (its
        ``control.input_output_response`` equals :meth:`simulate`), with the
        model's intersample behaviour unless ``intersample`` says otherwise.
        **In a digital loop pass** ``intersample="zoh"``: a controller drives
        the plant through a DAC that holds its input, and the held plant has
        no direct feedthrough (with D = 0), so
        ``control.interconnect`` + ``control.input_output_response`` close the
        loop with any discrete P, PI or PID.  A first-order hold uses the
        *current* input sample, which a loop cannot provide: python-control
        then reports an algebraic loop.

        The continuous system (no ``dt``) applies ``g`` to the input *as
        interpolated by the ODE solver* rather than interpolating ``g(u)``
        between samples as :meth:`simulate` does; for the samples themselves
        use the exact discrete system above (it reproduces :meth:`simulate` to
        rounding).  For ZOH inputs and with
        ``solve_ivp_kwargs={"rtol": 1e-10, "atol": 1e-12, "max_step": dt}``,
        fed the held input on a grid refined near each sample, the continuous
        system agrees with :meth:`simulate` to 1e-6.

        The static blocks (``control.nlsys`` without states) and ``H``
        (``control.ss`` in the realisation of :meth:`to_ss`) are wired with
        :func:`control.interconnect`; the result has input ``inputs`` and
        output ``outputs`` and can be wired into other python-control systems,
        e.g. a feedback loop with a controller.  Simulate it from the model's
        initial state with ``X0=model.state0()``.

        A dead time is exact in the discrete system (``dt`` given).  The
        continuous one carries it as a Pade approximant of order
        ``pade_order`` (default: :func:`pade_order_of`) between ``g`` and ``H``,
        starting at rest; its states come after ``H``'s (pad ``X0`` with zeros).

        Examples
        --------
        >>> import control as ct
        >>> from hammerstein_ctrl import HammersteinModel, Coulomb
        >>> plant = HammersteinModel(ct.tf([1], [1, 3.14, 0]), Coulomb(), [0.54, -0.4, 0.045]).to_iosys()
        >>> pid = ct.tf([20, 50], [1, 0], inputs="e", outputs="u")
        >>> err = ct.summing_junction(inputs=["r", "-y"], output="e")
        >>> loop = ct.interconnect([err, pid, plant], inputs="r", outputs="y")
        >>> loop.nstates
        3
        """
        import control

        (inputs,), (outputs,) = signal_names(inputs, "input"), signal_names(outputs, "output")
        if dt is not None:
            from ..simulate._export import sampled_iosys

            return sampled_iosys(self, dt, name=name, inputs=inputs, outputs=outputs, intersample=intersample)
        g, h, offset = self.g, self.h, self.offset
        delayed = "vd" if self.delay else "v"
        blocks = [control.nlsys(None, lambda t, x, u, p: g(np.atleast_1d(u)[:1]), inputs=[inputs],
                                outputs=["v"], name="g"),
                  self.to_ss(inputs=delayed, outputs="z", name="H"),
                  control.nlsys(None, lambda t, x, u, p: h(np.atleast_1d(u)[:1]) + offset, inputs=["z"],
                                outputs=[outputs], name="h")]
        if self.delay:      # after H in the list, so that H's states come first (X0 = [state0, zeros])
            order = pade_order_of(pade_order)
            blocks.append(control.ss(control.tf(*control.pade(self.delay, order)), inputs="v", outputs="vd",
                                     name="delay"))
        return control.interconnect(blocks, inputs=[inputs], outputs=[outputs], name=name or self.name)

    def linearize(self, u0: float = 0.0, *, z0: float | None = None, pade_order: int | None = None):
        """Small-signal transfer function ``h'(z0) H(p) g'(u0)`` around the input ``u0``.

        Parameters
        ----------
        u0 : float
            Operating input.
        z0 : float, optional
            Operating point of ``H``'s output, for an output nonlinearity.
            Default: the steady state ``H(0) g(u0)``; required when ``H`` has
            a pole at the origin (no steady state).
        pade_order : int, optional
            Order of the Pade approximant of a dead time (default ``config.defaults["delay.pade_order"]``).

        Returns
        -------
        control.TransferFunction
        """
        u0 = float(as_signal(u0, "u0")[0])
        gain = 1.0
        if self.input_nonlinearity is not None:
            gain = float(np.asarray(self.input_nonlinearity.derivative(np.array([u0]), self.input_params))[0])
        if self.output_nonlinearity is not None:
            z0 = self._steady_state(u0) if z0 is None else float(as_signal(z0, "z0")[0])
            gain *= float(np.asarray(self.output_nonlinearity.derivative(np.array([z0]), self.output_params))[0])
        return gain * self.linear_block(pade_order)

    def linear_block(self, pade_order: int | None = None):
        """``H(p)``, times a Pade approximant of ``e^{-tau p}`` of order ``pade_order`` when the model has a dead time.

        Examples
        --------
        >>> import control as ct
        >>> from hammerstein_ctrl import HammersteinModel, Tanh
        >>> m = HammersteinModel(ct.tf([1], [1, 1]), Tanh(), [1.0, 1.0], delay=0.5)
        >>> m.linear_block(2).den[0][0].size - 1          # one pole of H, two of the approximant
        3
        """
        if not self.delay:
            return self.linear
        import control

        order = pade_order_of(pade_order)
        return self.linear * control.tf(*control.pade(self.delay, order))

    def without_delay(self, pade_order: int | None = None) -> "BlockModel":
        """The same model with its dead time replaced by a Pade approximant (itself when it has none).

        Its ``initial_state`` is at rest: the approximant adds states of its own.
        """
        if not self.delay:
            return self
        return BlockModel.build(self.linear_block(pade_order), input_nonlinearity=self.input_nonlinearity,
                                input_params=self.input_params, output_nonlinearity=self.output_nonlinearity,
                                output_params=self.output_params, offset=self.offset,
                                intersample=self.intersample, name=self.name)

    def _steady_state(self, u0: float) -> float:
        den0 = float(np.asarray(self.linear.den[0][0], dtype=float)[-1])
        if den0 == 0:
            raise ParameterError("H has a pole at the origin (no steady state): give the operating point z0")
        return float(self.linear.num[0][0][-1]) / den0 * float(self.g(np.array([u0]))[0])

    # -- properties -------------------------------------------------------------
    def poles(self) -> np.ndarray:
        """Poles of the linear block."""
        return np.asarray(self.linear.poles())

    def is_stable(self) -> bool:
        """Whether every pole has a strictly negative real part."""
        return bool(np.all(self.poles().real < 0))

    def _blocks_repr(self) -> str:
        parts = [f"linear={self._tf_string()}"]
        if self.input_nonlinearity is not None:
            parts.append(f"g={self.input_nonlinearity.describe(self.input_params)}")
        if self.output_nonlinearity is not None:
            parts.append(f"h={self.output_nonlinearity.describe(self.output_params)}")
        return ", ".join(parts)

    def __repr__(self):
        extra = (f", offset={self.offset:.6g}" if self.offset else "") + (
            ", x(0) set" if self.initial_state is not None and np.any(self.initial_state) else "") + (
            ", zoh" if self.intersample == "zoh" else "")
        return f"{type(self).__name__}({self._blocks_repr()}{extra})"

    def _tf_string(self) -> str:
        def poly(c):
            c = np.trim_zeros(np.asarray(c, dtype=float), "f")
            deg = c.size - 1
            terms = []
            for i, a in enumerate(c):
                k = deg - i
                if a == 0 and deg:
                    continue
                pw = "" if k == 0 else ("p" if k == 1 else f"p^{k}")
                terms.append(pw if (a == 1 and pw) else f"{a:.6g}{(' ' + pw) if pw else ''}")
            return " + ".join(terms).replace("+ -", "- ") or "0"

        dead = f" e^(-{self.delay:.6g} p)" if self.delay else ""
        return f"({poly(self._num)})/({poly(self._den)}){dead}"           # python-control need not be imported

    # -- persistence and exact exports ----------------------------------------
    def save(self, path) -> None:
        """Write the model to ``path`` as versioned JSON (:func:`hammerstein_ctrl.load_model` reads it)."""
        from ._json import save_model

        save_model(self, path)

    def to_ss(self, **kwargs):
        """The linear block as a :class:`control.StateSpace` in the simulator's realisation.

        See :func:`hammerstein_ctrl.simulate.linear_ss`; ``initial_state``
        is a state of this system.
        """
        from ..simulate._export import linear_ss

        return linear_ss(self, **kwargs)

    # -- python-control time responses (logic in display.py) ----------------------
    def response(self, data_or_t, u=None):
        """:meth:`simulate` as a ``control.TimeResponseData`` (:func:`hammerstein_ctrl.data._display.response`)."""
        from ..data._display import response
        return response(self, data_or_t, u)

class HammersteinModel(BlockModel):
    """``y = H(p) g(u) + offset``: a static nonlinearity followed by the linear block.

    Parameters
    ----------
    linear : control.TransferFunction or control.StateSpace
    nonlinearity : Nonlinearity
        The input nonlinearity ``g``.
    params : array_like
        Its parameters.
    **kwargs
        ``offset``, ``initial_state``, ``intersample``, ``name`` (see :class:`BlockModel`).

    Attributes
    ----------
    nonlinearity, params
        ``g`` and its parameters (the same objects as ``input_nonlinearity``
        and ``input_params``).

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> m = HammersteinModel(([1.0], [1.0, 2.0]), hc.Polynomial(2), [1.0, 0.5])
    >>> round(float(m.simulate(np.arange(200) * 0.05, np.full(200, 2.0))[-1]), 4)       # g(2) = 4, then H(0) = 1/2
    2.0
    """

    kind = "hammerstein"

    def __init__(self, linear, nonlinearity: Nonlinearity, params, **kwargs):
        super().__init__(linear, input_nonlinearity=nonlinearity, input_params=params, **kwargs)
        if self.input_nonlinearity is None:
            raise ParameterError("a Hammerstein model needs a nonlinearity")

    @property
    def nonlinearity(self) -> Nonlinearity:
        return self.input_nonlinearity

    @property
    def params(self) -> np.ndarray:
        return self.input_params


class WienerModel(BlockModel):
    """``y = h(H(p) u) + offset``: the linear block followed by a static nonlinearity.

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> from hammerstein_ctrl import Saturation
    >>> m = WienerModel(ct.tf([1], [1, 1]), Saturation(), [2.0, 0.5])   # a sensor that clips at 1
    >>> float(m.simulate(np.arange(0, 10, 0.1), np.ones(100))[-1])
    1.0
    """

    kind = "wiener"

    def __init__(self, linear, nonlinearity: Nonlinearity, params, **kwargs):
        super().__init__(linear, output_nonlinearity=nonlinearity, output_params=params, **kwargs)
        if self.output_nonlinearity is None:
            raise ParameterError("a Wiener model needs a nonlinearity")

    @property
    def nonlinearity(self) -> Nonlinearity:
        return self.output_nonlinearity

    @property
    def params(self) -> np.ndarray:
        return self.output_params


class HammersteinWienerModel(BlockModel):
    """``y = h(H(p) g(u)) + offset``: input nonlinearity, linear block, output nonlinearity.

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> m = HammersteinWienerModel(([1.0], [1.0, 1.0]), hc.DeadZone(), [1.0, 0.5], hc.Saturation(), [1.0, 1.0])
    >>> y = m.simulate(np.arange(400) * 0.05, np.full(400, 3.0))
    >>> round(float(y[-1]), 4)                           # dead zone: 3 - 0.5, then saturated at 1
    1.0
    """

    kind = "hammerstein-wiener"

    def __init__(self, linear, input_nonlinearity: Nonlinearity, input_params,
                 output_nonlinearity: Nonlinearity, output_params, **kwargs):
        super().__init__(linear, input_nonlinearity=input_nonlinearity, input_params=input_params,
                         output_nonlinearity=output_nonlinearity, output_params=output_params, **kwargs)
        if self.input_nonlinearity is None or self.output_nonlinearity is None:
            raise ParameterError("a Hammerstein-Wiener model needs an input and an output nonlinearity")
