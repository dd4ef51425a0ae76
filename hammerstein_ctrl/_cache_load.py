"""Loading numba's cached machine code in a fresh process without what only its compiler needs.

A first call of a cached function in a fresh process paid, before this module,
for three things that running machine code does not need:

1. numba refreshes its target context before every load: the first refresh
   imports its compiler's registries (about 200 modules, 0.5 s).
   :func:`load_cached` starts only the runtime (memory management) and loads
   the registries first only for code that needs a symbol they add.
2. Cached code keeps the environments of the functions it links, each named
   after its module; numba imports that module to rebuild one, and its own
   array functions name ``numba.np.arrayobj`` and the like (about 25 modules
   of the registries, 0.12 s).  Compiled code reads an environment's
   constants only: a numba module not imported yet lends just its name
   (:func:`_rebuild_env`).
3. A cached library carries the LLVM bitcode of everything it defines, for
   linking into later compiles; numba parses it at every load and lists its
   symbols (7 ms a library, 70 ms for a first EMPS identification).  Here the
   bitcode is parsed when a compile first links the library, and the symbols
   are read from the object code's symbol table (ELF; other object formats
   take numba's own path).

Where numba lacks a part a piece uses (another numba version), that piece
takes numba's own way: :func:`fast_load_possible` for the cache,
:func:`_environments_without_imports` for the environments, :func:`_unserialize`
for the library.  The cache guard of :mod:`~hammerstein_ctrl._jit` calls
:func:`load_cached` and wraps numba's rebuild in :func:`rebuild_cached`.

Examples
--------
>>> needs_registries([("name", "object", (b"code _numba_hashsecret_ more", b"bitcode"))])
True
>>> needs_registries([("name", "object", (b"plain code", b"bitcode"))])
False
"""

from __future__ import annotations

import contextlib
import functools
import struct
import sys
import types
import weakref
from pathlib import Path

import llvmlite.binding as ll
import numba.core.environment
from numba.core.runtime import rtsys

__all__ = ["LATE_SYMBOLS", "fast_load_possible", "load_cached", "rebuild_cached", "needs_registries",
           "defined_symbols"]

#: Symbols numba adds to the compiled code's symbol table when a module of its registries is imported
#: (``numba.cpython.hashing``'s copy of the interpreter's hash secret), not when it starts its runtime.  Cached
#: code that refers to one is loaded after the registries (a symbol the loader cannot resolve would abort the
#: process).  Defence in depth: the load of such code imports that module itself as it rebuilds the code's
#: environment (:data:`_SYMBOL_MODULES`), and a test checks that the registries add no symbol outside this list.
LATE_SYMBOLS = (b"_numba_hashsecret_",)

#: numba modules whose import adds :data:`LATE_SYMBOLS`: an environment named after one is rebuilt by importing it.
_SYMBOL_MODULES = ("numba.cpython.hashing",)

#: The parts of numba's cache (``numba.core.caching.Cache``) that :func:`load_cached` uses.
_CACHE_PARTS = ("_load_overload", "_impl", "_guard_against_spurious_io_errors")

#: The first bytes of LLVM bitcode.
_BITCODE_MAGIC = b"BC\xc0\xde"
_ELF_SYMBOL_TABLE = 2                  # SHT_SYMTAB
_ELF_OBJECT, _ELF_FUNCTION = 1, 2      # STT_OBJECT, STT_FUNC

#: The parts of numba's code library that :func:`_unserialize` uses.
_LIBRARY_PARTS = ("enable_object_caching", "_set_compiled_object", "_finalize_final_module",
                  "_get_module_for_linking", "_shared_module")


def fast_load_possible(cache) -> bool:
    """Whether ``cache`` has every part :func:`load_cached` uses (numba's layout of 0.58 to 0.68)."""
    return all(hasattr(cache, part) for part in _CACHE_PARTS) and hasattr(cache._impl, "rebuild")


