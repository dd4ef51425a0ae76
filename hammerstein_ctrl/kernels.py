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

The generated source is Python.  Every kernel is translated to C
(:mod:`~hammerstein_ctrl._kernel_c`; an output map's formula with it) and built once per
machine by the system's C compiler (about 0.1-0.2 s a kernel, where numba
took 0.6-3 s), into the machine cache (:func:`~hammerstein_ctrl._native.kernel_address`):
a :class:`CKernel`, called from Python through the package's C library,
which checks its arrays' types and shapes, and from compiled code through
its address (:func:`normal_kernel_address`).  The translation is operation for
operation, without contraction into fused multiply-adds, so a kernel gives
the bits numba gives for the same source.  A kernel whose output map C
does not take (one reading fixed data sized with its parameters: the
piecewise-linear map) calls the compiled function of
:mod:`~hammerstein_ctrl.compiled_maps` instead: its source is written to a
per-version cache directory (:func:`cache_dir`) and compiled by numba with
``cache=True``, so a new process loads the machine code instead of compiling
again.  Larger dimensions use one generic compiled loop.

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
import inspect
import os
import sys
import tempfile
import types
from pathlib import Path

import numba
import numpy as np

from ._jit import (ENV_CACHE as _jit_ENV_CACHE, cached_njit, machine_cache_dir)
from ._kernel_source import (_CHECK_MASK, _OVERFLOW, _terms, HOLDS, INTERLEAVE, LANE_MIN, LANE_WIDTHS,
                             MAX_LANE_BASIS, MAX_NORMAL_LANES, MAX_PASS_STATES, MAX_UNROLLED_STATES,
                             MAX_VECTOR_STATES, MODES, OUTPUT_TERMS, kernel_source, lane_source,
                             normal_source, vector_chunks, vector_normal_source)
from ._kernel_c import translate
from ._native import entry_address, kernel_address, library
from .nonlinearities import NONLINEARITIES

__all__ = ["get_kernel", "get_coefficient_kernel", "get_normal_kernel", "get_lane_kernel", "lane_source",
           "has_basis_kernels", "has_output_maps", "kernel_source", "normal_kernel_address",
           "normal_source", "vector_normal_source", "cache_dir", "OUTPUT_TERMS",
           "MAX_UNROLLED_STATES", "MAX_PASS_STATES", "MAX_VECTOR_STATES", "MAX_NORMAL_LANES", "LANE_WIDTHS", "LANE_MIN",
           "MAX_LANE_BASIS", "INTERLEAVE", "MODES", "HOLDS", "ENV_CACHE"]

#: Environment variable overriding the kernel cache directory (:func:`~hammerstein_ctrl._jit.machine_cache_dir`).
ENV_CACHE = _jit_ENV_CACHE


