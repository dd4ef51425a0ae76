"""Exact sampled simulation of a Lur'e loop with friction: a linear block, sign friction fed back on one signal.

The loop (:mod:`~hammerstein_ctrl.blocks`) is

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

The simulation is C in the compiled core (``lure.cpp``).  Limits: a sign
change of ``z`` that starts and ends inside one sample (two crossings between
samples) is seen only where a quadratic estimate says it may happen (then it
is located exactly); a sample may hold at most :data:`MAX_EVENTS` switches
(the rest of it keeps the last mode).  ``z`` must be driven directly by ``w``
(``Cz B != 0``: relative degree 1 from ``w`` to ``z``).

Examples
--------
>>> import numpy as np
>>> setup = lure_setup(np.array([[1.0]]), np.array([[1.0, 1.0, 0.0]]), 0.01, np.zeros(1), FEEDBACK_CODES["velocity"])
>>> out = np.empty((1, 5))       # a mass with damping, pushed by 1 N against 0.5 N of friction, from rest
>>> _ = lure_run(*setup, np.array([0.5]), np.zeros(1), np.zeros((1, 2)), np.zeros(1), np.ones(5), False,
...              np.ones(5), out, True)
>>> bool(np.all(np.diff(out[0]) > 0))
True
"""

from __future__ import annotations

import numpy as np

from .. import _core

__all__ = ["lure_setup", "lure_run", "lure_loop_run", "MAX_EVENTS", "FEEDBACK_CODES"]

#: Most mode switches resolved within one sample.
MAX_EVENTS = 16
#: Code of each feedback signal in the compiled setup.
FEEDBACK_CODES = {"output": 0, "velocity": 1}


def _rows(*arrays, dtype=float):
    return tuple(np.ascontiguousarray(a, dtype=dtype) for a in arrays)


def lure_setup(num, den, dt, slope, feedback):
    """Per-candidate matrices of the loop: ``(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok)``.

    ``Adt = (A - k B Cz) dt`` (the slipping loop), ``Asdt = A_s dt`` (sticking:
    ``A_s = Ae - B Q``), ``Bdt = B dt``, ``h = Cz B``, ``Q = Cz Ae / h`` (the holding force is
    ``u - c + Q x``); ``Phi, G0, G1``
    the exact FOH step of the slipping loop, ``Ps = expm(A_s dt)``.  ``ok`` is
    False for a candidate with non-finite coefficients or ``h == 0``.

    Parameters
    ----------
    num, den : ndarray, shape (B, l+1) and (B, n+1)
        The linear blocks (``l <= n``, ``1 <= n <= MAX_ORDER``).
    dt : float
    slope : ndarray, shape (B,)
        The friction maps' linear slopes ``k``.
    feedback : int
        :data:`FEEDBACK_CODES` of the fed-back signal.
    """
    num, den, slope = _rows(num, den, slope)
    batch, n = den.shape[0], den.shape[1] - 1
    if num.ndim != 2 or den.ndim != 2 or num.shape[0] != batch or slope.shape != (batch,) or not (
            1 <= num.shape[1] <= den.shape[1]):
        raise ValueError(f"lure_setup takes rows of num and den (as many, den no shorter) and a slope per row, "
                         f"got {num.shape}, {den.shape} and {slope.shape}")
    matrices = [np.zeros((batch, n, n)), np.zeros((batch, n, n)), np.zeros((batch, n)), np.zeros((batch, n)),
                np.zeros((batch, n)), np.zeros(batch), np.zeros((batch, n)), np.zeros((batch, n, n)),
                np.zeros((batch, n)), np.zeros((batch, n)), np.zeros((batch, n, n)), np.ones(batch, dtype=bool)]
    if _core.hc_lure_setup(num, num.shape[1], den, den.shape[1], batch, float(dt), slope, int(feedback), *matrices):
        raise ValueError(f"Lur'e loops are simulated for orders 1 to {_core.MAX_ORDER}, not {n}")
    return tuple(matrices)