def load_cached(cache, sig, target_context):
    """numba's ``Cache.load_overload`` without loading the compiler's registries first, unless the code needs them.

    Only the runtime (memory management, which compiled code that allocates
    needs) is started before numba's own load, which rebuilds the code's
    environments without importing numba's modules
    (:func:`_environments_without_imports`); its rebuild of the cached code
    (:func:`rebuild_cached`) loads the registries first only for code that
    refers to one of :data:`LATE_SYMBOLS`, or whose cached form is not the one
    expected.  Compiling anything later loads them as numba always does.
    """
    rtsys.initialize(target_context)
    with cache._guard_against_spurious_io_errors(), _environments_without_imports():
        return cache._load_overload(sig, target_context)


@contextlib.contextmanager
def _environments_without_imports():
    """Rebuild the environments of cached code without importing numba modules they are named after.

    Compiled (nopython) code reads only an environment's constants; its
    globals serve object mode, which numba's own functions do not use.  Such
    an environment gets a globals dict holding the module's name alone (what
    numba writes when it caches the environment again), unless the module is
    imported already or adds symbols (:data:`_SYMBOL_MODULES`).  The stand-in
    stays numba's environment of that name for the process (a later compile
    of the same function gets it back, harmlessly).  The swap of numba's
    rebuild function is seen by the whole process while the load runs (under
    numba's compiler lock); the replacement carries numba's name, so anything
    pickled meanwhile refers to numba's own.  Without the parts it uses
    (another numba version) nothing is swapped.
    """
    module = numba.core.environment
    rebuild = getattr(module, "_rebuild_env", None)
    if not isinstance(rebuild, types.FunctionType) or not isinstance(getattr(module.Environment, "_memo", None),
                                                                     weakref.WeakValueDictionary):
        yield
        return
    module._rebuild_env = _quiet_rebuild(rebuild)
    try:
        yield
    finally:
        module._rebuild_env = rebuild


def _quiet_rebuild(rebuild):
    """:func:`_rebuild_env` around numba's ``rebuild``, named as numba's own (for pickle's lookup by name)."""
    @functools.wraps(rebuild)
    def quietly(*args):
        return _rebuild_env(rebuild, *args)
    return quietly


def _rebuild_env(rebuild, *args):
    """numba's ``_rebuild_env(modname, consts, env_name)``, with a stand-in for the globals of a numba module not
    imported yet."""
    Environment = numba.core.environment.Environment
    if len(args) != 3:                 # another numba's arguments: its own rebuild
        return rebuild(*args)
    modname, consts, env_name = args
    if (modname in sys.modules or not str(modname).startswith("numba.") or modname in _SYMBOL_MODULES
            or env_name in Environment._memo):
        return rebuild(*args)
    env = Environment({"__name__": modname})
    env.consts[:] = consts
    env.env_name = env_name
    Environment._memo[env_name] = env
    return env


def rebuild_cached(rebuild, folder, target_context, data):
    """numba's ``rebuild`` of cached code read from disk (from ``folder``): after the compiler's registries where
    it needs them, its library's bitcode left unparsed until a compile links it (:func:`_unserialize`)."""
    if needs_registries(data):
        target_context.refresh()
    codegen = target_context.codegen()
    own = codegen.__dict__.get("unserialize_library")
    codegen.unserialize_library = functools.partial(_unserialize, codegen, codegen.unserialize_library,
                                                    _entry_points(data), folder)
    try:
        return rebuild(target_context, data)
    finally:
        if own is None:
            del codegen.unserialize_library
        else:
            codegen.unserialize_library = own


def needs_registries(data) -> bool:
    """Whether a cached compile result (numba's reduced form) must be loaded after the compiler's registries."""
    form = _object_form(data[0] if isinstance(data, (tuple, list)) and data else None)
    return form is None or any(s in form[1] for s in LATE_SYMBOLS)


def _object_form(state) -> tuple[str, bytes, bytes] | None:
    """``(name, object code, bitcode)`` of a cached library in numba's object form, else ``None``."""
    try:
        name, kind, (object_code, bitcode) = state
    except (TypeError, ValueError):
        return None
    ok = kind == "object" and isinstance(object_code, bytes) and isinstance(bitcode, bytes)
    return (name, object_code, bitcode) if ok else None


