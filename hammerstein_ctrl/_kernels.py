"""The sampled recursions of a linear block: the compiled core's simulation kernels, as Python callables.

The kernels read, per candidate ``b``, the matrix exponential
``E[b] = expm([[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]])`` and run

* first-order hold (``"foh"``, the input linear between samples, the paper's
  semantics and ``control.forced_response``'s):
  ``x[k] = Ad x[k-1] + (Bd0 v[k-1] + Bd1 v[k])`` with ``Ad = E[:n, :n]``,
  ``Bd1 = E[:n, n+1]`` and ``Bd0 = E[:n, n] - Bd1``;
* zero-order hold (``"zoh"``, the input held between samples, as from a DAC):
  ``x[k] = Ad x[k-1] + Gamma v[k-1]`` with ``Gamma = E[:n, n]``;

from the initial state ``x[0] = X0[b]``, with output
``y[k] = C x[k] + D v[k] + Y0[b]``, or, with an output nonlinearity ``h``
(Wiener and Hammerstein-Wiener models), ``y[k] = h(C x[k] + D v[k]; HP[b]) + Y0[b]``
evaluated in the same pass (a built-in family's map, :data:`MAP_CODES`).  In
``"sse"`` mode a kernel returns the sum of squared errors against a measured
``y`` without storing the output.

Four families, all built when the package is installed (the extension
module ``hammerstein_ctrl._core``; nothing is compiled at run time), share
one definition of a candidate's arithmetic, so a candidate gets the same
bits from each:

* :func:`get_kernel`: candidates one to three at a time with the state in
  registers (the recursion is latency-bound, so independent chains keep the
  CPU busy); with ``K`` basis signals the signal ``P[b] @ Phi`` is formed in
  the pass instead of read from ``V``;
* :func:`get_coefficient_kernel`: the same, preceded by the realisation and
  the matrix exponential in one call (single evaluations);
* :func:`get_lane_kernel`: candidates in groups across vector lanes (batches);
* :func:`get_normal_kernel`: a point and its forward-difference neighbours
  across vector lanes, accumulating the normal equations of least squares.

The vector families run in the widest instruction set the processor has
(:func:`vector_isa`), with the same bits in every set.  Each callable checks
its arrays' types and shapes before the kernel runs (a ``TypeError`` or
``ValueError`` naming the argument), and runs it without the GIL.

Examples
--------
>>> import numpy as np
>>> from hammerstein_ctrl._kernels import get_kernel
>>> k = get_kernel(1, "outputs", "zoh")
>>> E = np.array([[[1.0, 0.5, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]]])  # integrator, dt = 0.5
>>> out = np.empty((1, 4))
>>> k(E, np.ones((1, 1)), np.zeros(1), np.zeros((1, 1)), np.zeros(1), np.ones((1, 4)), out)
>>> out
array([[0. , 0.5, 1. , 1.5]])
"""

from __future__ import annotations

import functools

from . import _core
from ._checks import MAX_ORDER

__all__ = ["get_kernel", "get_coefficient_kernel", "get_normal_kernel", "get_lane_kernel", "has_basis_kernels",
           "has_output_maps", "normal_kernel_number", "vector_isa", "Kernel", "MAP_CODES", "MAX_UNROLLED_STATES",
           "MAX_PASS_STATES", "MAX_NORMAL_LANES", "LANE_WIDTHS", "LANE_MIN", "MAX_LANE_BASIS", "MODES", "HOLDS"]