def _setup_fits(setup, X0, Y0, fc, c) -> tuple:
    """``(batch, n)`` of :func:`lure_setup`'s arrays, checked with the candidates' own rows."""
    Adt = setup[0]
    batch, n = Adt.shape[0], Adt.shape[1]
    shapes = [(batch, n, n), (batch, n, n), (batch, n), (batch, n), (batch, n), (batch,), (batch, n),
              (batch, n, n), (batch, n), (batch, n), (batch, n, n), (batch,)]
    if len(setup) != 12 or any(np.shape(a) != s for a, s in zip(setup, shapes)):
        raise ValueError("the loop's matrices are not lure_setup's")
    if X0.shape != (batch, n) or Y0.shape != (batch,) or fc.shape != (batch,) or c.shape != (batch,):
        raise ValueError(f"fc, c, X0 and Y0 must hold a row for each of the {batch} candidates ({n} states), got "
                         f"{fc.shape}, {c.shape}, {X0.shape} and {Y0.shape}")
    return batch, n


def lure_run(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok, fc, c, X0, Y0, u, foh, y, out, want_outputs):
    """Simulate every candidate over ``u``: outputs into ``out[b]`` (``want_outputs``) or the SSE against ``y``
    into ``out[b, 0]``; ``inf`` for a candidate that is not ``ok`` or overflows.  Returns ``out``.

    The first twelve arguments are :func:`lure_setup`'s results, as it returns
    them; ``fc``, ``c`` ``(B,)`` the friction levels and constant inputs; ``X0``
    ``(B, n)`` and ``Y0`` ``(B,)`` the initial states and output offsets;
    ``u`` ``(N,)`` the input and ``foh`` its hold (True: first order); ``y``
    ``(N,)`` the measured output (read for SSEs only); ``out`` ``(B, N)``
    for outputs or ``(B, 1)`` for SSEs (a writeable C-ordered float array).
    """
    setup = _rows(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps) + _rows(ok, dtype=bool)
    fc, c, X0, Y0, u, y = _rows(fc, c, X0, Y0, u, y)
    batch, n = _setup_fits(setup, X0, Y0, fc, c)
    N = u.size
    if u.ndim != 1 or y.shape != u.shape or out.shape != (batch, N if want_outputs else 1):
        raise ValueError(f"u and y must be records of the same length, and out of shape (B, N) for outputs or "
                         f"(B, 1) for sums: got {u.shape}, {y.shape} and {out.shape}")
    _core.hc_lure_run(*setup, batch, n, fc, c, X0, Y0, u, N, int(bool(foh)), y, out, int(bool(want_outputs)))
    return out


def lure_loop_run(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps, ok, fc, c, X0, Y0, Ac, Bc, Cc, Dc, xc0, r, d, Y, U):
    """Every candidate inside a known sampled controller ``(Ac, Bc, Cc, Dc)`` from its state ``xc0``, with
    reference ``r`` and added input ``d``: outputs into ``Y[b]`` and control signals into ``U[b]``; returns
    ``(Y, U)``.

    At sample ``k``: ``y_k = C x_k + y0``; ``u_k = Cc xc_k + Dc [r_k, y_k] + d_k``;
    ``xc_{k+1} = Ac xc_k + Bc [r_k, y_k]``; the plant holds ``u_k`` over the
    sample (a DAC: zero-order hold).  A candidate that is not ``ok`` gets
    ``inf`` everywhere.  The plant's arguments are as for :func:`lure_run`.
    """
    setup = _rows(Adt, Asdt, Bdt, C, Cz, h, Q, Phi, G0, G1, Ps) + _rows(ok, dtype=bool)
    fc, c, X0, Y0, Ac, Bc, Cc, Dc, xc0, r, d = _rows(fc, c, X0, Y0, Ac, Bc, Cc, Dc, xc0, r, d)
    batch, n = _setup_fits(setup, X0, Y0, fc, c)
    nc, N = Ac.shape[0], r.size
    if (Ac.shape != (nc, nc) or Bc.shape != (nc, 2) or Cc.shape != (nc,) or Dc.shape != (2,) or xc0.shape != (nc,)
            or r.shape != (N,) or d.shape != (N,) or Y.shape != (batch, N) or U.shape != (batch, N)):
        raise ValueError("the controller's matrices, the reference, the added input and the outputs do not fit one "
                         "another")
    if _core.hc_lure_loop_run(*setup, batch, n, fc, c, X0, Y0, Ac, Bc, Cc, Dc, nc, xc0, r, d, N, Y, U):
        raise MemoryError(f"no memory for a controller of {nc} states")
    return Y, U
