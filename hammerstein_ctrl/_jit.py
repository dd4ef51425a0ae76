"""Compiled functions cached on disk once per machine, loaded without numba's compiler registries, where a damaged
cache file is a cache miss rather than an error.

numba keeps each cached function in an index file (``.nbi``) and data files
(``.nbc``).  A write cut short (a killed process, a full disk) leaves a file
that no longer unpickles, and numba then raises ``EOFError`` or
``UnpicklingError`` from every call of the function, in every process, until
someone deletes the file.  :func:`cached_njit` compiles like ``numba.njit``
with ``cache=True`` and ``nogil=True``, and guards the load of a cached
version: a cache that cannot be read is set aside (its index removed), a
:class:`~hammerstein_ctrl.exceptions.CacheWarning` says which function it was,
and the function is compiled again and saved afresh (a library whose bitcode
turns out damaged only when a later compile links it fails that compile once,
and its folder's index is removed).  The cache lives under
:func:`machine_cache_dir`, keyed on each file's content, and a load from it
skips what only numba's compiler needs (:mod:`~hammerstein_ctrl._cache_load`).
Compiled code can call another compiled function through its address
(:func:`function_address`, :func:`typed_call`), so the callee is compiled once.

Examples
--------
>>> @cached_njit(cache=False)
... def twice(x):
...     return 2.0 * x
>>> twice(1.5)
3.0
"""

from __future__ import annotations

import functools
import hashlib
import os
import warnings
from pathlib import Path

import numba
import numba.core.caching
import numba.core.cgutils
import numba.core.errors

from ._cache_load import fast_load_possible, load_cached, rebuild_cached
from .exceptions import CacheWarning

__all__ = ["cached_njit", "kernel_signature", "only_for", "tolerate_damaged_cache", "machine_cache_dir",
           "machine_cache_root",
           "function_address", "typed_call", "ENV_CACHE"]

#: Environment variable overriding the per-machine cache root (also of the generated kernels).
ENV_CACHE = "HAMMERSTEIN_CTRL_CACHE"
_PACKAGE = Path(__file__).resolve().parent


def machine_cache_root() -> Path:
    """Where the per-machine root of the package's compiled code is, writable or not: ``$HAMMERSTEIN_CTRL_CACHE``,
    else ``$XDG_CACHE_HOME/hammerstein_ctrl`` (``~/.cache/hammerstein_ctrl``)."""
    return Path(os.environ.get(ENV_CACHE) or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "hammerstein_ctrl"))


@functools.lru_cache(maxsize=1)
def machine_cache_dir() -> Path | None:
    """The per-machine root of the package's compiled code (:func:`machine_cache_root`), created if need be;
    ``None`` if not writable."""
    root = machine_cache_root()
    try:
        Path(root).mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return Path(root) if os.access(root, os.W_OK) else None


@functools.lru_cache(maxsize=None)
def _file_digest(path: str) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


class _MachineCacheLocator(numba.core.caching._CacheLocator):
    """numba's cache of the package's own functions, kept once per machine and keyed on file content.

    numba's default puts it in ``__pycache__`` beside the sources and checks
    a file's modification time: every fresh clone, virtual environment or
    install compiled everything again.  Here the cache lives under
    :func:`machine_cache_dir`, in a folder per numba version and source file
    content, so every process, clone and test run of the same sources reuses
    it, and an edited file is never served stale code.
    """

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        digest = _file_digest(py_file)[:16]
        self._cache_path = str(machine_cache_dir() / f"numba-{numba.__version__}" / f"{Path(py_file).stem}-{digest}")

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return _file_digest(self._py_file)

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            inside = Path(py_file).resolve().is_relative_to(_PACKAGE)
        except (OSError, ValueError):
            return None
        if not inside or machine_cache_dir() is None:
            return None
        locator = cls(py_func, py_file)
        try:
            locator.ensure_cache_path()
        except OSError:
            return None
        return locator


if _MachineCacheLocator not in numba.core.caching.CacheImpl._locator_classes:
    numba.core.caching.CacheImpl._locator_classes.insert(0, _MachineCacheLocator)


def cached_njit(*, cache: bool = True, depends: tuple[str, ...] = (), signatures: tuple = (), **options):
    """``numba.njit(cache=cache, nogil=True, **options)``, its cache made tolerant (:func:`tolerate_damaged_cache`).

    Parameters
    ----------
    cache : bool, default True
        Keep the compiled code on disk (numba's cache).
    depends : tuple of str, optional
        Modules of the package (file names, e.g. ``"kernels.py"``) whose
        compiled code the function calls: numba keys its cache on the
        function's own file alone, so a digest of these files joins the key
        and an edit of one of them compiles the function again.
    signatures : tuple of tuple, optional
        Argument types (:func:`kernel_signature`) to compile (or load) at
        once; no other version is then compiled, and arguments convert to
        these types where numba allows it (a writeable array to a read-only
        one).  Default: a version per new combination of argument types, on
        first call.
    **options
        Further options of ``numba.njit`` (``fastmath``, ``error_model``, ...).

    Returns
    -------
    callable
        A decorator.
    """
    def decorate(fn):
        dispatcher = tolerate_damaged_cache(_keyed_on(numba.njit(cache=cache, nogil=True, **options)(fn), depends))
        return only_for(dispatcher, signatures) if signatures else dispatcher
    return decorate


