"""The linear blocks of a Wiener-Hammerstein model in static-gain form, and the sampled simulation of G1 -> f -> G2
(G1 exact at the samples, G2 with its input linear between substeps)."""

from __future__ import annotations

from typing import NamedTuple
import numpy as np
from ..simulate._batch import simulate_batch
from ..exceptions import ParameterError
from ._model import _finite_scalar
from ._nonlinearities import Nonlinearity
from ._structure import LinearStructure

__all__ = ["WHParts", "simulate_wh", "UnitGainBlock", "MAX_SUBSTEPS"]


#: Most substeps per sample.
MAX_SUBSTEPS = 64


class UnitGainBlock:
    """A linear block in static-gain form: numerator and denominator in ``q = time_unit p``, both with constant term 1.

    ``G(p) = (1 + b1 q + ... + bl q^l) / (1 + a1 q + ... + an q^n)``.

    Its static gain is 1 whatever the parameters; a zero leaves to infinity
    smoothly (its coefficient through 0), which the usual monic form reaches
    only as a coefficient grows without bound.  The coefficients are
    those of the block's time constants (``a1`` is the sum of the poles' time
    constants) in units of ``time_unit`` (seconds) to the power of their
    index: a unit near the block's time constants keeps them near 1, where a
    least-squares search's difference steps are relative.

    Parameters
    ----------
    num_order, den_order : int
        Degrees ``l <= n`` of the numerator and the denominator, ``n >= 1``.
    time_unit : float, default 1.0
        The unit of time of the coefficients, in seconds.

    Examples
    --------
    >>> g = UnitGainBlock(1, 2)
    >>> g.param_names
    ('b1', 'a1', 'a2')
    >>> num, den = g.coefficients([0.5, 3.0, 2.0])       # (1 + 0.5 p) / (1 + 3 p + 2 p^2)
    >>> num.tolist(), den.tolist()
    ([[0.5, 1.0]], [[2.0, 3.0, 1.0]])
    >>> g.free_parameters([1.0, 2.0], [1.0, 3.0, 2.0]).tolist()      # (p + 2)/(p^2 + 3 p + 2)
    [0.5, 1.5, 0.5]
    """

    #: No coefficient is fixed (the constant terms are 1 by construction).
    fixed: dict = {}
    delay = None

    def __init__(self, num_order: int, den_order: int, time_unit: float = 1.0):
        self.time_unit = _finite_scalar(time_unit, "time_unit")
        if not self.time_unit > 0:
            raise ParameterError(f"time_unit must be > 0 (seconds), got {time_unit!r}")
        for label, v in (("num_order", num_order), ("den_order", den_order)):
            if isinstance(v, bool) or int(v) != v or v < 0:
                raise ParameterError(f"{label} must be a whole number >= 0, got {v!r}")
        if den_order < 1 or num_order > den_order:
            raise ParameterError(f"a block needs 1 <= den_order and num_order <= den_order, got {num_order}, "
                                 f"{den_order}")
        self.num_order, self.den_order = int(num_order), int(den_order)
        self.param_names: tuple[str, ...] = tuple(f"b{i}" for i in range(1, self.num_order + 1)) + tuple(
            f"a{i}" for i in range(1, self.den_order + 1))
        m, n = self.num_order, self.den_order
        num0, den0 = np.zeros(m + 1), np.zeros(n + 1)
        num0[-1] = den0[-1] = 1.0
        self._template = (num0, den0, np.arange(m - 1, -1, -1), np.arange(n - 1, -1, -1))
        self._units = (self.time_unit ** np.arange(1, m + 1), self.time_unit ** np.arange(1, n + 1))

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def coefficient_template(self):
        """``(num0, den0, num_pos, den_pos)``: the constant terms, and where the free coefficients go."""
        return self._template

    def parameter_scales(self) -> np.ndarray:
        """``d coefficient / d parameter`` of each parameter: ``time_unit`` to the power of its index."""
        return np.concatenate(self._units)

    def coefficients(self, theta):
        """``(num, den)`` rows (descending powers, constant terms 1) of a parameter vector or batch."""
        T = np.atleast_2d(np.asarray(theta, dtype=float))
        num0, den0, num_pos, den_pos = self._template
        num, den = np.tile(num0, (T.shape[0], 1)), np.tile(den0, (T.shape[0], 1))
        num[:, num_pos] = T[:, :self.num_order] * self._units[0]
        den[:, den_pos] = T[:, self.num_order:] * self._units[1]
        return num, den

    def monic(self, theta):
        """``(num, den)`` rows scaled to a monic denominator (for the simulation)."""
        num, den = self.coefficients(theta)
        with np.errstate(all="ignore"):
            lead = den[:, :1]
            return num / lead, den / lead

    def free_parameters(self, num, den) -> np.ndarray:
        """The parameters of ``num/den`` (descending powers), each scaled to a constant term of 1 (its static gain
        dropped); ``num`` is padded to ``num_order + 1`` coefficients."""
        num, den = np.ravel(np.asarray(num, dtype=float)), np.ravel(np.asarray(den, dtype=float))
        num = np.concatenate([np.zeros(self.num_order + 1 - num.size), num])[-(self.num_order + 1):]
        den = np.concatenate([np.zeros(self.den_order + 1 - den.size), den])[-(self.den_order + 1):]
        with np.errstate(all="ignore"):
            num, den = num / num[-1], den / den[-1]
        return np.concatenate([num[self._template[2]] / self._units[0], den[self._template[3]] / self._units[1]])

    def describe(self) -> str:
        def poly(letter, order):
            return " + ".join(["1"] + [f"{letter}{i} q" + (f"^{i}" if i > 1 else "") for i in range(1, order + 1)])
        return f"({poly('b', self.num_order)})/({poly('a', self.den_order)}), q = {self.time_unit:.6g} s p"

    def __repr__(self):
        unit = "" if self.time_unit == 1.0 else f", time_unit={self.time_unit!r}"
        return f"UnitGainBlock({self.num_order}, {self.den_order}{unit})"


