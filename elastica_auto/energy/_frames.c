/* A rotation's frame in a generated module, point by point (energy/runtime.py): the frame
   R(q / |q|) of each quaternion, the body moment R^T m, the quaternion's rate q (x) (0, u) / 2,
   and the chain rule through the frame in the Jacobian (`chain`): for each point, dR/dq_j =
   2 (D_j(q) - q_j R) / |q|^2 and

       jac[rows_r[i], qcols[j]] += sum_ab f_r[i, a, b] dR_j[a, b]
       jac[rows_m[i], qcols[j]] += sum_c f_m[i, c] (dR_j^T m)_c,  (dR_j^T m)_c = sum_a dR_j[a, c] m_a
       jac[rows_m[i], mcols[a]] += sum_c f_m[i, c] R[a, c]

   with D_j(q)[a, b] = sum_c D[j, a, b, c] q_c (runtime._D: R = sum_j q_j D_j(q) / |q|^2).
   The constant tensors (runtime._QUADRATIC, _HALF_LEFT, _D) come from runtime.py, which
   derives them: one definition.

   Why compiled: on the 100 to 300 points of a mesh each numpy call costs about a microsecond
   whatever it computes, and these were several calls each (the frame: an outer product, a
   matrix product, an einsum and a division, 10 microseconds, nine or more times a
   continuation step), the chain 150 microseconds on 201 points (the frames' derivatives,
   four einsums, three fancy-indexed additions); the arithmetic is a few dozen to a few
   hundred products per point. Each sum is taken over its index in increasing order, in
   plain IEEE double (built with -ffp-contract=off), so the results are the same bits with
   every BLAS (the matrix products were BLAS calls). Arrays are reached through the buffer
   protocol (float64; outputs C-contiguous and writable, inputs with any strides). */

#include "../_buffers.h"

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

/* frame(q, Q, out): out[a, b, p] = sum_cd Q[3 a + b, 4 c + d] q_c q_d / |q|^2. */
static PyObject *frame(PyObject *self, PyObject *args)
{
    PyObject *q_obj, *qm_obj, *out_obj;
    if (!PyArg_ParseTuple(args, "OOO", &q_obj, &qm_obj, &out_obj))
        return NULL;
    Py_buffer q, Q, out;
    idx sq[2] = {4, -1};
    if (get_array(q_obj, &q, 2, sq, 0, "q") < 0)
        return NULL;
    idx sQ[2] = {9, 16}, so[3] = {3, 3, sq[1]};
    if (get_array(qm_obj, &Q, 2, sQ, 0, "Q") < 0) {
        PyBuffer_Release(&q);
        return NULL;
    }
    if (get_array(out_obj, &out, 3, so, 1, "out") < 0) {
        PyBuffer_Release(&q);
        PyBuffer_Release(&Q);
        return NULL;
    }
    idx npts = sq[1];
    /* the nonzero entries of Q (a few per row): the others add exact zeros */
    double qv[9][16];
    int qc[9][16], qd[9][16], qn[9];
    for (int ab = 0; ab < 9; ab++) {
        qn[ab] = 0;
        for (int cd = 0; cd < 16; cd++) {
            double v = AT2(Q, ab, cd);
            if (v != 0.0) {
                qv[ab][qn[ab]] = v;
                qc[ab][qn[ab]] = cd / 4;
                qd[ab][qn[ab]++] = cd % 4;
            }
        }
    }
    double *o = (double *)out.buf;
    for (idx p = 0; p < npts; p++) {
        double qq[4], n2 = 0.0;
        for (int c = 0; c < 4; c++) {
            qq[c] = AT2(q, c, p);
            n2 += qq[c] * qq[c];
        }
        for (int ab = 0; ab < 9; ab++) {
            double sum = 0.0;
            for (int t = 0; t < qn[ab]; t++)
                sum += qv[ab][t] * (qq[qc[ab][t]] * qq[qd[ab][t]]);
            o[ab * npts + p] = sum / n2;
        }
    }
    PyBuffer_Release(&q);
    PyBuffer_Release(&Q);
    PyBuffer_Release(&out);
    Py_RETURN_NONE;
}

