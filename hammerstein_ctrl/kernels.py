"""Compiled sampled recursions of a linear block, generated per state dimension and cached on disk.

The kernels read (or, those preceded by the discretisation, compute), per
candidate ``b``, the matrix exponential
``E[b] = expm([[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]])`` and runs

* first-order hold (``"foh"``, the input linear between samples, the paper's
  semantics and ``control.forced_response``'s):
  ``x[k] = Ad x[k-1] + (Bd0 v[k-1] + Bd1 v[k])`` with ``Ad = E[:n, :n]``,
  ``Bd1 = E[:n, n+1]`` and ``Bd0 = E[:n, n] - Bd1``;
* zero-order hold (``"zoh"``, the input held between samples, as from a DAC):
  ``x[k] = Ad x[k-1] + Gamma v[k-1]`` with ``Gamma = E[:n, n]``;

from the initial state ``x[0] = X0[b]``, with output
``y[k] = C x[k] + D v[k] + Y0[b]``, or, with an output nonlinearity ``h``
(Wiener and Hammerstein-Wiener models), ``y[k] = h(C x[k] + D v[k]; HP[b]) + Y0[b]``
evaluated in the same pass (:mod:`hammerstein_ctrl.compiled_maps`).  In
``"sse"`` mode the kernel returns the sum of squared errors against a
measured ``y`` without storing the output.

For state dimensions up to :data:`MAX_UNROLLED_STATES` the source is generated
per state dimension, in four families that share one generator of their
arithmetic (so a candidate's operations, and its rounding, are the same in each):

* :func:`get_kernel`: the state in scalars (registers) and :data:`INTERLEAVE`
  candidates side by side (the recursion is latency-bound, so independent
  chains keep the CPU busy); with ``K`` basis signals it forms the signal
  ``P[b] @ Phi`` in the pass instead of reading ``V``;
* :func:`get_coefficient_kernel`: the same, preceded by the realisation and
  the matrix exponential in one compiled call (single evaluations);
* :func:`get_lane_kernel`: candidates in groups across SIMD lanes (batches);
* :func:`get_normal_kernel`: a point and its forward-difference neighbours
  across SIMD lanes, accumulating the normal equations of least squares.

The generated source is written to a per-version cache directory
(:func:`cache_dir`) and compiled by numba with ``cache=True``, so a new
process loads the machine code instead of compiling again.  Larger
dimensions use one generic compiled loop.

Examples
--------
>>> import numpy as np
>>> from hammerstein_ctrl.kernels import get_kernel
>>> k = get_kernel(1, "outputs", "zoh")
>>> E = np.array([[[1.0, 0.5, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]]])  # integrator, dt = 0.5
>>> out = np.empty((1, 4))
>>> k(E, np.ones((1, 1)), np.zeros(1), np.zeros((1, 1)), np.zeros(1), np.ones((1, 4)), out)
>>> out
array([[0. , 0.5, 1. , 1.5]])
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import sys
import tempfile
import types
from pathlib import Path

import numba
import numba.core.cgutils
import numba.core.errors
import numba.extending
import numpy as np

from ._checks import MAX_ORDER
from ._jit import cached_njit
from ._simd import WIDTH

__all__ = ["get_kernel", "get_coefficient_kernel", "get_normal_kernel", "get_lane_kernel", "lane_source",
           "has_output_maps", "kernel_source", "normal_kernel_address", "call_normal_kernel", "normal_source",
           "vector_normal_source", "cache_dir", "OUTPUT_TERMS",
           "MAX_UNROLLED_STATES", "MAX_PASS_STATES", "MAX_VECTOR_STATES", "MAX_NORMAL_LANES", "LANE_WIDTHS", "LANE_MIN",
           "MAX_LANE_BASIS", "INTERLEAVE", "MODES", "HOLDS", "ENV_CACHE"]

#: State dimensions up to this get a generated kernel with the state in registers.
MAX_UNROLLED_STATES = 8
#: State dimensions up to this get the normal-equation pass (and its outputs mode): every order a
#: linear block may have, so that LM's Jacobian sums and the automatic starts' regressions stay
#: bounded in memory on long records whatever the block (a 10-state pass compiles in ~6 s, once).
MAX_PASS_STATES = MAX_ORDER
#: State dimensions up to this get the normal-equation pass with the neighbours in vectors
#: (:func:`vector_normal_source`): 1.3-3x faster than the lanes in an array up to 4 states, no faster at
#: 6, and its compile time grows faster with the order (10 states, 16 lanes: 56 s against 7 s).
MAX_VECTOR_STATES = 4
#: Candidates simulated side by side in one loop of a generated kernel.
INTERLEAVE = 2
#: ``"sse"``: sum of squared errors only; ``"outputs"``: the simulated output.
MODES = ("sse", "outputs")
#: Intersample behaviours of the input.
HOLDS = ("foh", "zoh")
#: Environment variable overriding the kernel cache directory.
ENV_CACHE = "HAMMERSTEIN_CTRL_CACHE"
#: A sum of squares above this is treated as overflowed.
_OVERFLOW = 1.7e308
#: Most candidates (one point and its forward-difference neighbours) of a normal-equation pass.
MAX_NORMAL_LANES = 16
#: One level of indentation of the generated source.
_INDENT = " " * 4
#: Terms of the output besides ``C x``: the direct term ``d v`` and the offset ``o``.
OUTPUT_TERMS = ("d", "o")
#: Candidates per group of a lanes kernel (16: two AVX-512 vectors, 8: one); the last
#: group is padded.
LANE_WIDTHS = (16, 8)
#: Fewest candidates for which the lanes kernel beats the interleaved one (a padded group
#: costs about as much as a full one: 70 us on EMPS, against 26-38 us per candidate).
LANE_MIN = 3
#: Most basis signals of a lanes kernel.
MAX_LANE_BASIS = 8
#: Samples between overflow checks in ``"sse"`` mode (a power of two, minus one).
_CHECK_MASK = 1023

_TEMPLATE = ('''"""Generated by hammerstein_ctrl.kernels: n = {n}, mode = {mode}, hold = {hold}, basis = {K}, '''
             '''map = {outmap}."""
import numpy as np

from hammerstein_ctrl._jit import cached_njit
{imports}

@cached_njit()
def kernel(E, C, D, X0, Y0, {inputs}, {args}):
    batch, N = {shape}
    b0 = 0
    while b0 + {group} <= batch:
{block_group}
        b0 += {group}
    while b0 < batch:
{block_single}
        b0 += 1
''')


def _next_state(n: int, hold: str, q, x, vp: str, vi: str) -> list:
    """Expressions of the next state, entry by entry: ``(A x)_r + (Bd0_r vp + Bd1_r vi)`` (zoh: ``Gamma_r vp``).

    Every kernel family builds its arithmetic here and in :func:`_output_expr`
    and :func:`_combination`, so their operations (and rounding) are the same;
    ``q(name)`` is the text of a candidate's coefficient ``name`` and ``x(c)``
    that of its state entry ``c``.
    """
    exprs = []
    for r in range(n):
        dyn = " + ".join(f"{q(f'a{r}_{c}')} * {x(c)}" for c in range(n))
        drive = f"({q(f'p{r}')} * {vp} + {q(f'q{r}')} * {vi})" if hold == "foh" else f"{q(f'p{r}')} * {vp}"
        exprs.append(f"({dyn}) + {drive}")
    return exprs


def _output_expr(n: int, q, x, v: str, terms=OUTPUT_TERMS, outmap=None) -> str:
    """Expression of the output sample ``((C x) + d v) + o`` (``h(...)`` inside an output map).

    A zero offset ``o`` adds exactly nothing to any output, and a zero direct
    term ``d`` nothing while the signal ``v`` is finite, so ``terms`` may
    leave them out (the lanes kernel then catches a non-finite last signal
    sample itself: see :func:`_lane_group`).
    """
    linear = " + ".join(f"{q(f'c{r}')} * {x(r)}" for r in range(n)) or "0.0"
    z = f"({linear})"
    if "d" in terms:
        z = f"({z} + {q('d')} * {v})"
    if outmap:
        z = f"h({z}, {q('hp')}, HX)"
    return f"{z} + {q('o')}" if "o" in terms else z


def _combination(q, K: int, f, target: str) -> list:
    """Lines setting ``target`` to the signal sample ``P @ phi``, summed basis row by basis row."""
    return [f"{target} = {q('P0')} * {f(0)}"] + [f"{target} += {q(f'P{k}')} * {f(k)}" for k in range(1, K)]


def _coefficient_loads(n: int, hold: str, q, row: str, states: str, K: int | None, terms=OUTPUT_TERMS,
                       block: str | None = None) -> list:
    """Lines loading row ``row``'s coefficients (of ``E``, ``C``, ``D``, ``Y0``, ``P``) and initial state (of
    ``states``).

    ``block`` names the row of the linear block's ``E``, ``C``, ``D`` if it is not ``row``.
    """
    lines, e = [], row if block is None else block
    for r in range(n):
        lines += [f"{q(f'a{r}_{c}')} = E[{e}, {r}, {c}]" for c in range(n)]
        if hold == "foh":
            lines += [f"{q(f'q{r}')} = E[{e}, {r}, {n + 1}]", f"{q(f'p{r}')} = E[{e}, {r}, {n}] - {q(f'q{r}')}"]
        else:
            lines.append(f"{q(f'p{r}')} = E[{e}, {r}, {n}]")
        lines += [f"{q(f'c{r}')} = C[{e}, {r}]", f"{q(f'x{r}')} = {states}[{row}, {r}]"]
    lines += [f"{q('d')} = D[{e}]"] if "d" in terms else []
    lines += [f"{q('o')} = Y0[{row}]"] if "o" in terms else []
    return lines + [f"{q(f'P{k}')} = P[{row}, {k}]" for k in range(K or 0)]


def _terms(direct: bool, offset: bool) -> tuple:
    """The :data:`OUTPUT_TERMS` present: ``"d"`` with a direct term, ``"o"`` with an offset."""
    return tuple(t for t, present in zip(OUTPUT_TERMS, (direct, offset)) if present)


def _scalar_names(g: int):
    """Candidate ``g``'s quantities as scalar variables (``a0_1`` -> ``a0_1_g``)."""
    return lambda name: f"{name}_{g}"


