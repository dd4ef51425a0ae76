"""Exact sampled simulation of a Lur'e loop with friction: a linear block, sign friction fed back on one signal.

The loop (:mod:`~hammerstein_ctrl.lure`) is

.. code-block:: text

    x' = A x + B w,   y = C x,   z = Cz x            (z: the output, or its derivative)
    w  = u - k z - fc sign(z) - c                      (friction on z; fc >= 0)

with the input ``u`` held between samples (``"zoh"``) or linear between them
(``"foh"``).  Between the instants where ``z`` changes sign the loop is linear
with a constant friction force, so it is solved exactly: the sampled recursion
of the block with ``k`` folded into ``A`` (one matrix exponential per
candidate) and ``+-fc`` added to the input.  A sample in which ``z`` changes
sign is split at the crossing (found by a bracketed root search on the exact
solution, evaluated by its Taylor series); at ``z = 0`` the motion continues
in the direction the forces push, or **sticks**: ``z`` stays 0 while the
friction force that keeps it there, ``f_eq``, lies within ``[-fc, fc]``
(Filippov's sliding solution, ``x' = A_s x``), and slips again where
``|f_eq|`` reaches ``fc``.

Limits: a sign change of ``z`` that starts and ends inside one sample (two
crossings between samples) is not seen; a sample may hold at most
:data:`MAX_EVENTS` switches (the rest of it keeps the last mode).  ``z`` must
be driven directly by ``w`` (``Cz B != 0``: relative degree 1 from ``w`` to ``z``).
"""

from __future__ import annotations

import functools

import numba
import numba.extending
import numpy as np

from ._attributes import never_inline
from ._jit import cached_njit, function_address, kernel_signature, typed_call
from ._linalg import copy_vector, expm_into, one_norm, tf_augmented
from ._native import DEPENDS as NATIVE_DEPENDS

__all__ = ["lure_setup", "lure_run", "lure_loop_run", "sample_address", "MAX_EVENTS", "FEEDBACK_CODES"]

#: Files whose compiled code these functions call (the matrix exponential, the 1-norm): an edit compiles them again.
_DEPENDS = ("_linalg.py",) + NATIVE_DEPENDS
#: Most mode switches resolved within one sample.
MAX_EVENTS = 16
#: Code of each feedback signal in the compiled setup.
FEEDBACK_CODES = {"output": 0, "velocity": 1}
#: Largest 1-norm of ``A dt`` over one Taylor segment (longer intervals are split).
_TAYLOR_NORM = 0.5
#: Most Taylor segments of one propagation; beyond, the matrix exponential.
_TAYLOR_MAX = 4
#: Iterations of the root search (bracketing; each at least halves the bracket every third step).
_ROOT_ITERATIONS = 200