#: Orders whose kernels form the signal from a basis, apply an output map in the pass, or run across lanes.
MAX_UNROLLED_STATES = _core.LANES_MAX_ORDER
#: Orders with a normal-equation pass (and its outputs mode): every order a linear block may have, so that LM's
#: Jacobian sums and the automatic starts' regressions stay bounded in memory on long records whatever the block.
MAX_PASS_STATES = _core.MAX_ORDER
#: Most candidates (one point and its forward-difference neighbours) of a normal-equation pass.
MAX_NORMAL_LANES = _core.MAX_LANES
#: Most basis signals of a kernel that forms the signal from a basis.
MAX_LANE_BASIS = _core.MAX_BASIS
#: Candidates per group of a lanes kernel (the last group padded).
LANE_WIDTHS = (8,)
#: Fewest candidates for which the lanes kernel beats the one-at-a-time kernel (a padded group costs about as much
#: as a full one).
LANE_MIN = 3
#: ``"sse"``: sum of squared errors only; ``"outputs"``: the simulated output.
MODES = ("sse", "outputs")
#: Intersample behaviours of the input.
HOLDS = ("foh", "zoh")
#: Code of each built-in family's map in the compiled passes (its name: :attr:`Nonlinearity.compiled_map`).
MAP_CODES = dict(_core.MAP_CODES)

#: Option bits of the kernel families (the core's hc.h).
_SSE, _BASIS, _MAP = 1, 2, 4
_DIRECT, _OFFSET, _OUTPUTS = 1, 2, 8
#: The message of a kernel's refusal (its status 1): a map whose parameters or data do not fit it.
_MAP_REFUSAL = "the output map's parameters (a row per candidate, as many as the map reads) or data do not fit it"

if _core.MAX_ORDER != MAX_ORDER:       # pragma: no cover - a core built from other sources
    raise ImportError(f"hammerstein_ctrl's compiled core is built for orders up to {_core.MAX_ORDER}, "
                      f"the package for {MAX_ORDER}: reinstall the package")


class Kernel:
    """A kernel of the compiled core: ``kernel(E, C, ...)`` checks its arrays against the shapes it takes (a
    ``ValueError`` or ``TypeError`` naming the argument) and runs it without the GIL.

    Parameters
    ----------
    number : int
        Its number in the core's table (:attr:`number`, for compiled callers).
    spec : str
        Its name and arguments, as the core's ``call`` reads them.
    messages : tuple of str
        The message of each refusal the kernel can return (status 1, 2, ...).
    prefix : tuple
        Arguments passed before the caller's (an output map's code).
    """

    __slots__ = ("number", "spec", "messages", "prefix")

    def __init__(self, number: int, spec: str, messages: tuple, prefix: tuple = ()):
        self.number, self.spec, self.messages, self.prefix = number, spec, messages, prefix
        if number < 0:
            raise ValueError(f"the compiled core has no kernel {spec.split('|')[0]}")

    def __call__(self, *args):
        status = _core.call(self.number, self.spec, *self.prefix, *args)
        if status:
            raise ValueError(f"{self.spec.split('|')[0]}: {self.messages[status - 1]}")

    def __repr__(self):
        return f"<Kernel {self.spec.split('|')[0]}>"


def _hold(hold: str) -> int:
    if hold not in HOLDS:
        raise ValueError(f"unknown hold {hold!r}")
    return HOLDS.index(hold)


def _map_code(outmap: str | None) -> tuple:
    """The kernel's prefix for an output map (its code), or none."""
    if outmap is None:
        return ()
    if outmap not in MAP_CODES:
        raise ValueError(f"no compiled output map {outmap!r}: known {sorted(MAP_CODES)}")
    return (MAP_CODES[outmap],)


def _block_shape(n: int, hold: str) -> str:
    """The trailing dimensions of ``E`` a kernel reads: ``n`` rows, ``n + 2`` columns (zoh: ``n + 1``), or more."""
    return f"{n}+,{n + (2 if hold == 'foh' else 1)}+"


def _check_sizes(n: int, K: int, max_states: int = MAX_UNROLLED_STATES):
    """Raise unless kernels forming the signal from a basis are built for ``n`` states and ``K`` basis signals."""
    if not (1 <= n <= max_states and 1 <= K <= MAX_LANE_BASIS):
        raise ValueError(f"kernels forming the signal from a basis are built for 1..{max_states} "
                         f"states and 1..{MAX_LANE_BASIS} basis signals, not n = {n}, K = {K}")


