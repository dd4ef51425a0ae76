"""Fitting a block structure with an input dead time.

A structure whose linear block has a dead time
(``LinearStructure(..., delay=0.12)`` fixed, or ``delay="estimate"``) is
fitted through :class:`DelayedCost`: the sum of squared output errors with
the exact fractional-delay simulation of :mod:`~hammerstein_ctrl.simulate._delay`,
and the least-squares protocol (``residuals``, ``residuals_batch``,
``normal_equations``) that every optimiser, the uncertainty and the verdicts
use.  An estimated dead time is a parameter like the others (named
``delay``, in seconds, after the block parameters), so its standard error
and its correlation with the lags come with the fit.

The cost in ``delay`` has a local minimum near every sample, so ``auto``
does not start from a guess: :func:`delay_candidates` ranks whole-sample
delays by the fit of ARX models (MATLAB's ``delayest`` idea), the best few
are fitted without delay on the record shifted by that many samples, and
the best of those starts the joint refinement of everything, the delay now
continuous.

Examples
--------
>>> import numpy as np, control as ct
>>> from hammerstein_ctrl import IOData, HammersteinStructure, LinearStructure, Tanh
>>> s = HammersteinStructure(LinearStructure(0, 1, delay="estimate"), Tanh())
>>> s.param_names
('a0', 'd0', 'd1', 'delay')
>>> t = np.arange(300) * 0.1
>>> data = IOData(np.sin(0.7 * t), np.zeros(300), dt=0.1)
>>> cost = DelayedCost(data, s)
>>> round(cost([1.0, 2.0, 0.5, 0.37]), 3) > 0
True
"""

from __future__ import annotations

import numpy as np

from .. import config
from ..simulate._delay import delayed_response
from ..exceptions import ParameterError
from ..data._iodata import IOData
from ..optimize._normal_equations import (NONFINITE_RESIDUAL, NormalEquations, from_residuals, neighbours,
                                          point_and_steps)
from ..simulate._simulate import unstable
from ..blocks._structure import BlockStructure
from ._cost import StructureSized

__all__ = ["DelayedCost", "delay_candidates", "shifted"]


class DelayedCost(StructureSized):
    """Sum of squared output errors of a block structure whose linear block has a dead time.

    Parameters
    ----------
    data : IOData
        The estimation record.
    structure : BlockStructure
        With ``structure.linear.delay`` a number or ``"estimate"``.
    reject_unstable : bool, default False
        Score candidates with a right-half-plane pole as ``inf``.

    Attributes
    ----------
    data : IOData
    structure : BlockStructure
    base : BlockStructure
        The same blocks and options without the dead time (the layout of
        ``beta`` without its ``delay`` entry).
    """

    def __init__(self, data, structure: BlockStructure, *, reject_unstable: bool = False):
        if not isinstance(data, IOData):
            raise ParameterError(f"data must be an IOData record, got {type(data).__name__}")
        if not isinstance(structure, BlockStructure):
            raise ParameterError("structure must be a HammersteinStructure, WienerStructure or "
                                 f"HammersteinWienerStructure, got {type(structure).__name__}")
        delay = structure.linear.delay
        if not structure.linear.estimates_delay and delay >= data.duration:
            raise ParameterError(f"the dead time {delay:g} s is not shorter than the record {data.name!r} "
                                 f"({data.duration:g} s): the record shows no response to its input")
        self.data = data
        self.structure = structure
        self.base = structure.with_delay(None)
        self.reject_unstable = bool(reject_unstable)
        self._y = np.ascontiguousarray(data.y, dtype=float)

    n_samples = property(lambda self: len(self.data))

    def to_base(self, beta) -> np.ndarray:
        """``beta`` without its ``delay`` entry (the layout of :attr:`base`)."""
        b = self.structure.check_beta(beta)
        if not self.structure.linear.estimates_delay:
            return b
        return np.delete(b, self.structure.n_core - 1, axis=-1)

    def from_base(self, beta, delay: float) -> np.ndarray:
        """A beta of :attr:`base` with the dead time ``delay`` put in (the inverse of :meth:`to_base`)."""
        b = self.base.check_beta(beta)
        if not self.structure.linear.estimates_delay:
            return b.copy()
        return np.insert(b, self.base.n_core, float(delay), axis=-1)

    def simulate(self, beta) -> np.ndarray:
        """The simulated output at one beta (NaN where it cannot be simulated: a negative delay, say)."""
        s = self.structure
        b = s.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("simulate(beta) takes one vector")
        tau = float(s.delay(b))
        num, den = s.linear.coefficients(s.linear_params(b))
        bad = not (np.isfinite(tau) and tau >= 0 and np.all(np.isfinite(b)) and den[0, 0] != 0)
        if bad or (self.reject_unstable and unstable(den)[0]):
            return np.full(len(self.data), np.nan)
        u = self.data.u
        offset, x0 = s.nuisance(b)
        with np.errstate(all="ignore"):
            v = u if s.input_nonlinearity is None else s.input_nonlinearity(u, s.input_params(b))
            if not np.all(np.isfinite(v)):
                return np.full(len(self.data), np.nan)
            z = delayed_response(num[0], den[0], v, self.data.dt, tau, x0=x0,
                                 intersample=self.data.intersample)
            y = z if s.output_nonlinearity is None else s.output_nonlinearity(z, s.output_params(b))
            return np.asarray(y, dtype=float) + (0.0 if offset is None else float(offset))

    def residuals(self, beta) -> np.ndarray:
        """``y - yhat`` (non-finite entries replaced by a large finite value, as the other costs do)."""
        with np.errstate(all="ignore"):
            r = self._y - self.simulate(beta)
        r[~np.isfinite(r)] = NONFINITE_RESIDUAL
        return r

    def residuals_batch(self, betas) -> np.ndarray:
        """:meth:`residuals` for each row of ``betas``."""
        b = np.atleast_2d(self.structure.check_beta(betas))
        return np.stack([self.residuals(row) for row in b])

    def __call__(self, beta) -> float:
        """J at one beta (``inf`` if it cannot be simulated)."""
        with np.errstate(all="ignore"):
            r = self._y - self.simulate(beta)
        J = float(r @ r)
        return J if np.isfinite(J) else np.inf

    def batch(self, betas) -> np.ndarray:
        """J for each row of ``betas``."""
        return np.array([self(row) for row in np.atleast_2d(self.structure.check_beta(betas))])

    def normal_equations(self, beta, steps=None) -> NormalEquations:
        """``r @ r``, ``J.T @ r`` and ``J.T @ J`` from forward differences with ``steps``."""
        b, h = point_and_steps(self.structure, beta, steps)
        return from_residuals(self.residuals_batch(neighbours(b, h)), h)

    def __repr__(self):
        return f"DelayedCost({self.data.name!r}, {len(self.data)} samples, {self.structure!r})"


