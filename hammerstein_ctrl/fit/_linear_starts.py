"""Candidate linear blocks from the data alone: poles placed over the record's band, ARX poles, and their
stabilisation."""

from __future__ import annotations

import numpy as np
from ..simulate._simulate import unstable
from ..optimize import _streamed_lstsq as streamed_lstsq
from ..optimize._streamed_lstsq import constant_column, factor_of_blocks, solve_minimum_norm, triangular_factor

__all__ = ["stabilize", "continuous_poles", "POLE_PATTERNS"]


#: Frequencies scanned per pole pattern (at least; see :data:`SCAN_PER_DECADE`).
SCAN_FREQUENCIES = 12
#: Density of the scanned frequencies on long records, whose band spans more decades (past four): the
#: band of a 1e6-sample record (five decades) had 2.9 times between scanned frequencies where a
#: 1e4-sample record's had 1.9, and no candidate came near a plant's poles.
SCAN_PER_DECADE = 3
#: Lowest scanned frequency: this many periods fit in the record.
MIN_PERIODS = 2.0
#: Highest scanned frequency as a fraction of the Nyquist frequency.
MAX_NYQUIST_FRACTION = 0.5
#: Pole patterns of the scan: repeated real poles, a damped pair (zeta) with
#: real poles, real poles spread geometrically by this ratio.
POLE_PATTERNS = ("real", "pair", "spread")
PAIR_DAMPING = 0.1
SPREAD_RATIO = 10.0
#: Half-planes of the scanned zeros (-1 left, +1 right).
ZERO_SIDES = (-1.0, 1.0)
#: Scan candidates refined by Levenberg-Marquardt on the reduced residual.
REFINED_CANDIDATES = 3
# ---------------------------------------------------------------------------
# candidate linear blocks
# ---------------------------------------------------------------------------
def _frequencies(data) -> np.ndarray:
    lo = 2 * np.pi * MIN_PERIODS / max(data.duration, data.dt)
    hi = MAX_NYQUIST_FRACTION * np.pi / data.dt
    hi = max(hi, 1.01 * lo)
    return np.geomspace(lo, hi, max(SCAN_FREQUENCIES, int(np.ceil(SCAN_PER_DECADE * np.log10(hi / lo)))))


def _poles(pattern: str, w: float, m: int) -> np.ndarray:
    if pattern == "pair" and m >= 2:
        wd = w * np.sqrt(1 - PAIR_DAMPING**2)
        pair = [-PAIR_DAMPING * w + 1j * wd, -PAIR_DAMPING * w - 1j * wd]
        return np.concatenate([pair, -w * np.ones(m - 2)])
    if pattern == "spread" and m >= 2:
        return -w * SPREAD_RATIO ** np.linspace(-0.5, 0.5, m)
    return -w * np.ones(m)


def _arx_poles(data, drives, m: int) -> np.ndarray | None:
    """Continuous-time poles of a discrete ARX fit of order ``m`` (stabilised), or ``None``.

    Equation error is biased by noise, but places the poles' time scales far
    better than a scan when they are a decade or more apart.  The lagged
    columns are views of the record (streamed, never stacked).
    """
    y = np.asarray(data.y, dtype=float)
    N = y.size
    if N <= 4 * m + 2:
        return None
    if drives.array is None:
        R = factor_of_blocks(_lagged_blocks(y, drives, m), (1 + drives.count) * m + 2)
    else:
        lagged = [y[m - i:N - i] for i in range(1, m + 1)]
        lagged += [d[m - i:N - i] for d in drives.array for i in range(1, m + 1)]
        R = triangular_factor(lagged + [constant_column(N - m)], y[m:])
    if not np.all(np.isfinite(R)):
        return None
    coef = solve_minimum_norm(R, N - m)
    return continuous_poles(np.roots(np.concatenate([[1.0], -coef[:m]])), data.dt)


