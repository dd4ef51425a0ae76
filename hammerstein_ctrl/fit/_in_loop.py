"""Identification inside a known control loop: fit the plant by simulating the closed loop the record came from.

A record taken in closed loop (the EMPS: the motor force is a position
controller's output) carries little information about the plant in its
open-loop output error: the controller keeps the position near the
reference, so drift dominates.  With the controller known (its sampled
implementation as a python-control system) and the reference recorded,
:func:`identify_in_loop` simulates the loop from the reference for each
candidate plant and matches the measured output, the measured control
signal, or both, each weighted.

.. code-block:: text

    y_k = plant output at t_k
    u_k = K(r, y)_k + d_k          the controller (sampled, discrete-time) plus a known added signal d
    the plant holds u_k over the sample (a DAC)

The plant is a :class:`~hammerstein_ctrl.blocks.LureStructure` (friction in
feedback, simulated exactly through stick-slip) or a block structure
(Hammerstein, Wiener, Hammerstein-Wiener; strictly proper, no dead time),
whose sampled step under the held input is exact
(:func:`~hammerstein_ctrl.simulate.simulate_known_loop`, compiled).  The
residual tests of an open-loop fit assume the input does not depend on
past outputs; a fit inside a loop is judged by its loop fits and its
parameters' uncertainty instead.

Examples
--------
>>> import numpy as np, control as ct, hammerstein_ctrl as hc
>>> from hammerstein_ctrl.blocks import lure_structure
>>> dt = 0.01; r = np.full(3000, 0.5)                                      # a set point of 0.5
>>> loop = KnownLoop(ct.ss([[1.0]], [[dt]], [[2.0]], [[8.0]], dt), r)     # a PI on the error r - y
>>> y, u = loop.simulate(lure_structure().model([0.4, 2.0, 0.3, 0.02]))  # a mass with friction
>>> round(float(y[-1]), 3)                                                # the integral action reaches it
0.5
"""

from __future__ import annotations

import time

import numpy as np

from .._deprecation import renamed
from .._checks import as_real_array
from ..simulate._lure_sim import lure_loop_run
from ..exceptions import DataError, ParameterError
from ..simulate._loop import sampled_plant, simulate_known_loop
from ..blocks._lure import LoopParts, LureModel, LureStructure, sign_map
from ..blocks._model import BlockModel
from ..optimize._normal_equations import NONFINITE_RESIDUAL
from ..blocks._structure import BlockStructure
from ._cost import StructureSized

__all__ = ["KnownLoop", "KnownLoopCost", "identify_in_loop", "MATCHES"]

#: The signals a loop fit can match.
MATCHES = ("output", "input", "both")


def _controller_matrices(controller, dt: float):
    """``(Ac, Bc, Cc, Dc)`` with ``Bc, Dc`` acting on ``[r, y]``, from a discrete python-control system."""
    import control as ct

    if not isinstance(controller, (ct.StateSpace, ct.TransferFunction)):
        raise ParameterError(f"controller must be a discrete-time control.StateSpace or TransferFunction, got "
                             f"{type(controller).__name__}")
    if not controller.isdtime(strict=True) or controller.dt is True:
        raise ParameterError("controller must be discrete-time (its sampled implementation) with dt set to the "
                             "record's sampling interval")
    if not np.isclose(float(controller.dt), dt, rtol=1e-9, atol=0.0):
        raise ParameterError(f"controller.dt = {controller.dt} differs from the record's dt = {dt}")
    if controller.noutputs != 1 or controller.ninputs not in (1, 2):
        raise ParameterError(f"controller must have one output (the control signal) and one input (the error "
                             f"r - y) or two (r, y); got {controller.ninputs} input(s), {controller.noutputs} "
                             f"output(s)")
    try:
        sys = ct.ss(controller)
    except ValueError as exc:
        raise ParameterError(f"controller cannot be realised as a state space ({exc}): is it improper?") from None
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    if not all(np.all(np.isfinite(m)) for m in (A, B, C, D)):
        raise ParameterError("controller has non-finite coefficients")
    if controller.ninputs == 1:                          # acts on e = r - y
        B, D = np.hstack([B, -B]), np.hstack([D, -D])
    if A.size == 0:
        A, B, C = np.zeros((1, 1)), np.zeros((1, 2)), np.zeros((1, 1))
    return (np.ascontiguousarray(A), np.ascontiguousarray(B), np.ascontiguousarray(C.reshape(-1)),
            np.ascontiguousarray(D.reshape(-1)))


