"""Robust PID design and the robustness figures of a loop.

:func:`ms_constrained_pid` is Åström and Hägglund's design for load
disturbances under a robustness constraint: among PI and PID controllers
``kp + ki/s + kd s/(tf s + 1)`` (``tf = Td/10``) it takes the one with the
largest integral gain ``ki`` (the smallest integrated error after a load
step) whose loop ``L = C P`` keeps

* the peak sensitivity ``Ms = max |1/(1 + L)|`` and the peak complementary
  sensitivity ``Mt = max |L/(1 + L)|`` at most ``max_sensitivity``,
* every crossing of the negative real axis inside ``-1/GM`` with
  ``GM = Ms/(Ms - 1)`` (no conditionally stable loop, which a saturating
  actuator would destabilise),
* the gain crossover below ``bandwidth`` (by default twice the model's
  fastest pole or zero, and a tenth of the Nyquist frequency of a digital
  controller): an identified model says nothing of faster dynamics,

and whose closed loop is stable (all roots of the characteristic polynomial
in the open left half-plane).  The search is a grid over ``kp`` and the
integral frequency ``ki/kp`` for several ratios ``Td/Ti``, refined around
the best point.  It needs no delay, handles right-half-plane zeros, light
damping and integrators, and works for either sign of the plant's gain.

:func:`loop_figures` gives the stability, the margins (gain, phase and
delay), ``Ms``, ``Mt`` and the closed-loop poles of a PID loop on a linear
plant, continuous or discrete.

Examples
--------
>>> import numpy as np
>>> kp, ki, kd, tf = ms_constrained_pid([-1.0, 2.0], [1.0, 3.0, 2.0])     # a right-half-plane zero at s = 2
>>> f = loop_figures([-1.0, 2.0], [1.0, 3.0, 2.0], kp, ki, kd, tf)
>>> f["stable"], bool(f["Ms"] <= 1.6 + 1e-9), bool(ki > 0)
(True, True, True)
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from .. import config
from ..exceptions import ParameterError

__all__ = ["ms_constrained_pid", "loop_figures", "discrete_loop_figures", "frequency_grid", "default_bandwidth",
           "pid_polynomials", "constraints", "FILTER_RATIO", "TD_RATIOS", "BANDWIDTH_FACTOR"]

#: Derivative filter ``tf = Td / FILTER_RATIO`` (the classical N = 10).
FILTER_RATIO = 10.0
#: Ratios ``Td / Ti`` searched (0: a PI controller).
TD_RATIOS = (0.0, 0.1, 0.25, 0.5)
#: Default largest gain crossover, in multiples of the model's fastest pole or zero.
BANDWIDTH_FACTOR = 2.0
#: Points of the coarse search grid along ``kp`` and ``ki/kp``.
GRID = 32


def pid_polynomials(kp: float, ki: float, kd: float, tf: float) -> tuple[np.ndarray, np.ndarray]:
    """``(num, den)`` of ``kp + ki/s + kd s/(tf s + 1)`` (descending powers).

    Examples
    --------
    >>> pid_polynomials(2.0, 1.0, 0.5, 0.05)
    (array([0.6 , 2.05, 1.  ]), array([0.05, 1.  , 0.  ]))
    >>> pid_polynomials(2.0, 0.0, 0.0, 0.0)
    (array([2.]), array([1.]))
    """
    if kd == 0.0:
        return (np.array([kp, ki]), np.array([1.0, 0.0])) if ki != 0.0 else (np.array([kp]), np.array([1.0]))
    return np.array([kp * tf + kd, kp + ki * tf, ki]), np.array([tf, 1.0, 0.0])


def _roots_scale(num, den) -> np.ndarray:
    roots = np.concatenate([np.roots(num) if np.size(num) > 1 else np.zeros(0), np.roots(den)])
    return np.abs(roots[np.abs(roots) > 1e-9 * max(1.0, float(np.max(np.abs(roots), initial=1.0)))])


def default_bandwidth(num, den, dt: float | None = None) -> float:
    """The largest gain crossover the design allows: :data:`BANDWIDTH_FACTOR` times the model's fastest pole or
    zero, and a tenth of the Nyquist frequency ``pi/dt`` of a digital controller."""
    mags = _roots_scale(num, den)
    w = BANDWIDTH_FACTOR * (float(mags.max()) if mags.size else 1.0)
    return min(w, math.pi / (10 * dt)) if dt else w


def frequency_grid(num, den, *, bandwidth: float | None = None, points: int = 400) -> np.ndarray:
    """Frequencies (rad/s) for the loop's peaks: three decades around the model's dynamics and the bandwidth,
    with extra points around lightly damped poles."""
    mags = _roots_scale(num, den)
    lo = 0.001 * (float(mags.min()) if mags.size else 1.0)
    hi = 1000 * max(float(mags.max()) if mags.size else 1.0, bandwidth or 0.0)
    w = np.geomspace(min(lo, 0.001 * (bandwidth or lo * 1e3)), hi, points)
    extra = []
    for p in np.roots(den):
        mod = abs(p)
        if mod > 0 and p.imag > 0 and -p.real / mod < 0.3:
            zeta = max(-p.real / mod, 1e-4)
            extra.append(mod * (1.0 + np.linspace(-8, 8, 81) * zeta))
    if extra:
        w = np.unique(np.concatenate([w] + [e[e > 0] for e in extra]))
    return w


def _effective_sign(num, den) -> float:
    """The sign of the plant's gain at low frequency (of ``s^k P`` for ``k`` integrators)."""
    d = np.trim_zeros(np.asarray(den, dtype=float), "b")
    n = np.trim_zeros(np.asarray(num, dtype=float), "b")
    return float(np.sign(n[-1] / d[-1])) or 1.0


