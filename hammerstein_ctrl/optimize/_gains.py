"""Gain sequences of the SPSA family.

``a(k) = a / (k + A)**alpha`` (step size) and ``c(k) = c / (k + 1)**gamma``
(perturbation size), for iterations ``k = 1, 2, ...``.  Spall's practical
guidelines (Spall 1998) are ``alpha = 0.602``, ``gamma = 0.101`` and ``A`` about
10 % of the number of iterations; :meth:`StepGain.spall` builds that.

Examples
--------
>>> a = StepGain(0.66, 24, 0.9)      # EMPS N-SPSA (paper Table 6)
>>> round(a(1), 6)
0.036425
>>> c = PerturbationGain(0.2, 1 / 6)
>>> round(c(1), 6)
0.17818
>>> StepGain.spall(0.1, maxiter=1000)
StepGain(a=0.1, A=100, alpha=0.602)
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ParameterError

__all__ = ["GainSequence", "StepGain", "PerturbationGain", "SPALL_ALPHA", "SPALL_GAMMA"]

#: Spall's recommended decay exponents.
SPALL_ALPHA = 0.602
SPALL_GAMMA = 0.101


class GainSequence:
    """``g(k) = scale / (k + offset)**exponent`` for ``k = 1, 2, ...``."""

    __slots__ = ("scale", "offset", "exponent")

    def __init__(self, scale: float, offset: float, exponent: float):
        for label, val in (("scale", scale), ("offset", offset), ("exponent", exponent)):
            if not np.isfinite(val):
                raise ParameterError(f"gain {label} must be finite, got {val!r}")
        if scale <= 0:
            raise ParameterError(f"gain scale must be positive, got {scale!r}")
        if offset <= -1:
            raise ParameterError(f"gain offset must exceed -1 so that k + offset > 0, got {offset!r}")
        self.scale, self.offset, self.exponent = float(scale), float(offset), float(exponent)

    def __call__(self, k) -> float:
        """The gain at iteration ``k`` (``k >= 1``; arrays are accepted)."""
        return self.scale / (k + self.offset) ** self.exponent

    def __eq__(self, other):
        return type(other) is type(self) and (self.scale, self.offset, self.exponent) == (
            other.scale, other.offset, other.exponent)

    def __hash__(self):
        return hash((type(self).__name__, self.scale, self.offset, self.exponent))

    def __getstate__(self):
        return (self.scale, self.offset, self.exponent)

    def __setstate__(self, state):
        self.scale, self.offset, self.exponent = state

    def __repr__(self):
        return f"GainSequence(scale={self.scale:g}, offset={self.offset:g}, exponent={self.exponent:g})"

    def to_dict(self) -> dict:
        """Plain-data form (for JSON reports)."""
        return {"type": type(self).__name__, "scale": self.scale, "offset": self.offset,
                "exponent": self.exponent}


class StepGain(GainSequence):
    """Step-size sequence ``a(k) = a / (k + A)**alpha``.

    Parameters
    ----------
    a : float
        Scale (> 0).
    A : float, default 0
        Stability constant.
    alpha : float, default 0.602
    """

    __slots__ = ()

    def __init__(self, a: float, A: float = 0.0, alpha: float = SPALL_ALPHA):
        super().__init__(a, A, alpha)

    @classmethod
    def spall(cls, a: float, maxiter: int, alpha: float = SPALL_ALPHA) -> "StepGain":
        """Spall's practical choice: ``A = 0.1 * maxiter``, ``alpha = 0.602``."""
        return cls(a, 0.1 * maxiter, alpha)

    def __repr__(self):
        return f"StepGain(a={self.scale:g}, A={self.offset:g}, alpha={self.exponent:g})"


class PerturbationGain(GainSequence):
    """Perturbation-size sequence ``c(k) = c / (k + 1)**gamma``.

    Parameters
    ----------
    c : float
        Scale (> 0); Spall suggests about the standard deviation of the noise in f.
    gamma : float, default 0.101
    """

    __slots__ = ()

    def __init__(self, c: float, gamma: float = SPALL_GAMMA):
        super().__init__(c, 1.0, gamma)

    def __repr__(self):
        return f"PerturbationGain(c={self.scale:g}, gamma={self.exponent:g})"


def as_gain(value, kind: type[GainSequence], label: str) -> GainSequence:
    """Accept a gain object or a bare scale (then the default exponents apply)."""
    if isinstance(value, GainSequence):
        return value
    if isinstance(value, (int, float, np.floating)) and not isinstance(value, bool):
        return kind(float(value))
    raise ParameterError(
        f"option {label!r} must be a {kind.__name__} (or a number for its scale), got {value!r}"
    )
