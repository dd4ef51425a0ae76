"""Sampled PID loops around a Hammerstein plant: fast compiled simulation and its python-control twin.

The loop, sampled with interval ``dt`` (a digital controller driving the plant
through a DAC, so the plant input is held between samples), is at each
sample ``k``:

.. code-block:: text

    y[k]   = C x[k] + offset                    plant output (strictly proper H)
    e[k]   = r[k] - y[k]
    D[k]   = tf/(tf+dt) D[k-1] + kd/(tf+dt) (e[k] - e[k-1])   filtered derivative
    uc[k]  = kp e[k] + I[k] + D[k]              controller output
    u[k]   = clip(uc[k], lo, hi)                actuator limit
    I[k+1] = I[k] + dt (ki e[k] + kt (u[k] - uc[k]))          back-calculation anti-windup
    x[k+1] = Ad x[k] + Bd g(u[k])               exact ZOH step of the plant

(backward-difference derivative, forward-Euler integral, Åström and
Hägglund's computer implementation).  :func:`simulate_loops` runs a batch of
candidate gains through this recursion in compiled code;
:func:`sampled_loop_iosys` builds the same loop as a ``control.interconnect``
of a summing junction, the PID (:func:`discrete_pid_iosys`), an actuator
saturation block and the plant's exact ``to_iosys(dt)`` export, so that
``control.input_output_response`` checks the compiled path.

Examples
--------
>>> import numpy as np, control as ct
>>> from hammerstein_ctrl import HammersteinModel, Coulomb
>>> plant = HammersteinModel(ct.tf([1], [1, 3.14, 0]), Coulomb(), [0.54, -0.4, 0.045])
>>> r = np.full(500, 0.1); gains = [[20.0, 10.0, 5.0, 0.03]]
>>> Y, U = simulate_loops(plant, gains, r, 1e-3, u_limit=(-4.0, 4.0))
>>> loop = sampled_loop_iosys(plant, gains[0], 1e-3, u_limit=(-4.0, 4.0))
>>> y = ct.input_output_response(loop, np.arange(500) * 1e-3, r).outputs[0]
>>> bool(np.allclose(Y[0], y, rtol=1e-9, atol=1e-12))
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import _core
from ._export import model_settings, sampled_iosys, sampled_matrices
from ..exceptions import DataError, ParameterError

__all__ = ["simulate_loops", "simulate_controller_loop", "simulate_known_loop",
           "sampled_plant", "SampledPlant", "sampled_loop_iosys",
           "discrete_pid_iosys", "saturation_iosys", "back_calculation_gain", "check_limits", "IDENTITY"]

#: A simulated output beyond this multiple of the reference's size counts as diverged.
DIVERGENCE_RATIO = 1e6


def back_calculation_gain(kp: float, ki: float, kd: float) -> float:
    """``kt = 1/Tt`` with Åström and Hägglund's ``Tt = sqrt(Ti Td)`` (``Ti`` for a PI).

    Examples
    --------
    >>> back_calculation_gain(2.0, 1.0, 0.0)    # Ti = 2
    0.5
    >>> round(back_calculation_gain(2.0, 1.0, 0.5), 6)    # Ti = 2, Td = 0.25
    1.414214
    """
    if ki <= 0 or kp <= 0:
        return 0.0
    ti = kp / ki
    td = kd / kp
    return 1.0 / (math.sqrt(ti * td) if td > 0 else ti)


def check_limits(u_limit) -> tuple[float, float]:
    """``(lo, hi)`` of an actuator, ``(-inf, inf)`` for None; ``lo < hi`` required."""
    if u_limit is None:
        return -math.inf, math.inf
    try:
        lo, hi = (float(v) for v in u_limit)
    except (TypeError, ValueError):
        raise ParameterError(f"u_limit must be a pair (lo, hi), got {u_limit!r}") from None
    if math.isnan(lo) or math.isnan(hi) or not lo < hi:
        raise ParameterError(f"actuator limits need lo < hi, got lo = {lo!r}, hi = {hi!r}")
    return lo, hi


#: Code of "no static block" (the identity) in the compiled loops.
IDENTITY = -1
#: Code of a static block the compiled loops do not know (a custom map): the loop then runs in Python.
PYTHON_MAP = -2


def _block_arrays(nl, params):
    """``(code, params, breakpoints)`` of a static block for the compiled loops (``IDENTITY`` for none,
    ``PYTHON_MAP`` for a map without a compiled form)."""
    if nl is None:
        return IDENTITY, np.zeros(1), np.zeros(2)
    name = nl.compiled_map
    if name is None:
        return PYTHON_MAP, np.asarray(params, dtype=float).reshape(-1), np.zeros(2)
    return (_core.MAP_CODES[name], np.ascontiguousarray(params, dtype=float),
            np.ascontiguousarray(nl.map_extra(), dtype=float))


def _gain_table(gains) -> np.ndarray:
    """``(B, 5)`` rows ``kp, ki, kd, tf, kt`` (``kt`` defaulted by :func:`back_calculation_gain`)."""
    G = np.atleast_2d(np.asarray(gains, dtype=float))
    if G.ndim != 2 or G.shape[1] not in (4, 5):
        raise ParameterError(f"gains must be rows (kp, ki, kd, tf[, kt]), got shape {G.shape}")
    if G.shape[1] == 4:
        kt = [back_calculation_gain(*np.abs(row[:3])) for row in G]
        G = np.column_stack([G, kt])
    if np.any(G[:, 3] < 0) or not np.all(np.isfinite(G)):
        raise ParameterError("gains must be finite and the filter time constant tf >= 0")
    return np.ascontiguousarray(G)


@dataclass(frozen=True)
class SampledPlant:
    """The arrays of a plant's exact ZOH step, computed once for many loop simulations."""

    Ad: np.ndarray
    Bd: np.ndarray
    C: np.ndarray
    x0: np.ndarray
    offset: float
    code: int
    params: np.ndarray
    breakpoints: np.ndarray
    dt: float
    hcode: int = IDENTITY
    hparams: np.ndarray = field(default_factory=lambda: np.zeros(1))
    hbreakpoints: np.ndarray = field(default_factory=lambda: np.zeros(2))
    #: The static blocks themselves (``(u, params) -> array``), used where a code is ``PYTHON_MAP``.
    g_map: object = None
    h_map: object = None

    @property
    def compiled(self) -> bool:
        """Whether the compiled loops know both static blocks (else the loops run in Python)."""
        return PYTHON_MAP not in (self.code, self.hcode)

    def _apply(self, code, fun, params, v: float) -> float:
        if code == IDENTITY:
            return v
        return float(np.asarray(fun(np.array([v]), params), dtype=float).reshape(-1)[0])

    def output(self, x: np.ndarray) -> float:
        """``h(C x) + offset`` (the Python twin of the compiled plant's output)."""
        return self._apply(self.hcode, self.h_map, self.hparams, float(self.C @ x)) + self.offset

    def step(self, x: np.ndarray, u: float) -> np.ndarray:
        """``Ad x + Bd g(u)``."""
        return self.Ad @ x + self.Bd * self._apply(self.code, self.g_map, self.params, u)

    def __post_init__(self):
        n = np.shape(self.x0)[0] if np.ndim(self.x0) == 1 else -1
        shapes = {"Ad": (n, n), "Bd": (n,), "C": (n,), "x0": (n,)}
        wrong = [name for name, shape in shapes.items() if np.shape(getattr(self, name)) != shape]
        wrong += [name for name in ("params", "breakpoints", "hparams", "hbreakpoints")
                  if np.ndim(getattr(self, name)) != 1]
        if wrong or not 0 <= n <= _core.MAX_ORDER:
            raise ParameterError(f"a sampled plant needs Ad (n x n), Bd, C and x0 (n each, n <= {_core.MAX_ORDER}) "
                                 f"and its blocks' parameters as vectors; these do not fit: {', '.join(wrong) or 'n'}")
        for name in ("Ad", "Bd", "C", "x0", "params", "breakpoints", "hparams", "hbreakpoints"):
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype=float))

    def arrays(self) -> tuple:
        """The plant's arguments of the compiled loops (``hc_pid_loops``, ``hc_controller_loop``)."""
        return (self.Ad, self.Bd, self.C, self.x0, self.x0.size, float(self.offset), self.code, self.params,
                self.params.size, self.breakpoints, self.breakpoints.size, self.hcode, self.hparams,
                self.hparams.size, self.hbreakpoints, self.hbreakpoints.size)