def _closed_loop_stable(num, den, gains: np.ndarray) -> np.ndarray:
    """Whether the loop of each PID row ``(kp, ki, kd, tf)`` has every closed-loop pole in the open left half-plane."""
    out = np.zeros(len(gains), dtype=bool)
    for i, (kp, ki, kd, tf) in enumerate(gains):
        cn, cd = pid_polynomials(kp, ki, kd, tf)
        with np.errstate(all="ignore"):
            char = np.trim_zeros(np.polyadd(np.polymul(den, cd), np.polymul(num, cn)), "f")
            companion = char[1:] / char[0] if char.size else char       # what np.roots decomposes
        out[i] = (char.size > 0 and np.all(np.isfinite(companion))
                  and (char.size == 1 or np.all(np.roots(char).real < 0)))
    return out


def constraints(P, w, KP, KI, KD, TF, ms: float, bandwidth: float):
    """``(peak, conditional, too_fast)`` of PID candidates (arrays of gains, any shape) on a plant's frequency
    response ``P`` at ``w``: ``max(Ms, Mt)``, a negative-real-axis crossing outside ``-1/GM``, and a gain
    crossover above ``bandwidth`` (the module notes)."""
    s = 1j * w
    C = KP[..., None] + KI[..., None] / s + KD[..., None] * s / (TF[..., None] * s + 1)
    L = C * P
    with np.errstate(all="ignore"):
        S = 1.0 / (1.0 + L)
        peak = np.maximum(np.abs(S).max(-1), np.abs(L * S).max(-1))
    gm = ms / (ms - 1.0)
    im = L.imag
    cross = (np.sign(im[..., :-1]) != np.sign(im[..., 1:])) & (L.real[..., :-1] < 0)
    conditional = np.any(cross & (np.abs(L[..., :-1]) > 1.0 / gm), axis=-1)
    too_fast = np.any(np.abs(L[..., w > bandwidth]) >= 1.0, axis=-1)
    return peak, conditional, too_fast


def _feasible(P, s, w, KP, KI, KD, TF, ms: float, bandwidth: float):
    """``(peak, ok)`` on a grid of candidates (leading axes) for the frequency response ``P(s)``."""
    peak, conditional, too_fast = constraints(P, w, KP, KI, KD, TF, ms, bandwidth)
    return peak, np.isfinite(peak) & (peak <= ms) & ~conditional & ~too_fast


