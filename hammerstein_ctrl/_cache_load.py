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
   constants only: a numba module not imported yet lends just its name.
3. A cached library carries the LLVM bitcode of everything it defines, for
   linking into later compiles; numba parses it at every load and lists its
   symbols (7 ms a library, 70 ms for a first EMPS identification).  Here the
   bitcode is parsed when a compile first links the library, and the symbols
   are read from the object code's symbol table (ELF; other object formats
   take numba's own path).

Every piece checks that numba still has the parts it uses
(:func:`fast_load_possible`); otherwise numba's own load runs.  The cache
guard of :mod:`~hammerstein_ctrl._jit` calls :func:`load_cached` and wraps
numba's rebuild in :func:`rebuild_cached`.

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

import llvmlite.binding as ll
import numba.core.environment
from numba.core.runtime import rtsys

__all__ = ["LATE_SYMBOLS", "CACHE_PARTS", "fast_load_possible", "load_cached", "rebuild_cached",
           "needs_registries", "defined_symbols"]

#: Symbols numba adds to the compiled code's symbol table when a module of its registries is imported
#: (``numba.cpython.hashing``'s copy of the interpreter's hash secret), not when it starts its runtime.  Cached
#: code that refers to one is loaded after the registries (a symbol the loader cannot resolve would abort the
#: process).  Defence in depth: the load of such code imports that module itself as it rebuilds the code's
#: environment, and a test checks that the registries add no symbol outside this list.
LATE_SYMBOLS = (b"_numba_hashsecret_",)

#: The parts of numba's cache (``numba.core.caching.Cache``) that :func:`load_cached` uses.
CACHE_PARTS = ("_load_overload", "_impl", "_guard_against_spurious_io_errors")

#: The parts of numba's code library that :func:`_unserialize` uses.
_LIBRARY_PARTS = ("enable_object_caching", "_set_compiled_object", "_finalize_final_module",
                  "_get_module_for_linking", "_shared_module")


def fast_load_possible(cache) -> bool:
    """Whether ``cache`` has every part :func:`load_cached` uses (numba's layout of 0.58 to 0.68)."""
    return all(hasattr(cache, part) for part in CACHE_PARTS) and hasattr(cache._impl, "rebuild")


def load_cached(cache, sig, target_context):
    """numba's ``Cache.load_overload`` without loading the compiler's registries first, unless the code needs them.

    Only the runtime (memory management, which compiled code that allocates
    needs) is started before numba's own load; its rebuild of the cached code
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
    imported already.  numba loads cached code under its compiler lock, so
    swapping its rebuild function here is seen by this load alone.
    """
    rebuild = numba.core.environment._rebuild_env
    numba.core.environment._rebuild_env = functools.partial(_rebuild_env, rebuild)
    try:
        yield
    finally:
        numba.core.environment._rebuild_env = rebuild


def _rebuild_env(rebuild, modname, consts, env_name):
    """numba's ``_rebuild_env``, with a stand-in for the globals of a numba module not imported yet."""
    Environment = numba.core.environment.Environment
    if modname in sys.modules or not str(modname).startswith("numba.") or env_name in Environment._memo:
        return rebuild(modname, consts, env_name)
    env = Environment({"__name__": modname})
    env.consts[:] = consts
    env.env_name = env_name
    Environment._memo[env_name] = env
    return env


def rebuild_cached(rebuild, target_context, data):
    """numba's ``rebuild`` of cached code read from disk: after the compiler's registries where it needs them,
    its library's bitcode left unparsed until a compile links it (:func:`_unserialize`)."""
    if needs_registries(data):
        target_context.refresh()
    codegen = target_context.codegen()
    own = codegen.__dict__.get("unserialize_library")
    codegen.unserialize_library = functools.partial(_unserialize, codegen, codegen.unserialize_library)
    try:
        return rebuild(target_context, data)
    finally:
        if own is None:
            del codegen.unserialize_library
        else:
            codegen.unserialize_library = own


def needs_registries(data) -> bool:
    """Whether a cached compile result (numba's reduced form) must be loaded after the compiler's registries."""
    try:
        _, kind, (object_code, _) = data[0]
    except (TypeError, ValueError, IndexError, KeyError):
        return True
    return kind != "object" or not isinstance(object_code, bytes) or any(s in object_code for s in LATE_SYMBOLS)


def _unserialize(codegen, unserialize, state):
    """numba's load of a cached code library (``CPUCodeLibrary._unserialize``), its bitcode parsed on first link.

    The library's defined symbols (numba's record of what the process's
    code defines) come from the object code's symbol table; the bitcode,
    which serves only a later compile that links this library, is parsed
    then (:func:`_module_for_linking`).  Any other cached form, an object
    format :func:`defined_symbols` does not read, or a numba whose library
    or engine lacks a part used here, takes numba's own load.
    """
    try:
        name, kind, (object_code, bitcode) = state
    except (TypeError, ValueError):
        return unserialize(state)
    symbols = defined_symbols(object_code) if kind == "object" and isinstance(object_code, bytes) else None
    defined = getattr(getattr(codegen, "_engine", None), "_defined_symbols", None)
    library = codegen.create_library(name) if symbols is not None and isinstance(defined, set) else None
    if library is None or not all(hasattr(library, part) for part in _LIBRARY_PARTS):
        return unserialize(state)
    library.enable_object_caching()
    library._set_compiled_object(object_code)
    library._get_module_for_linking = functools.partial(_module_for_linking, library, bitcode)
    library._finalize_final_module()
    defined |= symbols
    return library


def _module_for_linking(library, bitcode: bytes):
    """The module a compile links ``library`` from: its cached bitcode, parsed once (numba's ``_shared_module``)."""
    if library._shared_module is None:
        library._shared_module = ll.parse_bitcode(bitcode)
    return library._shared_module


_ELF_SYMBOL_TABLE = 2                  # SHT_SYMTAB
_ELF_OBJECT, _ELF_FUNCTION = 1, 2      # STT_OBJECT, STT_FUNC


def defined_symbols(object_code: bytes) -> set[str] | None:
    """Names of the functions and data an object file defines (its symbol table), or ``None`` if not 64-bit
    little-endian ELF.

    These are the names numba lists from the library's bitcode (its defined
    functions and global variables), read without parsing the bitcode.

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
        return names
    except (struct.error, ValueError, IndexError, UnicodeDecodeError):
        return None
