"""Exact python-control exports of a Hammerstein model.

Two python-control views of an identified model exist besides the model itself:

* :func:`linear_ss` gives the linear block ``H`` as a :class:`control.StateSpace`
  in the controllable canonical realisation that the package's simulator uses
  (:func:`hammerstein_ctrl.simulate.companion_realization`), so an initial
  state means the same thing in ``model.simulate``, in ``control.forced_response``
  on this system and in the exports below.
* :func:`sampled_iosys` gives a *discrete-time* :class:`control.NonlinearIOSystem`
  whose update is the exact sampled recursion of the model (first- or
  zero-order hold of ``v = g(u)`` between samples), so
  ``control.input_output_response(sys, t, u).outputs`` equals
  ``model.simulate(t, u)`` to rounding and the system can be interconnected with
  discrete-time controllers.  Use it for anything that must reproduce the
  identified model sample for sample (closed-loop tuning, digital control).
  The continuous-time ``model.to_iosys()`` integrates ``g(u(t))`` with an ODE
  solver instead: use it for continuous-time analysis, linearisation and
  loops with continuous-time controllers, knowing that it differs slightly
  from the sampled model (most with a discontinuous ``g`` such as ``sign``).

How the first-order hold is made causal
---------------------------------------
The FOH recursion ``x[k] = Ad x[k-1] + Bd0 v[k-1] + Bd1 v[k]`` needs the
*current* input to form the state.  The exported system therefore carries
``z[k] = x[k] - Bd1 v[k]``, whose update ``z[k+1] = Ad x[k] + Bd0 v[k]`` is
causal, and recovers ``x[k] = z[k] + Bd1 v[k]`` in the output.  At the first
sample ``x[0]`` is the model's initial state whatever ``v[0]`` is, so a last
state ``started`` (0 at ``k = 0``, 1 afterwards) switches the output map: with
``started = 0`` the state is ``x[0] = initial_state + z[0]``.  The default
initial condition of ``control.input_output_response`` (all zeros) thus
reproduces the model's own initial state; pass ``X0 = [x0_extra..., 0]`` to
start elsewhere.  With zero-order hold ``Bd1 = 0`` and the same code applies.

Examples
--------
>>> import numpy as np, control as ct
>>> from hammerstein_ctrl import HammersteinModel, Tanh
>>> m = HammersteinModel(ct.tf([1, -1.816], [1, 4.7681, 0.118]), Tanh(), [-4.7132, 0.1229])
>>> t = np.arange(0, 20, 0.1); u = np.sin(0.3 * t)
>>> sys = sampled_iosys(m, 0.1)
>>> y = ct.input_output_response(sys, t, u).outputs
>>> bool(np.allclose(y, m.simulate(t, u), rtol=1e-12, atol=1e-12))
True
"""

from __future__ import annotations

import numpy as np

from .._checks import require_siso_model
from .._checks import check_dt, check_intersample
from ..exceptions import DataError, ParameterError
from ._simulate import companion_realization, discretize

__all__ = ["linear_ss", "sampled_matrices", "sampled_iosys", "model_settings"]

#: Intersample behaviours of the model's input.
def model_settings(model) -> dict:
    """The model's ``offset``, ``initial_state`` (zeros when at rest) and ``intersample``.

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Coulomb
    >>> m = HammersteinModel(ct.tf([1], [1, 3.0, 0]), Coulomb(), [0.5, -0.4, 0.05])
    >>> s = model_settings(m)
    >>> s["offset"], s["initial_state"].tolist(), s["intersample"]
    (0.0, [0.0, 0.0], 'foh')
    """
    model = require_siso_model(model, "model_settings")
    return {"offset": model.offset, "initial_state": model.state0(), "intersample": model.intersample}


def _num_den(model):
    num = np.trim_zeros(np.asarray(model.linear.num[0][0], dtype=float), "f")
    den = np.trim_zeros(np.asarray(model.linear.den[0][0], dtype=float), "f")
    return (num if num.size else np.zeros(1)), den