def delayed_input(data: IOData, samples: int) -> IOData:
    """The record with its input delayed by ``samples`` (zeros before the record, as the state at rest says).

    Unlike :func:`shifted` it keeps every output sample, so an initial state
    or offset estimated on it belongs to the record's own ``t = 0``.

    Examples
    --------
    >>> delayed_input(IOData([1.0, 2, 3, 4], [5.0, 6, 7, 8], dt=0.5), 1).u.tolist()
    [0.0, 1.0, 2.0, 3.0]
    """
    if samples <= 0:
        return data
    u = np.zeros(len(data))
    u[samples:] = data.u[:len(data) - samples]
    return IOData(u, data.y, dt=data.dt, name=data.name, input_name=data.input_name, output_name=data.output_name,
                  input_unit=data.input_unit, output_unit=data.output_unit, intersample=data.intersample)


def shifted(data: IOData, samples: int) -> IOData:
    """The record with its output moved ``samples`` earlier (input ``u[:-samples]`` against ``y[samples:]``).

    Examples
    --------
    >>> d = IOData([0.0, 1, 2, 3], [5.0, 6, 7, 8], dt=0.5)
    >>> s = shifted(d, 1)
    >>> s.u.tolist(), s.y.tolist()
    ([0.0, 1.0, 2.0], [6.0, 7.0, 8.0])
    """
    if samples <= 0:
        return data
    n = len(data) - samples
    return IOData(data.u[:n], data.y[samples:], dt=data.dt, name=data.name, input_name=data.input_name,
                  output_name=data.output_name, input_unit=data.input_unit, output_unit=data.output_unit,
                  intersample=data.intersample)


def delay_candidates(data: IOData, order: int, *, max_shift: int | None = None,
                     count: int | None = None) -> list[int]:
    """Whole-sample dead times, best first, ranked by the fit of ARX models with that input delay.

    For each shift ``d`` an ARX model of ``order`` output lags and
    ``order + 1`` input lags starting at lag ``d`` (plus a constant) is
    fitted by least squares on the same samples; a continuous dead time
    ``tau`` shows as the best ``d`` near ``tau / dt`` (one more under a
    zero-order hold).  The shifts returned are dead times in samples:
    ``[d0, d0 - 1, d0 + 1, ...]`` around the best one, within range: ``count``
    of them (default ``config.defaults["delay.candidates"]``), shifts up to
    ``max_shift`` (default ``config.defaults["delay.max_samples"]``, at most a
    quarter of the record).

    Examples
    --------
    >>> import control as ct
    >>> t = np.arange(400) * 0.1
    >>> u = np.sign(np.sin(0.4 * t)) + 0.3 * np.sin(1.7 * t)
    >>> y = ct.forced_response(ct.tf([2.0], [1.0, 1.0]), t, np.r_[np.full(7, u[0]), u[:-7]]).outputs
    >>> delay_candidates(IOData(u, y, dt=0.1), 1)[0]
    7
    """
    u, y = np.asarray(data.u, dtype=float), np.asarray(data.y, dtype=float)
    N = u.size
    top = min(config.get("delay.max_samples") if max_shift is None else int(max_shift), max(0, N // 4))
    count = config.get("delay.candidates") if count is None else count
    first = top + order + 1                         # the same samples for every shift
    rows = N - first
    if rows <= 2 * order + 2:
        return [0]
    cols = [y[first - i:N - i] for i in range(1, order + 1)] + [np.ones(rows)]
    past = np.column_stack(cols)
    scores = np.empty(top + 1)
    target = y[first:]
    for d in range(top + 1):
        X = np.column_stack([past] + [u[first - d - j:N - d - j] for j in range(order + 1)])
        coef, *_ = np.linalg.lstsq(X, target, rcond=None)
        r = target - X @ coef
        scores[d] = r @ r
    best = int(np.argmin(scores)) - (1 if data.intersample == "zoh" else 0)
    around = [best, best - 1, best + 1, best - 2, best + 2]
    return [d for d in dict.fromkeys(around) if 0 <= d <= top][:max(1, int(count))]