def _entry_points(data) -> tuple[str, ...]:
    """The symbols numba looks up in the library of a cached compile result (its function and wrapper)."""
    fndesc = data[1] if isinstance(data, (tuple, list)) and len(data) > 1 else None
    try:
        return fndesc.llvm_func_name, fndesc.llvm_cpython_wrapper_name
    except AttributeError:
        return ()


def _unserialize(codegen, unserialize, entry_points, folder, state):
    """numba's load of a cached code library (``CPUCodeLibrary._unserialize``), its bitcode parsed on first link.

    The library's defined symbols (numba's record of what the process's
    code defines) come from the object code's symbol table; the bitcode,
    which serves only a later compile that links this library, is parsed
    then (:func:`_module_for_linking`).  numba's own load takes any other
    cached form, an object format :func:`defined_symbols` does not read, an
    object without the ``entry_points`` numba will look up, bitcode without
    its magic number, or a numba whose library or engine lacks a part used
    here.
    """
    form = _object_form(state)
    symbols = defined_symbols(form[1]) if form is not None and form[2][:4] == _BITCODE_MAGIC else None
    defined = getattr(getattr(codegen, "_engine", None), "_defined_symbols", None)
    if symbols is None or not entry_points or not symbols.issuperset(entry_points) or not isinstance(defined, set):
        return unserialize(state)
    name, object_code, bitcode = form
    library = codegen.create_library(name)
    if not all(hasattr(library, part) for part in _LIBRARY_PARTS):
        return unserialize(state)
    library.enable_object_caching()
    library._set_compiled_object(object_code)
    library._get_module_for_linking = functools.partial(_module_for_linking, library, bitcode, folder)
    library._finalize_final_module()
    defined |= symbols
    return library


def _module_for_linking(library, bitcode: bytes, folder):
    """The module a compile links ``library`` from: its cached bitcode, parsed once (numba's ``_shared_module``).

    Bitcode that does not parse (damaged past its first bytes, which the load
    checks) fails the compile that links it; the index files of its cache
    ``folder`` are removed first, so the next process compiles the folder's
    functions afresh.
    """
    if library._shared_module is None:
        try:
            library._shared_module = ll.parse_bitcode(bitcode)
        except RuntimeError as exc:
            for index in Path(folder).glob("*.nbi") if folder else ():
                with contextlib.suppress(OSError):
                    index.unlink()
            raise RuntimeError(f"the cached code of {library.name} in {folder} cannot be linked ({exc}); its index "
                               "was removed, so the next process compiles it afresh") from exc
    return library._shared_module


def defined_symbols(object_code: bytes) -> set[str] | None:
    """Names of the functions and data an object file defines (its symbol table), or ``None`` if it is not
    64-bit little-endian ELF or defines none.

    These are the names numba lists from the library's bitcode (its defined
    functions and global variables) that have a symbol: private definitions
    (a switch's lookup table) have none, and numba never looks them up.

    Examples
    --------
    >>> defined_symbols(b"MZ not an ELF file") is None
    True
    """
    if object_code[:6] != b"\x7fELF\x02\x01":
        return None
    try:
        offset, = struct.unpack_from("<Q", object_code, 0x28)
        entry_size, count = struct.unpack_from("<HH", object_code, 0x3A)
        sections = [struct.unpack_from("<IIQQQQIIQQ", object_code, offset + i * entry_size) for i in range(count)]
        names = set()
        for _, kind, _, _, start, size, link, _, _, step in sections:
            if kind != _ELF_SYMBOL_TABLE or step <= 0:
                continue
            strings = sections[link][4]
            for at in range(start, start + size, step):
                name, info, _, section = struct.unpack_from("<IBBH", object_code, at)
                if section and name and info & 0xF in (_ELF_OBJECT, _ELF_FUNCTION):
                    end = object_code.index(b"\0", strings + name)
                    names.add(object_code[strings + name:end].decode())
    except (struct.error, ValueError, IndexError):        # (a UnicodeDecodeError is a ValueError)
        return None
    return names or None               # no symbol table (or extended section numbering, count 0): numba's load