@functools.lru_cache(maxsize=None)
def get_kernel(n: int, mode: str, hold: str = "foh", outmap: str | None = None, K: int | None = None) -> Kernel:
    """The compiled recursion for ``n`` states, candidates one to three at a time.

    Parameters
    ----------
    n : int
        State dimension of the linear block (``1 .. MAX_PASS_STATES``; any, a static block's 0 included, for
        signals ``V`` without a map: ``E`` is then exactly ``(B, n + 2, n + 2)``).
    mode : {"sse", "outputs"}
    hold : {"foh", "zoh"}
    outmap : str, optional
        Name of a built-in output map (:data:`MAP_CODES`); only for
        ``n <= MAX_UNROLLED_STATES`` (see :func:`has_output_maps`).
    K : int, optional
        Form each candidate's signal from ``K`` basis signals in the pass
        (``1 .. MAX_LANE_BASIS``; only for ``n <= MAX_UNROLLED_STATES``): the
        kernel then takes ``P, Phi`` (shapes ``(B, K)`` and ``(K, N)``,
        signal ``P[b] @ Phi`` summed basis row by basis row) in place of ``V``.

    Returns
    -------
    Kernel
        ``kernel(E, C, D, X0, Y0, V, y, out)`` (``"sse"``: ``out`` of shape
        ``(B,)`` receives J) or ``kernel(E, C, D, X0, Y0, V, out)``
        (``"outputs"``: ``out`` of shape ``(B, N)``); with an output map, the
        map's parameters ``HP`` (``(B, m)``) and fixed data ``HX`` come before ``y``/``out``.
    """
    if K is not None:
        _check_sizes(n, K)
    if mode not in MODES:
        raise ValueError(f"unknown kernel mode {mode!r}")
    if outmap is not None and not has_output_maps(n):
        raise ValueError(f"output maps are applied in the pass for up to {MAX_UNROLLED_STATES} states, not {n}")
    if (n > MAX_PASS_STATES or n == 0) and K is None and outmap is None:   # a static block, or past the written-out
        # orders: one generic loop
        spec = (f"hc_kernel_n{n}_{mode}_{hold}|E:r:B,{n + 2},{n + 2} C:r:B,{n}+ D:r:B X0:r:B,{n}+ Y0:r:B V:r:B,N+"
                + (" y:r:N out:w:B" if mode == "sse" else " out:w:B,N+"))
        return Kernel(_core.hc_kernel_number(_core.ANY_ORDER, n, _hold(hold), _SSE if mode == "sse" else 0), spec,
                      ("", "", "no memory for the state"))
    options = (_SSE if mode == "sse" else 0) | (_BASIS if K is not None else 0) | (_MAP if outmap else 0)
    signal = "V:r:B,N+" if K is None else f"P:r:B,{K} Phi:r:{K}+,N+"
    mapped = " HP:r:B,M HX:r:X*" if outmap else ""
    out = " y:r:N out:w:B" if mode == "sse" else " out:w:B,N+"
    name = f"hc_kernel_n{n}_{mode}_{hold}" + (f"_{outmap}" if outmap else "") + (f"_k{K}" if K else "")
    spec = (f"{name}|" + ("map:i " if outmap else "") + f"E:r:B,{_block_shape(n, hold)} C:r:B,{n}+ D:r:B "
            f"X0:r:B,{n}+ Y0:r:B {signal}{mapped}{out}")
    return Kernel(_core.hc_kernel_number(_core.SINGLE, n, _hold(hold), options), spec, (_MAP_REFUSAL,),
                  _map_code(outmap))