def _signal(value, name: str) -> np.ndarray:
    """A finite 1-D signal of at least two samples (a column is taken as one)."""
    x = as_real_array(value, name)
    if x.ndim == 2 and 1 in x.shape:
        x = x.reshape(-1)
    if x.ndim != 1 or x.size < 2:
        raise DataError(f"{name} must be one signal of at least 2 samples, got an array of shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise DataError(f"{name} has non-finite samples")
    return np.ascontiguousarray(x, dtype=float)


class KnownLoop:
    """The loop a record was measured in: the sampled controller, the reference, and a known added signal.

    Parameters
    ----------
    controller : control.StateSpace or control.TransferFunction, discrete-time
        With one input it acts on the error ``r - y``; with two on ``[r, y]``.
        Its ``dt`` is the record's sampling interval.
    reference : array_like, shape (N,)
    added : array_like, shape (N,), optional
        A signal added to the controller's output before the plant (test
        pulses, a feed-forward); default zeros.
    initial_state : array_like, optional
        The controller's state at the first sample (default zeros).
    """

    def __init__(self, controller, reference, added=None, *, initial_state=None):
        self.reference = _signal(reference, "reference")
        n = self.reference.size
        self.added = np.zeros(n) if added is None else _signal(added, "added")
        if self.added.size != n:
            raise DataError(f"added has {self.added.size} samples, reference {n}")
        self.controller = controller
        self.dt = float(controller.dt) if getattr(controller, "dt", None) not in (None, True, 0) else np.nan
        self._matrices = _controller_matrices(controller, self.dt)
        nc = self._matrices[0].shape[0]
        states = 0 if not np.any(self._matrices[0]) and not np.any(self._matrices[2]) else nc
        x0 = np.zeros(nc) if initial_state is None else as_real_array(initial_state, "initial_state").reshape(-1)
        if x0.size not in (states, nc) or not np.all(np.isfinite(x0)):
            raise ParameterError(f"initial_state must be the controller's {states} state(s), finite, got "
                                 f"{np.shape(initial_state)}")
        self.initial_state = np.zeros(nc) if x0.size == 0 else x0

    def __len__(self) -> int:
        return self.reference.size

    def simulate_parts(self, parts: LoopParts):
        """``(Y, U)``, each ``(B, N)``: outputs and control signals of the loops around the plants ``parts``."""
        Y = np.empty((parts.den.shape[0], len(self)))
        U = np.empty_like(Y)
        with np.errstate(all="ignore"):
            lure_loop_run(*parts.setup(self.dt), parts.fc, parts.c, parts.x0, parts.y0, *self._matrices,
                          self.initial_state, self.reference, self.added, Y, U)
        return Y, U

    def simulate(self, model):
        """``(y, u)`` of the loop around ``model`` (a Lur'e or block model, from its initial state; a block model's
        input is held over each sample)."""
        if isinstance(model, BlockModel):
            if model.delay:
                raise ParameterError("a block model in a known loop cannot have a dead time yet (its sampled loop "
                                     "has none): fit without it, or use a Pade approximant (model.without_delay())")
            return simulate_known_loop(sampled_plant(model, self.dt), self._matrices, self.reference, self.added,
                                       initial_state=self.initial_state)
        if not isinstance(model, LureModel):
            raise ParameterError(f"model must be a LureModel or a block model (Hammerstein, Wiener, "
                                 f"Hammerstein-Wiener), got {type(model).__name__}")
        _friction_only(model.nonlinearity)
        Y, U = self.simulate_parts(model._parts())
        return Y[0], U[0]


def _friction_only(nonlinearity) -> None:
    """Refuse a Lur'e plant whose map is not friction: its loop inside a known controller is not simulated yet."""
    if not sign_map(nonlinearity):
        raise ParameterError(f"a Lur'e plant inside a known loop takes a friction map (Friction or Coulomb) for now, "
                             f"got {type(nonlinearity).__name__}: fit the plant open loop (identify(record, "
                             "structure)), or approximate its map by friction")


class KnownLoopCost(StructureSized):
    """Weighted least squares of the loop's simulated output and/or control signal against the record.

    ``residuals`` stacks ``w_y (y - y_hat)`` and ``w_u (u - u_hat)`` (the
    matched ones, in that order); ``J`` is their sum of squares.
    """

    def __init__(self, data, structure, loop: KnownLoop, *, match: str = "both", weights=None):
        if not isinstance(structure, (LureStructure, BlockStructure)):
            raise ParameterError(f"structure must be a LureStructure or a block structure (Hammerstein, Wiener, "
                                 f"Hammerstein-Wiener), got {type(structure).__name__}")
        if isinstance(structure, BlockStructure) and structure.linear.delay:
            raise ParameterError("a block structure in a known loop cannot have a dead time yet: fit without it")
        if isinstance(structure, LureStructure):
            _friction_only(structure.nonlinearity)
        if match not in MATCHES:
            raise ParameterError(f"match must be one of {MATCHES}, got {match!r}")
        data.require_siso("a loop fit")
        if len(loop) != len(data):
            raise DataError(f"the loop's reference has {len(loop)} samples, the record {len(data)}")
        if not np.isclose(loop.dt, data.dt, rtol=1e-9, atol=0.0):
            raise DataError(f"the controller's dt = {loop.dt} differs from the record's dt = {data.dt}")
        self.data, self.structure, self.loop, self.match = data, structure, loop, match
        self._y = np.asarray(data.y, dtype=float).reshape(-1)
        self._u = np.asarray(data.u, dtype=float).reshape(-1)
        self.signals = {"output": ("y",), "input": ("u",), "both": ("y", "u")}[match]
        self.weights = self._weights(weights)
        self.reject_unstable = False

    def _weights(self, weights) -> np.ndarray:
        """One weight per matched signal: given, or the inverse of each measured signal's spread."""
        if weights is None:
            spread = [np.std(self._y if s == "y" else self._u) for s in self.signals]
            flat = [s for s, v in zip(self.signals, spread) if not v > 0]
            if flat:
                raise DataError(f"the measured {' and '.join(dict(y='output', u='control signal')[s] for s in flat)} "
                                f"is constant: nothing to match (choose match= among the signals that vary)")
            return 1.0 / np.array(spread)
        w = as_real_array(weights, "weights").reshape(-1)
        if w.size != len(self.signals) or not np.all(np.isfinite(w) & (w >= 1e-100) & (w <= 1e100)):
            raise ParameterError(f"weights must be {len(self.signals)} number(s) between 1e-100 and 1e100, one per "
                                 f"matched signal {self.signals}, got {weights!r}")
        return w

    def simulate_batch(self, betas):
        """``(Y, U)`` of the loop around each candidate plant."""
        B = np.atleast_2d(self.structure.check_beta(betas))
        if isinstance(self.structure, LureStructure):
            return self.loop.simulate_parts(self.structure.parts(B))
        Y, U = np.empty((B.shape[0], len(self.loop))), np.empty((B.shape[0], len(self.loop)))
        with np.errstate(all="ignore"):
            for k, beta in enumerate(B):
                try:
                    Y[k], U[k] = self.loop.simulate(self.structure.model(beta, intersample="zoh"))
                except ParameterError:                  # a candidate that is no plant (improper, not finite)
                    Y[k], U[k] = np.inf, np.nan
        return Y, U

    def simulate(self, beta) -> np.ndarray:
        """The loop's output ``y`` around the candidate plant ``beta`` (its input is ``simulate_batch``'s ``U``)."""
        return self.simulate_batch(beta)[0][0]

    def residuals_batch(self, betas) -> np.ndarray:
        Y, U = self.simulate_batch(betas)
        parts = [w * ((self._y - Y) if s == "y" else (self._u - U)) for s, w in zip(self.signals, self.weights)]
        R = np.concatenate(parts, axis=1)
        R[~np.isfinite(R)] = NONFINITE_RESIDUAL
        return R

    def residuals(self, beta) -> np.ndarray:
        return self.residuals_batch(beta)[0]

    def batch(self, betas) -> np.ndarray:
        R = self.residuals_batch(betas)
        J = np.einsum("ij,ij->i", R, R)
        J[np.any(R == NONFINITE_RESIDUAL, axis=1)] = np.inf
        return J

    def __call__(self, beta) -> float:
        return float(self.batch(beta)[0])

    def trivial_sse(self) -> float:
        """``J`` of constant signals at the measured means (the level a useful fit must beat)."""
        return float(sum(w**2 * np.sum((v - v.mean()) ** 2)
                         for w, v in zip(self.weights, (self._y if s == "y" else self._u for s in self.signals))))


def _fits(cost: KnownLoopCost, x) -> dict:
    """Fit per cent of the loop's output and control signal against the record."""
    from ..data._metrics import fit_report

    Y, U = cost.simulate_batch(x)
    return {"y": fit_report(cost._y, Y[0])["fit_percent"], "u": fit_report(cost._u, U[0])["fit_percent"]}


def identify_in_loop(data, structure, loop: KnownLoop, *, match: str = "both", weights=None,
                     seed=None, maxfev: int | None = None, noise: str = "colored"):
    """Identify a plant by simulating the known loop the record was measured in.

    Parameters
    ----------
    data : IOData
        The record: ``u`` the measured control signal (the plant's input), ``y`` the measured output.
    structure : LureStructure or BlockStructure
        A Lur'e loop, or a Hammerstein, Wiener or Hammerstein-Wiener
        structure (strictly proper, no dead time; its input held over each
        sample).
    loop : KnownLoop
        The controller, the reference and any added signal of the record.
    match : {"output", "input", "both"}, default "both"
        Which measured signals the simulated loop must reproduce.
    weights : sequence of float, optional
        One per matched signal (output first); default the inverse of each
        signal's standard deviation (both count alike whatever their units).
    seed, maxfev
        As for :func:`~hammerstein_ctrl.fit`.
    noise : {"colored", "white"}
        Noise description of the covariance; with ``"both"`` each signal has its own.

    Returns
    -------
    IdentificationResult
        ``output_fits`` gives the loop's fit of ``y`` and of ``u``; the
        uncertainty is the sandwich covariance of the stacked residuals.

    Notes
    -----
    The starts come from the open-loop fit of ``(u, y)`` (``identify`` with
    the same structure), then Levenberg-Marquardt refines on the loop's
    residuals, with restarts from perturbations of the best.

    Examples
    --------
    >>> import numpy as np, control, hammerstein_ctrl as hc
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Polynomial(1))
    >>> r = np.repeat(np.random.default_rng(0).uniform(-1, 1, 20), 50)
    >>> loop = KnownLoop(control.ss([], [], [], [[1.5]], dt=0.05), r)          # a proportional controller
    >>> y, u = loop.simulate(s.model([2.0, 3.0], intersample="zoh"))
    >>> res = identify_in_loop(hc.IOData(u, y, dt=0.05, intersample="zoh"), s, loop)
    >>> res.success, np.round(res.x, 4).tolist()
    (True, [2.0, 3.0])
    """
    from ._auto import auto_minimize
    from ._auto_whole import auto_known_loop, auto_lure
    from ._lure_fit import LureCost
    from ._objective import HammersteinCost

    started = time.perf_counter()
    cost = KnownLoopCost(data, structure, loop, match=match, weights=weights)
    share = None if maxfev is None else max(1, maxfev // 3)
    if isinstance(structure, LureStructure):
        open_loop = auto_lure(LureCost(data, structure), maxfev=share, seed=seed)
    else:
        open_loop = auto_minimize(HammersteinCost(data, structure), maxfev=share, seed=seed, allow_unstable=True)
    x0 = open_loop.x if np.all(np.isfinite(open_loop.x)) else None
    rest = None if maxfev is None else max(1, maxfev - int(open_loop.nfev))
    if isinstance(structure, LureStructure):
        res = auto_lure(cost, x0, maxfev=rest, seed=seed)
    else:
        res = auto_known_loop(cost, [] if x0 is None else [x0], maxfev=rest, seed=seed)
    return _result(cost, res, noise, started)


def _result(cost: KnownLoopCost, res, noise: str, started: float):
    """The :class:`~hammerstein_ctrl.fit.IdentificationResult` of a loop fit: fits per signal, uncertainty,
    verdicts (no better than a constant; parameters the loop record does not determine)."""
    from ..assess._diagnostics import FAILURE, Verdict, identifiability_verdicts
    from ..data._metrics import fit_report
    from ._result import IdentificationResult
    from ..assess._uncertainty import channel_uncertainty

    x = np.asarray(res.x, dtype=float)
    finite = bool(np.all(np.isfinite(x)) and np.isfinite(res.fun))
    fits = _fits(cost, x) if finite else {"y": -np.inf, "u": -np.inf}
    verdicts, unc = [], None
    if not finite:
        verdicts.append(Verdict("no-model", FAILURE, "no model: the loop fit found no finite parameters"))
    for sig in cost.signals:
        if finite and not fits[sig] > 0:
            verdicts.append(Verdict("no-better", FAILURE, f"the loop's {dict(y='output', u='control signal')[sig]} "
                                                          f"fits {fits[sig]:.1f} %: no better than a constant"))
    if finite:
        r = cost.residuals(x)
        with np.errstate(all="ignore"):
            unc = channel_uncertainty(cost, x, r, len(cost.signals), noise=noise)
        verdicts += identifiability_verdicts(cost.structure, x, unc)
    y_hat = cost.simulate_batch(x)[0][0] if finite else np.full(len(cost.data), np.nan)
    report = fit_report(cost._y, y_hat) if finite else {"fit_percent": -np.inf, "rmse": np.inf, "nrmse": np.inf}
    success = bool(res.success) and not any(v.severity == FAILURE for v in verdicts)
    failures = [v.message for v in verdicts if v.severity == FAILURE]
    message = "; ".join(failures) + f" [{res.message}]" if failures else str(res.message)
    return IdentificationResult(
        model=cost.structure.model(x, intersample="zoh") if finite else None, x=x, fun=float(res.fun),
        nfev=int(res.nfev), fit_percent=report["fit_percent"], rmse=report["rmse"], nrmse=report["nrmse"],
        method="auto (in loop)", success=success, message=message, history=res.history,
        elapsed=time.perf_counter() - started, structure=cost.structure, optimize_result=res,
        covariance=None if unc is None else unc.covariance, warnings=[v.message for v in verdicts],
        verdicts=verdicts, uncertainty=unc, analysis=None, data=cost.data,
        output_fits={"y (in loop)": fits["y"], "u (in loop)": fits["u"]})


#: ``LoopCost``, the old name of :class:`KnownLoopCost`, for one release with a DeprecationWarning.
__getattr__ = renamed(__name__, {"LoopCost": ("KnownLoopCost", "control_design has a cost of its own")})