def sampled_plant(model, dt: float, *, x0=None) -> SampledPlant:
    """Precompute the sampled plant of :func:`simulate_loops` (strictly proper linear block required).

    ``model`` is a Hammerstein, Wiener or Hammerstein-Wiener model with named
    nonlinearity families; ``x0`` overrides its initial state (e.g. an
    equilibrium: :func:`~hammerstein_ctrl.design.operating_point`).
    """
    if getattr(model, "delay", 0):
        raise ParameterError(f"the compiled loop simulator has no dead time (the model's is {model.delay:g} s): "
                             "pass model.without_delay() (a Pade approximant, as tune_pid does) or build the loop "
                             "with sampled_loop_iosys, whose plant carries the dead time exactly")
    Ad, B0, _, C, D = sampled_matrices(model, dt, "zoh")
    if D != 0.0:
        raise ParameterError("a sampled loop needs a strictly proper linear block (no direct feedthrough)")
    settings = model_settings(model)
    code, p, bp = _block_arrays(model.input_nonlinearity, model.input_params)
    hcode, hp, hbp = _block_arrays(model.output_nonlinearity, model.output_params)
    start = settings["initial_state"] if x0 is None else np.asarray(x0, dtype=float).reshape(-1)
    if start.shape != (Ad.shape[0],) or not np.all(np.isfinite(start)):
        raise ParameterError(f"x0 must be {Ad.shape[0]} finite numbers (the states of H), got {np.shape(x0)}")
    return SampledPlant(np.ascontiguousarray(Ad), np.ascontiguousarray(B0), np.ascontiguousarray(C),
                        np.ascontiguousarray(start, dtype=float), settings["offset"], code, p, bp, float(dt),
                        hcode, hp, hbp, model.input_nonlinearity, model.output_nonlinearity)


