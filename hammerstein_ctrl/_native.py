"""The package's C library: compiled once per machine with the system's C compiler, called from Python and numba.

Code that every fit runs once per candidate or step (the matrix exponential
of the discretisation, a linear solve, eigenvalues of a small symmetric
matrix, the linear algebra of a Levenberg-Marquardt step and its loop, a
single evaluation from the coefficients) is written in C (:data:`SOURCES`).
numba compiled it for about 15 s of CPU on a machine's first fit; a C
compiler builds it in about a second.  The generated simulation kernels are
built the same way, one shared object each (:func:`kernel_address`, in a
``ckernels-`` folder of the machine cache keyed on the flags and the
processor, each file named after a digest of its C).  The library is kept under
:func:`~hammerstein_ctrl._jit.machine_cache_root` in a folder named after a
digest of the sources, the flags and the processor (it is built for this
processor, ``-march=native``), so every process of the machine loads it, an
edited source is never served stale code, and a cache shared by machines
never serves one another's instructions.  It is built with
``-ffp-contract=off`` and no fast-math: no fused multiply-add, so its results
are those of the source's arithmetic, the same bits at every optimisation
level (:data:`LEVELS`).

The library is also a Python extension module (:func:`library`), whose
functions take numpy arrays where the C functions take pointers: each checks
that an array is C-ordered, of the C type and, where the C function writes
it, writeable (else a ``TypeError`` naming the function and the argument),
and runs the C function without the GIL; its ``call`` runs a kernel (or a
function of :data:`ENTRIES`) on arrays checked against a description of
their shapes.  The wrappers are generated from
the C prototypes (:data:`SIGNATURES`, read off the sources), as are the
argument checks of compiled callers: compiled (numba) code calls a function
of the library by its symbol, which this module registers with LLVM when it
loads the library, so numba's cached machine code calls it directly
(:func:`c_call`).

The compiler is ``$CC``, else the one Python was built with, else ``cc``.

Examples
--------
>>> import numpy as np
>>> library().hc_one_norm(np.array([[1.0, -2.0], [3.0, 4.0]]), 2)
6.0
>>> SIGNATURES["hc_one_norm"]
('di', 'f')
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import fcntl
import functools
import hashlib
import importlib.util
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

import llvmlite.binding
import numba.core.cgutils
import numba.core.errors
from llvmlite import ir
from numba import types

from ._jit import machine_cache_dir, machine_cache_root
from .exceptions import NativeBuildError
from .safe_io import open_lock

__all__ = ["library", "c_call", "kernel_address", "entry_address", "ENTRIES", "KERNEL_LEVEL", "KERNEL_HEADER",
           "SOURCES", "BUILD_FLAGS", "LEVELS", "SIGNATURES", "DEPENDS", "prototypes", "wrapper_source"]

#: The C sources of the library: the small dense linear algebra, forward-difference steps and normal equations,
#: loops over a record's samples, the Levenberg-Marquardt step, and MINPACK's loops over a residual vector.
SOURCES = tuple(Path(__file__).resolve().parent / name for name in ("_native_linalg.c", "_native_normal.c",
                                                                       "_native_signal.c", "optimize/_native_lm.c",
                                                                       "_native_coefficients.c",
                                                                       "optimize/_native_lm_loop.c",
                                                                       "optimize/_native_minpack.c"))
#: Functions of the library called through its ``call`` as a kernel is (``int64_t f(const hc_arg *args)``).
ENTRIES = ("hc_coefficient_pass",)
#: The header of the arguments of a generated kernel built in C (included by the library and by every kernel).
KERNEL_HEADER = Path(__file__).resolve().parent / "_native_kernel.h"
#: The C of the extension module's ``call``, the Python door of the kernels built in C (:func:`kernel_address`).
_CALL_SOURCE = Path(__file__).resolve().parent / "_native_call.c"
#: The files that define the library's interface (package-relative): the cache key of every compiled function
#: that calls the library (``cached_njit(depends=...)``), so an edited prototype compiles its callers again.
DEPENDS = ("_native.py", "_native_call.c", "_native_kernel.h") + tuple(
    str(source.relative_to(Path(__file__).resolve().parent)) for source in SOURCES)
#: Flags of every compile of the build (a change builds a new library).
BUILD_FLAGS = ("-march=native", "-std=c99", "-fPIC", "-fno-fast-math", "-ffp-contract=off", "-fno-strict-aliasing")
#: Optimisation level of each source: the loops over a record's samples and over a residual vector are vectorised
#: at -O3; the rest runs as fast at -O2 and compiles in about half the time; the generated wrappers (glue around
#: one call) at -O1.  No level changes a result: there is no fast-math and no contraction.
LEVELS = {"_native_signal.c": "-O3", "optimize/_native_minpack.c": "-O3", "wrappers": "-O1"}
#: Optimisation of a generated kernel (:func:`kernel_address`): its loops over candidates' columns are vectorised
#: at -O3, and its loop over samples unrolled (a single candidate's recursion ran 10 % slower without).
KERNEL_LEVEL = ("-O3", "-funroll-loops")
#: Flags this platform's linker needs for an extension module (macOS resolves Python's symbols at load time).
_PLATFORM_FLAGS = ("-undefined", "dynamic_lookup") if sys.platform == "darwin" else ()
#: The module's name (its file is ``_hc_native`` with Python's extension suffix).
_MODULE = "_hc_native"

#: C parameter types and their kinds: an array of float64, int64, bool or float32 passed as its data pointer (lower
#: case: read; upper case: written), or a double or int64 passed by value.
_KINDS = {"const double *": "d", "double *": "D", "const int64_t *": "l", "int64_t *": "L", "const bool *": "b",
          "bool *": "B", "float *": "S", "double": "f", "int64_t": "i"}
#: C result types and their kinds.
_RESULTS = {"void": "", "double": "f", "bool": "b", "int": "i"}
#: Per array kind: (C element type, item size, buffer formats accepted, writeable).
_ARRAYS = {"d": ("double", 8, "d", False), "D": ("double", 8, "d", True), "l": ("int64_t", 8, "lq", False),
           "L": ("int64_t", 8, "lq", True), "b": ("bool", 1, "?", False), "B": ("bool", 1, "?", True),
           "S": ("float", 4, "f", True)}
_DEFINITION = re.compile(r"^(void|double|bool|int)\s+(hc_\w+)\(([^)]*)\)\s*\{", re.M)


def prototypes(text: str) -> dict:
    """``{name: (argument kinds, result kind)}`` of the exported (``hc_``, not static) functions defined in the C
    ``text``.

    Examples
    --------
    >>> prototypes("double hc_f(const double *x, int64_t n, bool *ok)\\n{")
    {'hc_f': ('diB', 'f')}
    """
    found = {}
    for result, name, params in _DEFINITION.findall(text):
        ctypes_ = [" ".join(param.replace("*", " * ").split()).rsplit(" ", 1)[0] for param in params.split(",")]
        unknown = [c for c in ctypes_ if c not in _KINDS]
        if unknown:
            raise NativeBuildError(f"{name} takes C types the package's bindings do not know: {unknown}")
        found[name] = ("".join(_KINDS[c] for c in ctypes_), _RESULTS[result])
    return found


#: The sources' text, read once: the signatures, the build's key and its wrappers come from it.
_SOURCE_TEXT = "".join(source.read_text() for source in SOURCES)
_CALL_TEXT = _CALL_SOURCE.read_text()
_HEADER_TEXT = KERNEL_HEADER.read_text()
#: The library's functions: name, then the kinds of its arguments and of its result (``""`` none, ``f`` a double,
#: ``b`` a bool, ``i`` an int), read off the C sources: one table for the Python and the compiled door.
SIGNATURES = prototypes(_SOURCE_TEXT)


def _compiler() -> list[str]:
    """The C compiler's command: ``$CC`` (as given), else Python's build compiler if it is here, else ``cc``."""
    given = shlex.split(os.environ.get("CC", ""))
    if given:
        return given
    words = shlex.split(sysconfig.get_config_var("CC") or "")
    return words if words and shutil.which(words[0]) else ["cc"]


@functools.lru_cache(maxsize=1)
def _host() -> tuple:
    """The processor (its name and features) and Python's extension suffix (the module's ABI)."""
    cpu = llvmlite.binding
    return (platform.machine(), cpu.get_host_cpu_name(), cpu.get_host_cpu_features().flatten(),
            sysconfig.get_config_var("EXT_SUFFIX"))


def _code_flags() -> tuple:
    """The options among ``$CC``'s words that change machine code (``-f...``, ``-O...``, ``-m...``).

    The build's own flags come after them (``-fno-fast-math`` and
    ``-ffp-contract=off`` undo a ``-ffast-math`` there); the rest still keys
    the build, so that code built with other options is never served to a
    process that asked for none.
    """
    return tuple(word for word in _compiler()[1:] if word.startswith(("-f", "-O", "-m")))


def _host_digest() -> str:
    """Key of what a build's machine code depends on besides its source: the flags (the build's, the linker's and
    those ``$CC`` adds), the processor and Python's version (the module's ABI).  Not the compiler itself: a
    library stays usable after the compiler that built it is gone (or another one is named in ``$CC``)."""
    text = repr((BUILD_FLAGS, sorted(LEVELS.items()), KERNEL_LEVEL, _PLATFORM_FLAGS, _code_flags(),
                 _host())).encode()
    return hashlib.sha256(text).hexdigest()[:16]


def _digest() -> str:
    """Key of a build of the library: the sources, this module (it writes the wrappers) and :func:`_host_digest`."""
    text = _SOURCE_TEXT.encode() + _CALL_TEXT.encode() + _HEADER_TEXT.encode() + Path(__file__).read_bytes()
    return hashlib.sha256(text + _host_digest().encode()).hexdigest()[:16]


def _cache_folder(key: str) -> Path | None:
    """The folder of the builds of ``key`` in the machine cache: there already (writable or not), else made if the
    cache can take it; ``None`` where the name is a link (never followed out of the cache) or there is no folder."""
    folder = machine_cache_root() / key
    if not folder.is_dir() and machine_cache_dir() is not None:
        with contextlib.suppress(OSError):
            folder.mkdir(exist_ok=True)
    return None if folder.is_symlink() or not folder.is_dir() else folder


def _temporary_folder() -> Path:
    """A folder of this process for a build the machine cache cannot keep, removed when the process ends."""
    try:
        folder = Path(tempfile.mkdtemp(prefix="hammerstein_ctrl-native-"))
    except OSError as exc:
        raise NativeBuildError(f"no folder to build hammerstein_ctrl's C library in: {exc}") from None
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return folder


_WRAPPER_HEAD = """#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