@cached_njit(depends=_DEPENDS)
def lure_setup(num, den, dt, slope, feedback):  # pragma: no cover - compiled
    """Per-candidate matrices of the loop: ``(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok)``.

    ``Adt = (A - k B Cz) dt`` (the slipping loop), ``Asdt = A_s dt`` (sticking:
    ``A_s = Ae - B Q``), ``Bdt = B dt``, ``h = Cz B``, ``Q = Cz Ae / h`` (the holding force is
    ``u - c + Q x``); ``Phi, G0, G1``
    the exact FOH step of the slipping loop, ``Ps = expm(A_s dt)``.  ``ok`` is
    False for a candidate with non-finite coefficients or ``h == 0``.
    """
    batch, n = den.shape[0], den.shape[1] - 1
    M, C, D = tf_augmented(num, den, 1.0)
    Adt = np.zeros((batch, n, n))
    Asdt = np.zeros((batch, n, n))
    Bdt = np.zeros((batch, n))
    Cz = np.zeros((batch, n))
    h = np.zeros(batch)
    Q = np.zeros((batch, n))
    Phi = np.zeros((batch, n, n))
    G0 = np.zeros((batch, n))
    G1 = np.zeros((batch, n))
    Ps = np.zeros((batch, n, n))
    ok = np.ones(batch, dtype=np.bool_)
    aug = np.zeros((n + 2, n + 2))
    E = np.zeros((n + 2, n + 2))
    Es = np.zeros((n, n))
    for b in range(batch):
        A = M[b, :n, :n]
        B = M[b, :n, n]
        good = np.isfinite(slope[b]) and D[b] == 0.0
        for i in range(n):
            good = good and np.isfinite(C[b, i]) and np.isfinite(B[i])
            for j in range(n):
                good = good and np.isfinite(A[i, j])
        if feedback == 0:
            copy_vector(C[b], Cz[b])
        else:
            for j in range(n):
                s = 0.0
                for i in range(n):
                    s += C[b, i] * A[i, j]
                Cz[b, j] = s
        hb = 0.0
        for i in range(n):
            hb += Cz[b, i] * B[i]
        h[b] = hb
        if not good or hb == 0.0 or not np.isfinite(hb):
            ok[b] = False
            continue
        Ae = A.copy()
        for i in range(n):
            for j in range(n):
                Ae[i, j] -= slope[b] * B[i] * Cz[b, j]
        q = Q[b]                               # Cz Ae / h
        for j in range(n):
            s = 0.0
            for i in range(n):
                s += Cz[b, i] * Ae[i, j]
            q[j] = s / hb
        for i in range(n):
            Bdt[b, i] = B[i] * dt
            for j in range(n):
                Adt[b, i, j] = Ae[i, j] * dt
                Asdt[b, i, j] = (Ae[i, j] - B[i] * q[j]) * dt
        aug[:, :] = 0.0
        for i in range(n):
            for j in range(n):
                aug[i, j] = Adt[b, i, j]
            aug[i, n] = Bdt[b, i]
        aug[n, n + 1] = 1.0
        expm_into(aug, E)
        expm_into(Asdt[b].copy(), Es)
        for i in range(n):
            for j in range(n):
                Phi[b, i, j] = E[i, j]
                Ps[b, i, j] = Es[i, j]
            G0[b, i] = E[i, n]
            G1[b, i] = E[i, n + 1]
        for i in range(n):
            for j in range(n):
                if not (np.isfinite(Phi[b, i, j]) and np.isfinite(Ps[b, i, j])):
                    ok[b] = False
    return Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok


@cached_njit(depends=_DEPENDS)
def _propagate(Adt, Bdt, x, w0, s, delta, out, t1, t2):  # pragma: no cover - compiled
    """``out = x(delta)`` of ``x' = Adt x + Bdt (w0 + s tau)`` (normalised time) from ``x(0) = x``.

    A Taylor series where ``||Adt|| delta`` is small (split into pieces with
    ``||Adt|| piece <= 0.5``; each piece's series summed until its terms no
    longer change the sum); past :data:`_TAYLOR_MAX` pieces (a stiff block or
    a coarse sample) the matrix exponential of the augmented system.
    """
    never_inline()                      # called at a dozen places of the event handling: one copy of it
    n = x.shape[0]
    pieces = max(1, int(np.ceil(one_norm(Adt) * delta / _TAYLOR_NORM)))
    if pieces > _TAYLOR_MAX:
        _propagate_expm(Adt, Bdt, x, w0, s, delta, out)
        return
    step = delta / pieces
    copy_vector(x, out)
    w = w0
    for _ in range(pieces):
        # t1: the current derivative term d_k step^k / k!; t2: scratch
        for i in range(n):
            acc = Bdt[i] * w
            for j in range(n):
                acc += Adt[i, j] * out[j]
            t1[i] = acc * step
        for i in range(n):
            out[i] += t1[i]
        k = 2
        while k < 60:
            small = True
            for i in range(n):
                acc = Bdt[i] * s * step if k == 2 else 0.0
                for j in range(n):
                    acc += Adt[i, j] * t1[j]
                t2[i] = acc * step / k
            for i in range(n):
                t1[i] = t2[i]
                new = out[i] + t1[i]
                if new != out[i]:
                    small = False
                out[i] = new
            if small and k > 2:
                break
            k += 1
        w += s * step


