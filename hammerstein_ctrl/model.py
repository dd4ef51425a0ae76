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

from ._checks import as_signal
from .exceptions import ParameterError
from .nonlinearities import Nonlinearity

__all__ = ["HammersteinModel"]


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
    name : str, optional
        Name used for the interconnected system.

    Attributes
    ----------
    linear : control.TransferFunction
    nonlinearity : Nonlinearity
    params : ndarray
    """

    def __init__(self, linear, nonlinearity: Nonlinearity, params, *, name: str | None = None):
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
        self.name = name or "hammerstein"

    # -- evaluation -------------------------------------------------------------
    def g(self, u) -> np.ndarray:
        """Evaluate the static nonlinearity ``g(u)``."""
        return self.nonlinearity(u, self.params)

    def simulate(self, t, u=None) -> np.ndarray:
        """Simulate the model with the sampled (identification) semantics.

        Parameters
        ----------
        t : array_like or IOData
            Uniform time grid, or a record whose ``t`` and ``u`` are used.
        u : array_like, optional
            Input samples (required unless ``t`` is a record).

        Returns
        -------
        ndarray
            The output, equal to ``control.forced_response(H, t, g(u)).outputs``.
        """
        from .datasets import IOData
        from .simulate import simulate

        if isinstance(t, IOData):
            if u is not None:
                raise ParameterError("pass either a record or (t, u), not both")
            t, u = t.t, t.u
        elif u is None:
            raise ParameterError("simulate needs the input u (or an IOData record)")
        return simulate(self.linear, self.nonlinearity, self.params, t, u)

    # -- python-control interop -------------------------------------------------
    def to_iosys(self, name: str | None = None, *, inputs: str = "u", outputs: str = "y"):
        """The model as a :class:`control.NonlinearIOSystem` interconnection.

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

        params = self.params
        nonlinearity = self.nonlinearity

        def output(t, x, u, p):
            return nonlinearity(np.atleast_1d(u)[:1], params)

        g = control.nlsys(None, output, inputs=[inputs], outputs=["v"], name="g")
        lin = control.ss(self.linear, inputs="v", outputs=[outputs], name="H")
        return control.interconnect(
            [g, lin], inputs=[inputs], outputs=[outputs], name=name or self.name
        )

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
        return (
            f"HammersteinModel(linear={self._tf_string()}, "
            f"g={self.nonlinearity.describe(self.params)})"
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

    # -- python-control time responses (logic in display.py) ----------------------
    def response(self, data_or_t, u=None):
        """:meth:`simulate` as a ``control.TimeResponseData`` (:func:`hammerstein_ctrl.display.response`)."""
        from .display import response
        return response(self, data_or_t, u)
