/* The chain rule through a rotation's frame in a generated module's Jacobian
   (energy/runtime.py `chain`): for each point, dR/dq_j = 2 (D_j(q) - q_j R) / |q|^2 and

       jac[rows_r[i], qcols[j]] += sum_ab f_r[i, a, b] dR_j[a, b]
       jac[rows_m[i], qcols[j]] += sum_c f_m[i, c] (dR_j^T m)_c,  (dR_j^T m)_c = sum_a dR_j[a, c] m_a
       jac[rows_m[i], mcols[a]] += sum_c f_m[i, c] R[a, c]

   with D_j(q)[a, b] = sum_c D[j, a, b, c] q_c (runtime._D: R = sum_j q_j D_j(q) / |q|^2).

   Why compiled: written with numpy this was the frames' derivatives (4, 3, 3, m), four
   einsums and three fancy-indexed additions, about 150 microseconds on the 200 points of a
   100-interval mesh, most of a spatial rod's Jacobian; the arithmetic is a few hundred
   products per point. Each sum is taken over its index in increasing order, in plain IEEE
   double (built with -ffp-contract=off). Arrays are reached through the buffer protocol
   (float64; jac C-contiguous and writable, the others with any strides). */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

typedef Py_ssize_t idx;

/* A float64 buffer of `ndim` dimensions; `shape` entries < 0 are any length and are stored
   back; C-contiguous and writable if `out`. */
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
        PyErr_Format(PyExc_ValueError, "%s: expected a float64 array of %d dimensions "
                     "of the shape the frame asks", what, ndim);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* The entry of a strided buffer of 2, 3 or 4 dimensions. */
#define AT2(v, i, j) (*(const double *)((const char *)(v).buf + (i) * (v).strides[0] \
                                        + (j) * (v).strides[1]))
#define AT3(v, i, j, k) (*(const double *)((const char *)(v).buf + (i) * (v).strides[0] \
                                           + (j) * (v).strides[1] + (k) * (v).strides[2]))
#define AT4(v, i, j, k, l) (*(const double *)((const char *)(v).buf + (i) * (v).strides[0] \
                                              + (j) * (v).strides[1] + (k) * (v).strides[2] \
                                              + (l) * (v).strides[3]))

/* A sequence of indices into `out` (at most `most`), each in [0, bound). */
static int get_indices(PyObject *obj, idx *out, idx most, idx bound, idx *count,
                       const char *what)
{
    PyObject *seq = PySequence_Fast(obj, what);
    if (!seq)
        return -1;
    idx n = PySequence_Fast_GET_SIZE(seq);
    if (n > most) {
        PyErr_Format(PyExc_ValueError, "%s: at most %zd indices", what, most);
        Py_DECREF(seq);
        return -1;
    }
    for (idx i = 0; i < n; i++) {
        idx v = PyLong_AsSsize_t(PySequence_Fast_GET_ITEM(seq, i));
        if (v == -1 && PyErr_Occurred()) {
            Py_DECREF(seq);
            return -1;
        }
        if (v < 0 || v >= bound) {
            PyErr_Format(PyExc_ValueError, "%s: index %zd out of range", what, v);
            Py_DECREF(seq);
            return -1;
        }
        out[i] = v;
    }
    *count = n;
    Py_DECREF(seq);
    return 0;
}

#define MOST 64