def only_for(dispatcher, signatures):
    """Compile (or load) ``dispatcher`` for ``signatures`` now and no other version later; returns it.

    For a function whose source sits beside others that are not always used
    (a module of generated kernels): declared lazily, fixed when first asked
    for.  Asking again is harmless.

    Parameters
    ----------
    dispatcher : numba dispatcher
    signatures : sequence of tuple
        Argument types (:func:`kernel_signature`).

    Returns
    -------
    The dispatcher: arguments convert to these types where numba allows it; others raise ``TypeError``.

    Examples
    --------
    >>> import numpy as np
    >>> @cached_njit(cache=False)
    ... def total(a):
    ...     return a.sum()
    >>> total = only_for(total, (kernel_signature("r1"),))
    >>> frozen = np.arange(3.0); frozen.flags.writeable = False
    >>> float(total(np.arange(3.0))), float(total(frozen)), len(total.signatures)
    (3.0, 3.0, 1)
    """
    for signature in signatures:
        if signature not in dispatcher.overloads:       # asked again (another cache key of the caller): done
            dispatcher.compile(signature)
    dispatcher.disable_compile()
    return dispatcher


_SIGNATURE_CODES = {"r": True, "w": False}


def kernel_signature(spec: str) -> tuple:
    """Argument types from a compact description: ``r2`` a read-only C-ordered float64 array of 2 dimensions,
    ``w1`` a writeable one of 1, ``b1`` a writeable boolean one of 1, ``f`` a float64, ``i`` an int64.

    Declaring the arrays a function only reads as read-only lets one compiled
    version take writeable and read-only arrays alike (a record's arrays are
    read-only, a caller's fresh ones are not): numba otherwise compiles a
    version for each combination it meets.

    Examples
    --------
    >>> [str(t) for t in kernel_signature("r1 w2 b1 f")]
    ['readonly array(float64, 1d, C)', 'array(float64, 2d, C)', 'array(bool, 1d, C)', 'float64']
    """
    types = []
    for code in spec.split():
        if code in ("f", "i"):
            types.append(numba.types.float64 if code == "f" else numba.types.int64)
        elif len(code) == 2 and code[0] in _SIGNATURE_CODES and code[1].isdigit():
            types.append(numba.types.Array(numba.types.float64, int(code[1]), "C", readonly=_SIGNATURE_CODES[code[0]]))
        elif len(code) == 2 and code[0] == "b" and code[1].isdigit():
            types.append(numba.types.Array(numba.types.bool_, int(code[1]), "C"))
        else:
            raise ValueError(f"unknown argument code {code!r} in {spec!r}")
    return tuple(types)


def _keyed_on(dispatcher, depends: tuple[str, ...]):
    """``dispatcher`` with the digest of the package files ``depends`` in the key of each cached version."""
    cache = getattr(dispatcher, "_cache", None)
    key = getattr(cache, "_index_key", None)
    if not depends or key is None:
        return dispatcher
    cache._index_key = lambda sig, codegen: (*key(sig, codegen), _digest(tuple(depends)))
    return dispatcher


@functools.lru_cache(maxsize=None)
def _digest(names: tuple[str, ...]) -> str:
    """Digest of the sources of the package files ``names`` (read once per process)."""
    here = Path(__file__).parent
    return hashlib.sha256(b"".join((here / name).read_bytes() for name in names)).hexdigest()


def tolerate_damaged_cache(dispatcher):
    """Make a cache file of ``dispatcher`` that cannot be read a cache miss: compiled again, with a warning.

    The guard wraps the two methods numba calls to load and to save a cached
    version (once per signature and process), so calls cost nothing more; the
    load skips what only numba's compiler needs (:mod:`~hammerstein_ctrl._cache_load`).  A
    version that cannot be saved (a full disk, a cache folder no longer
    writable) runs from memory in this process, with a warning.  A
    dispatcher without a disk cache is returned unchanged.
    """
    cache = getattr(dispatcher, "_cache", None)
    load, save = getattr(cache, "load_overload", None), getattr(cache, "save_overload", None)
    if load is None or save is None or isinstance(cache, numba.core.caching.NullCache):
        return dispatcher
    name = f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__}"
    # numba's own load where its cache lacks a part load_cached uses (another numba version)
    fast = fast_load_possible(cache)
    if fast:
        cache._impl.rebuild = functools.partial(rebuild_cached, cache._impl.rebuild,
                                                getattr(cache, "_cache_path", None))

    def load_overload(sig, target_context):
        try:
            return load_cached(cache, sig, target_context) if fast else load(sig, target_context)
        except Exception as exc:       # any failure to read back cached code: compile it again
            _set_aside(cache, sig, target_context)
            _warn(f"numba's cache of {name} could not be read ({type(exc).__name__}: {exc}); "
                  "compiled again and saved afresh")
            return None

    def save_overload(sig, data):
        try:
            save(sig, data)
        except OSError as exc:         # the compiled version still runs: only the disk copy is missing
            _warn(f"numba's cache of {name} could not be saved ({type(exc).__name__}: {exc}); "
                  "compiled for this process only")

    cache.load_overload, cache.save_overload = load_overload, save_overload
    return dispatcher