def _indent(ind: str, lines: list) -> list:
    return [ind + line for line in lines]


def _output(n: int, g: int, v: str, outmap) -> str:
    """Expression of candidate ``g``'s output sample given its input sample ``v``."""
    q = _scalar_names(g)
    return _output_expr(n, q, lambda r: q(f"x{r}"), v, outmap=outmap)


def _advance(n: int, g: int, hold: str, ind: str) -> list:
    """Candidate ``g``'s state from the previous sample to this one (signal ``vp_g`` before, ``vi_g`` now)."""
    q = _scalar_names(g)
    exprs = _next_state(n, hold, q, lambda c: q(f"x{c}"), q("vp"), q("vi"))
    return ([f"{ind}{q(f'n{r}')} = {e}" for r, e in enumerate(exprs)]
            + [f"{ind}{q(f'x{r}')} = {q(f'n{r}')}" for r in range(n)])


_FROM_COEFFICIENTS = ('''

@cached_njit()
def from_coefficients(num, den, dt, max_norm, X0, Y0, P, Phi, y, out):
    """Discretise the transfer functions and run ``kernel``, in one call; False (nothing done) unless every row '''
                      '''is clean."""
    E, C, D, ok, big, clean = tf_discrete(num, den, dt, max_norm)
    if clean:
        kernel(E, C, D, X0, Y0, P, Phi, y, out)
    return clean
''')


def _signal(g: int, i: str, K: int | None) -> list:
    """Lines setting candidate ``g``'s signal sample ``vi_g`` at sample ``i``: read from ``V``, or ``P @ Phi``."""
    q = _scalar_names(g)
    if K is None:
        return [f"{q('vi')} = V[b0 + {g}, {i}]"]
    return _combination(q, K, lambda k: f"Phi[{k}, {i}]", q("vi"))


def _setup(n: int, g: int, hold: str, mode: str, ind: str, outmap=None, K: int | None = None) -> list:
    """Load candidate ``b0 + g``'s coefficients and initial state into scalars."""
    q, row = _scalar_names(g), f"b0 + {g}"
    lines = _coefficient_loads(n, hold, q, row, "X0", K) + _signal(g, "0", K) + [f"{q('vp')} = {q('vi')}"]
    if outmap:
        lines.append(f"{q('hp')} = HP[{row}]")
    lines.append(f"{q('yh')} = {_output(n, g, q('vp'), outmap)}")
    if mode == "sse":
        lines += [f"{q('e')} = y[0] - {q('yh')}", f"{q('J')} = {q('e')} * {q('e')}"]
    else:
        lines.append(f"out[{row}, 0] = {q('yh')}")
    return _indent(ind, lines)


def _step(n: int, g: int, hold: str, mode: str, ind: str, outmap=None, K: int | None = None) -> list:
    """One sample of candidate ``b0 + g``'s recursion."""
    q = _scalar_names(g)
    lines = _indent(ind, _signal(g, "i", K)) + _advance(n, g, hold, ind)
    lines.append(f"{ind}{q('yh')} = {_output(n, g, q('vi'), outmap)}")
    if mode == "sse":
        lines += [f"{ind}{q('e')} = yi - {q('yh')}", f"{ind}{q('J')} += {q('e')} * {q('e')}"]
    else:
        lines.append(f"{ind}out[b0 + {g}, i] = {q('yh')}")
    lines.append(f"{ind}{q('vp')} = {q('vi')}")
    return lines


def _block(n: int, group: int, hold: str, mode: str, ind: str, outmap=None, K: int | None = None) -> str:
    """Source simulating rows ``b0 .. b0+group-1`` with ``n`` states held in scalars."""
    lines = []
    for g in range(group):
        lines += _setup(n, g, hold, mode, ind, outmap, K)
    lines.append(f"{ind}for i in range(1, N):")
    body = ind + "    "
    if mode == "sse":
        lines.append(f"{body}yi = y[i]")
    for g in range(group):
        lines += _step(n, g, hold, mode, body, outmap, K)
    if mode == "sse":
        # stop early only when every interleaved sum has overflowed (or is NaN)
        alive = " or ".join(f"J_{g} <= {_OVERFLOW!r}" for g in range(group))
        lines += [f"{body}if (i & {_CHECK_MASK}) == 0 and not ({alive}):", f"{body}    break"]
        lines += [f"{ind}out[b0 + {g}] = J_{g} if J_{g} <= {_OVERFLOW!r} else np.inf" for g in range(group)]
    return "\n".join(lines)


