"""Write the Python wrappers of the compiled core's library functions (run by meson when the core is built).

Reads the prototypes of ``hc.h`` (every ``hc_`` function whose argument and
result types are listed in ``KINDS`` and ``RESULTS``; the few that are not
for Python are in ``UNWRAPPED``) and writes, for each, a ``METH_FASTCALL``
wrapper that checks its arguments (an array: C-ordered, of the C type and,
where the function writes it, writeable; a size: a non-negative integer;
a float) and runs the function without the GIL, then the method table's
entries.  The output is C included by ``module.c``.

Usage: ``python generate_wrappers.py hc.h wrappers.inc``
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

#: C parameter types and their kinds: an array of float64, int64, bool or float32 passed as its data pointer (lower
#: case: read; upper case: written), or a double, a size (int64_t, never below zero) or an integer that may be
#: negative (hc_signed) passed by value.
KINDS = {"const double *": "d", "double *": "D", "const int64_t *": "l", "int64_t *": "L", "const bool *": "b",
         "bool *": "B", "float *": "S", "double": "f", "int64_t": "i", "hc_signed": "I"}
#: C result types and their kinds.
RESULTS = {"void": "", "double": "f", "bool": "b", "int": "i", "int64_t": "q"}
#: Per array kind: (C element type, item size, buffer formats accepted, writeable).
ARRAYS = {"d": ("double", 8, "d", False), "D": ("double", 8, "d", True), "l": ("int64_t", 8, "lq", False),
          "L": ("int64_t", 8, "lq", True), "b": ("bool", 1, "?", False), "B": ("bool", 1, "?", True),
          "S": ("float", 4, "f", True)}
#: Functions of the header that are not for Python (they take or give pointers of other kinds, or run at import).
UNWRAPPED = {"hc_kernel_at", "hc_vector_isa", "hc_core_init"}
_PROTOTYPE = re.compile(r"(void|double|bool|int|int64_t|hc_kernel|const char \*)\s*(hc_\w+)\(([^)]*)\)")


def prototypes(text: str) -> dict:
    """``{name: (argument kinds, result kind)}`` of the functions declared in the C ``text`` (but
    :data:`UNWRAPPED`).

    >>> prototypes("double hc_f(const double *x, int64_t n, bool *ok);")
    {'hc_f': ('diB', 'f')}
    """
    found = {}
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)                  # comments
    text = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))   # the preprocessor's
    for statement in " ".join(text.split()).split(";"):
        match = _PROTOTYPE.fullmatch(statement.strip())
        if match is None:
            continue
        result, name, params = match.groups()
        if name in UNWRAPPED:
            continue
        types = [" ".join(param.replace("*", " * ").split()).rsplit(" ", 1)[0] for param in params.split(",")]
        unknown = [t for t in types if t not in KINDS] + ([result] if result not in RESULTS else [])
        if unknown:
            raise SystemExit(f"generate_wrappers: {name} takes or gives C types the wrappers do not know: {unknown}")
        found[name] = ("".join(KINDS[t] for t in types), RESULTS[result])
    return found


def wrapper(name: str, kinds: str, result: str) -> str:
    """The C of the Python wrapper of ``name``: its arguments checked and converted, the call without the GIL."""
    arrays = sum(kind in ARRAYS for kind in kinds)
    lines = [f"static PyObject *w_{name}(PyObject *self, PyObject *const *args, Py_ssize_t nargs)", "{",
             f"    Py_buffer views[{max(arrays, 1)}];", "    int taken = 0;", "    (void)self;",
             f"    if (nargs != {len(kinds)})",
             f"        return PyErr_Format(PyExc_TypeError, \"{name} takes {len(kinds)} arguments, not %zd\", nargs);"]
    values, view = [], 0
    for i, kind in enumerate(kinds):
        if kind in ARRAYS:
            ctype, size, formats, writeable = ARRAYS[kind]
            take = f"take(args[{i}], &views[{view}], {size}, \"{formats}\", {int(writeable)}, \"{name}\", {i})"
            lines += [f"    if ({take} < 0)", "        goto fail;", "    taken++;"]
            values.append(f"({'' if writeable else 'const '}{ctype} *)views[{view}].buf")
            view += 1
        elif kind == "f":
            lines += [f"    double a{i} = PyFloat_AsDouble(args[{i}]);",
                      f"    if (a{i} == -1.0 && PyErr_Occurred())", "        goto fail;"]
            values.append(f"a{i}")
        elif kind == "I":
            lines += [f"    long long a{i} = PyLong_AsLongLong(args[{i}]);",
                      f"    if (a{i} == -1 && PyErr_Occurred())", "        goto fail;"]
            values.append(f"(int64_t)a{i}")
        else:
            lines += [f"    long long a{i};", f"    if (size(args[{i}], &a{i}, \"{name}\", {i}) < 0)",
                      "        goto fail;"]
            values.append(f"(int64_t)a{i}")
    call = f"{name}({', '.join(values)})"
    store = {"": "", "f": "double r = 0.0;", "b": "bool r = false;", "i": "int r = 0;", "q": "int64_t r = 0;"}[result]
    back = {"": "Py_RETURN_NONE;", "f": "return PyFloat_FromDouble(r);", "b": "return PyBool_FromLong(r);",
            "i": "return PyLong_FromLong(r);", "q": "return PyLong_FromLongLong((long long)r);"}[result]
    lines += [f"    {store}" if store else "", "    Py_BEGIN_ALLOW_THREADS",
              f"    {'r = ' if result else ''}{call};", "    Py_END_ALLOW_THREADS",
              "    for (int k = 0; k < taken; k++)", "        PyBuffer_Release(&views[k]);", f"    {back}",
              "fail:", "    for (int k = 0; k < taken; k++)", "        PyBuffer_Release(&views[k]);",
              "    return NULL;", "}", ""]
    return "\n".join(line for line in lines if line != "")


def source(header: str) -> str:
    """The wrappers of every function of ``header`` and the method table's entries (``HC_WRAPPED_METHODS``)."""
    found = prototypes(header)
    parts = ["/* Generated by generate_wrappers.py from hc.h when the core is built: do not edit. */", ""]
    parts += [wrapper(name, kinds, result) for name, (kinds, result) in found.items()]
    entries = [f"    {{\"{name}\", (PyCFunction)(void (*)(void))w_{name}, METH_FASTCALL, NULL}}," for name in found]
    parts += ["#define HC_WRAPPED_METHODS \\", " \\\n".join(entries), ""]
    return "\n".join(parts)


def main(argv: list[str]) -> int:
    header, output = argv
    Path(output).write_text(source(Path(header).read_text()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