@cached_njit(depends=_DEPENDS)
def _propagate_expm(Adt, Bdt, x, w0, s, delta, out):  # pragma: no cover - compiled
    """:func:`_propagate` by the exponential of ``[[Adt delta, Bdt delta, 0], [0, 0, 1], [0, 0, 0]]``."""
    n = x.shape[0]
    M = np.zeros((n + 2, n + 2))
    E = np.empty((n + 2, n + 2))
    for i in range(n):
        for j in range(n):
            M[i, j] = Adt[i, j] * delta
        M[i, n] = Bdt[i] * delta
    M[n, n + 1] = 1.0
    expm_into(M, E)
    for i in range(n):
        acc = E[i, n] * w0 + E[i, n + 1] * s * delta
        for j in range(n):
            acc += E[i, j] * x[j]
        out[i] = acc


@cached_njit(depends=_DEPENDS)
def _dot(a, x):  # pragma: no cover - compiled
    s = 0.0
    for i in range(x.shape[0]):
        s += a[i] * x[i]
    return s


@cached_njit(depends=_DEPENDS)
def _decide(Cz, q, x, force, fc, h):  # pragma: no cover - compiled
    """Mode at ``z = 0``: +1 or -1 where the forces move ``z`` that way, 0 (stick) where friction holds it.

    ``force = u - c`` at that instant; ``q = Cz Ae / h``, so that the friction
    force that keeps ``z' = 0`` is ``f_eq = force + q x``.
    """
    feq = force + _dot(q, x)
    up = h * (feq - fc) > 0.0               # z' with friction +fc
    down = h * (feq + fc) < 0.0             # z' with friction -fc
    if up and down:
        return 1 if h * feq >= 0.0 else -1
    if up:
        return 1
    if down:
        return -1
    return 0


@cached_njit(depends=_DEPENDS)
def _first_mode(Cz, q, x, force, fc, h):  # pragma: no cover - compiled
    """The mode at the start: the side ``z`` is on, or :func:`_decide`'s choice on ``z = 0``."""
    z = _dot(Cz, x)
    return 1 if z > 0 else (-1 if z < 0 else _decide(Cz, q, x, force, fc, h))


@cached_njit(depends=_DEPENDS)
def _event_value(Adt, Bdt, p, x, w0, s, delta, offset, xs, t1, t2):  # pragma: no cover - compiled
    """``(g, g')`` at ``delta`` of the event function ``g = p . x(delta) + s delta + offset`` along
    ``x' = Adt x + Bdt (w0 + s tau)``, the state at ``delta`` left in ``xs``."""
    _propagate(Adt, Bdt, x, w0, s, delta, xs, t1, t2)
    value, slope = offset, 0.0
    w = w0 + s * delta
    for i in range(xs.shape[0]):
        value += p[i] * xs[i]
        acc = Bdt[i] * w
        for j in range(xs.shape[0]):
            acc += Adt[i, j] * xs[j]
        slope += p[i] * acc
    return value, slope


@cached_njit(depends=_DEPENDS)
def _root(Adt, Bdt, p, x, w0, s, ramp, offset, lo_val, hi, hi_val, xs, t1, t2):  # pragma: no cover - compiled
    """The instant in ``(0, hi]`` where ``g = p . x(tau) + ramp tau + offset`` changes sign (``g(0) = lo_val``,
    ``g(hi) = hi_val`` of opposite signs): Newton's method kept inside the bracket (bisection where a step
    leaves it).  The state there is left in ``xs``."""
    a, fa, b = 0.0, lo_val, hi
    m = hi * lo_val / (lo_val - hi_val) if lo_val != hi_val else 0.5 * hi
    for _ in range(_ROOT_ITERATIONS):
        if not (a < m < b):
            m = 0.5 * (a + b)
        fm, dm = _event_value(Adt, Bdt, p, x, w0, s, m, offset, xs, t1, t2)
        fm += ramp * m
        dm += ramp
        if fm == 0.0:
            return m
        if (fm > 0) == (fa > 0):
            a, fa = m, fm
        else:
            b = m
        step = fm / dm if dm != 0.0 else np.inf
        if abs(step) <= 2e-16 * max(1.0, m) or b - a <= 4e-16 * max(1.0, b):
            return m
        m = m - step
    return 0.5 * (a + b)


