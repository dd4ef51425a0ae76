/* The extension module hammerstein_ctrl._core: the Python doors of the compiled core.
 *
 * - call(number, spec, *args) runs kernel `number` of the table (hc_kernel_number) on args and returns its status.
 *   spec is "name|arg arg ...", one word per argument: "X:r:B,4" (a C-ordered float64 array only read, of two
 *   dimensions: B, bound by its first appearance and the same in every array naming it, and 4), "out:w:B" (one that
 *   is written), "begin:i" (an integer), "dt:f" (a float: its bits in shape[0]).  A dimension is a number, a number
 *   followed by + (at least that), a capital letter, a capital letter followed by + (bound, and at least 1) or *
 *   (any).  An argument that does not fit is a TypeError or a ValueError naming the kernel and the argument; the
 *   kernel runs without the GIL.
 * - one wrapper per library function (hc.h), generated when the core is built (generate_wrappers.py): each array
 *   argument is checked to be C-ordered, of the C type and, where the function writes it, writeable (else a
 *   TypeError naming the function and the argument); sizes are non-negative integers; the function runs without
 *   the GIL.
 * - constants: the kernel families, the map codes (MAP_CODES), the limits the kernels are built for.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hc.h"

#define HC_MAX_ARGS 16

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

#include "wrappers.inc"

/* The next word of spec (up to a space or its end) copied to word; the position after it. */
static const char *next_word(const char *spec, char *word, size_t size)
{
    size_t n = 0;
    while (*spec == ' ')
        spec++;
    while (*spec && *spec != ' ') {
        if (n + 1 < size)
            word[n++] = *spec;
        spec++;
    }
    word[n] = '\0';
    return spec;
}

/* Check view's shape against the dimensions dims ("B,4"); 0, or -1 with a ValueError. */
static int fit_shape(const Py_buffer *view, const char *dims, long long *bound, const char *kernel,
                     const char *name)
{
    int ndim = 0;
    const char *d = dims;
    char given[96] = "", bindings[96] = "";
    while (*d) {
        long long size = ndim < view->ndim ? (long long)view->shape[ndim] : -1;
        if (*d >= 'A' && *d <= 'Z') {
            int symbol = *d - 'A';
            d++;
            if (*d == '*')
                d++;
            else {
                if (*d == '+') {
                    d++;
                    if (size == 0)
                        goto bad;
                }
                if (bound[symbol] < 0)
                    bound[symbol] = size;
                else if (bound[symbol] != size) {
                    snprintf(bindings, sizeof bindings, "; %c = %lld", 'A' + symbol, bound[symbol]);
                    goto bad;
                }
            }
        } else {
            char *end;
            long long literal = strtoll(d, &end, 10);
            if (end == d)
                goto bad;
            d = end;
            if (*d == '+') {
                d++;
                if (size < literal)
                    goto bad;
            } else if (literal != size)
                goto bad;
        }
        ndim++;
        if (*d == ',')
            d++;
    }
    if (ndim == view->ndim && ndim <= 3)
        return 0;
bad:                                /* the message is written only for a refusal, never on the way of a call */
    for (int k = 0; k < view->ndim && k < 3; k++) {
        size_t used = strlen(given);
        snprintf(given + used, sizeof given - used, k ? ", %lld" : "%lld", (long long)view->shape[k]);
    }
    PyErr_Format(PyExc_ValueError, "%s: %s has shape (%s), not (%s)%s", kernel, name, given, dims, bindings);
    return -1;
}

/* Take args[k] as the word ("X:r:B,4") says, into arg; 0, or -1 with an exception. */
static int take_arg(PyObject *o, const char *word, hc_arg *arg, Py_buffer *view, int *taken, long long *bound,
                    const char *kernel)
{
    char name[32] = "";
    const char *colon = strchr(word, ':');
    if (colon == NULL || colon[1] == '\0') {
        PyErr_Format(PyExc_ValueError, "%s: bad argument description '%s'", kernel, word);
        return -1;
    }
    snprintf(name, sizeof name, "%.*s", (int)(colon - word), word);
    char mode = colon[1];
    if (mode == 'f') {
        double value = PyFloat_AsDouble(o);
        if (value == -1.0 && PyErr_Occurred())
            return -1;
        arg->data = NULL;
        memcpy(&arg->shape[0], &value, sizeof value);
        return 0;
    }
    if (mode == 'i') {
        long long value = PyLong_AsLongLong(o);
        if (value == -1 && PyErr_Occurred())
            return -1;
        arg->data = NULL;
        arg->shape[0] = value;
        return 0;
    }
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (mode == 'w' ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(o, view, flags) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "%s: %s must be a C-ordered%s float64 array", kernel, name,
                     mode == 'w' ? ", writeable" : "");
        return -1;
    }
    (*taken)++;
    const char *format = view->format ? view->format : "B";
    while (*format == '@' || *format == '=' || *format == '<')
        format++;
    if (view->itemsize != 8 || strcmp(format, "d") != 0) {
        PyErr_Format(PyExc_TypeError, "%s: %s must be a float64 array", kernel, name);
        return -1;
    }
    if (fit_shape(view, colon[2] == ':' ? colon + 3 : "", bound, kernel, name) < 0)
        return -1;
    arg->data = view->buf;
    for (int k = 0; k < 3; k++)
        arg->shape[k] = k < view->ndim ? view->shape[k] : 0;
    return 0;
}