def kernel_source(n: int, mode: str, hold: str, outmap: str | None = None, K: int | None = None) -> str:
    """Python source of the generated kernel for ``n`` states (an output map, if named; ``K`` basis signals, if
    given)."""
    ind = _INDENT * 2
    args = ("HP, HX, " if outmap else "") + ("y, out" if mode == "sse" else "out")
    imports = f"from hammerstein_ctrl.compiled_maps import {outmap} as h\n" if outmap else ""
    inputs, shape = ("V", "V.shape") if K is None else ("P, Phi", "E.shape[0], Phi.shape[1]")
    fused = K is not None and mode == "sse" and outmap is None     # with from_coefficients
    if fused:
        imports += "from hammerstein_ctrl._linalg import tf_discrete\n"
    src = _TEMPLATE.format(
        n=n, mode=mode, hold=hold, K=K, outmap=outmap, imports=imports, inputs=inputs, shape=shape, args=args,
        group=INTERLEAVE, block_group=_block(n, INTERLEAVE, hold, mode, ind, outmap, K),
        block_single=_block(n, 1, hold, mode, ind, outmap, K),
    )
    return src + _FROM_COEFFICIENTS if fused else src


_LANES_TEMPLATE = ('''"""Generated by hammerstein_ctrl.kernels: candidates across SIMD lanes, n = {n}, '''
                   '''hold = {hold}, basis = {K}, terms = {terms}."""
import numpy as np

from hammerstein_ctrl._jit import cached_njit


@cached_njit()
def kernel(E, C, D, X0, Y0, P, Phi, y, out):
    batch = E.shape[0]
    N = Phi.shape[1]
    b0 = 0
{groups}
''')


class _LaneRows:
    """Row of each lane quantity in a group's ``Z`` array (one column per candidate).

    ``terms`` names the output terms present (``"d"``: direct term, ``"o"``:
    offset); ``extra`` the rows after the state and previous signal sample
    (the running ``J``, or the output ``yh`` of a normal-equation pass).
    """

    def __init__(self, n: int, hold: str, K: int, terms: tuple, extra: tuple = ("J",)):
        names = [f"a{r}_{c}" for r in range(n) for c in range(n)] + [f"p{r}" for r in range(n)]
        names += [f"q{r}" for r in range(n)] if hold == "foh" else []
        names += [f"c{r}" for r in range(n)] + list(terms) + [f"P{k}" for k in range(K)]
        names += [f"x{r}" for r in range(n)] + ["vp"] + list(extra)
        self.terms = terms
        self.index = {name: i for i, name in enumerate(names)}

    def __getitem__(self, name: str) -> str:
        return f"Z[{self.index[name]}, w]"

    def __len__(self):
        return len(self.index)


def _lane_output(n: int, z: _LaneRows, x: str, v: str, outmap: str | None = None) -> str:
    """Output expression of a lane from its state in the locals ``x0, x1, ...`` (prefix ``x``) and signal ``v``.

    With an output map, the lane's map parameters are the row ``HP[lane]``.
    """
    q = (lambda name: "HP[lane]" if name == "hp" else z[name]) if outmap else z.__getitem__
    return _output_expr(n, q, lambda r: f"{x}{r}", v, z.terms, outmap)


def _lane_coefficients(n: int, hold: str, K: int, z: _LaneRows, ind: str, states: str,
                       block: str | None = None) -> list:
    """Load row ``b``'s coefficients and state (of ``states``) into column ``w``, and the state into ``x0, x1, ...``.

    ``block``: the row of the linear block, if not ``b`` (see :func:`_coefficient_loads`).
    """
    lines = _coefficient_loads(n, hold, z.__getitem__, "b", states, K, z.terms, block)
    return _indent(ind, lines + [f"x{r} = {states}[b, {r}]" for r in range(n)])


def _lane_setup(n: int, hold: str, K: int, z: _LaneRows, ind: str) -> list:
    """Load a group's coefficients (padding with its first candidate), state, first signal sample and J."""
    lines = [f"{ind}for w in range(W):", f"{ind}    b = b0 + w if w < m else b0"]
    body = ind + "    "
    lines += _lane_coefficients(n, hold, K, z, body, "X0")
    lines += [f"{body}f{k} = Phi[{k}, 0]" for k in range(K)] + _lane_signal(z, K, body)
    lines += [f"{body}{z['vp']} = vi", f"{body}e = y[0] - ({_lane_output(n, z, 'x', 'vi')})",
              f"{body}{z['J']} = e * e"]
    return lines


def _lane_signal(z: _LaneRows, K: int, ind: str) -> list:
    """``vi = P @ phi`` of a lane, from the basis samples ``f0, f1, ...``."""
    return _indent(ind, _combination(z.__getitem__, K, lambda k: f"f{k}", "vi"))


def _lane_step(n: int, hold: str, K: int, z: _LaneRows, body: str) -> list:
    """A lane's signal sample ``vi`` and its state advanced to ``n0, n1, ...`` (stored back in its column)."""
    lines = _lane_signal(z, K, body) + [f"{body}vp = {z['vp']}"]
    lines += [f"{body}x{r} = {z[f'x{r}']}" for r in range(n)]
    exprs = _next_state(n, hold, z.__getitem__, lambda c: f"x{c}", "vp", "vi")
    lines += [f"{body}n{r} = {e}" for r, e in enumerate(exprs)]
    return lines + [f"{body}{z[f'x{r}']} = n{r}" for r in range(n)] + [f"{body}{z['vp']} = vi"]


def _lane_loop(n: int, hold: str, K: int, z: _LaneRows, ind: str) -> list:
    """The samples of a group: the shared basis and output sample, then every lane's step (vectorised)."""
    lines = [f"{ind}for i in range(1, N):", f"{ind}    yi = y[i]"]
    lines += [f"{ind}    f{k} = Phi[{k}, i]" for k in range(K)]
    lines.append(f"{ind}    for w in range(W):")
    body = ind + _INDENT * 2
    lines += _lane_step(n, hold, K, z, body)
    lines += [f"{body}e = yi - ({_lane_output(n, z, 'n', 'vi')})", f"{body}{z['J']} += e * e"]
    # stop early once every candidate of the group has overflowed (or is NaN)
    lines += [f"{ind}    if (i & {_CHECK_MASK}) == 0:", f"{ind}        alive = False",
              f"{ind}        for w in range(m):", f"{ind}            alive = alive or {z['J']} <= {_OVERFLOW!r}",
              f"{ind}        if not alive:", f"{ind}            break"]
    return lines