@cached_njit(depends=_DEPENDS)
def _row_times(p, A, out):  # pragma: no cover - compiled
    """``out = p A`` (a row vector times a matrix)."""
    for j in range(A.shape[1]):
        acc = 0.0
        for i in range(A.shape[0]):
            acc += p[i] * A[i, j]
        out[j] = acc


@cached_njit(depends=_DEPENDS)
def _slip_dip(Adt, Bdt, Cz, x, xn, w0, s, rest, mode, pv, xs, t1, t2):  # pragma: no cover - compiled
    """``(tau, z)`` where ``z`` has the opposite sign inside a slipping segment whose ends share a sign (it turns
    back towards zero and away again), or ``(-1, 0)``: the turning point of ``z`` is located (``z' = 0``) and
    ``z`` read there."""
    if not _dot(Cz, x) * mode > 0.0:         # leaving the surface (from sticking): no turn back to look for
        return -1.0, 0.0
    _row_times(Cz, Adt, pv)                  # z' = pv . x + cb (w0 + s tau)
    cb = _dot(Cz, Bdt)
    d0 = _dot(pv, x) + cb * w0
    d1 = _dot(pv, xn) + cb * (w0 + s * rest)
    if not (d0 * mode < 0.0 < d1 * mode):
        return -1.0, 0.0
    turn = _root(Adt, Bdt, pv, x, w0, s, cb * s, cb * w0, d0, rest, d1, xs, t1, t2)
    _propagate(Adt, Bdt, x, w0, s, turn, xs, t1, t2)
    z = _dot(Cz, xs)
    return (turn, z) if z * mode < 0.0 else (-1.0, 0.0)


#: Margin of :func:`_may_turn` over the quadratic estimate of how far ``z`` turns back inside a sample.
_TURN_MARGIN = 4.0


@cached_njit(depends=_DEPENDS)
def _may_turn(z0, d0, d1):  # pragma: no cover - compiled
    """Whether ``z`` (slipping, signs taken so that its side is positive: ``z0 > 0``) may reach zero inside a
    sample whose ends are on its side: it heads back (``d0 = z'(0) < 0``), turns (``d1 = z'(1) > 0``), and the
    depth of the turn, ``d0^2 / (2 (d1 - d0))`` for a quadratic, comes within :data:`_TURN_MARGIN` of ``z0``.
    Then :func:`_slip_dip` locates the turn exactly."""
    return d0 < 0.0 < d1 and z0 * (d1 - d0) <= _TURN_MARGIN * 0.5 * d0 * d0


@cached_njit(depends=_DEPENDS)
def _crossing(Adt, Bdt, Cz, x, w0, s, hi, z_hi, mode, pv, xn, xs, t1, t2):  # pragma: no cover - compiled
    """Where ``z`` reaches zero in ``(0, hi]`` while slipping in direction ``mode`` (``z(hi)`` is on the other side).

    From ``z`` on the mode's side, the bracketed root.  From the surface itself
    (``z(0) = 0``, just after an event, its rounding on either side), the root
    after ``z`` turns back: the turn (``z' = 0``) is located first, so that the
    search does not return the start.  ``xn`` is overwritten.
    """
    z0 = _dot(Cz, x)
    if z0 * mode > 0.0:
        return _root(Adt, Bdt, Cz, x, w0, s, 0.0, 0.0, z0, hi, z_hi, xs, t1, t2)
    _row_times(Cz, Adt, pv)                  # z' = pv . x + cb (w0 + s tau)
    cb = _dot(Cz, Bdt)
    d0 = _dot(pv, x) + cb * w0
    _propagate(Adt, Bdt, x, w0, s, hi, xs, t1, t2)
    d1 = _dot(pv, xs) + cb * (w0 + s * hi)
    if not (d0 * mode > 0.0 > d1 * mode):
        return 0.0
    turn = _root(Adt, Bdt, pv, x, w0, s, cb * s, cb * w0, d0, hi, d1, xs, t1, t2)
    _propagate(Adt, Bdt, x, w0, s, turn, xn, t1, t2)
    z_turn = _dot(Cz, xn)
    if not z_turn * mode > 0.0:
        return 0.0
    return turn + _root(Adt, Bdt, Cz, xn, w0 + s * turn, s, 0.0, 0.0, z_turn, hi - turn, z_hi, xs, t1, t2)