static PyObject *chain(PyObject *self, PyObject *args)
{
    PyObject *jac_obj, *r_obj, *q_obj, *m_obj, *qcols_obj, *mcols_obj, *rows_r_obj, *fr_obj,
        *rows_m_obj, *fm_obj, *d_obj;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOO", &jac_obj, &r_obj, &q_obj, &m_obj, &qcols_obj,
                          &mcols_obj, &rows_r_obj, &fr_obj, &rows_m_obj, &fm_obj, &d_obj))
        return NULL;
    Py_buffer jac, R, q, m, fr, fm, D;
    Py_buffer *views[7] = {NULL};
    int nviews = 0;
    idx sj[3] = {-1, -1, -1};
    if (get_array(jac_obj, &jac, 3, sj, 1, "jac") < 0)
        return NULL;
    views[nviews++] = &jac;
    idx npts = sj[2];
    idx sr[3] = {3, 3, npts}, sq[2] = {4, npts}, sm[2] = {3, npts}, sd[4] = {4, 3, 3, 4};
    idx qcols[4], mcols[3], rows_r[MOST], rows_m[MOST], nq, nm, nr = 0, nrm = 0;
    int have_r = fr_obj != Py_None, have_m = fm_obj != Py_None;
    PyObject *result = NULL;
    if (get_array(r_obj, &R, 3, sr, 0, "R") < 0)
        goto done;
    views[nviews++] = &R;
    if (get_array(q_obj, &q, 2, sq, 0, "q") < 0)
        goto done;
    views[nviews++] = &q;
    if (get_array(m_obj, &m, 2, sm, 0, "m") < 0)
        goto done;
    views[nviews++] = &m;
    if (get_array(d_obj, &D, 4, sd, 0, "D") < 0)
        goto done;
    views[nviews++] = &D;
    if (get_indices(qcols_obj, qcols, 4, sj[1], &nq, "qcols") < 0
        || get_indices(mcols_obj, mcols, 3, sj[1], &nm, "mcols") < 0)
        goto done;
    if (nq != 4 || nm != 3) {
        PyErr_SetString(PyExc_ValueError, "chain: 4 quaternion and 3 moment columns");
        goto done;
    }
    if (have_r) {
        if (get_indices(rows_r_obj, rows_r, MOST, sj[0], &nr, "rows_r") < 0)
            goto done;
        idx s4[4] = {nr, 3, 3, npts};
        if (get_array(fr_obj, &fr, 4, s4, 0, "f_r") < 0)
            goto done;
        views[nviews++] = &fr;
    }
    if (have_m) {
        if (get_indices(rows_m_obj, rows_m, MOST, sj[0], &nrm, "rows_m") < 0)
            goto done;
        idx s3[3] = {nrm, 3, npts};
        if (get_array(fm_obj, &fm, 3, s3, 0, "f_m") < 0)
            goto done;
        views[nviews++] = &fm;
    }
    double d[4][3][3][4];
    for (idx j = 0; j < 4; j++)
        for (idx a = 0; a < 3; a++)
            for (idx b = 0; b < 3; b++)
                for (idx c = 0; c < 4; c++)
                    d[j][a][b][c] = AT4(D, j, a, b, c);
    double *out = (double *)jac.buf;
    idx ncol = sj[1];
    for (idx p = 0; p < npts; p++) {
        double qq[4], mm[3], rr[3][3], dr[4][3][3];
        for (idx c = 0; c < 4; c++)
            qq[c] = AT2(q, c, p);
        for (idx a = 0; a < 3; a++) {
            mm[a] = AT2(m, a, p);
            for (idx b = 0; b < 3; b++)
                rr[a][b] = AT3(R, a, b, p);
        }
        double norm2 = 0.0;
        for (idx c = 0; c < 4; c++)
            norm2 += qq[c] * qq[c];
        double two = 2.0 / norm2;
        for (idx j = 0; j < 4; j++)
            for (idx a = 0; a < 3; a++)
                for (idx b = 0; b < 3; b++) {
                    double dq = 0.0;
                    for (idx c = 0; c < 4; c++)
                        dq += d[j][a][b][c] * qq[c];
                    dr[j][a][b] = (dq - qq[j] * rr[a][b]) * two;
                }
        for (idx i = 0; i < nr; i++) {
            double f[3][3];
            for (idx a = 0; a < 3; a++)
                for (idx b = 0; b < 3; b++)
                    f[a][b] = AT4(fr, i, a, b, p);
            for (idx j = 0; j < 4; j++) {
                double sum = 0.0;
                for (idx a = 0; a < 3; a++)
                    for (idx b = 0; b < 3; b++)
                        sum += f[a][b] * dr[j][a][b];
                out[(rows_r[i] * ncol + qcols[j]) * npts + p] += sum;
            }
        }
        if (nrm) {
            double dmb[3][4];            /* (dR_j^T m)_c */
            for (idx c = 0; c < 3; c++)
                for (idx j = 0; j < 4; j++) {
                    double sum = 0.0;
                    for (idx a = 0; a < 3; a++)
                        sum += dr[j][a][c] * mm[a];
                    dmb[c][j] = sum;
                }
            for (idx i = 0; i < nrm; i++) {
                double f[3];
                for (idx c = 0; c < 3; c++)
                    f[c] = AT3(fm, i, c, p);
                for (idx j = 0; j < 4; j++) {
                    double sum = 0.0;
                    for (idx c = 0; c < 3; c++)
                        sum += f[c] * dmb[c][j];
                    out[(rows_m[i] * ncol + qcols[j]) * npts + p] += sum;
                }
                for (idx a = 0; a < 3; a++) {
                    double sum = 0.0;
                    for (idx c = 0; c < 3; c++)
                        sum += f[c] * rr[a][c];
                    out[(rows_m[i] * ncol + mcols[a]) * npts + p] += sum;
                }
            }
        }
    }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    for (int i = 0; i < nviews; i++)
        PyBuffer_Release(views[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"chain", chain, METH_VARARGS,
     "chain(jac, R, q, m, qcols, mcols, rows_r, f_r, rows_m, f_m, D): add to jac (n, n', "
     "npts) the derivatives through the frames R (3, 3, npts) of the quaternions q (4, "
     "npts) and the body moments R^T m (runtime.chain); f_r or f_m may be None."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_frames",
    "The chain rule through a rotation's frame in a generated module's Jacobian "
    "(energy/runtime.py).", -1, methods,
};

PyMODINIT_FUNC PyInit__frames(void)
{
    return PyModule_Create(&module);
}