def _check_block(block, label: str, time_unit: float) -> UnitGainBlock:
    """A :class:`UnitGainBlock` in ``time_unit`` from one (its orders), from orders ``(num_order, den_order)``, or
    from a plain :class:`~hammerstein_ctrl.blocks.LinearStructure` (its orders)."""
    if isinstance(block, UnitGainBlock):
        return UnitGainBlock(block.num_order, block.den_order, time_unit)
    if isinstance(block, tuple) and len(block) == 2:
        return UnitGainBlock(*block, time_unit)
    if not isinstance(block, LinearStructure):
        raise ParameterError(f"{label} must be a LinearStructure, a UnitGainBlock or (num_order, den_order), got "
                             f"{type(block).__name__}")
    if block.estimates_delay:
        raise ParameterError(f"{label} estimates its dead time: a Wiener-Hammerstein structure takes a fixed one "
                             "(delay=seconds) for now; scan a few values and compare J, or use a Hammerstein "
                             "structure")
    if not block.monic_numerator or set(block.fixed) - {f"b{block.num_order}"}:
        raise ParameterError(f"{label} fixes coefficients or carries a gain (monic_numerator=False): a "
                             "Wiener-Hammerstein structure writes both linear blocks with static gain 1, "
                             "(1 + b1 p + ...)/(1 + a1 p + ...), and lets the map carry the gain; give the orders "
                             "only")
    return UnitGainBlock(block.num_order, block.den_order, time_unit)


class WHParts(NamedTuple):
    """What the simulation of a batch of Wiener-Hammerstein candidates needs (rows: candidates)."""

    num1: np.ndarray
    den1: np.ndarray
    map_params: np.ndarray
    num2: np.ndarray
    den2: np.ndarray
    y0: np.ndarray
    x1: np.ndarray
    x2: np.ndarray


