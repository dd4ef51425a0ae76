"""The Hammerstein model: a static nonlinearity followed by an LTI block.

Two views of the same model exist on purpose:

* :meth:`HammersteinModel.simulate` uses the *sampled* semantics the paper's
  numbers depend on: ``g`` is applied to the input samples and ``g(u)`` is
  interpolated linearly between samples (exactly
  ``control.forced_response(H, t, g(u))``).  This is what identification uses.
* :meth:`HammersteinModel.to_iosys` returns a :class:`control.NonlinearIOSystem`
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

from ._checks import as_signal, check_intersample
from .exceptions import ParameterError
from .nonlinearities import Nonlinearity

__all__ = ["HammersteinModel"]


def _finite_scalar(value, label: str) -> float:
    try:
        v = float(value)
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


class HammersteinModel:
    """``y = H(p) g(u)`` with ``H`` a :class:`control.TransferFunction`.

    Parameters
    ----------
    linear : control.TransferFunction or control.StateSpace
        Continuous-time SISO linear block ``H(p)`` (state-space blocks are
        converted to a transfer function).
    nonlinearity : Nonlinearity
        The static nonlinearity family.
    params : array_like
        Parameters of the nonlinearity.
    offset : float, default 0
        Constant added to the output: ``y = H(p) g(u) + offset``.
    initial_state : array_like, optional
        State ``x(0)`` of ``H``'s controllable canonical realisation
        (:func:`~hammerstein_ctrl.simulate.companion_realization`, the one
        :meth:`to_ss` returns); default: at rest.
    intersample : {"foh", "zoh"}, default "foh"
        Default intersample behaviour of the input in :meth:`simulate` when it
        is given ``(t, u)`` arrays; a record's own ``intersample`` wins.
    name : str, optional
        Name used for the interconnected system.

    Attributes
    ----------
    linear : control.TransferFunction
    nonlinearity : Nonlinearity
    params : ndarray
    offset : float
    initial_state : ndarray or None
    intersample : str
    """

    def __init__(self, linear, nonlinearity: Nonlinearity, params, *, offset: float = 0.0,
                 initial_state=None, intersample: str = "foh", name: str | None = None):
        import control

        if isinstance(linear, control.StateSpace):
            linear = control.ss2tf(linear)
        if not isinstance(linear, control.TransferFunction):
            raise ParameterError(
                f"linear must be a control.TransferFunction, got {type(linear).__name__}"
            )
        if linear.ninputs != 1 or linear.noutputs != 1:
            raise ParameterError("the linear block must be SISO")
        if linear.isdtime(strict=True):
            raise ParameterError("the linear block must be continuous-time (dt=0)")
        num, den = np.trim_zeros(linear.num[0][0], "f"), np.trim_zeros(linear.den[0][0], "f")
        if num.size > den.size:
            raise ParameterError("the linear block must be proper (numerator degree <= denominator degree)")
        if not isinstance(nonlinearity, Nonlinearity):
            raise ParameterError(
                f"nonlinearity must be a Nonlinearity, got {type(nonlinearity).__name__}"
            )
        p = nonlinearity.check_params(params)
        if p.ndim != 1:
            raise ParameterError("a model takes one parameter vector for its nonlinearity")
        if not np.all(np.isfinite(p)):
            raise ParameterError(f"nonlinearity parameters must be finite, got {p.tolist()}")
        self.linear = linear
        self.nonlinearity = nonlinearity
        self.params = p.copy()
        self.params.setflags(write=False)
        self.offset = _finite_scalar(offset, "offset")
        self.initial_state = _state_vector(initial_state, den.size - 1)
        self.intersample = check_intersample(intersample)
        self.name = name or "hammerstein"

    @property
    def order(self) -> int:
        """Number of states of the linear block."""
        return np.trim_zeros(np.asarray(self.linear.den[0][0], dtype=float), "f").size - 1

    def state0(self) -> np.ndarray:
        """The initial state ``x(0)`` (zeros when the model starts at rest)."""
        return np.zeros(self.order) if self.initial_state is None else self.initial_state.copy()

    # -- evaluation -------------------------------------------------------------
    def g(self, u) -> np.ndarray:
        """Evaluate the static nonlinearity ``g(u)``."""
        return self.nonlinearity(u, self.params)

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
            The output; at rest, with first-order hold and no offset it equals
            ``control.forced_response(H, t, g(u)).outputs``.
        """
        from .datasets import IOData
        from .simulate import simulate

        hold = self.intersample
        if isinstance(t, IOData):
            if u is not None:
                raise ParameterError("pass either a record or (t, u), not both")
            t, u, hold = t.t, t.u, t.intersample
        elif u is None:
            raise ParameterError("simulate needs the input u (or an IOData record)")
        x0 = self.initial_state if initial_state is None else _state_vector(initial_state, self.order)
        return simulate(self.linear, self.nonlinearity, self.params, t, u, x0=x0, offset=self.offset,
                        intersample=hold if intersample is None else intersample)

    # -- python-control interop -------------------------------------------------
    def to_iosys(self, name: str | None = None, *, dt: float | None = None, inputs: str = "u",
                 outputs: str = "y"):
        """The model as a :class:`control.NonlinearIOSystem` interconnection.

        With ``dt`` given, the exact discrete-time system of
        :func:`hammerstein_ctrl.exact_export.sampled_iosys` instead (its
        ``control.input_output_response`` equals :meth:`simulate`).

        The static block ``g`` (``control.nlsys`` without states, output
        ``"v"``) feeds ``H`` (``control.ss``); the result has input ``inputs``
        and output ``outputs`` and can be wired into other python-control
        systems, e.g. a feedback loop with a controller.

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

        if dt is not None:
            from .exact_export import sampled_iosys

            return sampled_iosys(self, dt, name=name, inputs=inputs, outputs=outputs)
        params = self.params
        nonlinearity = self.nonlinearity

        def output(t, x, u, p):
            return nonlinearity(np.atleast_1d(u)[:1], params)

        g = control.nlsys(None, output, inputs=[inputs], outputs=["v"], name="g")
        blocks = [g]
        if self.offset:
            offset = self.offset
            lin = self.to_ss(inputs="v", outputs="z", name="H")
            blocks += [lin, control.nlsys(None, lambda t, x, u, p: np.atleast_1d(u)[:1] + offset,
                                          inputs=["z"], outputs=[outputs], name="offset")]
        else:
            blocks.append(self.to_ss(inputs="v", outputs=[outputs], name="H"))
        return control.interconnect(blocks, inputs=[inputs], outputs=[outputs], name=name or self.name)

    def linearize(self, u0: float = 0.0):
        """Small-signal transfer function ``g'(u0) H(p)`` around the input ``u0``.

        Returns
        -------
        control.TransferFunction
        """
        u0 = float(as_signal(u0, "u0")[0])
        gain = float(np.asarray(self.nonlinearity.derivative(np.array([u0]), self.params))[0])
        return gain * self.linear

    # -- properties -------------------------------------------------------------
    def poles(self) -> np.ndarray:
        """Poles of the linear block."""
        return np.asarray(self.linear.poles())

    def is_stable(self) -> bool:
        """Whether every pole has a strictly negative real part."""
        return bool(np.all(self.poles().real < 0))

    def __repr__(self):
        extra = (f", offset={self.offset:.6g}" if self.offset else "") + (
            ", x(0) set" if self.initial_state is not None and np.any(self.initial_state) else "") + (
            ", zoh" if self.intersample == "zoh" else "")
        return (
            f"HammersteinModel(linear={self._tf_string()}, "
            f"g={self.nonlinearity.describe(self.params)}{extra})"
        )

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

        return f"({poly(self.linear.num[0][0])})/({poly(self.linear.den[0][0])})"

    # -- persistence and exact exports (issue 9) -----------------------------
    def save(self, path) -> None:
        """Write the model to ``path`` as versioned JSON (:func:`hammerstein_ctrl.load_model` reads it)."""
        from .persistence import save_model

        save_model(self, path)

    def to_ss(self, **kwargs):
        """The linear block as a :class:`control.StateSpace` in the simulator's realisation.

        See :func:`hammerstein_ctrl.exact_export.linear_ss`; ``initial_state``
        is a state of this system.
        """
        from .exact_export import linear_ss

        return linear_ss(self, **kwargs)

    # -- python-control time responses (logic in display.py) ----------------------
    def response(self, data_or_t, u=None):
        """:meth:`simulate` as a ``control.TimeResponseData`` (:func:`hammerstein_ctrl.display.response`)."""
        from .display import response
        return response(self, data_or_t, u)