@cached_njit(depends=_DEPENDS)
def _stick_peak(Asdt, Bdt, q, x, xn, f0, s, rest, fc, pv, xs, t1, t2):  # pragma: no cover - compiled
    """``(tau, f)`` where the holding force ``f`` passes the Coulomb level inside a sticking segment whose ends are
    within it (it peaks between them), or ``(-1, 0)``."""
    _row_times(q, Asdt, pv)                  # f' = s + pv . x  (x' = Asdt x while stuck)
    e0, e1 = s + _dot(pv, x), s + _dot(pv, xn)
    if not e0 * e1 < 0.0:
        return -1.0, 0.0
    turn = _root(Asdt, Bdt, pv, x, 0.0, 0.0, 0.0, s, e0, rest, e1, xs, t1, t2)
    _propagate(Asdt, Bdt, x, 0.0, 0.0, turn, xs, t1, t2)
    f = f0 + s * turn + _dot(q, xs)
    return (turn, f) if abs(f) > fc else (-1.0, 0.0)


@cached_njit(depends=_DEPENDS)
def _sample(Adt, Asdt, Bdt, Cz, q, h, Phi, G0, G1, Ps, x, mode, uk, s, c, fc, xn, xs, t1, t2, pv):  # pragma: no cover
    """Advance ``x`` (in place) over one sample from mode ``mode``; returns the mode at its end."""
    n = x.shape[0]
    tau = 0.0
    for _ in range(MAX_EVENTS + 1):
        rest = 1.0 - tau
        if mode != 0:
            w0 = uk + s * tau - c - mode * fc
            if tau == 0.0:
                for i in range(n):
                    acc = G0[i] * w0 + G1[i] * s
                    for j in range(n):
                        acc += Phi[i, j] * x[j]
                    xn[i] = acc
            else:
                _propagate(Adt, Bdt, x, w0, s, rest, xn, t1, t2)
            hi, z1 = rest, _dot(Cz, xn)
            if z1 * mode >= 0.0:
                hi, z1 = _slip_dip(Adt, Bdt, Cz, x, xn, w0, s, rest, mode, pv, xs, t1, t2)
                if hi < 0.0:
                    copy_vector(xn, x)
                    return mode
            d = _crossing(Adt, Bdt, Cz, x, w0, s, hi, z1, mode, pv, xn, xs, t1, t2)
            _propagate(Adt, Bdt, x, w0, s, d, xs, t1, t2)
            copy_vector(xs, x)
            tau += d
            mode = _decide(Cz, q, x, uk + s * tau - c, fc, h)
            if mode == 0:                       # on z = 0 exactly (the root search leaves ~1e-19)
                z = _dot(Cz, x) / h
                for i in range(n):
                    x[i] -= Bdt[i] / Bdt[0] * z if Bdt[0] != 0.0 else 0.0
        else:
            f0 = uk + s * tau - c
            now = f0 + _dot(q, x)
            if abs(now) > fc:                   # the input stepped past the friction: slips at once
                mode = 1 if now * h > 0 else -1
                continue
            if tau == 0.0:
                for i in range(n):
                    acc = 0.0
                    for j in range(n):
                        acc += Ps[i, j] * x[j]
                    xn[i] = acc
            else:
                _propagate(Asdt, Bdt, x, 0.0, 0.0, rest, xn, t1, t2)
            hi, f1 = rest, f0 + s * rest + _dot(q, xn)
            if abs(f1) <= fc:
                hi, f1 = _stick_peak(Asdt, Bdt, q, x, xn, f0, s, rest, fc, pv, xs, t1, t2)
                if hi < 0.0:
                    copy_vector(xn, x)
                    return 0
            sign = 1.0 if f1 > 0 else -1.0
            lo_val = f0 + _dot(q, x) - sign * fc
            d = _root(Asdt, Bdt, q, x, 0.0, 0.0, s, f0 - sign * fc, lo_val, hi, f1 - sign * fc, xs, t1, t2)
            _propagate(Asdt, Bdt, x, 0.0, 0.0, d, xs, t1, t2)
            copy_vector(xs, x)
            tau += d
            mode = 1 if sign * h > 0 else -1
        if tau >= 1.0:
            return mode
    # too many switches: finish the sample in the last mode without further checks
    if mode != 0:
        _propagate(Adt, Bdt, x.copy(), uk + s * tau - c - mode * fc, s, max(0.0, 1.0 - tau), x, t1, t2)
    else:
        _propagate(Asdt, Bdt, x.copy(), 0.0, 0.0, max(0.0, 1.0 - tau), x, t1, t2)
    return mode


