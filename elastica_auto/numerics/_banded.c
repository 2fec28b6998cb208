/* The banded LU factorisation with partial pivoting, and its solves, of numerics/bordered.py.

   The algorithm and the storage are LAPACK's unblocked banded LU (dgbtf2) and its solve
   (dgbtrs with dtbsv): a matrix A of order N with kl sub- and ku superdiagonals is held by
   columns, column c at ab[c * ldab ...], ldab = 2 kl + ku + 1, entry A(r, c) at
   ab[c * ldab + kv + r - c] with kv = kl + ku; the first kl places of each column are room
   for the fill-in that row exchanges bring. The factorisation overwrites ab with U (its kv
   superdiagonals) and the multipliers of L (below the diagonal); piv[j] is the row (0-based)
   exchanged with row j at step j.

   Why compiled: at the engine's sizes (a node block of 5-20 unknowns, tens to a thousand
   nodes) LAPACK's unblocked code makes four BLAS calls per column (idamax, dswap, dscal,
   dger) on vectors of about kl numbers: the calls' own cost, not the arithmetic, is most of
   the time. The same loops written out here do the same operations without a call per column.

   The arithmetic is plain IEEE double, each product and sum rounded (built with
   -ffp-contract=off: no fused multiply-add), in a fixed order that depends on nothing but the
   matrix: the results are the same bits on every machine and with every BLAS. Vectors are
   reached through the buffer protocol (C-contiguous float64; piv of Py_ssize_t), so numpy is
   not needed to build this file. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

typedef Py_ssize_t idx;

/* A writable C-contiguous buffer of items of `itemsize` bytes, its format one of `formats`
   (after a byte-order mark, if any), holding `count` items (any number if count < 0). */