def _loop_inputs(model, r, dt, u_limit, x0):
    r = np.ascontiguousarray(r, dtype=float).reshape(-1)
    if r.size < 2 or not np.all(np.isfinite(r)):
        raise DataError(f"the reference needs at least two finite samples, got {r.size}")
    lo, hi = check_limits(u_limit)
    plant = model if isinstance(model, SampledPlant) else sampled_plant(model, dt, x0=x0)
    if plant.dt != float(dt):
        raise ParameterError(f"the sampled plant has dt = {plant.dt}, not {dt}")
    bound = DIVERGENCE_RATIO * max(1.0, float(np.max(np.abs(r))))
    return r, lo, hi, plant, bound


def _drive(plant: SampledPlant, x, y: float, uc: float, lo: float, hi: float, bound: float, k: int, Y, U):
    """The compiled ``Plant::drive`` in Python: record ``y`` and ``u = clip(uc)``, then step (``None`` once the
    output passed ``bound``: the rest of the record cut to ``inf``/``NaN``)."""
    u = min(max(uc, lo), hi) if not math.isnan(uc) else uc
    Y[k], U[k] = y, u
    if not abs(y) <= bound:
        Y[k + 1:], U[k + 1:] = np.inf, np.nan
        return None, u
    return plant.step(x, u), u


def _pid_loop_in_python(plant: SampledPlant, gains, r, dt, lo, hi, bias, bound, Y, U) -> None:
    """The recursion of the module notes for a plant with a map the compiled loops do not know (numpy's speed)."""
    kp, ki, kd, tf, kt = gains
    ad, bd = tf / (tf + dt), kd / (tf + dt)
    x, integ, deriv, ep = plant.x0.copy(), bias, 0.0, 0.0
    for k in range(r.size):
        y = plant.output(x)
        e = r[k] - y
        deriv = ad * deriv + bd * (e - ep)
        uc = kp * e + integ + deriv
        x, u = _drive(plant, x, y, uc, lo, hi, bound, k, Y, U)
        if x is None:
            return
        integ += dt * (ki * e + kt * (u - uc))
        ep = e


def _controller_loop_in_python(plant: SampledPlant, controller, r, lo, hi, bias, bound, Y, U) -> None:
    """:func:`simulate_controller_loop`'s recursion in Python (a map the compiled loops do not know)."""
    Ac, Bc, Cc, Dc = controller
    x, xc = plant.x0.copy(), np.zeros(Ac.shape[0])
    for k in range(r.size):
        y = plant.output(x)
        e = r[k] - y
        x, _ = _drive(plant, x, y, bias + Dc * e + float(Cc @ xc), lo, hi, bound, k, Y, U)
        if x is None:
            return
        xc = Ac @ xc + Bc * e