#: Argument types of :func:`_sample` as compiled for calls through its address.
_SAMPLE_SIGNATURE = kernel_signature("w2 w2 w1 w1 w1 f w2 w1 w1 w2 w1 i f f f f w1 w1 w1 w1 w1")


@functools.lru_cache(maxsize=1)
def sample_address() -> int:
    """Address of :func:`_sample`'s machine code: the simulations call it through this address, so its code
    (the event handling, most of the simulator) is compiled once, not again into each of them.

    Examples
    --------
    >>> sample_address() > 0
    True
    """
    return function_address(_sample, _SAMPLE_SIGNATURE, numba.types.int64)


@numba.extending.intrinsic
def _call_sample(typingctx, address, Adt, Asdt, Bdt, Cz, q, h, Phi, G0, G1, Ps, x, mode, uk, s, c, fc, xn, xs, t1,
                 t2, pv):
    """``_sample(Adt, ..., pv)`` called at ``address`` (:func:`sample_address`) from compiled code."""
    return typed_call("_call_sample", _SAMPLE_SIGNATURE, address,
                      (Adt, Asdt, Bdt, Cz, q, h, Phi, G0, G1, Ps, x, mode, uk, s, c, fc, xn, xs, t1, t2, pv),
                      numba.types.int64)


@cached_njit(depends=_DEPENDS)
def _lure_run(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok, fc, c, X0, Y0, u, foh, y, out, want_outputs,
              sample):  # pragma: no cover - compiled
    """Simulate every candidate over ``u``: outputs into ``out[b]`` (``want_outputs``) or the SSE
    against ``y`` into ``out[b, 0]``; ``inf`` for a candidate that is not ``ok`` or overflows."""
    batch, n = Cz.shape
    x = np.zeros(n)
    xn = np.zeros(n)
    xs = np.zeros(n)
    t1 = np.zeros(n)
    t2 = np.zeros(n)
    pv = np.zeros(n)
    for b in range(batch):
        if not ok[b]:
            out[b, :] = np.inf
            continue
        Ab, Asb, Bb, Cb, Czb, Phib, G0b, G1b, Psb = Adt[b], Asdt[b], Bdt[b], C[b], Cz[b], Phi[b], G0[b], G1[b], Ps[b]
        hb, cb, fcb, y0, q = h[b], c[b], abs(fc[b]), Y0[b], Q[b]
        copy_vector(X0[b], x)
        mode = _first_mode(Czb, q, x, u[0] - cb, fcb, hb)
        if n == 2:
            sse = _samples_two(Ab, Asb, Bb, Cb, Czb, q, hb, Phib, G0b, G1b, Psb, x, mode, cb, fcb, y0, u, y, out[b],
                               want_outputs, foh, xn, xs, t1, t2, pv, sample)
        else:
            sse = _samples(Ab, Asb, Bb, Cb, Czb, q, hb, Phib, G0b, G1b, Psb, x, mode, cb, fcb, y0, u, y, out[b],
                           want_outputs, foh, xn, xs, t1, t2, pv, sample)
        if not want_outputs:
            out[b, 0] = sse if np.isfinite(sse) and sse < 1.7e308 else np.inf
    return out


