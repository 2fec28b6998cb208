/* The buffer-protocol helper the package's C files share (numerics/_blocks.c,
   energy/_frames.c): one definition of how a float64 array argument is read. Included by
   those files only (each a module of its own: the function is static in each). */

#ifndef ELASTICA_AUTO_BUFFERS_H
#define ELASTICA_AUTO_BUFFERS_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

typedef Py_ssize_t idx;

/* A float64 buffer of `ndim` dimensions with the shape `shape` (an entry < 0: any length,
   stored back), writable and C-contiguous if `out`; otherwise any strides (multiples of the
   item). ValueError naming `what` where it is not. */
static int get_array(PyObject *obj, Py_buffer *view, int ndim, idx *shape, int out,
                     const char *what)
{
    int flags = out ? (PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS | PyBUF_FORMAT)
                    : (PyBUF_STRIDES | PyBUF_FORMAT);
    if (PyObject_GetBuffer(obj, view, flags) < 0)
        return -1;
    const char *f = view->format ? view->format : "B";
    if (*f == '@' || *f == '=' || *f == '<')
        f++;
    int ok = view->itemsize == 8 && strcmp(f, "d") == 0 && view->ndim == ndim;
    for (int i = 0; ok && i < ndim; i++) {
        if (shape[i] < 0)
            shape[i] = view->shape[i];
        ok = view->shape[i] == shape[i] && (view->strides[i] % 8) == 0;
    }
    if (!ok) {
        PyErr_Format(PyExc_ValueError, "%s: expected a float64 array of %d dimensions, "
                     "its shape (%zd, ...)", what, ndim, shape[0]);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

#endif