def _lane_group(n: int, hold: str, K: int, terms: tuple, width: int, ind: str) -> list:
    """Source of the groups of ``width`` candidates (the narrowest width also takes the padded rest)."""
    z = _LaneRows(n, hold, K, terms)
    least = width if width != LANE_WIDTHS[-1] else 1
    lines = [f"{ind}W = {width}", f"{ind}Z = np.zeros(({len(z)}, W))",
             f"{ind}while batch - b0 >= {least}:", f"{ind}    m = min(W, batch - b0)"]
    lines += _lane_setup(n, hold, K, z, ind + "    ") + _lane_loop(n, hold, K, z, ind + "    ")
    # the last signal sample reaches the output only through the direct term (zoh): without
    # that term a non-finite one would go unseen, so it scores inf as it would with d = 0
    lines += [f"{ind}    for w in range(m):", f"{ind}        J = {z['J']}",
              f"{ind}        out[b0 + w] = J if J <= {_OVERFLOW!r} and np.isfinite({z['vp']}) else np.inf",
              f"{ind}    b0 += m"]
    return lines


def lane_source(n: int, hold: str, K: int, direct: bool = True, offset: bool = True) -> str:
    """Python source of the lanes kernel for ``n`` states and a basis of ``K`` signals.

    Parameters as for :func:`get_lane_kernel`, which compiles it.

    Examples
    --------
    >>> src = lane_source(2, "foh", 3, direct=False, offset=False)
    >>> "def kernel(E, C, D, X0, Y0, P, Phi, y, out):" in src, "D[b]" in src
    (True, False)
    """
    terms = _terms(direct, offset)
    groups = []
    for width in LANE_WIDTHS:
        groups += _lane_group(n, hold, K, terms, width, _INDENT)
    return _LANES_TEMPLATE.format(n=n, hold=hold, K=K, terms=terms, groups="\n".join(groups))


@functools.lru_cache(maxsize=None)
def get_lane_kernel(n: int, hold: str, K: int, direct: bool = True, offset: bool = True):
    """The compiled sum of squared errors of candidates side by side in SIMD lanes.

    Candidate ``b``'s signal is ``P[b] @ Phi`` (a nonlinearity linear in its
    parameters, or ``Phi = u`` and ``P = 1``), formed sample by sample inside
    the kernel.  Candidates are taken in groups of :data:`LANE_WIDTHS` whose
    quantities sit in the columns of one small array, so LLVM vectorises the
    step of the whole group; each candidate's arithmetic is that of
    :func:`get_kernel`'s ``"sse"`` kernel on ``P @ Phi``, operation for
    operation, so the sums are bit-identical to it.  A group that is not
    full is padded (its unused lanes repeat its first candidate), so batches
    of fewer than :data:`LANE_MIN` candidates are faster in :func:`get_kernel`.

    Parameters
    ----------
    n : int
        State dimension (at most :data:`MAX_UNROLLED_STATES`).
    hold : {"foh", "zoh"}
    K : int
        Number of basis signals, ``1 .. MAX_LANE_BASIS``.
    direct, offset : bool, default True
        Whether the output has a direct term ``D v`` and an offset ``Y0``;
        without them (``D`` and ``Y0`` all zero) the kernel does less work
        per sample and gives the same sums.

    Returns
    -------
    callable
        ``kernel(E, C, D, X0, Y0, P, Phi, y, out)``: ``P`` of shape ``(B, K)``,
        ``Phi`` of shape ``(K, N)``; ``out`` (shape ``(B,)``) receives J.

    Examples
    --------
    >>> import numpy as np
    >>> k = get_lane_kernel(1, "zoh", 1)
    >>> E = np.array([[[1.0, 0.5, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]]] * 3)  # integrator, dt = 0.5
    >>> J = np.empty(3)
    >>> k(E, np.ones((3, 1)), np.zeros(3), np.zeros((3, 1)), np.zeros(3), np.array([[1.0], [2.0], [0.0]]),
    ...   np.ones((1, 4)), np.zeros(4), J)
    >>> J                               # y = 0, yhat = theta (0, 0.5, 1, 1.5): 3.5 theta**2
    array([ 3.5, 14. ,  0. ])
    """
    if hold not in HOLDS:
        raise ValueError(f"unknown hold {hold!r}")
    _check_sizes(n, K)
    name = f"hc_lanes_n{n}_{hold}_k{K}" + "".join(f"_{t}" for t in _terms(direct, offset))
    return _load_source(lane_source(int(n), hold, int(K), bool(direct), bool(offset)), name)


_NORMAL_TEMPLATE = ('''"""Generated by hammerstein_ctrl.kernels: normal equations, n = {n}, hold = {hold}, '''
                    '''lanes = {lanes}, basis = {K}, map = {outmap}."""
import numpy as np

from hammerstein_ctrl._jit import cached_njit
{imports}

@cached_njit(fastmath={{"contract"}})
def kernel(E, C, D, X, Y0, VP, P, Phi, HP, HX, y, begin, acc):
    N = Phi.shape[1]
    W = {width}
    Z = np.zeros(({rows}, W))
{setup}
    start = 0
    if begin == 0 and N > 0:
{first}
        start = 1
    for i in range(start, N):
        yi = y[i]
{fetch}
        for w in range(W):
{step}
{sums}
{store}
''')


def _normal_rows(n: int, hold: str, K: int, terms: tuple) -> _LaneRows:
    """The rows of a normal-equation pass: the output terms present, and the lanes' output sample."""
    return _LaneRows(n, hold, K, terms, extra=("yh",))


def _normal_setup(n: int, hold: str, K: int, lanes: int, z: _LaneRows, ind: str, outputs: bool = False) -> list:
    """Every lane's coefficients, state and previous signal (padding lanes repeat lane 0), and the sums."""
    lines = [f"{ind}for w in range(W):", f"{ind}    b = w if w < {lanes} else 0",
             f"{ind}    e = b if b < E.shape[0] else 0"]
    lines += _lane_coefficients(n, hold, K, z, ind + "    ", "X", "e")
    lines.append(f"{ind}    {z['vp']} = VP[b]")
    if outputs:
        return lines
    p = lanes - 1
    lines.append(f"{ind}f = acc[0]")
    lines += [f"{ind}g{j} = acc[{1 + j}]" for j in range(p)]
    lines += [f"{ind}H{j}_{k} = acc[{1 + p + j * p + k}]" for j in range(p) for k in range(j + 1)]
    return lines


def _normal_sums(lanes: int, z: _LaneRows, ind: str) -> list:
    """The residual of lane 0 and the forward differences to the others, added to the running sums."""
    p = lanes - 1
    yh = z.index["yh"]
    lines = [f"{ind}y0 = Z[{yh}, 0]", f"{ind}r = yi - y0", f"{ind}f += r * r"]
    lines += [f"{ind}j{j} = y0 - Z[{yh}, {j + 1}]" for j in range(p)]
    lines += [f"{ind}g{j} += j{j} * r" for j in range(p)]
    return lines + [f"{ind}H{j}_{k} += j{j} * j{k}" for j in range(p) for k in range(j + 1)]


def _lane_outputs(lanes: int, z: _LaneRows, ind: str, sample: str) -> list:
    """Store every lane's output sample in row ``sample`` of ``acc`` (an outputs pass)."""
    yh = z.index["yh"]
    return [f"{ind}acc[{sample}, {w}] = Z[{yh}, {w}]" for w in range(lanes)]