def _best_on_grid(num, den, P, s, w, kps, wis, ratios, ms, bandwidth, factors=(1.0,)):
    """The feasible grid point of largest ``|ki|`` whose loop is stable for every gain factor of the plant."""
    best = None
    for ratio in ratios:
        KP, WI = np.meshgrid(kps, wis, indexing="ij")
        KI = KP * WI
        KD = KP * ratio / WI
        TF = np.abs(KD / KP) / FILTER_RATIO
        ok = np.ones(KP.shape, dtype=bool)
        for k in factors:
            ok &= _feasible(k * P, s, w, KP, KI, KD, TF, ms, bandwidth)[1]
        idx = np.argwhere(ok)
        if idx.size == 0:
            continue
        idx = idx[np.argsort(-np.abs(KI[ok]))]
        for chunk in range(0, len(idx), 64):
            sel = idx[chunk:chunk + 64]
            rows = np.column_stack([KP[sel[:, 0], sel[:, 1]], KI[sel[:, 0], sel[:, 1]], KD[sel[:, 0], sel[:, 1]],
                                    TF[sel[:, 0], sel[:, 1]]])
            stable = np.ones(len(rows), dtype=bool)
            for k in factors:
                stable &= _closed_loop_stable(k * np.asarray(num), den, rows)
            if stable.any():
                row = rows[np.argmax(stable)]
                if best is None or abs(row[1]) > abs(best[0][1]):
                    best = (row, ratio)
                break
    return best


def ms_constrained_pid(num, den, *, max_sensitivity: float | None = None, kind: str = "pid",
                       bandwidth: float | None = None, dt: float | None = None,
                       gain_factors=(1.0,)) -> tuple[float, float, float, float]:
    """The PI or PID with the largest integral gain under the module's robustness constraints.

    Parameters
    ----------
    num, den : array_like
        The linear plant (small-signal, at the operating point), descending powers.
    max_sensitivity : float, optional
        Default ``config.defaults["control.max_sensitivity"]`` (1.6).
        Largest ``Ms`` and ``Mt`` (1.2-2.0; 1.4 is conservative, 2.0 aggressive).
    kind : {"pid", "pi"}
        ``"pid"`` searches PI and PID and keeps the better (it may be a PI).
    bandwidth : float, optional
        Largest gain crossover (rad/s); default :func:`default_bandwidth`.
    dt : float, optional
        A digital controller's sampling interval (bounds the default bandwidth).
    gain_factors : sequence of float, default (1,)
        The plant's gain as a multiple of ``num/den`` over the operating range
        (a nonlinear plant's small-signal gain varies with the operating
        point): every constraint must hold for each.

    Returns
    -------
    (kp, ki, kd, tf)

    Raises
    ------
    ParameterError
        When no controller meets the constraints (e.g. an unstable plant, or
        a bandwidth too small to stabilise).
    """
    num = np.trim_zeros(np.atleast_1d(np.asarray(num, dtype=float)), "f")
    den = np.trim_zeros(np.atleast_1d(np.asarray(den, dtype=float)), "f")
    ms = config.get("control.max_sensitivity") if max_sensitivity is None else float(max_sensitivity)
    if not 1.0 < ms < 10.0:
        raise ParameterError(f"max_sensitivity must be between 1 and 10 (1.4-2.0 is usual), got {max_sensitivity!r}")
    if kind not in ("pid", "pi"):
        raise ParameterError(f"kind must be 'pid' or 'pi', got {kind!r}")
    bw = default_bandwidth(num, den, dt) if bandwidth is None else float(bandwidth)
    if not (math.isfinite(bw) and bw > 0):
        raise ParameterError(f"bandwidth must be a positive frequency (rad/s), got {bandwidth!r}")
    w = frequency_grid(num, den, bandwidth=bw)
    s = 1j * w
    with np.errstate(all="ignore"):
        P = np.polyval(num, s) / np.polyval(den, s)
    scale = _effective_sign(num, den) / float(np.abs(P[np.argmin(np.abs(w - bw))]))   # |kp P| ~ 1 at bw
    ratios = TD_RATIOS if kind == "pid" else (0.0,)
    kps = scale * np.geomspace(1e-4, 1e2, GRID)
    wis = np.geomspace(w[0], bw, GRID)
    factors = tuple(float(k) for k in gain_factors)
    if not factors or not all(math.isfinite(k) and k > 0 for k in factors):
        raise ParameterError(f"gain_factors must be positive multiples of the plant's gain, got {gain_factors!r}")
    best = _best_on_grid(num, den, P, s, w, kps, wis, ratios, ms, bw, factors)
    if best is None:
        raise ParameterError(f"no PI or PID keeps Ms and Mt <= {ms:g} with a crossover below {bw:.4g} rad/s on this "
                             "plant: raise max_sensitivity or the bandwidth, or check that the plant is stable")
    (kp, ki, _, _), ratio = best
    fine_kp = kp * np.geomspace(0.7, 1.4, 16)
    fine_wi = (ki / kp) * np.geomspace(0.7, 1.4, 16)
    refined = _best_on_grid(num, den, P, s, w, fine_kp, fine_wi, (ratio,), ms, bw, factors)
    row = refined[0] if refined is not None and abs(refined[0][1]) >= abs(ki) else best[0]
    return tuple(float(v) for v in row)