def linear_ss(model, *, inputs: str = "v", outputs: str = "y", name: str | None = None):
    """The linear block as a :class:`control.StateSpace` in the simulator's realisation.

    The controllable canonical form of
    :func:`hammerstein_ctrl.simulate.companion_realization`: the state ``x`` of
    this system is the state that ``initial_state`` refers to.  The output
    offset is not part of the linear block.

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Coulomb
    >>> m = HammersteinModel(ct.tf([1], [1, 3.0, 0]), Coulomb(), [0.5, -0.4, 0.05])
    >>> linear_ss(m).A
    array([[-3., -0.],
           [ 1.,  0.]])
    """
    model = require_siso_model(model, "linear_ss")
    import control

    A, B, C, D = companion_realization(*_num_den(model))
    n = A.shape[1]
    return control.ss(A[0], B[0].reshape(n, 1), C[0].reshape(1, n), D[:1].reshape(1, 1),
                      inputs=inputs, outputs=outputs, name=name or "H")


def sampled_matrices(model, dt: float, intersample: str | None = None):
    """``(Ad, B0, B1, C, D)`` of the exact sampled recursion of the linear block.

    ``x[k] = Ad x[k-1] + B0 v[k-1] + B1 v[k]``, ``y[k] = C x[k] + D v[k]``; for
    zero-order hold ``B1 = 0`` and ``B0`` is the ZOH input matrix.

    Parameters
    ----------
    model : HammersteinModel
    dt : float
        Sampling interval (> 0).
    intersample : {"foh", "zoh"}, optional
        Overrides the model's own setting.

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Coulomb
    >>> m = HammersteinModel(ct.tf([1], [1, 0]), Coulomb(), [1.0, 0.0, 0.0])
    >>> [float(M.ravel()[0]) for M in sampled_matrices(m, 0.5)[:3]]
    [1.0, 0.25, 0.25]
    >>> [float(M.ravel()[0]) for M in sampled_matrices(m, 0.5, "zoh")[:3]]
    [1.0, 0.5, 0.0]
    """
    model = require_siso_model(model, "sampled_matrices")
    dt = _check_dt(dt)
    mode = model_settings(model)["intersample"] if intersample is None else intersample
    try:
        mode = check_intersample(mode)
    except DataError as exc:
        raise ParameterError(str(exc)) from None
    A, B, C, D = companion_realization(*_num_den(model))
    Ad, Bd0, Bd1 = discretize(A, B, dt, mode)
    return Ad[0], Bd0[0], Bd1[0], C[0], float(D[0])


def _check_dt(dt) -> float:
    return check_dt(dt, error=ParameterError)