def simulate_loops(model, gains, r, dt: float, *, u_limit=None, bias: float = 0.0, x0=None):
    """Simulate the sampled loop for a batch of PID gains (compiled, exact recursion).

    Parameters
    ----------
    model : BlockModel or SampledPlant
        The plant (strictly proper linear block), or its precomputed
        :func:`sampled_plant` at ``dt``.  A map without a compiled form (a
        :class:`~hammerstein_ctrl.blocks.CustomNonlinearity`) runs
        the same recursion in Python, at numpy's speed.
    gains : array_like, shape (B, 4) or (B, 5)
        Rows ``kp, ki, kd, tf`` and optionally the back-calculation gain ``kt``.
    r : array_like, shape (N,)
        Reference samples, ``N >= 2``.
    dt : float
        Sampling interval.
    u_limit : (lo, hi), optional
        Actuator limits.
    bias : float, default 0
        The integral's start: the controller's output before any error (the
        operating point's input, for a bumpless start there).
    x0 : array_like, optional
        The plant's start state (default the model's own; ignored for a ``SampledPlant``).

    Returns
    -------
    Y, U : ndarray, shape (B, N)
        Plant outputs and actuator outputs; a diverging run (output beyond
        ``DIVERGENCE_RATIO`` times the reference's size) is cut short with
        ``Y = inf`` and ``U = nan`` from then on.
    """
    r, lo, hi, plant, bound = _loop_inputs(model, r, dt, u_limit, x0)
    G = _gain_table(gains)
    Y = np.empty((G.shape[0], r.size))
    U = np.empty_like(Y)
    if not plant.compiled:
        for b, (kp, ki, kd, tf, kt) in enumerate(G):
            _pid_loop_in_python(plant, (kp, ki, kd, tf, kt), r, float(dt), lo, hi, float(bias), bound, Y[b], U[b])
        return Y, U
    if _core.hc_pid_loops(*plant.arrays(), G, G.shape[0], r, r.size, float(dt), lo, hi, float(bias), bound, Y, U):
        raise ParameterError(f"the compiled loop simulator takes plants of order up to {_core.MAX_ORDER} with "
                             "static blocks that fit their families")
    return Y, U


def simulate_controller_loop(model, controller, r, dt: float, *, u_limit=None, bias: float = 0.0, x0=None):
    """Simulate the sampled loop with a linear discrete controller (``e -> u``), compiled.

    ``u[k] = clip(bias + C_c(q) e[k], lo, hi)`` with ``C_c`` a discrete
    python-control system of sampling interval ``dt`` (single input and
    output, from rest); the plant as in :func:`simulate_loops`.  Equals
    ``control.input_output_response`` of the same loop built by hand around
    ``model.to_iosys(dt, intersample="zoh")``.

    Returns
    -------
    y, u : ndarray, shape (N,)
    """
    import control

    sys = control.ss(controller)
    if sys.ninputs != 1 or sys.noutputs != 1 or not sys.isdtime() or not np.isclose(sys.dt, dt, rtol=1e-12):
        raise ParameterError(f"the controller must be a SISO discrete-time system with dt = {dt}")
    r, lo, hi, plant, bound = _loop_inputs(model, r, dt, u_limit, x0)
    A, B, C, D = (np.ascontiguousarray(np.asarray(M, dtype=float)) for M in (sys.A, sys.B, sys.C, sys.D))
    Y = np.empty((1, r.size))
    U = np.empty_like(Y)
    if not plant.compiled:
        _controller_loop_in_python(plant, (A, B[:, 0], C[0], float(D[0, 0])), r, lo, hi, float(bias), bound, Y[0],
                                   U[0])
        return Y[0], U[0]
    status = _core.hc_controller_loop(*plant.arrays(), A, B[:, 0].copy(), C[0].copy(), float(D[0, 0]), A.shape[0],
                                      r, r.size, lo, hi, float(bias), bound, Y, U)
    if status:
        raise (MemoryError("no memory for the controller's state") if status == 2 else ParameterError(
            f"the compiled loop simulator takes plants of order up to {_core.MAX_ORDER} with static blocks that fit "
            "their families"))
    return Y[0], U[0]