@functools.lru_cache(maxsize=None)
def get_lane_kernel(n: int, hold: str, K: int, direct: bool = True, offset: bool = True) -> Kernel:
    """The compiled sum of squared errors of candidates side by side in vector lanes.

    Candidate ``b``'s signal is ``P[b] @ Phi`` (a nonlinearity linear in its
    parameters, or ``Phi = u`` and ``P = 1``), formed sample by sample inside
    the kernel.  Candidates are taken in groups of :data:`LANE_WIDTHS` whose
    quantities sit in the columns of one small array, so the whole group
    steps in vector instructions (AVX2 where the processor has it); each candidate's arithmetic is that of
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
    Kernel
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
    _check_sizes(n, K)
    terms = ("_d" if direct else "") + ("_o" if offset else "")
    spec = (f"hc_lanes_n{n}_{hold}_k{K}{terms}|E:r:B,{_block_shape(n, hold)} C:r:B,{n}+ D:r:B X0:r:B,{n}+ Y0:r:B "
            f"P:r:B,{K} Phi:r:{K}+,N+ y:r:N out:w:B")
    options = (_DIRECT if direct else 0) | (_OFFSET if offset else 0)
    return Kernel(_core.hc_kernel_number(_core.LANES, n, _hold(hold), options), spec, ("a basis of no signals",))


@functools.lru_cache(maxsize=None)
def get_normal_kernel(n: int, hold: str, lanes: int, K: int, direct: bool = True, offset: bool = True,
                      outmap: str | None = None, outputs: bool = False) -> Kernel:
    """The compiled normal-equation pass: a point and its forward-difference neighbours side by side.

    Lane 0 simulates the point, lane ``j`` the point with parameter ``j - 1``
    moved by a step ``h``; the signal of lane ``g`` is ``P[g] @ Phi`` (a
    nonlinearity linear in its parameters, or ``Phi = u`` and ``P = 1``).
    Per sample the pass adds ``r**2``, ``d r`` and ``d d^T`` to running sums,
    with ``r = y - yhat_0`` and ``d[j] = yhat_0 - yhat_{j+1}`` (``h_j`` times
    the forward-difference derivative of ``r``: the caller divides by the
    steps once at the end), so the Jacobian is never stored.  The lanes step
    side by side in vector instructions; the pass counts them at run time
    (the length of ``VP``), so one pass serves every lane count.

    Parameters
    ----------
    n : int
        State dimension (at most :data:`MAX_PASS_STATES`; an output map in the
        pass needs at most :data:`MAX_UNROLLED_STATES`).
    hold : {"foh", "zoh"}
    lanes : int
        Number of candidates, ``2 .. MAX_NORMAL_LANES`` (checked; the pass reads
        them from ``VP``).
    K : int
        Number of basis signals, ``1 .. MAX_LANE_BASIS``.
    direct, offset : bool, default True
        As for :func:`get_lane_kernel`.
    outmap : str, optional
        A built-in output map (:data:`MAP_CODES`) applied to every lane's
        output (Wiener and Hammerstein-Wiener structures); lane ``j``'s map
        parameters are the row ``HP[j]``, the map's fixed data ``HX``.
    outputs : bool, default False
        Store every lane's output samples instead of summing (for a streamed
        QR factor of the Jacobian, :func:`~hammerstein_ctrl.simulate._simulate.normal_factor`).

    Returns
    -------
    Kernel
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
    _check_sizes(n, K, MAX_PASS_STATES)
    if not 2 <= lanes <= MAX_NORMAL_LANES:
        raise ValueError(f"normal-equation passes are built for 2..{MAX_NORMAL_LANES} lanes, not {lanes}")
    if outmap is not None and not has_output_maps(n):
        raise ValueError(f"output maps are applied in the pass for up to {MAX_UNROLLED_STATES} states, not {n}")
    options = ((_DIRECT if direct else 0) | (_OFFSET if offset else 0) | (_MAP if outmap else 0)
               | (_OUTPUTS if outputs else 0))
    name = (f"hc_normal_n{n}_{hold}_k{K}" + ("_d" if direct else "") + ("_o" if offset else "")
            + (f"_{outmap}" if outmap else "") + ("_outputs" if outputs else ""))
    spec = (f"{name}|" + ("map:i " if outmap else "") + f"E:r:R,{_block_shape(n, hold)} C:r:S,{n}+ D:r:T* "
            f"X:w:A,{n}+ Y0:r:Q* VP:w:L* P:r:G*,H* Phi:r:F*,U* HP:r:V*,W* HX:r:I* y:r:M* begin:i "
            + ("acc:w:Z*,Y*" if outputs else "acc:w:Z*"))
    refusal = (f"the pass takes 2 to {MAX_NORMAL_LANES} lanes (the length of VP), and X, P (and Y0) with a row for "
               f"each, {K} basis rows, y as long as the basis, "
               f"{'an output row' if outputs else 'sums'} for them all, a linear block"
               + (", and a map's parameters and data that fit it" if outmap else ""))
    return Kernel(_core.hc_kernel_number(_core.NORMAL, n, _hold(hold), options), spec, (refusal,),
                  _map_code(outmap))