static int get_vector(PyObject *obj, Py_buffer *view, idx count, idx itemsize,
                      const char *formats, const char *what)
{
    if (PyObject_GetBuffer(obj, view, PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        return -1;
    const char *f = view->format ? view->format : "B";
    if (*f == '@' || *f == '=' || *f == '<')
        f++;
    if (view->itemsize != itemsize || strlen(f) != 1 || !strchr(formats, *f)
        || (count >= 0 && view->len != count * itemsize)) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd contiguous items of %zd bytes "
                     "(format %s), got %zd bytes of format %s", what, count, itemsize,
                     formats, (idx)view->len, view->format ? view->format : "B");
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* lu(ab, kl, ku, piv) -> info: ab (N * ldab float64) and piv (N) overwritten by the factors;
   info = 0, or 1 + the first step whose pivot is exactly zero (the factorisation continues,
   as LAPACK's does: U is then singular). */
static PyObject *lu(PyObject *self, PyObject *args)
{
    PyObject *ab_obj, *piv_obj;
    idx kl, ku;
    if (!PyArg_ParseTuple(args, "OnnO", &ab_obj, &kl, &ku, &piv_obj))
        return NULL;
    if (kl < 0 || ku < 0) {
        PyErr_SetString(PyExc_ValueError, "kl and ku must not be negative");
        return NULL;
    }
    const idx ldab = 2 * kl + ku + 1, kv = kl + ku;
    Py_buffer vab, vpiv;
    if (get_vector(ab_obj, &vab, -1, 8, "d", "ab") < 0)
        return NULL;
    const idx n = (idx)(vab.len / (8 * ldab));
    if (vab.len != n * ldab * 8) {
        PyErr_SetString(PyExc_ValueError, "ab: not a whole number of band columns");
        PyBuffer_Release(&vab);
        return NULL;
    }
    if (get_vector(piv_obj, &vpiv, n, sizeof(idx), "lqn", "piv") < 0) {
        PyBuffer_Release(&vab);
        return NULL;
    }
    double *ab = (double *)vab.buf;
    idx *piv = (idx *)vpiv.buf;
    idx info = 0;

    Py_BEGIN_ALLOW_THREADS
    /* the fill-in room of the first kv columns (later columns: cleared at their turn) */
    for (idx c = 0; c < n && c < kv; c++)
        for (idx p = 0; p < kl; p++)
            ab[c * ldab + p] = 0.0;
    idx ju = 0;                                   /* the last column touched so far */
    for (idx j = 0; j < n; j++) {
        if (j + kv < n)
            for (idx p = 0; p < kl; p++)
                ab[(j + kv) * ldab + p] = 0.0;
        double *col = ab + j * ldab + kv;         /* col[i] = A(j + i, j) */
        const idx km = kl < n - 1 - j ? kl : n - 1 - j;
        idx jp = 0;                               /* the first largest |A(j + i, j)| */
        double big = fabs(col[0]);
        for (idx i = 1; i <= km; i++)
            if (fabs(col[i]) > big) {
                big = fabs(col[i]);
                jp = i;
            }
        piv[j] = j + jp;
        if (col[jp] != 0.0) {
            idx last = j + ku + jp < n - 1 ? j + ku + jp : n - 1;
            if (last > ju)
                ju = last;
            if (jp != 0)                          /* exchange rows j and j + jp, columns j..ju */
                for (idx c = j; c <= ju; c++) {
                    double *a = ab + c * ldab + kv - c;
                    double t = a[j];
                    a[j] = a[j + jp];
                    a[j + jp] = t;
                }
            if (km > 0) {
                const double r = 1.0 / col[0];
                for (idx i = 1; i <= km; i++)
                    col[i] *= r;
                for (idx c = j + 1; c <= ju; c++) {   /* A(j+1.., c) -= l A(j, c) */
                    double *a = ab + c * ldab + kv - c;
                    const double t = a[j];
                    if (t != 0.0) {
                        double *dst = a + j;
                        for (idx i = 1; i <= km; i++)
                            dst[i] -= t * col[i];
                    }
                }
            }
        }
        else if (info == 0)
            info = j + 1;
    }
    Py_END_ALLOW_THREADS

    PyBuffer_Release(&vab);
    PyBuffer_Release(&vpiv);
    return PyLong_FromSsize_t(info);
}

/* solve(ab, kl, ku, piv, b, trans): b (N float64) overwritten by the solution of A x = b
   (trans false) or A^T x = b (trans true), from the factors of lu(). */
static PyObject *solve(PyObject *self, PyObject *args)
{
    PyObject *ab_obj, *piv_obj, *b_obj;
    idx kl, ku;
    int trans;
    if (!PyArg_ParseTuple(args, "OnnOOp", &ab_obj, &kl, &ku, &piv_obj, &b_obj, &trans))
        return NULL;
    if (kl < 0 || ku < 0) {
        PyErr_SetString(PyExc_ValueError, "kl and ku must not be negative");
        return NULL;
    }
    const idx ldab = 2 * kl + ku + 1, kv = kl + ku;
    Py_buffer vab, vpiv, vb;
    if (get_vector(b_obj, &vb, -1, 8, "d", "b") < 0)
        return NULL;
    const idx n = (idx)(vb.len / 8);
    if (get_vector(ab_obj, &vab, n * ldab, 8, "d", "ab") < 0) {
        PyBuffer_Release(&vb);
        return NULL;
    }
    if (get_vector(piv_obj, &vpiv, n, sizeof(idx), "lqn", "piv") < 0) {
        PyBuffer_Release(&vb);
        PyBuffer_Release(&vab);
        return NULL;
    }
    const double *ab = (const double *)vab.buf;
    const idx *piv = (const idx *)vpiv.buf;
    double *x = (double *)vb.buf;

    Py_BEGIN_ALLOW_THREADS
    if (!trans) {
        /* L: the row exchanges and multipliers in the order they were made */
        for (idx j = 0; j + 1 < n; j++) {
            const idx lm = kl < n - 1 - j ? kl : n - 1 - j;
            const idx p = piv[j];
            if (p != j) {
                double t = x[p];
                x[p] = x[j];
                x[j] = t;
            }
            const double t = x[j];
            const double *l = ab + j * ldab + kv;
            for (idx i = 1; i <= lm; i++)
                x[j + i] -= t * l[i];
        }
        /* U, by columns from the last */
        for (idx j = n - 1; j >= 0; j--) {
            const double *u = ab + j * ldab + kv - j;     /* u[i] = U(i, j) */
            if (x[j] != 0.0) {
                x[j] /= u[j];
                const double t = x[j];
                for (idx i = j - kv > 0 ? j - kv : 0; i < j; i++)
                    x[i] -= t * u[i];
            }
        }
    }
    else {
        /* U^T, forward */
        for (idx j = 0; j < n; j++) {
            const double *u = ab + j * ldab + kv - j;
            double t = x[j];
            for (idx i = j - kv > 0 ? j - kv : 0; i < j; i++)
                t -= u[i] * x[i];
            x[j] = t / u[j];
        }
        /* L^T, backward, undoing the row exchanges */
        for (idx j = n - 2; j >= 0; j--) {
            const idx lm = kl < n - 1 - j ? kl : n - 1 - j;
            const double *l = ab + j * ldab + kv;
            double dot = 0.0;
            for (idx i = 1; i <= lm; i++)
                dot += l[i] * x[j + i];
            x[j] -= dot;
            const idx p = piv[j];
            if (p != j) {
                double t = x[p];
                x[p] = x[j];
                x[j] = t;
            }
        }
    }
    Py_END_ALLOW_THREADS

    PyBuffer_Release(&vb);
    PyBuffer_Release(&vab);
    PyBuffer_Release(&vpiv);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"lu", lu, METH_VARARGS,
     "lu(ab, kl, ku, piv) -> info: the banded LU with partial pivoting, in place (LAPACK's "
     "dgbtf2; ab C-contiguous float64 of N * (2 kl + ku + 1), column by column; piv N "
     "Py_ssize_t, 0-based)."},
    {"solve", solve, METH_VARARGS,
     "solve(ab, kl, ku, piv, b, trans): b overwritten by A^-1 b (A^-T b if trans), from lu()'s "
     "factors (LAPACK's dgbtrs, one right-hand side)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_banded",
    "The banded LU with partial pivoting and its solves (numerics/bordered.py).", -1, methods,
};

PyMODINIT_FUNC PyInit__banded(void)
{
    return PyModule_Create(&module);
}