def _normal_store(n: int, lanes: int, z: _LaneRows, ind: str, outputs: bool = False) -> list:
    """Write the lanes' states, previous signals and the sums back for the next block of samples."""
    lines = [f"{ind}for w in range({lanes}):"]
    lines += [f"{ind}    X[w, {r}] = {z[f'x{r}']}" for r in range(n)] + [f"{ind}    VP[w] = {z['vp']}"]
    if outputs:         # the caller checks VP for a non-finite signal sample not yet in any output
        return lines
    # a non-finite signal sample not yet in the state (zoh: the last one) may reach no sum when the
    # direct term is left out: the sum of squares is then not finite, as it would be with d = 0
    lines += [f"{ind}    if not np.isfinite({z['vp']}):", f"{ind}        f = np.nan"]
    p = lanes - 1
    lines.append(f"{ind}acc[0] = f")
    lines += [f"{ind}acc[{1 + j}] = g{j}" for j in range(p)]
    lines += [f"{ind}acc[{1 + p + j * p + k}] = acc[{1 + p + k * p + j}] = H{j}_{k}"
              for j in range(p) for k in range(j + 1)]
    return lines


_VECTOR_TEMPLATE = ('''"""Generated by hammerstein_ctrl.kernels: normal equations, neighbours in vectors, '''
                    '''n = {n}, hold = {hold}, lanes = {lanes}, basis = {K}."""
import numpy as np

from hammerstein_ctrl._jit import cached_njit
from hammerstein_ctrl._simd import lane, pack, rotate, splat


@cached_njit(fastmath={{"contract"}})
def kernel(E, C, D, X, Y0, VP, P, Phi, HP, HX, y, begin, acc):
    N = Phi.shape[1]
{setup}
    start = 0
    if begin == 0 and N > 0:
{first}
        start = 1
    for i in range(start, N):
{step}
{store}
''')


def _lane_names(n: int, hold: str, K: int, terms: tuple) -> list:
    """Names of a lane's coefficients, initial state and previous signal, as :func:`_coefficient_loads` sets them."""
    names = [f"a{r}_{c}" for r in range(n) for c in range(n)] + [f"p{r}" for r in range(n)]
    names += [f"q{r}" for r in range(n)] if hold == "foh" else []
    return names + [f"c{r}" for r in range(n)] + list(terms) + [f"P{k}" for k in range(K)] + [
        f"x{r}" for r in range(n)] + ["vp"]


def _vector_names(c: int):
    """Chunk ``c``'s quantities as vectors (``a0_1`` -> ``a0_1_v0``)."""
    return lambda name: f"{name}_v{c}"