@cached_njit(depends=_DEPENDS)
def _samples(Ab, Asb, Bb, Cb, Czb, q, hb, Phib, G0b, G1b, Psb, x, mode, cb, fcb, y0, u, y, outb, want_outputs, foh,
             xn, xs, t1, t2, pv, sample):  # pragma: no cover - compiled
    """One candidate over the record (any order): its outputs into ``outb``, or its SSE returned."""
    n, N = x.shape[0], u.shape[0]
    pz = np.zeros(n)                         # z' = pz . x + cz w (a turn of z inside a sample: the full check)
    _row_times(Czb, Ab, pz)
    cz = _dot(Czb, Bb)
    sse = 0.0
    for k in range(N):
        yk = y0
        for i in range(n):
            yk += Cb[i] * x[i]
        if want_outputs:
            outb[k] = yk
        else:
            e = yk - y[k]
            sse += e * e
        if k + 1 == N:
            break
        s = (u[k + 1] - u[k]) if foh else 0.0
        if mode != 0:                       # the common case: a whole sample slipping one way
            w0 = u[k] - cb - mode * fcb
            z1 = 0.0
            for i in range(n):
                acc = G0b[i] * w0 + G1b[i] * s
                for j in range(n):
                    acc += Phib[i, j] * x[j]
                xn[i] = acc
                z1 += Czb[i] * acc
            if z1 * mode >= 0.0 and not _may_turn(_dot(Czb, x) * mode, (_dot(pz, x) + cz * w0) * mode,
                                                  (_dot(pz, xn) + cz * (w0 + s)) * mode):
                copy_vector(xn, x)
                continue
        mode = _call_sample(sample, Ab, Asb, Bb, Czb, q, hb, Phib, G0b, G1b, Psb, x, mode, u[k], s, cb, fcb, xn, xs,
                            t1, t2, pv)
    return sse


@cached_njit(depends=_DEPENDS)
def _samples_two(Ab, Asb, Bb, Cb, Czb, q, hb, Phib, G0b, G1b, Psb, x, mode, cb, fcb, y0, u, y, outb, want_outputs,
                 foh, xn, xs, t1, t2, pv, sample):  # pragma: no cover - compiled
    """:func:`_samples` for two states (a mass: the common case), the state in registers between switches."""
    N = u.shape[0]
    p00, p01, p10, p11 = Phib[0, 0], Phib[0, 1], Phib[1, 0], Phib[1, 1]
    g0, g1, r0, r1 = G0b[0], G0b[1], G1b[0], G1b[1]
    c0, c1, z0, z1 = Cb[0], Cb[1], Czb[0], Czb[1]
    x0, x1 = x[0], x[1]
    pz0 = z0 * Ab[0, 0] + z1 * Ab[1, 0]       # z' = pz . x + cz w (a turn of z inside a sample: the full check)
    pz1 = z0 * Ab[0, 1] + z1 * Ab[1, 1]
    cz = z0 * Bb[0] + z1 * Bb[1]
    sse = 0.0
    side = float(mode)
    shift = cb + side * fcb                  # the input's constant part while slipping: c + fc sign(z)
    for k in range(N):
        yk = y0 + c0 * x0 + c1 * x1
        if want_outputs:
            outb[k] = yk
        else:
            e = yk - y[k]
            sse += e * e
        if k + 1 == N:
            break
        s = (u[k + 1] - u[k]) if foh else 0.0
        if mode != 0:
            w0 = u[k] - shift
            n0 = p00 * x0 + p01 * x1 + g0 * w0 + r0 * s
            n1 = p10 * x0 + p11 * x1 + g1 * w0 + r1 * s
            if (z0 * n0 + z1 * n1) * side >= 0.0 and not _may_turn(
                    (z0 * x0 + z1 * x1) * side, (pz0 * x0 + pz1 * x1 + cz * w0) * side,
                    (pz0 * n0 + pz1 * n1 + cz * (w0 + s)) * side):
                x0, x1 = n0, n1
                continue
        x[0], x[1] = x0, x1
        mode = _call_sample(sample, Ab, Asb, Bb, Czb, q, hb, Phib, G0b, G1b, Psb, x, mode, u[k], s, cb, fcb, xn, xs,
                            t1, t2, pv)
        x0, x1 = x[0], x[1]
        side = float(mode)
        shift = cb + side * fcb
    return sse