/* body(R, m, out): out[c, p] = sum_a R[a, c, p] m[a, p]. */
static PyObject *body(PyObject *self, PyObject *args)
{
    PyObject *r_obj, *m_obj, *out_obj;
    if (!PyArg_ParseTuple(args, "OOO", &r_obj, &m_obj, &out_obj))
        return NULL;
    Py_buffer R, m, out;
    idx sr[3] = {3, 3, -1};
    if (get_array(r_obj, &R, 3, sr, 0, "R") < 0)
        return NULL;
    idx sm[2] = {3, sr[2]};
    if (get_array(m_obj, &m, 2, sm, 0, "m") < 0) {
        PyBuffer_Release(&R);
        return NULL;
    }
    if (get_array(out_obj, &out, 2, sm, 1, "out") < 0) {
        PyBuffer_Release(&R);
        PyBuffer_Release(&m);
        return NULL;
    }
    idx npts = sr[2];
    double *o = (double *)out.buf;
    for (idx p = 0; p < npts; p++)
        for (int c = 0; c < 3; c++) {
            double sum = 0.0;
            for (int a = 0; a < 3; a++)
                sum += AT3(R, a, c, p) * AT2(m, a, p);
            o[c * npts + p] = sum;
        }
    PyBuffer_Release(&R);
    PyBuffer_Release(&m);
    PyBuffer_Release(&out);
    Py_RETURN_NONE;
}

/* quaternion_rate(q, u, H, out): out[i, p] = sum_kc H[i, 4 k + c] u_k q_c, q' = q (x) (0, u)
   / 2. */
static PyObject *quaternion_rate(PyObject *self, PyObject *args)
{
    PyObject *q_obj, *u_obj, *h_obj, *out_obj;
    if (!PyArg_ParseTuple(args, "OOOO", &q_obj, &u_obj, &h_obj, &out_obj))
        return NULL;
    Py_buffer q, u, H, out;
    idx sq[2] = {4, -1};
    if (get_array(q_obj, &q, 2, sq, 0, "q") < 0)
        return NULL;
    idx su[2] = {3, sq[1]}, sh[2] = {4, 12};
    if (get_array(u_obj, &u, 2, su, 0, "u") < 0) {
        PyBuffer_Release(&q);
        return NULL;
    }
    if (get_array(h_obj, &H, 2, sh, 0, "H") < 0) {
        PyBuffer_Release(&q);
        PyBuffer_Release(&u);
        return NULL;
    }
    if (get_array(out_obj, &out, 2, sq, 1, "out") < 0) {
        PyBuffer_Release(&q);
        PyBuffer_Release(&u);
        PyBuffer_Release(&H);
        return NULL;
    }
    double hv[4][12];
    int hk[4][12], hc[4][12], hn[4];
    for (int i = 0; i < 4; i++) {
        hn[i] = 0;
        for (int kc = 0; kc < 12; kc++) {
            double v = AT2(H, i, kc);
            if (v != 0.0) {
                hv[i][hn[i]] = v;
                hk[i][hn[i]] = kc / 4;
                hc[i][hn[i]++] = kc % 4;
            }
        }
    }
    idx npts = sq[1];
    double *o = (double *)out.buf;
    for (idx p = 0; p < npts; p++) {
        double qq[4], uu[3];
        for (int c = 0; c < 4; c++)
            qq[c] = AT2(q, c, p);
        for (int k = 0; k < 3; k++)
            uu[k] = AT2(u, k, p);
        for (int i = 0; i < 4; i++) {
            double sum = 0.0;
            for (int t = 0; t < hn[i]; t++)
                sum += hv[i][t] * (uu[hk[i][t]] * qq[hc[i][t]]);
            o[i * npts + p] = sum;
        }
    }
    PyBuffer_Release(&q);
    PyBuffer_Release(&u);
    PyBuffer_Release(&H);
    PyBuffer_Release(&out);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"frame", frame, METH_VARARGS,
     "frame(q, Q, out): the frames R(q / |q|) (3, 3, npts) of the quaternions q (4, npts) "
     "into out, Q (9, 16) the quadratic form (runtime.frame)."},
    {"body", body, METH_VARARGS,
     "body(R, m, out): R^T m (3, npts) into out (runtime.body)."},
    {"quaternion_rate", quaternion_rate, METH_VARARGS,
     "quaternion_rate(q, u, H, out): q (x) (0, u) / 2 (4, npts) into out, H (4, 12) "
     "(runtime.quaternion_rate)."},
    {"chain", chain, METH_VARARGS,
     "chain(jac, R, q, m, qcols, mcols, rows_r, f_r, rows_m, f_m, D): add to jac (n, n', "
     "npts) the derivatives through the frames R (3, 3, npts) of the quaternions q (4, "
     "npts) and the body moments R^T m (runtime.chain); f_r or f_m may be None."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_frames",
    "A rotation's frame, body moment, quaternion rate and the chain rule through the frame "
    "in a generated module, point by point (energy/runtime.py).", -1, methods,
};

PyMODINIT_FUNC PyInit__frames(void)
{
    return PyModule_Create(&module);
}