def _vector_setup(n: int, hold: str, K: int, lanes: int, terms: tuple) -> list:
    """Each lane's coefficients, state and previous signal in scalars (padding lanes repeat lane 0), packed by
    chunks."""
    chunks = -(-(lanes - 1) // WIDTH)
    lines = []
    for g in range(1 + chunks * WIDTH):
        q = _scalar_names(g)
        lines += [f"b{g} = {g if g < lanes else 0}", f"e{g} = b{g} if b{g} < E.shape[0] else 0"]
        lines += _coefficient_loads(n, hold, q, f"b{g}", "X", K, terms, f"e{g}") + [f"vp_{g} = VP[b{g}]"]
    for c in range(chunks):
        members = range(1 + c * WIDTH, 1 + (c + 1) * WIDTH)
        lines += [f"{name}_v{c} = pack({', '.join(f'{name}_{g}' for g in members)})"
                  for name in _lane_names(n, hold, K, terms)]
        lines += [f"G{c} = splat(0.0)"] + [f"S{c}_{s} = splat(0.0)" for s in range(3)]
        lines += [f"T{c}_{d}_{s} = splat(0.0)" for d in range(c) for s in range(WIDTH)]
    return _indent(_INDENT, lines + ["f = acc[0]"])


def _vector_sample(n: int, hold: str, K: int, chunks: int, terms: tuple, first: bool) -> list:
    """One sample: the point's step in scalars, the neighbours' in vectors, and the sums of the differences."""
    q0, i = _scalar_names(0), "0" if first else "i"
    lines = [f"yi = y[{i}]"] + [f"f{k} = Phi[{k}, {i}]" for k in range(K)] + [f"F{k} = splat(f{k})" for k in range(K)]
    for q, f in [(q0, lambda k: f"f{k}")] + [(_vector_names(c), lambda k: f"F{k}") for c in range(chunks)]:
        lines += _combination(q, K, f, q("vi"))
        if not first:
            exprs = _next_state(n, hold, q, lambda r, q=q: q(f"x{r}"), q("vp"), q("vi"))
            lines += [f"{q(f'n{r}')} = {e}" for r, e in enumerate(exprs)]
            lines += [f"{q(f'x{r}')} = {q(f'n{r}')}" for r in range(n)]
        lines += [f"{q('vp')} = {q('vi')}",
                  f"{q('yh')} = {_output_expr(n, q, lambda r, q=q: q(f'x{r}'), q('vi'), terms)}"]
    lines += ["r = yi - yh_0", "f += r * r", "Y = splat(yh_0)", "R = splat(r)"]
    for c in range(chunks):
        lines += [f"J{c} = Y - yh_v{c}", f"G{c} += J{c} * R", f"S{c}_0 += J{c} * J{c}"]
        lines += [f"S{c}_{s} += J{c} * rotate(J{c}, {s})" for s in (1, 2)]
        lines += [f"T{c}_{d}_{s} += J{c} * rotate(J{d}, {s})" for d in range(c) for s in range(WIDTH)]
    return _indent(_INDENT * 2, lines)


def _product_lane(j: int, k: int) -> str:
    """The vector lane holding the sum of ``d_j d_k`` (``j >= k``, neighbour indices) in :func:`_vector_sample`'s
    sums."""
    (cj, aj), (ck, ak) = divmod(j, WIDTH), divmod(k, WIDTH)
    s = (ak - aj) % WIDTH
    if cj != ck:
        return f"lane(T{cj}_{ck}_{s}, {aj})"
    if s == WIDTH - 1:                  # d_k d_j with k one lane before j, in the rotation by one
        return f"lane(S{cj}_1, {ak})"
    return f"lane(S{cj}_{s}, {aj})"


def _vector_store(n: int, lanes: int, p: int) -> list:
    """Lanes' states and previous signals written back (a non-finite one makes the sum NaN), and the sums added to
    ``acc``."""
    lines = []
    for g in range(lanes):
        c, a = divmod(g - 1, WIDTH)
        value = (lambda name: f"{name}_0") if g == 0 else (lambda name, c=c, a=a: f"lane({name}_v{c}, {a})")
        lines += [f"X[{g}, {r}] = {value(f'x{r}')}" for r in range(n)] + [f"VP[{g}] = {value('vp')}"]
        lines += [f"if not np.isfinite(VP[{g}]):", "    f = np.nan"]
    lines.append("acc[0] = f")
    lines += [f"acc[{1 + j}] += lane(G{j // WIDTH}, {j % WIDTH})" for j in range(p)]
    for j in range(p):
        for k in range(j + 1):
            lines += [f"h = acc[{1 + p + j * p + k}] + {_product_lane(j, k)}",
                      f"acc[{1 + p + j * p + k}] = acc[{1 + p + k * p + j}] = h"]
    return _indent(_INDENT, lines)


def vector_normal_source(n: int, hold: str, lanes: int, K: int, direct: bool = True, offset: bool = True) -> str:
    """Python source of the normal-equation pass with the point in scalars and its neighbours in vectors.

    The neighbours step :data:`~hammerstein_ctrl._simd.WIDTH` at a time in
    :class:`~hammerstein_ctrl._simd.Lanes4` values, which stay in registers
    from one sample to the next, and the products of their differences are
    summed in vectors too (a chunk with itself by rotations of its lanes).
    Used by :func:`get_normal_kernel` for passes that sum (no output map).

    Examples
    --------
    >>> src = vector_normal_source(2, "foh", 5, 3, direct=False, offset=False)
    >>> "x0_v0 = pack(x0_1, x0_2, x0_3, x0_4)" in src, "J1" in src
    (True, False)
    """
    terms = _terms(direct, offset)
    chunks = -(-(lanes - 1) // WIDTH)
    return _VECTOR_TEMPLATE.format(
        n=n, hold=hold, lanes=lanes, K=K, setup="\n".join(_vector_setup(n, hold, K, lanes, terms)),
        first="\n".join(_vector_sample(n, hold, K, chunks, terms, first=True)),
        step="\n".join(_vector_sample(n, hold, K, chunks, terms, first=False)),
        store="\n".join(_vector_store(n, lanes, lanes - 1)))


def normal_source(n: int, hold: str, lanes: int, K: int, direct: bool = True, offset: bool = True,
                  outmap: str | None = None, outputs: bool = False) -> str:
    """Python source of the normal-equation pass for ``n`` states, ``lanes`` candidates and ``K`` basis signals.

    ``direct`` and ``offset`` say whether the output has the terms ``d v``
    and ``o``, ``outmap`` names an output map of
    :mod:`~hammerstein_ctrl.compiled_maps`, and ``outputs`` makes the pass
    store every lane's output sample instead of summing (see
    :func:`get_normal_kernel`, which compiles it).
    """
    z = _normal_rows(n, hold, K, _terms(direct, offset))
    width = next(w for w in sorted(LANE_WIDTHS) if w >= lanes)
    ind1, ind2, ind3 = (_INDENT * level for level in (1, 2, 3))
    lane = [f"{ind3}lane = w if w < {lanes} else 0"] if outmap else []
    fetch = [f"{ind2}f{k} = Phi[{k}, i]" for k in range(K)]
    first = [f"{ind2}f{k} = Phi[{k}, 0]" for k in range(K)] + [f"{ind2}yi = y[0]", f"{ind2}for w in range(W):"]
    first += lane + _lane_signal(z, K, ind3) + [f"{ind3}{z['vp']} = vi"]
    first += [f"{ind3}x{r} = {z[f'x{r}']}" for r in range(n)]
    first += [f"{ind3}{z['yh']} = {_lane_output(n, z, 'x', 'vi', outmap)}"]
    first += _lane_outputs(lanes, z, ind2, "0") if outputs else _normal_sums(lanes, z, ind2)
    step = lane + _lane_step(n, hold, K, z, ind3) + [f"{ind3}{z['yh']} = {_lane_output(n, z, 'n', 'vi', outmap)}"]
    sums = _lane_outputs(lanes, z, ind2, "i") if outputs else _normal_sums(lanes, z, ind2)
    return _NORMAL_TEMPLATE.format(
        n=n, hold=hold, lanes=lanes, K=K, width=width, rows=len(z), outmap=outmap,
        imports=f"from hammerstein_ctrl.compiled_maps import {outmap} as h\n" if outmap else "",
        setup="\n".join(_normal_setup(n, hold, K, lanes, z, ind1, outputs)), first="\n".join(first),
        fetch="\n".join(fetch), step="\n".join(step), sums="\n".join(sums),
        store="\n".join(_normal_store(n, lanes, z, ind1, outputs)),
    )


@functools.lru_cache(maxsize=None)
def get_normal_kernel(n: int, hold: str, lanes: int, K: int, direct: bool = True, offset: bool = True,
                      outmap: str | None = None, outputs: bool = False):
    """The compiled normal-equation pass: a point and its forward-difference neighbours side by side.

    Lane 0 simulates the point, lane ``j`` the point with parameter ``j - 1``
    moved by a step ``h``; the signal of lane ``g`` is ``P[g] @ Phi`` (a
    nonlinearity linear in its parameters, or ``Phi = u`` and ``P = 1``).
    Per sample the pass adds ``r**2``, ``d r`` and ``d d^T`` to running sums,
    with ``r = y - yhat_0`` and ``d[j] = yhat_0 - yhat_{j+1}`` (``h_j`` times
    the forward-difference derivative of ``r``: the caller divides by the
    steps once at the end), so the Jacobian is never stored.
    Up to :data:`MAX_VECTOR_STATES` states a summing pass (no output map)
    keeps the point in scalars and the neighbours four at a time in vectors
    that stay in registers (:func:`vector_normal_source`); the point and a
    neighbour that equals it give the same bits, so a difference is exactly
    the effect of its step.  Otherwise the lanes step side by side in the
    columns of one small array (as in :func:`get_lane_kernel`), so LLVM
    vectorises their recursion.

    Parameters
    ----------
    n : int
        State dimension (at most :data:`MAX_PASS_STATES`; an output map in the
        pass needs at most :data:`MAX_UNROLLED_STATES`).
    hold : {"foh", "zoh"}
    lanes : int
        Number of candidates, ``2 .. MAX_NORMAL_LANES``.
    K : int
        Number of basis signals, ``1 .. MAX_LANE_BASIS``.
    direct, offset : bool, default True
        As for :func:`get_lane_kernel`.
    outmap : str, optional
        An output map of :mod:`~hammerstein_ctrl.compiled_maps` applied to
        every lane's output (Wiener and Hammerstein-Wiener structures); lane
        ``j``'s map parameters are the row ``HP[j]``, the map's fixed data ``HX``.
    outputs : bool, default False
        Store every lane's output samples instead of summing (for a streamed
        QR factor of the Jacobian, :func:`~hammerstein_ctrl.simulate.normal_factor`).

    Returns
    -------
    callable
        ``kernel(E, C, D, X, Y0, VP, P, Phi, HP, HX, y, begin, acc)`` (without
        a map, ``HP`` and ``HX`` are not read: pass empty arrays).  With
        ``outputs``, ``acc`` is an ``(N_block, lanes)`` array that receives
        every lane's output samples, and ``y`` is not read.  ``E``,
        ``C``, ``D`` may have fewer rows than there are lanes: the lanes past
        them share row 0's linear block (neighbours that move only the
        signal, the offset or the initial state).  ``X``
        (lanes' states), ``VP`` (previous signal samples) and ``acc``
        (``[f, sum d r (p), sum d d^T (p x p)]``; the lower triangle of the
        last is read, all of it written) are read and updated, so a long
        record can be passed a block of samples at a time; ``begin`` is the
        index of the block's first sample in the record.

    Examples
    --------
    >>> import numpy as np
    >>> k = get_normal_kernel(1, "zoh", 2, 1)
    >>> E = np.array([[[0.5, 1.0, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]]] * 2)  # x+ = x/2 + 2 theta u
    >>> C, D, X, VP = np.ones((2, 1)), np.zeros(2), np.zeros((2, 1)), np.zeros(2)
    >>> P = np.array([[2.0], [2.5]])                # theta = 1 and theta + h with h = 0.25
    >>> acc = np.zeros(3)
    >>> k(E, C, D, X, np.zeros(2), VP, P, np.ones((1, 3)), np.zeros((2, 0)), np.zeros(0), np.zeros(3), 0, acc)
    >>> acc            # y = 0: r = -(0, 2, 3) theta and d = h dr/dtheta = -(0, 2, 3) / 4
    array([13.    ,  3.25  ,  0.8125])
    """
    if hold not in HOLDS:
        raise ValueError(f"unknown hold {hold!r}")
    _check_sizes(n, K, MAX_PASS_STATES)
    if not 2 <= lanes <= MAX_NORMAL_LANES:
        raise ValueError(f"normal-equation passes are compiled for 2..{MAX_NORMAL_LANES} lanes, not {lanes}")
    if outmap is not None and not has_output_maps(n):
        raise ValueError(f"output maps are compiled for up to {MAX_UNROLLED_STATES} states, not {n}")
    name = (f"hc_normal_n{n}_{hold}_l{lanes}_k{K}" + "".join(f"_{t}" for t in _terms(direct, offset))
            + (f"_{outmap}" if outmap else "") + ("_outputs" if outputs else ""))
    if outmap is None and not outputs and n <= MAX_VECTOR_STATES:
        src = vector_normal_source(int(n), hold, int(lanes), int(K), bool(direct), bool(offset))
    else:
        src = normal_source(int(n), hold, int(lanes), int(K), bool(direct), bool(offset), outmap, bool(outputs))
    return _load_source(src, name)


#: Array types of :func:`get_normal_kernel`'s arguments as :func:`call_normal_kernel` passes them
#: (all but ``Phi`` and ``y``, whose types the caller's arrays give): fresh, writeable, C-contiguous.
_NORMAL_ARGUMENT_DIMS = {"E": 3, "C": 2, "D": 1, "X": 2, "Y0": 1, "VP": 1, "P": 2, "HP": 2, "HX": 1, "acc": 1}


def _normal_signature(basis_type, y_type) -> tuple:
    """The argument types of a summing normal-equation kernel called with a basis and a record of these numba types."""
    a = {name: numba.types.Array(numba.types.float64, dims, "C") for name, dims in _NORMAL_ARGUMENT_DIMS.items()}
    return (a["E"], a["C"], a["D"], a["X"], a["Y0"], a["VP"], a["P"], basis_type, a["HP"], a["HX"], y_type,
            numba.types.int64, a["acc"])


@functools.lru_cache(maxsize=None)
def normal_kernel_address(n: int, hold: str, lanes: int, K: int, direct: bool, basis_type, y_type) -> int:
    """Address of :func:`get_normal_kernel`'s summing kernel (no offset, map or outputs), for
    :func:`call_normal_kernel`.

    Compiled code that calls the kernel through its address is compiled once
    for every kernel (numba would otherwise compile the caller again for
    each kernel it calls, and could not cache it).  ``basis_type`` and
    ``y_type`` are the numba types (``numba.typeof``) of the basis and the
    record the caller passes; the other arrays must be fresh float64 arrays
    (C-contiguous, writeable), as :func:`call_normal_kernel` checks when the caller is compiled.
    The address is valid for the life of the process.

    Examples
    --------
    >>> import numba, numpy as np
    >>> Phi, y = np.ones((1, 3)), np.zeros(3)
    >>> normal_kernel_address(1, "zoh", 2, 1, False, numba.typeof(Phi), numba.typeof(y)) > 0
    True
    """
    kernel = get_normal_kernel(n, hold, lanes, K, direct, False)
    signature = _normal_signature(basis_type, y_type)
    kernel.compile(signature)
    compiled = kernel.overloads[signature]
    return compiled.library.get_pointer_to_function(compiled.fndesc.llvm_func_name)


@numba.extending.intrinsic
def call_normal_kernel(typingctx, address, E, C, D, X, Y0, VP, P, Phi, HP, HX, y, begin, acc):
    """Call the kernel at ``address`` (:func:`normal_kernel_address`) from compiled code, as ``kernel(E, ..., acc)``.

    The arguments' types are checked against the kernel's when the caller is
    compiled: the same types give the same machine code, called through the pointer.
    """
    args = (E, C, D, X, Y0, VP, P, Phi, HP, HX, y, begin, acc)
    expected = _normal_signature(Phi, y)
    records = (isinstance(Phi, numba.types.Array) and isinstance(y, numba.types.Array) and Phi.ndim == 2
               and y.ndim == 1 and Phi.layout == y.layout == "C" and Phi.dtype == y.dtype == numba.types.float64)
    if address != numba.types.int64 or tuple(numba.types.unliteral(a) for a in args) != expected or not records:
        raise numba.core.errors.TypingError(
            f"call_normal_kernel takes an int64 address and {expected}, got {(address, *args)}")

    def codegen(context, builder, signature, llargs):
        function = context.call_conv.get_function_type(numba.types.none, expected)
        pointer = builder.inttoptr(llargs[0], function.as_pointer())
        status, _ = context.call_conv.call_function(builder, pointer, numba.types.none, expected, llargs[1:])
        with numba.core.cgutils.if_unlikely(builder, status.is_error):
            context.call_conv.return_status_propagate(builder, status)
        return context.get_dummy_value()
    return numba.types.none(address, *args), codegen


#: Package modules whose compiled functions the generated kernels call.
_CALLED_MODULES = ("_linalg.py", "compiled_maps.py", "nonlinearities.py", "_simd.py")


@functools.lru_cache(maxsize=1)
def cache_dir() -> Path | None:
    """Directory holding the generated kernel sources (and numba's cache beside them).

    ``$HAMMERSTEIN_CTRL_CACHE`` if set, else ``$XDG_CACHE_HOME/hammerstein_ctrl``
    (``~/.cache/hammerstein_ctrl``), in a sub-directory named after a digest of
    this module's source and numba's version, so a new release never loads
    stale machine code.  ``None`` if no writable location exists (kernels are
    then compiled in memory in every process).
    """
    # the generated modules call compiled code of these modules, which numba's cache does not track
    here = Path(__file__).parent
    sources = b"".join((here / name).read_bytes() for name in ("kernels.py",) + _CALLED_MODULES)
    digest = hashlib.sha256(sources + numba.__version__.encode()).hexdigest()[:16]
    root = os.environ.get(ENV_CACHE) or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
        "hammerstein_ctrl")
    path = Path(root) / f"kernels-{digest}"
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(dir=path, delete=True)
        probe.close()
    except OSError:
        return None
    return path


def _check_sizes(n: int, K: int, max_states: int = MAX_UNROLLED_STATES):
    """Raise unless kernels forming the signal from a basis are compiled for ``n`` states and ``K`` basis signals."""
    if not (1 <= n <= max_states and 1 <= K <= MAX_LANE_BASIS):
        raise ValueError(f"kernels forming the signal from a basis are compiled for 1..{max_states} "
                         f"states and 1..{MAX_LANE_BASIS} basis signals, not n = {n}, K = {K}")


def _write_once(path: Path, text: str):
    """Write ``text`` atomically unless the file already holds it (keeps numba's cache valid); a damaged file is
    rewritten."""
    if path.is_file() and path.read_text(errors="replace") == text:
        return
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        fh.write(text)
    os.replace(tmp, path)


def _load_generated(n: int, mode: str, hold: str, outmap: str | None = None, K: int | None = None):
    return _load_source(kernel_source(n, mode, hold, outmap, K), _module_name(n, mode, hold, outmap, K))


@functools.lru_cache(maxsize=None)
def get_coefficient_kernel(n: int, hold: str, K: int):
    """:func:`get_kernel`'s ``"sse"`` kernel with a basis, preceded by the discretisation, in one compiled call.

    Parameters
    ----------
    n : int
        State dimension (at most :data:`MAX_UNROLLED_STATES`).
    hold : {"foh", "zoh"}
    K : int
        Number of basis signals, ``1 .. MAX_LANE_BASIS``.

    Returns
    -------
    callable
        ``from_coefficients(num, den, dt, max_norm, X0, Y0, P, Phi, y, out) -> bool``:
        the transfer functions ``num/den`` (rows, descending powers) are
        realised and discretised (:func:`hammerstein_ctrl._linalg.tf_discrete`)
        and J goes to ``out``; ``False`` (``out`` untouched) if a row is not
        usable or its exponential needs more than the compiled Pade
        (1-norm above ``max_norm``), for the caller's general path.

    Examples
    --------
    >>> import numpy as np
    >>> from hammerstein_ctrl.simulate import COMPILED_EXPM_MAX_NORM
    >>> f = get_coefficient_kernel(1, "zoh", 1)
    >>> J = np.empty(1)
    >>> f(np.ones((1, 1)), np.array([[1.0, 0.0]]), 0.5, COMPILED_EXPM_MAX_NORM, np.zeros((1, 1)), np.zeros(1),
    ...   np.ones((1, 1)), np.ones((1, 4)), np.zeros(4), J), J        # an integrator: y = (0, 0.5, 1, 1.5)
    (True, array([3.5]))
    """
    get_kernel(n, "sse", hold, None, K)        # checks the arguments
    return _load_source(kernel_source(n, "sse", hold, None, K), _module_name(n, "sse", hold, None, K),
                        "from_coefficients")


def _module_name(n: int, mode: str, hold: str, outmap: str | None, K: int | None) -> str:
    return f"hc_kernel_n{n}_{mode}_{hold}" + (f"_{outmap}" if outmap else "") + (f"_k{K}" if K else "")


def _load_source(src: str, name: str, attr: str = "kernel"):
    """Compile generated source as module ``name`` (from the disk cache, else in memory); its ``attr``."""
    return getattr(_load_module(src, name), attr)


@functools.lru_cache(maxsize=None)
def _load_module(src: str, name: str):
    folder = cache_dir()
    path = None if folder is None else folder / f"{name}.py"
    if path is not None:
        try:
            _write_once(path, src)
        except OSError:
            path = None
    if path is None:
        module = types.ModuleType(name)
        exec(compile(src.replace("@cached_njit(", "@cached_njit(cache=False, "), f"<{name}>", "exec"), module.__dict__)
        return module
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


@functools.lru_cache(maxsize=None)
def get_kernel(n: int, mode: str, hold: str = "foh", outmap: str | None = None, K: int | None = None):
    """The compiled recursion for ``n`` states.

    Parameters
    ----------
    n : int
        State dimension of the linear block.
    mode : {"sse", "outputs"}
    hold : {"foh", "zoh"}
    outmap : str, optional
        Name of an output map in :mod:`hammerstein_ctrl.compiled_maps`; only
        for ``n <= MAX_UNROLLED_STATES`` (see :func:`has_output_maps`).
    K : int, optional
        Form each candidate's signal from ``K`` basis signals in the pass
        (``1 .. MAX_LANE_BASIS``; only for ``n <= MAX_UNROLLED_STATES``): the
        kernel then takes ``P, Phi`` (shapes ``(B, K)`` and ``(K, N)``,
        signal ``P[b] @ Phi`` summed basis row by basis row) in place of ``V``.

    Returns
    -------
    callable
        ``kernel(E, C, D, X0, Y0, V, y, out)`` (``"sse"``: ``out`` of shape
        ``(B,)`` receives J) or ``kernel(E, C, D, X0, Y0, V, out)``
        (``"outputs"``: ``out`` of shape ``(B, N)``); with an output map, the
        map's parameters ``HP`` (``(B, m)``) and fixed data ``HX`` come before ``y``/``out``.
    """
    if K is not None:
        _check_sizes(n, K)
    if mode not in MODES or hold not in HOLDS:
        raise ValueError(f"unknown kernel mode {mode!r} / hold {hold!r}")
    if outmap is not None and not has_output_maps(n):
        raise ValueError(f"output maps are compiled for up to {MAX_UNROLLED_STATES} states, not {n}")
    if n <= MAX_UNROLLED_STATES:
        return _load_generated(int(n), mode, hold, outmap, None if K is None else int(K))
    zoh = hold == "zoh"
    if mode == "sse":
        return lambda E, C, D, X0, Y0, V, y, out: _sse_generic(E, C, D, X0, Y0, V, y, out, zoh)
    return lambda E, C, D, X0, Y0, V, out: _outputs_generic(E, C, D, X0, Y0, V, out, zoh)


def has_output_maps(n: int) -> bool:
    """Whether kernels for ``n`` states can apply an output map in the compiled pass."""
    return n <= MAX_UNROLLED_STATES


@cached_njit()
def _step_generic(E, b, n, x, xn, vp, vi, zoh):  # pragma: no cover - compiled
    for r in range(n):
        s = 0.0
        for c in range(n):
            s += E[b, r, c] * x[c]
        if zoh:
            xn[r] = s + E[b, r, n] * vp
        else:
            bd1 = E[b, r, n + 1]
            xn[r] = s + ((E[b, r, n] - bd1) * vp + bd1 * vi)
    for r in range(n):
        x[r] = xn[r]


@cached_njit()
def _outputs_generic(E, C, D, X0, Y0, V, out, zoh):  # pragma: no cover - compiled
    batch, N = V.shape
    n = E.shape[1] - 2
    xn = np.zeros(n)
    for b in range(batch):
        x = X0[b].copy()
        for i in range(N):
            if i > 0:
                _step_generic(E, b, n, x, xn, V[b, i - 1], V[b, i], zoh)
            out[b, i] = np.dot(C[b], x) + D[b] * V[b, i] + Y0[b]


@cached_njit()
def _sse_generic(E, C, D, X0, Y0, V, y, out, zoh):  # pragma: no cover - compiled
    batch, N = V.shape
    n = E.shape[1] - 2
    xn = np.zeros(n)
    for b in range(batch):
        x = X0[b].copy()
        J = 0.0
        for i in range(N):
            if i > 0:
                _step_generic(E, b, n, x, xn, V[b, i - 1], V[b, i], zoh)
            e = y[i] - (np.dot(C[b], x) + D[b] * V[b, i] + Y0[b])
            J += e * e
            if (i & _CHECK_MASK) == 0 and not J <= _OVERFLOW:
                break
        out[b] = J if J <= _OVERFLOW else np.inf