/* A C-ordered buffer of the given item size and format (one of formats), writeable if asked; else a TypeError. */
static int take(PyObject *o, Py_buffer *view, Py_ssize_t itemsize, const char *formats, int writeable,
                const char *function, int index)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writeable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(o, view, flags) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "%s: argument %d must be a C-ordered%s array", function, index,
                     writeable ? ", writeable" : "");
        return -1;
    }
    const char *format = view->format ? view->format : "B";
    while (*format == '@' || *format == '=' || *format == '<')
        format++;
    if (view->itemsize != itemsize || strlen(format) != 1 || strchr(formats, *format) == NULL) {
        char given[8] = {0};
        strncpy(given, format, sizeof given - 1);   /* the exporter may free its format on release */
        PyBuffer_Release(view);
        PyErr_Format(PyExc_TypeError, "%s: argument %d has items of format '%s', not '%s'", function, index,
                     given, formats);
        return -1;
    }
    return 0;
}

/* A size, count or flag: a non-negative integer; else a ValueError (or TypeError) naming it. */
static int size(PyObject *o, long long *value, const char *function, int index)
{
    *value = PyLong_AsLongLong(o);
    if (*value == -1 && PyErr_Occurred())
        return -1;
    if (*value < 0) {
        PyErr_Format(PyExc_ValueError, "%s: argument %d must be a size (>= 0), not %lld", function, index, *value);
        return -1;
    }
    return 0;
}
"""


def _wrapper(name: str, kinds: str, result: str) -> str:
    """The C of the Python wrapper of ``name``: its arguments checked and converted, the call without the GIL."""
    arrays = sum(kind in _ARRAYS for kind in kinds)
    lines = [f"static PyObject *w_{name}(PyObject *self, PyObject *const *args, Py_ssize_t nargs)", "{",
             f"    Py_buffer views[{max(arrays, 1)}];", "    int taken = 0;",
             f"    if (nargs != {len(kinds)})",
             f"        return PyErr_Format(PyExc_TypeError, \"{name} takes {len(kinds)} arguments, not %zd\", nargs);"]
    values, view = [], 0
    for i, kind in enumerate(kinds):
        if kind in _ARRAYS:
            ctype, size, formats, writeable = _ARRAYS[kind]
            take = f"take(args[{i}], &views[{view}], {size}, \"{formats}\", {int(writeable)}, \"{name}\", {i})"
            lines += [f"    if ({take} < 0)", "        goto fail;", "    taken++;"]
            values.append(f"({'' if writeable else 'const '}{ctype} *)views[{view}].buf")
            view += 1
        elif kind == "f":
            lines += [f"    double a{i} = PyFloat_AsDouble(args[{i}]);",
                      f"    if (a{i} == -1.0 && PyErr_Occurred())", "        goto fail;"]
            values.append(f"a{i}")
        else:
            lines += [f"    long long a{i};", f"    if (size(args[{i}], &a{i}, \"{name}\", {i}) < 0)",
                      "        goto fail;"]
            values.append(f"(int64_t)a{i}")
    call = f"{name}({', '.join(values)})"
    store = {"": "", "f": "double r = 0.0;", "b": "bool r = false;", "i": "int r = 0;"}[result]
    lines += [f"    {store}" if store else "", "    Py_BEGIN_ALLOW_THREADS",
              f"    {'r = ' if result else ''}{call};", "    Py_END_ALLOW_THREADS",
              "    for (int k = 0; k < taken; k++)", "        PyBuffer_Release(&views[k]);",
              "    " + {"": "Py_RETURN_NONE;", "f": "return PyFloat_FromDouble(r);", "b": "return PyBool_FromLong(r);",
                        "i": "return PyLong_FromLong(r);"}[result],
              "fail:", "    for (int k = 0; k < taken; k++)", "        PyBuffer_Release(&views[k]);",
              "    return NULL;", "}", ""]
    return "\n".join(line for line in lines if line != "")


def wrapper_source(text: str, module: str = _MODULE) -> str:
    """The C of an extension module ``module`` wrapping every exported function of the C ``text`` (their
    prototypes are copied from it)."""
    heads = re.findall(r"^((?:void|double|bool|int)\s+hc_\w+\([^)]*\))\s*\{", text, re.M)
    parts = [_WRAPPER_HEAD, _CALL_TEXT] + [" ".join(head.split()) + ";" for head in heads] + [""]
    table = ["    {\"call\", (PyCFunction)(void (*)(void))call_kernel, METH_FASTCALL, NULL},"]
    for name, (kinds, result) in prototypes(text).items():
        parts.append(_wrapper(name, kinds, result))
        table.append(f"    {{\"{name}\", (PyCFunction)(void (*)(void))w_{name}, METH_FASTCALL, NULL}},")
    parts += ["static PyMethodDef methods[] = {", *table, "    {NULL, NULL, 0, NULL}", "};",
              f"static struct PyModuleDef definition = {{PyModuleDef_HEAD_INIT, \"{module}\", NULL, -1, methods}};",
              f"PyMODINIT_FUNC PyInit_{module}(void) {{ return PyModule_Create(&definition); }}", ""]
    return "\n".join(parts)


class _WriteError(NativeBuildError):
    """The library was compiled, or could be, but not written where asked (a full disk, a read-only folder)."""


def _build(compiler: list[str], target: Path, kernel: str | None = None) -> None:
    """Compile :data:`SOURCES` and their wrappers (or the C of one ``kernel``, :func:`kernel_address`) into
    ``target``, then its digest beside it (so a file cut short is never loaded); :class:`NativeBuildError` on
    failure (:class:`_WriteError` if only the writing failed).  No temporary file is left behind, whatever stops
    the build."""
    folder, made = target.parent, []
    try:
        try:
            for suffix in (".so.tmp", "-wrappers.c" if kernel is None else "-kernel.c"):
                fd, path = tempfile.mkstemp(dir=folder, suffix=suffix)
                os.close(fd)
                made.append(path)
            Path(made[1]).write_text(wrapper_source(_SOURCE_TEXT) if kernel is None else kernel)
        except OSError as exc:
            raise _WriteError(f"hammerstein_ctrl's C library cannot be written to {folder}: {exc}") from None
        if kernel is None:
            _compile(compiler, made[0], made[1])
        else:
            _run(compiler, [*compiler, *BUILD_FLAGS, *KERNEL_LEVEL, "-shared", *_PLATFORM_FLAGS, "-o", made[0],
                            made[1], "-lm"], cwd=str(folder))
        try:
            os.chmod(made[0], 0o755 & ~_UMASK)
            os.replace(made[0], target)
            _write_digest(target)
        except OSError as exc:
            raise _WriteError(f"hammerstein_ctrl's C library cannot be written to {folder}: {exc}") from None
    finally:
        _remove(*made)


def _compile(compiler: list[str], output: str, wrappers: str) -> None:
    """Compile :data:`SOURCES` and ``wrappers``, each at its level (:data:`LEVELS`, else -O2), and link them into
    ``output``; :class:`NativeBuildError` if the compiler does not run or fails."""
    root = Path(__file__).resolve().parent
    groups: dict = {}
    for source in SOURCES:
        groups.setdefault(LEVELS.get(str(source.relative_to(root)), "-O2"), []).append(str(source))
    groups.setdefault(LEVELS["wrappers"], []).append(wrappers)
    include = f"-I{sysconfig.get_paths()['include']}"
    package = f"-I{root}"
    try:
        scratch = tempfile.TemporaryDirectory(prefix="hammerstein_ctrl-objects-")
    except OSError as exc:
        raise _WriteError(f"no folder for hammerstein_ctrl's C library's objects: {exc}") from None
    with scratch as objects:
        for level, files in groups.items():
            _run(compiler, [*compiler, *BUILD_FLAGS, level, include, package, "-c", *files], cwd=objects)
        _run(compiler, [*compiler, "-shared", *_PLATFORM_FLAGS, "-o", output,
                        *sorted(str(p) for p in Path(objects).glob("*.o")), "-lm"], cwd=objects)


def _run(compiler: list[str], command: list[str], cwd: str) -> None:
    try:
        done = subprocess.run(command, capture_output=True, text=True, check=False, cwd=cwd)
    except OSError as exc:
        raise NativeBuildError(f"hammerstein_ctrl builds its C library once per machine, and no C compiler ran "
                               f"({compiler[0]}: {exc.strerror}): install one (gcc) or name it in $CC") from None
    if done.returncode != 0:
        lines = done.stderr.strip().splitlines() or ["no message"]
        first = next((line for line in lines if "error" in line.lower()), lines[0])
        if "No space left" in done.stderr or "File too large" in done.stderr:
            raise _WriteError(f"building hammerstein_ctrl's C library with {compiler[0]} failed: {first}")
        raise NativeBuildError(f"building hammerstein_ctrl's C library with {compiler[0]} failed: {first}")


def _remove(*paths) -> None:
    for path in paths:
        with contextlib.suppress(OSError):
            os.unlink(path)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: The process's umask, read once at import (reading it sets it, for an instant).
_UMASK = _umask()


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _write_digest(target: Path) -> None:
    """Write ``target``'s digest beside it, whole or not at all, readable as the library is."""
    fd, tmp = tempfile.mkstemp(dir=target.parent, suffix=".sha256.tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(_file_digest(target))
        os.chmod(tmp, 0o644 & ~_UMASK)
        os.replace(tmp, target.with_name(target.name + ".sha256"))
    finally:
        _remove(tmp)


def _load(path: Path, kernel: bool = False):
    """The module at ``path`` with the addresses of its functions (a ``kernel``'s: its handle and the address of
    its function ``kernel``); ``None`` if the file is missing, a link, not the file its digest was written for
    (cut short, damaged) or does not load."""
    record = path.with_name(path.name + ".sha256")
    try:
        if path.is_symlink() or record.is_symlink() or not path.is_file():
            return None
        if record.read_text().strip() != _file_digest(path):
            return None
        if kernel:
            handle = ctypes.CDLL(str(path))
            return handle, ctypes.cast(handle.kernel, ctypes.c_void_p).value
        spec = importlib.util.spec_from_file_location(f"hammerstein_ctrl.{_MODULE}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        handle = ctypes.CDLL(str(path))
        addresses = {name: ctypes.cast(getattr(handle, name), ctypes.c_void_p).value
                     for name in (*SIGNATURES, *ENTRIES)}
    except (ImportError, OSError, AttributeError, ValueError):
        return None
    if any(not hasattr(module, name) for name in (*SIGNATURES, "call")):
        return None
    return module, addresses


@functools.lru_cache(maxsize=1)
def library():
    """The C library as a Python module, built on this machine's first use (about 1.2 s of the compiler's CPU); its
    symbols registered for compiled callers.

    Processes that find it missing at once build it one at a time (a lock
    file beside it): the first builds, the others load its build.  A library
    that cannot be written into the machine cache (a full disk, a read-only
    folder) is built in a temporary folder of this process instead.

    Raises
    ------
    NativeBuildError
        If it is not built yet and no C compiler can build it.
    """
    loaded = _loaded(_MODULE + sysconfig.get_config_var("EXT_SUFFIX"), "native-" + _digest())
    module, addresses = loaded
    for symbol, address in addresses.items():
        llvmlite.binding.add_symbol(symbol, address)
    _ENTRY_ADDRESSES.update((name, addresses[name]) for name in ENTRIES)
    return module


#: Addresses of :data:`ENTRIES` in the loaded library.
_ENTRY_ADDRESSES: dict = {}


def entry_address(name: str) -> int:
    """Address of the library's function ``name`` (one of :data:`ENTRIES`), for its ``call``."""
    library()
    return _ENTRY_ADDRESSES[name]


def _locked_build(compiler: list[str], target: Path, kernel: str | None = None):
    """The library (or ``kernel``'s object, :func:`kernel_address`) at ``target``, built under the folder's lock
    unless another process built it meanwhile; ``None`` if the folder cannot take it (a full disk, no locks: then
    built elsewhere); :class:`NativeBuildError` if no compiler can build it."""
    name = ".lock" if kernel is None else target.name + ".lock"        # a kernel's own: builds of others go on
    try:
        lock = open_lock(target.with_name(name), readonly=True)         # an UnsafePathError is an OSError too
    except OSError:
        return None
    with lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX)
        except OSError:
            return None
        loaded = _load(target, kernel is not None)
        if loaded is not None:
            return loaded
        try:
            _build(compiler, target, kernel)
        except _WriteError:
            return None
        return _load(target, kernel is not None)


def _built(compiler: list[str], target: Path, kernel: str | None = None):
    """The library (or ``kernel``'s object) built and loaded at ``target``; :class:`NativeBuildError` if it cannot
    be."""
    _build(compiler, target, kernel)
    loaded = _load(target, kernel is not None)
    if loaded is None:
        raise NativeBuildError(f"hammerstein_ctrl's C library at {target} was built but does not load")
    return loaded


def _loaded(file: str, digest: str, kernel: str | None = None):
    """The library (or ``kernel``'s object) of build key ``digest`` from the machine cache, built there first if
    need be (else in a temporary folder)."""
    compiler = _compiler()
    folder = _cache_folder(digest)
    loaded = None if folder is None else _load(folder / file, kernel is not None)
    if loaded is None and folder is not None:
        loaded = _locked_build(compiler, folder / file, kernel)
    if loaded is None:
        loaded = _built(compiler, _temporary_folder() / file, kernel)
    return loaded


#: The kernels' objects loaded in this process (kept, so that their code stays mapped).
_KERNELS: list = []
#: The kernels whose build failed in this process, with the error.
_FAILED: dict = {}


@functools.lru_cache(maxsize=None)
def kernel_address(name: str, text: str) -> int:
    """Address of the function ``int64_t kernel(const hc_arg *args)`` of the C ``text``
    (:func:`~hammerstein_ctrl._kernel_c.translate`), built once per machine (about 0.1-0.2 s of the compiler's
    CPU) into the machine cache, in a file named after ``name`` and a digest of ``text``; valid for the life of
    the process.  Python calls it through the library's ``call``; the library's own C calls it by address (the
    Levenberg-Marquardt loop, the single evaluation from coefficients).

    Raises
    ------
    NativeBuildError
        If it is not built yet and no C compiler can build it.
    """
    file = f"{name}-{hashlib.sha256(text.encode()).hexdigest()[:16]}.so"
    if file in _FAILED:                 # not tried again in this process: the same error at once
        raise NativeBuildError(_FAILED[file])
    try:
        handle, address = _loaded(file, "ckernels-" + _host_digest(), text)
    except NativeBuildError as exc:
        _FAILED[file] = str(exc)
        raise
    _KERNELS.append(handle)
    return address


_C_TYPES = {"d": types.float64, "l": types.int64, "b": types.boolean, "s": types.float32}


def _argument(given, kind: str) -> bool:
    """Whether the numba type ``given`` passes as an argument of ``kind`` (:data:`SIGNATURES`): a C-ordered array
    of the element type (writeable if the C function writes it), a float, or an integer."""
    if kind.lower() in _C_TYPES:
        return (isinstance(given, types.Array) and given.dtype == _C_TYPES[kind.lower()] and given.layout == "C"
                and (kind.islower() or given.mutable))
    return isinstance(given, types.Float if kind == "f" else types.Integer)


def c_call(name: str, args: tuple):
    """The typing of an intrinsic calling the library's function ``name`` (a key of :data:`SIGNATURES`) with
    ``args`` (numba types): ``(signature, codegen)``; arguments of other kinds raise a ``TypingError``.

    The arrays are passed as their data pointers, alive for the call; the
    library must be loaded (:func:`library`) before code calling it runs.

    Examples
    --------
    >>> import numba, numba.extending, numpy as np
    >>> @numba.extending.intrinsic
    ... def one_norm(typingctx, M, n):
    ...     return c_call("hc_one_norm", (M, n))
    >>> @numba.njit
    ... def norm(M):
    ...     return one_norm(M, M.shape[0])
    >>> _ = library(); norm(np.eye(3))
    1.0
    """
    codes, result = SIGNATURES[name]
    if len(args) != len(codes) or not all(map(_argument, args, codes)):
        raise numba.core.errors.TypingError(f"{name} takes arguments of kinds {codes!r}, got {args}")
    restype = {"": types.none, "f": types.float64, "b": types.boolean, "i": types.int32}[result]

    def codegen(context, builder, signature, llargs):
        values = [_c_value(context, builder, ty, value, code)
                  for ty, value, code in zip(signature.args, llargs, codes)]
        returned = {"": ir.VoidType(), "f": ir.DoubleType(), "b": ir.IntType(8), "i": ir.IntType(32)}[result]
        function = numba.core.cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(returned, [v.type for v in values]), name)
        value = builder.call(function, values)
        if result == "":
            return context.get_dummy_value()
        return builder.icmp_unsigned("!=", value, ir.Constant(value.type, 0)) if result == "b" else value
    return restype(*args), codegen


def _c_value(context, builder, ty, value, code):
    """The C argument of ``value`` (numba type ``ty``): an array's data pointer, a double, or an int64."""
    if code.lower() in _C_TYPES:
        return builder.bitcast(context.make_array(ty)(context, builder, value).data, ir.IntType(8).as_pointer())
    if code == "f":
        return context.cast(builder, value, ty, types.float64)
    return context.cast(builder, value, ty, types.int64)


library()   # built (on a machine's first use) and its symbols registered before any compiled caller loads