def simulate_known_loop(plant: SampledPlant, controller, reference, added, *, initial_state=None):
    """``(y, u)`` of the loop ``u[k] = d[k] + Dc [r[k], y[k]] + Cc xc[k]``, ``xc[k+1] = Ac xc[k] + Bc [r[k], y[k]]``
    around ``plant`` (no actuator limit), compiled; a map without a compiled form runs it in Python.

    ``controller`` is ``(Ac, Bc, Cc, Dc)`` with ``Bc`` of shape ``(nc, 2)`` and ``Dc`` two numbers (acting on
    ``[r, y]``), ``initial_state`` its state at the first sample (zeros by default).  A diverging run is cut
    short as in :func:`simulate_loops`.
    """
    Ac, Bc, Cc, Dc = (np.ascontiguousarray(np.asarray(M, dtype=float)) for M in controller)
    nc = Ac.shape[0]
    if Ac.shape != (nc, nc) or Bc.shape != (nc, 2) or Cc.shape != (nc,) or Dc.shape != (2,):
        raise ParameterError(f"the controller's matrices do not fit one another: Ac {Ac.shape}, Bc {Bc.shape} "
                             f"(nc x 2), Cc {Cc.shape}, Dc {Dc.shape} (2)")
    r, d = (np.ascontiguousarray(v, dtype=float).reshape(-1) for v in (reference, added))
    xc0 = np.zeros(nc) if initial_state is None else np.ascontiguousarray(initial_state, dtype=float).reshape(-1)
    if d.size != r.size or xc0.shape != (nc,):
        raise ParameterError(f"the added signal must have the reference's {r.size} samples and the initial state "
                             f"the controller's {nc} states; got {d.size} and {xc0.size}")
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(d)) and np.all(np.isfinite(xc0))
            and all(np.all(np.isfinite(M)) for M in (Ac, Bc, Cc, Dc))):
        raise ParameterError("the reference, the added signal, the controller and its initial state must be finite")
    bound = DIVERGENCE_RATIO * max(1.0, float(np.max(np.abs(r))))
    Y, U = np.empty(r.size), np.empty(r.size)
    if not plant.compiled:
        x, xc = plant.x0.copy(), xc0.copy()
        for k in range(r.size):
            y = plant.output(x)
            x, _ = _drive(plant, x, y, d[k] + Dc[0] * r[k] + Dc[1] * y + float(Cc @ xc), -math.inf, math.inf,
                          bound, k, Y, U)
            if x is None:
                break
            xc = Ac @ xc + Bc @ np.array([r[k], y])
        return Y, U
    status = _core.hc_known_loop(*plant.arrays(), Ac, Bc, Cc, Dc, nc, xc0, r, d, r.size, bound, Y, U)
    if status:
        raise (MemoryError("no memory for the controller's state") if status == 2 else ParameterError(
            f"the compiled loop simulator takes plants of order up to {_core.MAX_ORDER} with static blocks that fit "
            "their families"))
    return Y, U


def discrete_pid_iosys(gains, dt: float, *, bias: float = 0.0, name: str = "pid"):
    """The sampled PID with back-calculation as a discrete :class:`control.NonlinearIOSystem`.

    Inputs ``e`` (error) and ``u`` (the actuator's actual output, for the
    anti-windup), output ``uc`` (``bias`` added: the operating point's
    input); states ``I`` (integral), ``D`` (filtered derivative) and
    ``e_prev``.  The recursion is the module's.
    """
    import control

    kp, ki, kd, tf, kt = _gain_table(gains)[0]
    ad, bd = tf / (tf + dt), kd / (tf + dt)

    def parts(x, e):
        deriv = ad * x[1] + bd * (e - x[2])
        return deriv, kp * e + x[0] + deriv + bias

    def update(t, x, u, p):
        e, act = u[0], u[1]
        deriv, uc = parts(x, e)
        return np.array([x[0] + dt * (ki * e + kt * (act - uc)), deriv, e])

    def output(t, x, u, p):
        return np.array([parts(x, u[0])[1]])

    return control.nlsys(update, output, inputs=["e", "u"], outputs=["uc"], states=["I", "D", "e_prev"],
                         dt=dt, name=name)


def saturation_iosys(u_limit, *, dt=None, name: str = "actuator"):
    """Static actuator limit ``u = clip(uc, lo, hi)`` as a :class:`control.NonlinearIOSystem`."""
    import control

    lo, hi = check_limits(u_limit)
    return control.nlsys(None, lambda t, x, u, p: np.clip(u[:1], lo, hi), inputs=["uc"], outputs=["u"],
                         dt=dt, name=name)


def sampled_loop_iosys(model, gains, dt: float, *, u_limit=None, bias: float = 0.0, name: str = "loop"):
    """The sampled loop as a ``control.interconnect`` (input ``r``; outputs ``y``, ``u``).

    Simulated with ``control.input_output_response`` on a grid of step ``dt``
    it equals :func:`simulate_loops` for the same gains and ``bias`` (and the
    model's initial state).
    """
    import control

    sampled_plant(model, dt)  # same checks as the compiled path
    plant = sampled_iosys(model, dt, intersample="zoh", name="plant", inputs="u", outputs="y")
    err = control.summing_junction(inputs=["r", "-y"], output="e", dt=dt, name="error")
    return control.interconnect(
        [err, discrete_pid_iosys(gains, dt, bias=bias), saturation_iosys(u_limit, dt=dt), plant],
        inputs=["r"], outputs=["y", "u"], dt=dt, name=name)