def _fine_input(u: np.ndarray, m: int, hold: str) -> np.ndarray:
    """The input at ``m`` instants per sample, interpolated by its own hold (exact)."""
    if m == 1:
        return u
    j = np.arange(m) / m
    if hold == "zoh":
        fine = np.repeat(u[:-1], m)
    else:
        fine = (u[:-1, None] + np.diff(u)[:, None] * j).reshape(-1)
    return np.concatenate([fine, u[-1:]])


def _shifted_fine_input(u: np.ndarray, m: int, hold: str, shift: int) -> np.ndarray:
    """The input at ``m`` instants per sample, delayed by ``shift`` of those instants: the record's own hold
    curve read ``shift h`` earlier (``h = dt / m``), zero before the record (joined to its first sample by the
    hold, as :mod:`~hammerstein_ctrl.simulate._delay` joins it)."""
    fine = _fine_input(np.r_[0.0, u], m, hold)           # from one sample before the record, where the input is 0
    start = m - shift                                     # fine index of t = 0 in it, less the shift
    if start >= 0:
        return np.ascontiguousarray(fine[start:start + (u.size - 1) * m + 1])
    return np.ascontiguousarray(np.r_[np.zeros(-start), fine][:(u.size - 1) * m + 1])


def _delayed_middle(nonlinearity, parts: WHParts, u, m: int, h: float, hold: str, delay: float) -> np.ndarray:
    """``f(G1 u(t - delay))`` at the substep instants: the whole substeps of the delay shift the input (exact:
    the shifted input's breaks fall on instants), the rest by the exact delayed recursion of each candidate."""
    shift = int(np.floor(delay / h + 1e-9))
    rest = max(0.0, delay - shift * h)
    fine = _shifted_fine_input(u, m, hold, shift)
    if rest <= 1e-12 * h:
        return simulate_batch(parts.num1, parts.den1, fine, h, x0=parts.x1, intersample=hold,
                              output_map=(nonlinearity, parts.map_params))
    from ..simulate._delay import delayed_response

    W = np.full((parts.num1.shape[0], fine.size), np.nan)
    for b in range(W.shape[0]):
        try:
            x = delayed_response(parts.num1[b], parts.den1[b], fine, h, rest, x0=parts.x1[b], intersample=hold)
        except ParameterError:          # a candidate that is no block (non-finite coefficients)
            continue
        W[b] = nonlinearity(x, parts.map_params[b])
    return W


def simulate_wh(nonlinearity: Nonlinearity, parts: WHParts, u, dt: float, hold: str = "foh",
                substeps: int = 1, delay: float = 0.0) -> np.ndarray:
    """Outputs ``(B, N)`` of a batch of Wiener-Hammerstein candidates driven by one input ``u``.

    Rows of candidates that cannot be simulated hold NaN or inf.  See the module
    docstring for the intersample behaviour and ``substeps``; a dead time
    ``delay`` (seconds) delays the input exactly, as :mod:`~hammerstein_ctrl.simulate._delay`
    does for a block model (the input is zero before the record).
    """
    u = np.ascontiguousarray(u, dtype=float).reshape(-1)
    m = int(substeps)
    fine = _fine_input(u, m, hold)
    h = dt / m
    with np.errstate(all="ignore"):
        if delay:
            W = _delayed_middle(nonlinearity, parts, u, m, h, hold, float(delay))
        else:
            W = simulate_batch(parts.num1, parts.den1, fine, h, x0=parts.x1, intersample=hold,
                               output_map=(nonlinearity, parts.map_params))
        Y = simulate_batch(parts.num2, parts.den2, W, h, x0=parts.x2, offset=parts.y0, intersample="foh", out=W)
    return np.ascontiguousarray(Y[:, ::m]) if m > 1 else Y