def sampled_iosys(model, dt: float, *, intersample: str | None = None, name: str | None = None,
                  inputs: str = "u", outputs: str = "y"):
    """The model as an exact discrete-time :class:`control.NonlinearIOSystem`.

    ``control.input_output_response(sys, t, u)`` on a grid of step ``dt``
    equals ``model.simulate(t, u)`` (same hold, offset and initial state) to
    rounding.  States: ``z[0..n-1]`` (see the module notes) and ``started``.

    Parameters
    ----------
    model : BlockModel
        A Hammerstein, Wiener or Hammerstein-Wiener model.
    dt : float
        Sampling interval of the system (the grid it must be simulated on).
    intersample : {"foh", "zoh"}, optional
        Overrides the model's own setting (e.g. ``"zoh"`` for a plant driven by
        a digital controller through a DAC).
    name, inputs, outputs : str, optional
        Labels of the system and its signals.

    Returns
    -------
    control.NonlinearIOSystem
        With a dead time the states also hold the last ``d + 1`` samples of
        ``g(u)`` (``d`` whole samples of delay), named ``v[k-1]``, ...,
        before ``started``; the delay is exact, fraction of a sample included.
    """
    model = require_siso_model(model, "sampled_iosys")
    import control

    if getattr(model, "delay", 0):
        return _delayed_iosys(model, _check_dt(dt), intersample, name=name, inputs=inputs, outputs=outputs)
    Ad, B0, B1, C, D = sampled_matrices(model, dt, intersample)
    settings = model_settings(model)
    x0, offset = settings["initial_state"], settings["offset"]
    n = Ad.shape[0]
    g, h = model.g, model.h  # input and output nonlinearities (identity where absent)

    def state(z, v):
        # x[k] from z[k]; at the first sample (started = 0) x[0] = initial_state + z[0]
        return z[:n] + (B1 * v if z[n] else x0)

    def update(t, z, u, p):
        v = float(g(np.atleast_1d(u)[:1])[0])
        out = np.empty(n + 1)
        out[:n] = Ad @ state(z, v) + B0 * v
        out[n] = 1.0
        return out

    def output(t, z, u, p):
        v = float(g(np.atleast_1d(u)[:1])[0])
        return np.array([float(h(np.array([C @ state(z, v) + D * v]))[0]) + offset])

    return control.nlsys(update, output, inputs=[inputs], outputs=[outputs],
                         states=[f"z[{i}]" for i in range(n)] + ["started"], dt=dt,
                         name=name or getattr(model, "name", None) or "hammerstein")


#: Most samples of dead time the exact discrete export holds as states.
MAX_DELAY_STATES = 100_000


def _delayed_iosys(model, dt: float, intersample, *, name, inputs, outputs):
    """:func:`sampled_iosys` of a model with a dead time (:func:`~hammerstein_ctrl.simulate._delay.delay_matrices`)."""
    import control

    from ._delay import delay_matrices, delayed_values

    settings = model_settings(model)
    mode = settings["intersample"] if intersample is None else intersample
    try:
        mode = check_intersample(mode)
    except DataError as exc:
        raise ParameterError(str(exc)) from None
    if model.delay / dt > MAX_DELAY_STATES:
        raise ParameterError(f"a dead time of {model.delay:g} s is {model.delay / dt:.3g} samples of {dt:g} s: the "
                             f"exact discrete system would need that many states (at most {MAX_DELAY_STATES}); use a "
                             "longer dt, or model.to_iosys() with its Pade approximant")
    M, Pa, Pb, Pc, C, D, d, a = delay_matrices(*_num_den(model), dt, model.delay, mode)
    x0, offset = settings["initial_state"], settings["offset"]
    n, L = M.shape[0], d + 1
    g, h = model.g, model.h

    def inputs_now(z, u):
        """``(v, past, w0, w1)``: ``g(u)``, the last ``d + 1`` samples of it (zero before the record) and the
        delayed input now and ``a dt`` later."""
        v = float(g(np.atleast_1d(u)[:1])[0])
        past = z[n:n + L] if z[n + L] else np.zeros(L)
        s = np.concatenate(([v], past))                # s[i] = v[k - i], i = 0 .. d + 1
        return (v, past, *delayed_values(s[d], s[d + 1], a, mode))

    def state(z, w0):
        return z[:n] + (Pc * w0 if z[n + L] else x0)

    def update(t, z, u, p):
        v, past, w0, w1 = inputs_now(z, u)
        out = np.empty(n + L + 1)
        out[:n] = M @ state(z, w0) + Pa * w0 + Pb * w1
        out[n] = v
        out[n + 1:n + L] = past[:L - 1]
        out[n + L] = 1.0
        return out

    def output(t, z, u, p):
        _, _, w0, _ = inputs_now(z, u)
        return np.array([float(h(np.array([C @ state(z, w0) + D * w0]))[0]) + offset])

    return control.nlsys(update, output, inputs=[inputs], outputs=[outputs],
                         states=[f"z[{i}]" for i in range(n)] + [f"v[k-{i}]" for i in range(1, L + 1)] + ["started"],
                         dt=dt, name=name or getattr(model, "name", None) or "hammerstein")