def loop_figures(num, den, kp: float, ki: float, kd: float, tf: float) -> dict:
    """Stability, margins, ``Ms``, ``Mt`` and closed-loop poles of a continuous PID loop on a linear plant.

    Returns
    -------
    dict
        ``stable``, ``poles``, ``Ms``, ``Mt``, ``gain_margin``,
        ``phase_margin`` (deg), ``delay_margin`` (s), ``w_gain_crossover``,
        ``w_phase_crossover``.
    """
    cn, cd = pid_polynomials(kp, ki, kd, tf)
    return _figures(np.polymul(num, cn), np.polymul(den, cd), None)


def discrete_loop_figures(loop_num, loop_den, dt: float) -> dict:
    """:func:`loop_figures` of a discrete loop transfer function ``L(z) = loop_num / loop_den``."""
    return _figures(np.asarray(loop_num, dtype=float), np.asarray(loop_den, dtype=float), float(dt))


def _figures(lnum, lden, dt) -> dict:
    import control

    L = control.tf(lnum, lden, dt) if dt else control.tf(lnum, lden)
    char = np.trim_zeros(np.polyadd(np.asarray(lden, float), np.asarray(lnum, float)), "f")
    poles = np.roots(char) if char.size > 1 else np.zeros(0, dtype=complex)
    stable = bool(np.all(np.abs(poles) < 1.0)) if dt else bool(np.all(poles.real < 0))
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)          # python-control's note on its frd fallback
        gm, pm, _, wpc, wgc, _ = control.stability_margins(L)
    if dt:
        w = np.linspace(1e-6, math.pi / dt, 20000)
    else:
        mags = _roots_scale(lnum, lden)
        w = np.geomspace(1e-4 * (float(mags.min()) if mags.size else 1.0),
                         1e4 * (float(mags.max()) if mags.size else 1.0), 20000)
    resp = control.frequency_response(L, w)
    Lw = np.asarray(resp.complex).reshape(-1)
    with np.errstate(all="ignore"):
        ms = float(np.nanmax(np.abs(1.0 / (1.0 + Lw))))
        mt = float(np.nanmax(np.abs(Lw / (1.0 + Lw))))
    delay = float(np.radians(pm) / wgc) if np.isfinite(pm) and np.isfinite(wgc) and wgc > 0 else math.inf
    return {"stable": stable, "poles": poles, "Ms": ms, "Mt": mt, "gain_margin": float(gm),
            "phase_margin": float(pm), "delay_margin": delay, "w_gain_crossover": float(wgc),
            "w_phase_crossover": float(wpc)}