@functools.lru_cache(maxsize=None)
def normal_kernel_number(n: int, hold: str, lanes: int, K: int, direct: bool) -> int:
    """Number in the core's table of :func:`get_normal_kernel`'s summing kernel (no offset, map or outputs), for the
    core's Levenberg-Marquardt loop (:mod:`~hammerstein_ctrl.optimize._normal_lm`).

    Examples
    --------
    >>> normal_kernel_number(1, "zoh", 2, 1, False) >= 0
    True
    """
    return get_normal_kernel(n, hold, lanes, K, direct, False).number


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
    >>> from hammerstein_ctrl.simulate._simulate import COMPILED_EXPM_MAX_NORM
    >>> f = get_coefficient_kernel(1, "zoh", 1)
    >>> J = np.empty(1)
    >>> f(np.ones((1, 1)), np.array([[1.0, 0.0]]), 0.5, COMPILED_EXPM_MAX_NORM, np.zeros((1, 1)), np.zeros(1),
    ...   np.ones((1, 1)), np.ones((1, 4)), np.zeros(4), J), J        # an integrator: y = (0, 0.5, 1, 1.5)
    (True, array([3.5]))
    """
    number = get_kernel(n, "sse", hold, None, K).number
    spec = (f"hc_coefficient_pass_n{n}_k{K}|kernel:i num:r:B,L den:r:B,{n + 1} dt:f max_norm:f X0:r:B,{n}+ Y0:r:B "
            f"P:r:B,{K} Phi:r:{K}+,N+ y:r:N out:w:B")
    return functools.partial(_coefficient_pass, spec, number)


#: The core's number of the single evaluation from coefficients.
_COEFFICIENT_PASS = _core.hc_kernel_number(_core.COEFFICIENT, 1, 0, 0)


def _coefficient_pass(spec: str, number: int, *args) -> bool:
    """:func:`get_coefficient_kernel`'s call: the core's discretisation and the kernel ``number``."""
    status = _core.call(_COEFFICIENT_PASS, spec, number, *args)
    if status > 1:
        raise MemoryError("no memory for the discretised blocks") if status == 3 else ValueError(
            f"{spec.split('|')[0]}: num has more coefficients than den" if status == 2 else
            f"{spec.split('|')[0]}: the kernel refused its arrays")
    return status == 0


def has_basis_kernels(n: int, K: int = 1) -> bool:
    """Whether kernels forming the signal from ``K`` basis signals are built for ``n`` states (as
    :func:`get_kernel` with ``K`` and :func:`get_coefficient_kernel` take them).

    Examples
    --------
    >>> has_basis_kernels(2, 3), has_basis_kernels(MAX_UNROLLED_STATES + 1)
    (True, False)
    """
    return 1 <= n <= MAX_UNROLLED_STATES and 1 <= K <= MAX_LANE_BASIS


def has_output_maps(n: int) -> bool:
    """Whether kernels for ``n`` states can apply an output map in the compiled pass (a static block's map, n = 0,
    is applied after it).

    Examples
    --------
    >>> has_output_maps(2), has_output_maps(0)
    (True, False)
    """
    return 1 <= n <= MAX_UNROLLED_STATES


def vector_isa() -> str:
    """The instruction set the vector kernels run in on this processor: ``"avx2"`` (x86-64 processors that have it)
    or ``"baseline"`` (SSE2 on other x86-64 processors, NEON on arm64); every set gives the same bits.

    Examples
    --------
    >>> vector_isa() in ("avx2", "baseline")
    True
    """
    return _core.vector_isa()
