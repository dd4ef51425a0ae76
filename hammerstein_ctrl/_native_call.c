/* The Python door of the generated kernels built in C (hammerstein_ctrl._kernel_c): part of the extension module
 * of hammerstein_ctrl._native, compiled with its generated wrappers (it needs Python.h).
 *
 * call(address, spec, *args) runs the kernel at address (int64_t kernel(const hc_arg *args)) on args and returns
 * its status.  spec is "name|arg arg ...", one word per argument: "X:r:B,4" (a C-ordered float64 array only
 * read, of two dimensions: B, bound by its first appearance and the same in every array naming it, and 4),
 * "out:w:B" (one that is written), "begin:i" (an integer), "dt:f" (a float: its bits in shape[0]).  A dimension
 * is a number, a number followed by + (at least that), a capital letter, a capital letter followed by + (bound,
 * and at least 1) or * (any).  An argument that does not fit is a TypeError or a
 * ValueError naming the kernel and the argument; the kernel runs without the GIL.
 */
#include <stdio.h>
#include <stdlib.h>

#include "_native_kernel.h"

#define HC_MAX_ARGS 16

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
    long long bound[26];
    int taken = 0;
    char kernel[64] = "", word[64];
    if (nargs < 2 || nargs - 2 > HC_MAX_ARGS)
        return PyErr_Format(PyExc_TypeError, "call takes an address, a description and at most %d arguments",
                            HC_MAX_ARGS);
    long long address = PyLong_AsLongLong(args[0]);
    if (address == -1 && PyErr_Occurred())
        return NULL;
    const char *spec = PyUnicode_AsUTF8(args[1]);
    if (spec == NULL)
        return NULL;
    const char *bar = strchr(spec, '|');
    if (address == 0 || bar == NULL)
        return PyErr_Format(PyExc_ValueError, "call: no kernel at address %lld or no '|' in '%s'", address, spec);
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
    int64_t (*function)(const hc_arg *) = (int64_t (*)(const hc_arg *))(intptr_t)address;
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