static PyObject *call_kernel(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    hc_arg cargs[HC_MAX_ARGS];
    Py_buffer views[HC_MAX_ARGS];
    (void)self;
    long long bound[26];
    int taken = 0;
    char kernel[64] = "", word[64];
    if (nargs < 2 || nargs - 2 > HC_MAX_ARGS)
        return PyErr_Format(PyExc_TypeError, "call takes a kernel number, a description and at most %d arguments",
                            HC_MAX_ARGS);
    long long number = PyLong_AsLongLong(args[0]);
    if (number == -1 && PyErr_Occurred())
        return NULL;
    const char *spec = PyUnicode_AsUTF8(args[1]);
    if (spec == NULL)
        return NULL;
    const char *bar = strchr(spec, '|');
    hc_kernel function = hc_kernel_at(number);
    if (function == NULL || bar == NULL)
        return PyErr_Format(PyExc_ValueError, "call: no kernel number %lld or no '|' in '%s'", number, spec);
    snprintf(kernel, sizeof kernel, "%.*s", (int)(bar - spec), spec);
    for (int s = 0; s < 26; s++)
        bound[s] = -1;
    const char *p = bar + 1;
    for (Py_ssize_t k = 2; k < nargs; k++) {
        p = next_word(p, word, sizeof word);
        if (word[0] == '\0') {
            PyErr_Format(PyExc_TypeError, "%s takes %zd arguments, not %zd", kernel, k - 2, nargs - 2);
            goto fail;
        }
        if (take_arg(args[k], word, &cargs[k - 2], &views[taken], &taken, bound, kernel) < 0)
            goto fail;
    }
    next_word(p, word, sizeof word);
    if (word[0] != '\0') {
        PyErr_Format(PyExc_TypeError, "%s takes more than %zd arguments", kernel, nargs - 2);
        goto fail;
    }
    int64_t status;
    Py_BEGIN_ALLOW_THREADS
    status = function(cargs);
    Py_END_ALLOW_THREADS
    for (int k = 0; k < taken; k++)
        PyBuffer_Release(&views[k]);
    return PyLong_FromLongLong(status);
fail:
    for (int k = 0; k < taken; k++)
        PyBuffer_Release(&views[k]);
    return NULL;
}

static PyObject *vector_isa(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    return PyUnicode_FromString(hc_vector_isa());
}

static PyMethodDef methods[] = {
    {"call", (PyCFunction)(void (*)(void))call_kernel, METH_FASTCALL,
     "call(number, spec, *args): run kernel number of the table on args checked against spec; its status."},
    {"vector_isa", vector_isa, METH_NOARGS, "The instruction set the vector kernels run with on this processor."},
    HC_WRAPPED_METHODS
    {NULL, NULL, 0, NULL}
};

static struct PyModuleDef definition = {
    PyModuleDef_HEAD_INIT, "_core", "The compiled core of hammerstein_ctrl (built when the package is installed).",
    -1, methods, NULL, NULL, NULL, NULL};

/* name = value in the module, or -1. */
static int constant(PyObject *module, const char *name, long value)
{
    return PyModule_AddIntConstant(module, name, value);
}

PyMODINIT_FUNC PyInit__core(void)
{
    static const char *const map_names[HC_MAP_COUNT] = {"tanh", "coulomb", "polynomial", "saturation", "deadzone",
                                                        "piecewise_linear", "sigmoid", "friction"};
    hc_core_init();
    PyObject *module = PyModule_Create(&definition);
    if (module == NULL)
        return NULL;
    PyObject *codes = PyDict_New();
    if (codes == NULL)
        goto fail;
    for (long i = 0; i < HC_MAP_COUNT; i++) {
        PyObject *value = PyLong_FromLong(i);
        int failed = value == NULL || PyDict_SetItemString(codes, map_names[i], value) < 0;
        Py_XDECREF(value);
        if (failed) {
            Py_DECREF(codes);
            goto fail;
        }
    }
    if (PyModule_AddObject(module, "MAP_CODES", codes) < 0) {
        Py_DECREF(codes);
        goto fail;
    }
    if (constant(module, "SINGLE", HC_SINGLE) < 0 || constant(module, "LANES", HC_LANES) < 0 ||
        constant(module, "NORMAL", HC_NORMAL) < 0 || constant(module, "COEFFICIENT", HC_COEFFICIENT) < 0 ||
        constant(module, "ANY_ORDER", HC_ANY_ORDER) < 0 ||
        constant(module, "MAX_ORDER", HC_MAX_ORDER) < 0 || constant(module, "LANES_MAX_ORDER", HC_LANES_MAX_ORDER) < 0 ||
        constant(module, "MAX_BASIS", HC_MAX_BASIS) < 0 || constant(module, "MAX_LANES", HC_MAX_LANES) < 0)
        goto fail;
    return module;
fail:
    Py_DECREF(module);
    return NULL;
}