def _warn(message: str):
    """A :class:`CacheWarning` attributed to numba's dispatcher (the caller of the guarded method)."""
    warnings.warn(message, CacheWarning, stacklevel=3)


def _set_aside(cache, sig, target_context):
    """Drop what could not be read: the entry of ``sig`` where the index reads, else the index file.

    Other signatures keep their entries and data files; the next save writes
    the entry (or a new index) instead of reading the damaged file again.
    """
    files = getattr(cache, "_cache_file", None)
    try:
        overloads = files._load_index()
        if overloads.pop(cache._index_key(sig, target_context.codegen()), None) is not None:
            files._save_index(overloads)
        return
    except Exception:                  # the index itself cannot be read or written (or numba's layout changed)
        pass
    index = getattr(files, "_index_path", None)
    if index:
        try:
            os.remove(index)
        except OSError:
            pass


def function_address(dispatcher, signature: tuple, returns=None) -> int:
    """Address of ``dispatcher``'s machine code for the argument types ``signature`` (compiled or loaded if need be).

    For compiled callers that call it through the address (:func:`typed_call`):
    its code is then compiled once, not again into every caller, which numba
    does for a direct call (and each caller's machine code holds a copy).
    The address is valid for the life of the process.

    Parameters
    ----------
    dispatcher : numba dispatcher
    signature : tuple
        Argument types (:func:`kernel_signature`).
    returns : numba type, optional
        The return type the callers read: another one raises ``TypeError``
        (a caller would misread the result).

    Examples
    --------
    >>> @cached_njit(cache=False)
    ... def half(x):
    ...     return 0.5 * x
    >>> function_address(half, kernel_signature("f"), numba.types.float64) > 0
    True
    """
    if signature not in dispatcher.overloads:
        dispatcher.compile(signature)
    compiled = dispatcher.overloads[signature]
    if returns is not None and compiled.signature.return_type != returns:
        raise TypeError(f"{dispatcher.py_func.__name__} returns {compiled.signature.return_type}, not the {returns} "
                        "its callers read")
    return compiled.library.get_pointer_to_function(compiled.fndesc.llvm_func_name)


def typed_call(name: str, argtypes: tuple, address, args: tuple, restype=numba.types.none):
    """The typing of an intrinsic calling the function at ``address`` (:func:`function_address`) with ``args``
    passed as ``argtypes``, returning ``restype``: ``(signature, codegen)``.

    Arguments of other types are refused with a ``TypingError`` when the caller
    is compiled (a writeable array passes where a read-only one is expected);
    an exception the callee raises propagates to the caller.

    Examples
    --------
    >>> import numba.extending
    >>> @numba.extending.intrinsic
    ... def call_half(typingctx, address, x):
    ...     return typed_call("call_half", kernel_signature("f"), address, (x,), numba.types.float64)
    >>> @cached_njit(cache=False)
    ... def caller(address, x):
    ...     return call_half(address, x)
    >>> @cached_njit(cache=False)
    ... def half(x):
    ...     return 0.5 * x
    >>> caller(function_address(half, kernel_signature("f")), 3.0)
    1.5
    """
    if address != numba.types.int64 or len(args) != len(argtypes) or not all(map(_converts, args, argtypes)):
        raise numba.core.errors.TypingError(f"{name} takes an int64 address and {argtypes}, got {(address, *args)}")

    def codegen(context, builder, signature, llargs):
        return _call_through(context, builder, llargs, argtypes, restype)
    return restype(address, *args), codegen


def _call_through(context, builder, llargs, argtypes, restype):
    """Code calling the function at address ``llargs[0]`` (numba's calling convention) with ``llargs[1:]`` as
    ``argtypes``; its result of type ``restype``; an exception it raises propagates."""
    function = context.call_conv.get_function_type(restype, argtypes)
    pointer = builder.inttoptr(llargs[0], function.as_pointer())
    status, value = context.call_conv.call_function(builder, pointer, restype, argtypes, llargs[1:])
    with numba.core.cgutils.if_unlikely(builder, status.is_error):
        context.call_conv.return_status_propagate(builder, status)
    return context.get_dummy_value() if restype == numba.types.none else value


def _converts(given, expected) -> bool:
    """Whether an argument of numba type ``given`` passes unchanged as ``expected``: its own type, or a writeable
    array where a read-only one is expected (numba stores both alike), never a read-only one where the callee writes."""
    if isinstance(given, numba.types.Array) and isinstance(expected, numba.types.Array) and not expected.mutable:
        return given.copy(readonly=True) == expected
    return numba.types.unliteral(given) == expected