def continuous_poles(z, dt: float) -> np.ndarray | None:
    """Stable continuous-time poles ``s = log(z) / dt`` of discrete ones ``z`` (``None`` if one is at 0).

    A negative real discrete pole (an oscillation at the Nyquist rate, typical
    of a noisy fit) has no continuous-time image: its log has the imaginary
    part ``pi/dt`` and no conjugate, which would make a real polynomial of the
    poles unstable; its decay rate stands in for it.  Right-half-plane images
    are reflected.

    Examples
    --------
    >>> np.round(continuous_poles([-0.5, -0.6], 0.05).real, 2).tolist()
    [-13.86, -10.22]
    """
    z = np.asarray(z, dtype=complex)
    nyquist = (np.abs(z.imag) <= 1e-12 * np.abs(z)) & (z.real < 0)
    with np.errstate(all="ignore"):
        s = np.where(nyquist, np.log(np.abs(z)) + 0j, np.log(z)) / dt
    if not np.all(np.isfinite(s)):
        return None
    return np.where(s.real > 0, -s.real + 1j * s.imag, s)


def _lagged_blocks(y, drives, m: int):
    """Blocks of ``[y lags, drive lags, 1, y]`` at samples ``m..N-1`` (the ARX regression), ``drives`` (the
    initialisation's drive signals) formed by blocks."""
    N = y.size
    width = (1 + drives.count) * m + 2
    size = streamed_lstsq.BLOCK_SAMPLES
    block = np.empty((min(size, N - m), width), order="F")
    for a in range(m, N, size):
        b = min(a + size, N)
        part, D = block[:b - a], drives.part(a - m, b - 1)
        for i in range(1, m + 1):
            part[:, i - 1] = y[a - i:b - i]
            part[:, m * np.arange(1, 1 + drives.count) + i - 1] = D[:, m - i:m - i + b - a].T
        part[:, -2] = 1.0
        part[:, -1] = y[a:b]
        yield part


def _candidate_linear(linear, data, drives) -> dict:
    """Free coefficients of stable candidate blocks, grouped by the half-plane of their zeros.

    Pole sets: the scan patterns over the record's bandwidth and the ARX fit.
    Zeros (if any) sit at a scanned frequency, in the left half-plane or, for
    a non-minimum-phase plant, in the right half-plane.  A local search cannot
    move a zero across the origin (the gain vanishes there), so both groups
    are refined.
    """
    freqs = _frequencies(data)
    pole_sets = [_poles(pattern, w, linear.den_order)
                 for pattern in (POLE_PATTERNS if linear.den_order >= 2 else ("real",)) for w in freqs]
    arx = _arx_poles(data, drives, linear.den_order)
    if arx is not None:
        pole_sets.append(arx)
    groups: dict = {}
    nums: dict = {}                     # each numerator once: pole sets share the scanned zeros
    for i, poles in enumerate(pole_sets):
        den = np.real(np.poly(poles))
        zero_freqs = freqs if i == len(pole_sets) - 1 and arx is not None else [freqs[i % freqs.size]]
        for w in zero_freqs:
            for side in ZERO_SIDES if linear.num_order else (-1.0,):
                if (w, side) not in nums:
                    nums[w, side] = np.real(np.poly(side * w * np.ones(linear.num_order)))
                groups.setdefault(side, []).append(linear.free_parameters(nums[w, side], den))
    return {side: np.unique(np.array(rows), axis=0) for side, rows in groups.items()}


def stabilize(linear, theta) -> np.ndarray:
    """Reflect right-half-plane poles of a linear block into the left half-plane.

    Fixed coefficients keep their values (so a fixed pole at the origin stays).

    Examples
    --------
    >>> from hammerstein_ctrl.blocks import LinearStructure
    >>> stabilize(LinearStructure(0, 2, fixed={"a0": 0.0}), [-1.0]).tolist()   # p^2 - p -> p^2 + p
    [1.0]
    """
    theta = np.asarray(theta, dtype=float)
    num, den = linear.coefficients(theta)
    if not unstable(den)[0]:
        return theta.copy()
    roots = np.roots(den[0])
    roots = np.where(roots.real > 0, -roots.real + 1j * roots.imag, roots)
    return linear.free_parameters(num[0], np.real(np.poly(roots)))