@cached_njit(depends=_DEPENDS)
def _lure_loop_run(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok, fc, c, X0, Y0, Ac, Bc, Cc, Dc, xc0, r, d,
                   Y, U, sample):  # pragma: no cover - compiled
    """Every candidate inside a known sampled controller: outputs ``Y[b]`` and control signals ``U[b]``.

    At sample ``k``: ``y_k = C x_k + y0``; ``u_k = Cc xc_k + Dc [r_k, y_k] + d_k``;
    ``xc_{k+1} = Ac xc_k + Bc [r_k, y_k]``; the plant holds ``u_k`` over the sample (a DAC: zero-order hold).
    A candidate that is not ``ok`` gets ``inf`` everywhere.
    """
    batch, n = Cz.shape
    N, nc = r.shape[0], Ac.shape[0]
    x, xn, xs, t1, t2, pv = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    xc, xcn = np.zeros(nc), np.zeros(nc)
    for b in range(batch):
        if not ok[b]:
            Y[b, :] = np.inf
            U[b, :] = np.inf
            continue
        hb, cb, fcb, q = h[b], c[b], abs(fc[b]), Q[b]
        copy_vector(X0[b], x)
        copy_vector(xc0, xc)
        mode = 2                                # decided at the first sample, once u_0 is known
        for k in range(N):
            yk = Y0[b] + _dot(C[b], x)
            uk = Dc[0] * r[k] + Dc[1] * yk + d[k] + _dot(Cc, xc)
            Y[b, k] = yk
            U[b, k] = uk
            for i in range(nc):
                acc = Bc[i, 0] * r[k] + Bc[i, 1] * yk
                for j in range(nc):
                    acc += Ac[i, j] * xc[j]
                xcn[i] = acc
            copy_vector(xcn, xc)
            if mode == 2:
                mode = _first_mode(Cz[b], q, x, uk - cb, fcb, hb)
            if k + 1 < N:
                mode = _call_sample(sample, Adt[b], Asdt[b], Bdt[b], Cz[b], q, hb, Phi[b], G0[b], G1[b], Ps[b], x, mode,
                                    uk, 0.0, cb, fcb, xn, xs, t1, t2, pv)
    return Y, U


def lure_run(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok, fc, c, X0, Y0, u, foh, y, out, want_outputs):
    """Simulate every candidate over ``u``: outputs into ``out[b]`` (``want_outputs``) or the SSE against ``y``
    into ``out[b, 0]``; ``inf`` for a candidate that is not ``ok`` or overflows.  Returns ``out``.

    The first twelve arguments are :func:`lure_setup`'s results, as it returns
    them: the sample with events is compiled for writeable C-ordered float
    arrays alone, so a read-only or differently laid-out ``Adt``, ``Asdt``,
    ``Bdt``, ``Cz``, ``Q``, ``Phi``, ``G0``, ``G1`` or ``Ps`` is refused
    (a ``TypingError``) when the simulation is compiled;
    ``fc``, ``c`` ``(B,)`` the friction levels and constant inputs; ``X0``
    ``(B, n)`` and ``Y0`` ``(B,)`` the initial states and output offsets;
    ``u`` ``(N,)`` the input and ``foh`` its hold (True: first order); ``y``
    ``(N,)`` the measured output (read for SSEs only); ``out`` ``(B, N)``
    for outputs or ``(B, 1)`` for SSEs.
    """
    return _lure_run(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok, fc, c, X0, Y0, u, foh, y, out, want_outputs,
                     sample_address())


def lure_loop_run(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok, fc, c, X0, Y0, Ac, Bc, Cc, Dc, xc0, r, d, Y, U):
    """Every candidate inside a known sampled controller ``(Ac, Bc, Cc, Dc)`` from its state ``xc0``, with
    reference ``r`` and added input ``d``: outputs into ``Y[b]`` and control signals into ``U[b]``; returns
    ``(Y, U)`` (:func:`_lure_loop_run` gives the recursion).  The plant's arguments are as for :func:`lure_run`."""
    return _lure_loop_run(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok, fc, c, X0, Y0, Ac, Bc, Cc, Dc, xc0, r, d,
                          Y, U, sample_address())