@functools.lru_cache(maxsize=None)
def get_lane_kernel(n: int, hold: str, K: int, direct: bool = True, offset: bool = True):
    """The compiled sum of squared errors of candidates side by side in SIMD lanes.

    Candidate ``b``'s signal is ``P[b] @ Phi`` (a nonlinearity linear in its
    parameters, or ``Phi = u`` and ``P = 1``), formed sample by sample inside
    the kernel.  Candidates are taken in groups of :data:`LANE_WIDTHS` whose
    quantities sit in the columns of one small array, so the C compiler vectorises the
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
    src = lane_source(int(n), hold, int(K), bool(direct), bool(offset))
    return _c_kernel(src, name, _basis_shapes(n, hold, "sse", K))


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
    the effect of its step; such a pass counts its lanes at run time (the
    length of ``VP``), so one compiled pass serves 2 to 5 lanes, one 6 to 9,
    and so on.  Otherwise the lanes step side by side in the
    columns of one small array (as in :func:`get_lane_kernel`), so the C compiler
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
    terms = "".join(f"_{t}" for t in _terms(direct, offset))
    if outmap is None and not outputs and n <= MAX_VECTOR_STATES:   # one pass per number of neighbour vectors
        src = vector_normal_source(int(n), hold, int(lanes), int(K), bool(direct), bool(offset))
        name = f"hc_normal_n{n}_{hold}_c{vector_chunks(lanes)}_k{K}{terms}"
        return _c_kernel(src, name, _pass_shapes(n, hold, outputs))
    name = f"hc_normal_n{n}_{hold}_l{lanes}_k{K}{terms}" + (f"_{outmap}" if outmap else "") + (
        "_outputs" if outputs else "")
    src = normal_source(int(n), hold, int(lanes), int(K), bool(direct), bool(offset), outmap, bool(outputs))
    return _built(src, name, outmap, _pass_shapes(n, hold, outputs, outmap is not None))


@functools.lru_cache(maxsize=None)
def normal_kernel_address(n: int, hold: str, lanes: int, K: int, direct: bool) -> int:
    """Address of :func:`get_normal_kernel`'s summing kernel (no offset, map or outputs), for the C library's
    Levenberg-Marquardt loop (:mod:`~hammerstein_ctrl.optimize.normal_lm`), valid for the life of the process.

    Examples
    --------
    >>> normal_kernel_address(1, "zoh", 2, 1, False) > 0
    True
    """
    return get_normal_kernel(n, hold, lanes, K, direct, False).address


class CKernel:
    """A generated kernel built in C (:func:`~hammerstein_ctrl._native.kernel_address`): called from Python as
    ``kernel(E, C, ...)``, its arrays checked against the shapes it takes (a ``ValueError`` or ``TypeError``
    naming the argument); :attr:`address` for compiled callers.

    Parameters
    ----------
    address : int
        The kernel's machine code.
    spec : str
        Its name and arguments, as the library's ``call`` reads them.
    messages : tuple of str
        The message of each refusal the kernel can return (its source's ``raise`` statements).
    """

    __slots__ = ("address", "spec", "messages", "_call")

    def __init__(self, address: int, spec: str, messages: tuple):
        self.address, self.spec, self.messages = address, spec, messages
        self._call = library().call

    def __call__(self, *args):
        status = self._call(self.address, self.spec, *args)
        if status:
            raise ValueError(self.messages[status - 1])

    def __repr__(self):
        return f"<CKernel {self.spec.split('|')[0]}>"


@functools.lru_cache(maxsize=None)
def _c_kernel(src: str, name: str, shapes: tuple, output_map: str | None = None) -> CKernel:
    """The generated kernel ``src`` translated to C and built (once per machine), its arguments of ``shapes``
    (``(name, dimensions)`` pairs, as the library's ``call`` reads them; ``{map}`` the fewest parameters of its
    output map, whose formula's source is ``output_map``)."""
    c = translate(src, output_map)
    dims = {a: d.replace("{map}", str(c.map_params)) for a, d in shapes}
    words = [f"{a}:i" if code == "i" else f"{a}:{code[0]}:{dims[a]}" for a, code in zip(c.names, c.codes)]
    return CKernel(kernel_address(name, c.text), name + "|" + " ".join(words), c.messages)


def _block_shape(n: int, hold: str) -> str:
    """The trailing dimensions of ``E`` a kernel reads: ``n`` rows, ``n + 2`` columns (zoh: ``n + 1``), or more."""
    return f"{n}+,{n + (2 if hold == 'foh' else 1)}+"


def _basis_shapes(n: int, hold: str, mode: str, K: int | None, outmap: bool = False) -> tuple:
    """The shapes a kernel of :func:`kernel_source` or :func:`lane_source` takes: ``B`` candidates, ``N`` samples
    (with an output map, a row of its parameters per candidate, at least as many as it reads)."""
    signal = (("V", "B,N+"),) if K is None else (("P", f"B,{K}+"), ("Phi", f"{K}+,N+"))
    out = (("y", "N"), ("out", "B")) if mode == "sse" else (("out", "B,N+"),)
    mapped = (("HP", "B,{map}+"), ("HX", "X*")) if outmap else ()
    return (("E", f"B,{_block_shape(n, hold)}"), ("C", f"B,{n}+"), ("D", "B"), ("X0", f"B,{n}+"),
            ("Y0", "B")) + signal + mapped + out


def _pass_shapes(n: int, hold: str, outputs: bool, outmap: bool = False) -> tuple:
    """The shapes a normal-equation pass takes: the linear block's trailing dimensions, the output map's parameters
    (at least as many as it reads); the pass checks the rest."""
    return (("E", f"R,{_block_shape(n, hold)}"), ("C", f"S,{n}+"), ("D", "T*"), ("X", f"A,{n}+"), ("Y0", "Q*"),
            ("VP", "L*"),
            ("P", "G*,H*"), ("Phi", "F*,U*"), ("HP", "V*,{map}+" if outmap else "V*,W*"), ("HX", "I*"), ("y", "M*"),
            ("acc", "Z*,Y*" if outputs else "Z*"))


#: Package modules whose compiled functions the generated kernels call.
_CALLED_MODULES = ("compiled_maps.py", "nonlinearities.py", "_simd.py", "_attributes.py")


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
    sources = b"".join((here / name).read_bytes() for name in ("kernels.py", "_kernel_source.py") + _CALLED_MODULES)
    digest = hashlib.sha256(sources + numba.__version__.encode()).hexdigest()[:16]
    root = machine_cache_dir()
    if root is None:
        return None
    path = root / f"kernels-{digest}"
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
    src, name = kernel_source(n, mode, hold, outmap, K), _module_name(n, mode, hold, outmap, K)
    return _built(src, name, outmap, _basis_shapes(n, hold, mode, K, outmap is not None))


def _built(src: str, name: str, outmap: str | None, shapes: tuple):
    """The kernel ``src`` built in C; with an output map whose formula C cannot take (one that reads fixed data
    sized with its parameters), compiled by numba."""
    if outmap is None:
        return _c_kernel(src, name, shapes)
    try:
        return _c_kernel(src, name, shapes, _map_source(outmap))
    except NotImplementedError:
        return _load_source(src, name)


def _map_source(outmap: str) -> str:
    """The Python source of the formula of the output map ``outmap`` (``<family>_map``)."""
    family = NONLINEARITIES.get(outmap.removesuffix("_map"))
    if family is None or family.formula is None:
        raise NotImplementedError(f"no formula for the output map {outmap!r}")
    try:
        return inspect.getsource(family.formula)
    except OSError:                     # no source installed: numba compiles the map from its bytecode
        raise NotImplementedError(f"no source of the output map {outmap!r}") from None


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
    address = get_kernel(n, "sse", hold, None, K).address
    shapes = (f"kernel:i num:r:B,L den:r:B,{n + 1} dt:f max_norm:f X0:r:B,{n}+ Y0:r:B P:r:B,{K}+ Phi:r:{K}+,N+ "
              "y:r:N out:w:B")
    return functools.partial(_coefficient_pass, f"hc_coefficient_pass_n{n}_k{K}|{shapes}", address)


#: The C library's call and its single evaluation from coefficients (``hc_coefficient_pass``).
_CALL, _COEFFICIENT_PASS = library().call, entry_address("hc_coefficient_pass")


def _coefficient_pass(spec: str, address: int, *args) -> bool:
    """:func:`get_coefficient_kernel`'s call: the C library's discretisation and the kernel at ``address``."""
    status = _CALL(_COEFFICIENT_PASS, spec, address, *args)
    if status > 1:
        raise MemoryError("no memory for the discretised blocks") if status == 3 else ValueError(
            f"{spec.split('|')[0]}: num has more coefficients than den" if status == 2 else
            f"{spec.split('|')[0]}: the kernel refused its arrays")
    return status == 0


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


def has_basis_kernels(n: int, K: int = 1) -> bool:
    """Whether kernels forming the signal from ``K`` basis signals are compiled for ``n`` states (as
    :func:`get_kernel` with ``K`` and :func:`get_coefficient_kernel` take them).

    Examples
    --------
    >>> has_basis_kernels(2, 3), has_basis_kernels(MAX_UNROLLED_STATES + 1)
    (True, False)
    """
    return 1 <= n <= MAX_UNROLLED_STATES and 1 <= K <= MAX_LANE_BASIS


def has_output_maps(n: int) -> bool:
    """Whether kernels for ``n`` states can apply an output map in the compiled pass."""
    return n <= MAX_UNROLLED_STATES


@cached_njit(depends=("_kernel_source.py",))
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


@cached_njit(depends=("_kernel_source.py",))
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


@cached_njit(depends=("_kernel_source.py",))
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
