/* The direct count's block work, numerics/stability.py's `_inertia` for forms of k components
   (any k): the P2 element matrices, the elimination of each element's midpoint, and the
   levels of the odd-even (cyclic) reduction of the block tridiagonal node matrix and its
   constraint columns, with the count of the pivots' negative eigenvalues (docs/stability.md,
   "The direct count"); and the last nodes' matrix's inertia about the singularity threshold
   (`window`: two LDL^T factorisations with Bunch-Kaufman pivoting).

   Why compiled: at the engine's sizes (100 to 200 blocks of 3 x 3 per level) each of these
   steps written with numpy was a few dozen calls on small arrays, and the calls' own cost,
   not the arithmetic, was most of the time. The loops here do the same operations without a
   call per operation.

   The algorithm and its decisions are those stability.py documents: the element matrices by
   Simpson's rule on the P2 basis, their terms in the order of its formulas; a pivot of 2 or 3
   components inverted as its adjugate over its determinant, its negative eigenvalues counted
   by Descartes' rule of signs on its characteristic polynomial, singular where |det| <= scale
   |c_(k-1)|; a larger pivot by its eigendecomposition (Jacobi's method), singular where an
   eigenvalue is within scale of zero; the products of an elimination associated as K D^-1 K'
   (y = D^-1 x first, then x^T y), each sum taken over its index in increasing order. The
   arithmetic is plain IEEE double, each product and sum rounded (built with
   -ffp-contract=off: no fused multiply-add), so the results are the same bits on every
   machine and with every BLAS. Arrays are reached through the buffer protocol (float64; the
   fields with any strides, the outputs C-contiguous), so numpy is not needed to build this
   file.

   The file also holds the cubic collocation's Jacobian assembly (`cubic_gather`,
   `cubic_blocks`, `cubic_column`, below, for numerics/collocation.py), compiled for the same
   reason. */

#include "../_buffers.h"
#include <math.h>

/* A field (P, k, k) of any strides: entry (q, i, j). */
typedef struct {
    const char *buf;
    idx s0, s1, s2;
} field;

static inline double at(const field *f, idx q, idx i, idx j)
{
    return *(const double *)(f->buf + q * f->s0 + i * f->s1 + j * f->s2);
}

/* Sweeps of the cyclic Jacobi method at most: each sweep squares the off-diagonal part once
   the eigenvalues are separated (quadratic convergence), so a 6 x 6 block takes 5 to 8. */
#define JACOBI_SWEEPS 60

/* The eigenvalues w and eigenvectors (the columns of v) of the symmetric k x k block m
(row-major, its lower triangle read, as LAPACK's eigensolver reads it; a: room for k x k), by
   the cyclic Jacobi method: each rotation in the plane (p, q),
   A <- J^T A J with J_pp = J_qq = c, J_pq = s = -J_qp, t = s / c the smaller root of
   t^2 + 2 t theta - 1 = 0, theta = (a_qq - a_pp) / (2 a_pq), zeroes a_pq; the sweeps go on
   until every off-diagonal entry is below 1e-17 of the block's Frobenius norm, where the
   diagonal is the spectrum to rounding (an eigenvalue moves by at most the off-diagonal
   part's norm): the accuracy of LAPACK's eigensolver, eps |A|. */
static void jacobi(const double *m, idx k, double *w, double *v, double *a)
{
    double fro = 0.0;
    for (idx i = 0; i < k; i++)
        for (idx j = 0; j < k; j++) {
            a[i * k + j] = i >= j ? m[i * k + j] : m[j * k + i];
            fro += a[i * k + j] * a[i * k + j];
        }
    const double small = 1e-17 * sqrt(fro);
    for (idx i = 0; i < k * k; i++)
        v[i] = (i / k == i % k) ? 1.0 : 0.0;
    for (int sweep = 0; sweep < JACOBI_SWEEPS; sweep++) {
        int rotated = 0;
        for (idx p = 0; p < k - 1; p++)
            for (idx q = p + 1; q < k; q++) {
                const double apq = a[p * k + q];
                if (fabs(apq) <= small)
                    continue;
                rotated = 1;
                const double theta = (a[q * k + q] - a[p * k + p]) / (2.0 * apq);
                double t = 1.0 / (fabs(theta) + sqrt(theta * theta + 1.0));
                if (theta < 0)
                    t = -t;
                const double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (idx r = 0; r < k; r++) {       /* A J: columns p and q */
                    const double arp = a[r * k + p], arq = a[r * k + q];
                    a[r * k + p] = c * arp - s * arq;
                    a[r * k + q] = s * arp + c * arq;
                }
                for (idx r = 0; r < k; r++) {       /* J^T (A J): rows p and q */
                    const double apr = a[p * k + r], aqr = a[q * k + r];
                    a[p * k + r] = c * apr - s * aqr;
                    a[q * k + r] = s * apr + c * aqr;
                }
                a[p * k + q] = a[q * k + p] = 0.0;
                for (idx r = 0; r < k; r++) {       /* V J */
                    const double vrp = v[r * k + p], vrq = v[r * k + q];
                    v[r * k + p] = c * vrp - s * vrq;
                    v[r * k + q] = s * vrp + c * vrq;
                }
            }
        if (!rotated)
            break;
    }
    for (idx i = 0; i < k; i++)
        w[i] = a[i * k + i];
}

/* The inverse and the number of negative eigenvalues of the symmetric k x k block m
   (row-major): -1 where it is singular to `scale`. k = 2, 3: the adjugate over
   the determinant and Descartes' rule of signs on the characteristic polynomial; k >= 4: the
   eigendecomposition (Jacobi), singular where an eigenvalue is within scale of zero, the
   inverse V diag(1 / w) V^T (work: room for 2 k^2 + k numbers). */
static int pivot(const double *m, idx k, double scale, double *inv, double *work)
{
    if (k > 3) {
        double *w = work, *v = w + k;
        jacobi(m, k, w, v, v + k * k);
        int negative = 0;
        for (idx i = 0; i < k; i++) {
            if (fabs(w[i]) <= scale)
                return -1;
            negative += w[i] < 0;
        }
        for (idx i = 0; i < k; i++)
            for (idx j = 0; j < k; j++) {
                double t = 0.0;
                for (idx q = 0; q < k; q++)
                    t += (v[i * k + q] / w[q]) * v[j * k + q];
                inv[i * k + j] = t;
            }
        return negative;
    }
    if (k == 1) {
        const double w = m[0];
        if (fabs(w) <= scale)
            return -1;
        inv[0] = 1.0 / w;
        return w < 0;
    }
    double c1, c2, det;
    if (k == 2) {
        const double a = m[0], b = m[3], d = m[1];
        det = a * b;
        det -= d * d;
        c2 = det;
        c1 = a + b;
        const double c_last = c1;
        if (fabs(det) <= scale * fabs(c_last))
            return -1;
        inv[0] = b / det;
        inv[1] = (d * -1.0) / det;
        inv[2] = (d * -1.0) / det;
        inv[3] = a / det;
        const int n1 = c1 < 0, n2 = c2 < 0;
        return n1 + (n1 != n2);
    }
    const double a = m[0], b = m[4], c = m[8], d = m[1], e = m[2], f = m[5];
    const double c00 = b * c - f * f, c11 = a * c - e * e, c22 = a * b - d * d;
    const double c01 = e * f - d * c, c02 = d * f - b * e, c12 = d * e - a * f;
    det = a * c00;
    det += d * c01;
    det += e * c02;
    double c_last = c00 + c11;
    c_last += c22;
    c1 = a + b;
    c1 += c;
    c2 = c_last;
    if (fabs(det) <= scale * fabs(c_last))
        return -1;
    inv[0] = c00 / det;
    inv[1] = c01 / det;
    inv[2] = c02 / det;
    inv[3] = c01 / det;
    inv[4] = c11 / det;
    inv[5] = c12 / det;
    inv[6] = c02 / det;
    inv[7] = c12 / det;
    inv[8] = c22 / det;
    const int n1 = c1 < 0, n2 = c2 < 0, n3 = det < 0;
    return n1 + (n1 != n2) + (n2 != n3);
}

/* y = inv x (k x k times k x w) and z = x^T y (w x w), each sum over its index in order. */
static void eliminate(const double *inv, const double *x, idx k, idx w, double *y, double *z)
{
    for (idx i = 0; i < k; i++)
        for (idx j = 0; j < w; j++) {
            double t = 0.0;
            for (idx m = 0; m < k; m++)
                t += inv[i * k + m] * x[m * w + j];
            y[i * w + j] = t;
        }
    if (z)
        for (idx i = 0; i < w; i++)
            for (idx j = 0; j < w; j++) {
                double t = 0.0;
                for (idx m = 0; m < k; m++)
                    t += x[m * w + i] * y[m * w + j];
                z[i * w + j] = t;
            }
}

/* condense(s, a, b, c, ulps, d, u, inv, y) -> (negative, scale), negative -1 where a midpoint
   block is singular. s: the N nodes; a, b, c: the fields (2N - 1, k, k) on the nodes and
   midpoints (any strides); d (N, k, k), u (N - 1, k, k): the node matrix's diagonal and upper
   blocks after the midpoints' elimination (without E0, E1); inv (N - 1, k, k): the midpoint
   blocks' inverses; y (N - 1, k, 2k): inv [K_m0, K_m2] (`_inertia`'s y); scale = ulps times
   the largest |k00| + |k22|. */
static PyObject *condense(PyObject *self, PyObject *args)
{
    PyObject *s_obj, *a_obj, *b_obj, *c_obj, *d_obj, *u_obj, *inv_obj, *y_obj;
    double ulps;
    if (!PyArg_ParseTuple(args, "OOOOdOOOO", &s_obj, &a_obj, &b_obj, &c_obj, &ulps, &d_obj,
                          &u_obj, &inv_obj, &y_obj))
        return NULL;
    Py_buffer vs, va, vb, vc, vd, vu, vinv, vy;
    idx sh_s[1] = {-1};
    if (get_array(s_obj, &vs, 1, sh_s, 0, "s") < 0)
        return NULL;
    const idx n = sh_s[0], n_el = n - 1, np_ = 2 * n - 1;
    idx sh_a[3] = {np_, -1, -1};
    if (n < 2 || get_array(a_obj, &va, 3, sh_a, 0, "a") < 0) {
        if (n < 2)
            PyErr_SetString(PyExc_ValueError, "s: at least two nodes");
        PyBuffer_Release(&vs);
        return NULL;
    }
    const idx k = sh_a[1];
    if (k < 1 || sh_a[2] != k) {
        PyErr_SetString(PyExc_ValueError, "a: square blocks");
        PyBuffer_Release(&vs);
        PyBuffer_Release(&va);
        return NULL;
    }
    idx sh_f[3] = {np_, k, k}, sh_d[3] = {n, k, k}, sh_u[3] = {n_el, k, k},
        sh_inv[3] = {n_el, k, k}, sh_y[3] = {n_el, k, 2 * k};
    int got = 2;
    Py_buffer *views[8] = {&vs, &va, &vb, &vc, &vd, &vu, &vinv, &vy};
    if (get_array(b_obj, &vb, 3, sh_f, 0, "b") == 0 && ++got
        && get_array(c_obj, &vc, 3, sh_f, 0, "c") == 0 && ++got
        && get_array(d_obj, &vd, 3, sh_d, 1, "d") == 0 && ++got
        && get_array(u_obj, &vu, 3, sh_u, 1, "u") == 0 && ++got
        && get_array(inv_obj, &vinv, 3, sh_inv, 1, "inv") == 0 && ++got
        && get_array(y_obj, &vy, 3, sh_y, 1, "y") == 0)
        got = 8;
    if (got < 8) {
        for (int i = 0; i < got; i++)
            PyBuffer_Release(views[i]);
        return NULL;
    }
    const char *sb = (const char *)vs.buf;
    const idx ss = vs.strides[0];
    const field fa = {va.buf, va.strides[0], va.strides[1], va.strides[2]};
    const field fb = {vb.buf, vb.strides[0], vb.strides[1], vb.strides[2]};
    const field fc = {vc.buf, vc.strides[0], vc.strides[1], vc.strides[2]};
    double *d = (double *)vd.buf, *u = (double *)vu.buf, *inv = (double *)vinv.buf,
           *y = (double *)vy.buf;
    const idx kk = k * k, w = 2 * k;
    int negative = 0;
    double scale = 0.0;

    /* the element matrices k00, k22, k02, k0m, k2m, kmm of every element first (the scale,
       which decides the pivots' singularity, is the largest |k00| + |k22| of them all) */
    double *blocks = PyMem_Malloc((size_t)(n_el * 6 * kk + k * w + w * w + 2 * kk + k)
                                  * sizeof(double));
    if (!blocks) {
        for (int i = 0; i < 8; i++)
            PyBuffer_Release(views[i]);
        return PyErr_NoMemory();
    }

    Py_BEGIN_ALLOW_THREADS
    /* (w0 a0 + wm am + w2 a2) / (6 h) for k00, k22, k02, k0m, k2m (stability._P2_A) */
    static const double w0[5] = {9, 1, 3, -12, -4}, wm[5] = {4, 4, -4, 0, 0},
                        w2[5] = {1, 9, 3, -4, -12};
    double big = 0.0;
    for (idx e = 0; e < n_el; e++) {
        const double h = *(const double *)(sb + (e + 1) * ss) - *(const double *)(sb + e * ss);
        const idx q0 = 2 * e, qm = 2 * e + 1, q2 = 2 * e + 2;
        double *blk = blocks + e * 6 * kk;        /* k00, k22, k02, k0m, k2m, kmm */
        for (idx i = 0; i < k; i++)
            for (idx j = 0; j < k; j++) {
                const idx ij = i * k + j;
                const double a0 = at(&fa, q0, i, j), am = at(&fa, qm, i, j),
                             a2 = at(&fa, q2, i, j);
                for (int t = 0; t < 5; t++) {
                    double v = w0[t] * a0;
                    v += wm[t] * am;
                    v += w2[t] * a2;
                    blk[t * kk + ij] = v / (6 * h);
                }
                blk[ij] += (h / 6) * at(&fb, q0, i, j);
                blk[kk + ij] += (h / 6) * at(&fb, q2, i, j);
                blk[5 * kk + ij] = (16.0 / 6.0) * (a0 + a2) / h
                                   + (4.0 / 6.0) * h * at(&fb, qm, i, j);
            }
        /* the terms of C (c0t, c2t: C transposed at the element's ends) */
        for (idx i = 0; i < k; i++)
            for (idx j = 0; j < k; j++) {
                const idx ij = i * k + j;
                const double c0 = at(&fc, q0, i, j), c0t = at(&fc, q0, j, i),
                             cm = at(&fc, qm, i, j), c2 = at(&fc, q2, i, j),
                             c2t = at(&fc, q2, j, i);
                blk[ij] -= 0.5 * (c0 + c0t);
                blk[kk + ij] += 0.5 * (c2 + c2t);
                blk[2 * kk + ij] += (c2 - c0t) / 6;
                blk[3 * kk + ij] += (4.0 / 6.0) * (c0t - cm);
                blk[4 * kk + ij] += (4.0 / 6.0) * (cm - c2t);
            }
        for (idx t = 0; t < kk; t++) {
            const double v = fabs(blk[t]) + fabs(blk[kk + t]);
            if (v > big)
                big = v;
        }
    }
    scale = ulps * big;
    /* each midpoint eliminated: x = [K_m0, K_m2] = [k0m^T, k2m^T] (k x 2k), y = kmm^-1 x,
       z = x^T y; d[e] gets k00 - z[:k, :k], d[e + 1] k22 - z[k:, k:], u[e] = k02 - z[:k, k:] */
    memset(d, 0, (size_t)(n * kk) * sizeof(double));
    for (idx e = 0; e < n_el; e++) {
        const double *blk = blocks + e * 6 * kk;
        double *inv_e = inv + e * kk, *y_e = y + e * k * w, *x = blocks + n_el * 6 * kk,
               *z = x + k * w;
        const int neg = pivot(blk + 5 * kk, k, scale, inv_e, z + w * w);
        if (neg < 0) {
            negative = -1;
            break;
        }
        negative += neg;
        for (idx i = 0; i < k; i++)
            for (idx j = 0; j < k; j++) {
                x[i * w + j] = blk[3 * kk + j * k + i];
                x[i * w + k + j] = blk[4 * kk + j * k + i];
            }
        eliminate(inv_e, x, k, w, y_e, z);
        double *d0 = d + e * kk, *d2 = d + (e + 1) * kk, *ue = u + e * kk;
        for (idx i = 0; i < k; i++)
            for (idx j = 0; j < k; j++) {
                d0[i * k + j] += blk[i * k + j] - z[i * w + j];
                d2[i * k + j] += blk[kk + i * k + j] - z[(k + i) * w + k + j];
                ue[i * k + j] = blk[2 * kk + i * k + j] - z[i * w + k + j];
            }
    }
    Py_END_ALLOW_THREADS

    PyMem_Free(blocks);
    for (int i = 0; i < 8; i++)
        PyBuffer_Release(views[i]);
    return Py_BuildValue("(id)", negative, scale);
}

/* reduce(d, u, f, scale, tail, total, size) -> (negative, n): `_reduce`'s levels of the
   odd-even reduction of the block tridiagonal node matrix (diagonal d (N, k, k), upper u
   (N - 1, k, k)) and its constraint columns f (N, k, r), in place, until `tail` nodes or
   fewer are left: negative counts the eliminated pivots' negative eigenvalues (-1 where one
   is singular to `scale`), and d, u, f begin with the n nodes left. total and size (r, r)
   accumulate C K^-1 C^T of the eliminated nodes and the same sum of absolute values. */
static PyObject *reduce(PyObject *self, PyObject *args)
{
    PyObject *d_obj, *u_obj, *f_obj, *total_obj, *size_obj;
    double scale;
    idx tail;
    if (!PyArg_ParseTuple(args, "OOOdnOO", &d_obj, &u_obj, &f_obj, &scale, &tail, &total_obj,
                          &size_obj))
        return NULL;
    if (tail < 1) {
        PyErr_SetString(PyExc_ValueError, "tail: at least one node is left");
        return NULL;
    }
    Py_buffer vd, vu, vf, vt, vs;
    idx sh_d[3] = {-1, -1, -1};
    if (get_array(d_obj, &vd, 3, sh_d, 1, "d") < 0)
        return NULL;
    idx n = sh_d[0];
    const idx k = sh_d[1];
    if (n < 1 || k < 1 || sh_d[2] != k) {
        PyErr_SetString(PyExc_ValueError, "d: at least one square block");
        PyBuffer_Release(&vd);
        return NULL;
    }
    idx sh_u[3] = {n - 1, k, k}, sh_f[3] = {n, k, -1}, sh_t[2] = {-1, -1};
    int got = 1;
    Py_buffer *views[5] = {&vd, &vu, &vf, &vt, &vs};
    if (get_array(u_obj, &vu, 3, sh_u, 1, "u") == 0 && ++got
        && get_array(f_obj, &vf, 3, sh_f, 1, "f") == 0 && ++got
        && (sh_t[0] = sh_t[1] = sh_f[2], get_array(total_obj, &vt, 2, sh_t, 1, "total") == 0)
        && ++got && get_array(size_obj, &vs, 2, sh_t, 1, "size") == 0)
        got = 5;
    if (got < 5) {
        for (int i = 0; i < got; i++)
            PyBuffer_Release(views[i]);
        return NULL;
    }
    const idx r = sh_f[2], kk = k * k, w = 2 * k, kr = k * r;
    double *d = (double *)vd.buf, *u = (double *)vu.buf, *f = (double *)vf.buf,
           *total = (double *)vt.buf, *size = (double *)vs.buf;
    /* per odd node of the first level: its pivot's inverse, x, y = D^-1 x, z = x^T y; and
       the k x r products of the constraint columns */
    const idx room = n / 2 + 1;
    double *scratch = PyMem_Malloc((size_t)(room * (kk + 2 * k * w + w * w) + 3 * kr
                                            + 2 * kk + k) * sizeof(double));
    if (!scratch) {
        for (int i = 0; i < 5; i++)
            PyBuffer_Release(views[i]);
        return PyErr_NoMemory();
    }
    double *inv = scratch, *x = inv + room * kk, *y = x + room * k * w, *z = y + room * k * w,
           *fa = z + room * w * w, *fb = fa + kr, *fc = fb + kr, *work = fc + kr;
    int negative = 0;

    Py_BEGIN_ALLOW_THREADS
    while (n > tail && negative >= 0) {
        const idx p = n / 2, n_right = (n - 1) / 2;
        for (idx j = 0; j < p; j++) {
            const double *dj = d + (2 * j + 1) * kk, *u_left = u + 2 * j * kk;
            double *inv_j = inv + j * kk, *x_j = x + j * k * w;
            const int neg = pivot(dj, k, scale, inv_j, work);
            if (neg < 0) {
                negative = -1;
                break;
            }
            negative += neg;
            /* x = [K[o, o-1], K[o, o+1]] = [u[o-1]^T, u[o]] (zero: no right neighbour) */
            for (idx i = 0; i < k; i++)
                for (idx m = 0; m < k; m++) {
                    x_j[i * w + m] = u_left[m * k + i];
                    x_j[i * w + k + m] = j < n_right ? u[(2 * j + 1) * kk + i * k + m] : 0.0;
                }
            eliminate(inv_j, x_j, k, w, y + j * k * w, z + j * w * w);
            if (r) {   /* C K^-1 C^T of this pivot: fo^T (D^-1 fo), and its |.| sum */
                const double *fo = f + (2 * j + 1) * kr;
                for (idx i = 0; i < k; i++)
                    for (idx c = 0; c < r; c++) {
                        double t = 0.0, ta = 0.0;
                        for (idx m = 0; m < k; m++) {
                            t += inv_j[i * k + m] * fo[m * r + c];
                            ta += fabs(inv_j[i * k + m]) * fabs(fo[m * r + c]);
                        }
                        fa[i * r + c] = t;
                        fb[i * r + c] = ta;
                    }
                for (idx a = 0; a < r; a++)
                    for (idx c = 0; c < r; c++) {
                        double t = 0.0, ta = 0.0;
                        for (idx m = 0; m < k; m++) {
                            t += fo[m * r + a] * fa[m * r + c];
                            ta += fabs(fo[m * r + a]) * fb[m * r + c];
                        }
                        total[a * r + c] += t;
                        size[a * r + c] += ta;
                    }
            }
        }
        if (negative < 0)
            break;
        /* the even nodes, in place (node j from 2j and its odd neighbours 2j +- 1, all at or
           after j): D - K D_o^-1 K^T of each neighbour, the left one's first */
        const idx ne = n - p;
        for (idx j = 0; j < ne; j++) {
            double *dj = d + j * kk;
            const double *de = d + 2 * j * kk;
            for (idx t = 0; t < kk; t++)
                dj[t] = de[t];
            if (j < p) {
                const double *zj = z + j * w * w;
                for (idx i = 0; i < k; i++)
                    for (idx m = 0; m < k; m++)
                        dj[i * k + m] -= zj[i * w + m];
            }
            if (j >= 1 && j <= n_right) {
                const double *zj = z + (j - 1) * w * w;
                for (idx i = 0; i < k; i++)
                    for (idx m = 0; m < k; m++)
                        dj[i * k + m] -= zj[(k + i) * w + k + m];
            }
            if (j < n_right) {   /* the new coupling -(y[:, :k]^T x[:, k:]) */
                const double *yj = y + j * k * w, *xj = x + j * k * w;
                double *uj = u + j * kk;
                for (idx i = 0; i < k; i++)
                    for (idx m = 0; m < k; m++) {
                        double t = 0.0;
                        for (idx q = 0; q < k; q++)
                            t += yj[q * w + i] * xj[q * w + k + m];
                        uj[i * k + m] = -t;
                    }
            }
            if (r) {   /* f[2j] - y[:, :k]^T fo_j - y_(j-1)[:, k:]^T fo_(j-1) */
                for (idx t = 0; t < kr; t++)
                    fc[t] = f[2 * j * kr + t];
                if (j < p) {
                    const double *yj = y + j * k * w, *fo = f + (2 * j + 1) * kr;
                    for (idx i = 0; i < k; i++)
                        for (idx c = 0; c < r; c++) {
                            double t = 0.0;
                            for (idx q = 0; q < k; q++)
                                t += yj[q * w + i] * fo[q * r + c];
                            fc[i * r + c] -= t;
                        }
                }
                if (j >= 1 && j <= n_right) {
                    const double *yj = y + (j - 1) * k * w, *fo = f + (2 * j - 1) * kr;
                    for (idx i = 0; i < k; i++)
                        for (idx c = 0; c < r; c++) {
                            double t = 0.0;
                            for (idx q = 0; q < k; q++)
                                t += yj[q * w + k + i] * fo[q * r + c];
                            fc[i * r + c] -= t;
                        }
                }
                for (idx t = 0; t < kr; t++)
                    f[j * kr + t] = fc[t];
            }
        }
        n = ne;
    }
    Py_END_ALLOW_THREADS

    PyMem_Free(scratch);
    for (int i = 0; i < 5; i++)
        PyBuffer_Release(views[i]);
    return Py_BuildValue("(in)", negative, n);
}

/* rates(a, a_min, b, c, out): the refinement's wavenumber at each of the P points (fields
   (P, k, k), k = 2 or 3, any strides; a_min (P,)): sqrt(|B - C^T A^-1 C| / a_min) + |A^-1 C|
   (Frobenius norms), A^-1 = adj(A) / det(A) by the same cofactors as `pivot` and
   stability._adjugate (stability.rates: the numpy form was a dozen calls on 3 x 3 blocks). */
static PyObject *rates(PyObject *self, PyObject *args)
{
    PyObject *a_obj, *amin_obj, *b_obj, *c_obj, *out_obj;
    if (!PyArg_ParseTuple(args, "OOOOO", &a_obj, &amin_obj, &b_obj, &c_obj, &out_obj))
        return NULL;
    Py_buffer va, vm, vb, vc, vo;
    idx sh_a[3] = {-1, -1, -1};
    if (get_array(a_obj, &va, 3, sh_a, 0, "a") < 0)
        return NULL;
    const idx np_ = sh_a[0], k = sh_a[1];
    if ((k != 2 && k != 3) || sh_a[2] != k) {
        PyErr_SetString(PyExc_ValueError, "a: blocks of 2 x 2 or 3 x 3");
        PyBuffer_Release(&va);
        return NULL;
    }
    idx sh_f[3] = {np_, k, k}, sh_p[1] = {np_};
    Py_buffer *views[5] = {&va, &vm, &vb, &vc, &vo};
    int got = 1;
    if (get_array(amin_obj, &vm, 1, sh_p, 0, "a_min") < 0)
        goto fail;
    got++;
    if (get_array(b_obj, &vb, 3, sh_f, 0, "b") < 0)
        goto fail;
    got++;
    if (get_array(c_obj, &vc, 3, sh_f, 0, "c") < 0)
        goto fail;
    got++;
    if (get_array(out_obj, &vo, 1, sh_p, 1, "out") < 0)
        goto fail;
    got++;
    const field fa = {va.buf, va.strides[0], va.strides[1], va.strides[2]};
    const field fb = {vb.buf, vb.strides[0], vb.strides[1], vb.strides[2]};
    const field fc = {vc.buf, vc.strides[0], vc.strides[1], vc.strides[2]};
    double *out = (double *)vo.buf;
    for (idx q = 0; q < np_; q++) {
        double inv[9], turn[9];
        if (k == 2) {
            const double a = at(&fa, q, 0, 0), b = at(&fa, q, 1, 1), d = at(&fa, q, 0, 1);
            double det = a * b;
            det -= d * d;
            inv[0] = b / det;
            inv[1] = (d * -1.0) / det;
            inv[2] = (d * -1.0) / det;
            inv[3] = a / det;
        } else {
            const double a = at(&fa, q, 0, 0), b = at(&fa, q, 1, 1), c = at(&fa, q, 2, 2),
                         d = at(&fa, q, 0, 1), e = at(&fa, q, 0, 2), f = at(&fa, q, 1, 2);
            const double c00 = b * c - f * f, c11 = a * c - e * e, c22 = a * b - d * d,
                         c01 = e * f - d * c, c02 = d * f - b * e, c12 = d * e - a * f;
            double det = a * c00;
            det += d * c01;
            det += e * c02;
            inv[0] = c00 / det;
            inv[1] = c01 / det;
            inv[2] = c02 / det;
            inv[3] = c01 / det;
            inv[4] = c11 / det;
            inv[5] = c12 / det;
            inv[6] = c02 / det;
            inv[7] = c12 / det;
            inv[8] = c22 / det;
        }
        double turn2 = 0.0, schur2 = 0.0;
        for (idx i = 0; i < k; i++)
            for (idx j = 0; j < k; j++) {
                double sum = 0.0;
                for (idx l = 0; l < k; l++)
                    sum += inv[i * k + l] * at(&fc, q, l, j);
                turn[i * k + j] = sum;
                turn2 += sum * sum;
            }
        for (idx i = 0; i < k; i++)
            for (idx j = 0; j < k; j++) {
                double sum = 0.0;
                for (idx l = 0; l < k; l++)
                    sum += at(&fc, q, l, i) * turn[l * k + j];
                const double v = at(&fb, q, i, j) - sum;
                schur2 += v * v;
            }
        const double a_min = *(const double *)((const char *)vm.buf + q * vm.strides[0]);
        out[q] = sqrt(sqrt(schur2) / a_min) + sqrt(turn2);
    }
    for (int i = 0; i < got; i++)
        PyBuffer_Release(views[i]);
    Py_RETURN_NONE;
fail:
    for (int i = 0; i < got; i++)
        PyBuffer_Release(views[i]);
    return NULL;
}

/* The cubic (Lobatto IIIA) collocation's Jacobian blocks, numerics/collocation.py
   `Discretisation.blocks` (docs/numerics.md, "The collocation corrector"). Why compiled: on
   100 intervals of 13 x 13 blocks the numpy element-wise passes that assemble dC_i/dy_i and
   dC_i/dy_{i+1} from f_y and the product J_mid [J_i, J_{i+1}] (a dozen of them, each a
   temporary array) cost more than their arithmetic; these loops do the same IEEE operations,
   in the same order and each rounded (no fused multiply-add), so the blocks are the same bits
   as the numpy formulas'. The product itself stays numpy's batched matmul (BLAS): its sums
   are rounded the way the BLAS kernel does them, not in index order, and a loop here would
   change the results' last bits. */

/* cubic_gather(jac, jac_all, cat): jac (n, n, M) any strides, f_y at the M = 2m - 1 nodes and
   midpoints as the equation module gives it; jac_all (M, n, n): the same blocks contiguous,
   (point, row, column); cat (m - 1, n, 2n): [J_i, J_{i+1}] side by side, the right factor of
   the batched product J_mid [J_i, J_{i+1}]. Copies only. */
static PyObject *cubic_gather(PyObject *self, PyObject *args)
{
    PyObject *jac_obj, *all_obj, *cat_obj;
    if (!PyArg_ParseTuple(args, "OOO", &jac_obj, &all_obj, &cat_obj))
        return NULL;
    Py_buffer vj, va, vc;
    idx sh_j[3] = {-1, -1, -1};
    if (get_array(jac_obj, &vj, 3, sh_j, 0, "jac") < 0)
        return NULL;
    const idx n = sh_j[0], big = sh_j[2], m = (big + 1) / 2;
    if (n < 1 || sh_j[1] != n || big < 3 || big % 2 == 0) {
        PyErr_SetString(PyExc_ValueError, "jac: (n, n, 2m - 1) with m >= 2");
        PyBuffer_Release(&vj);
        return NULL;
    }
    idx sh_a[3] = {big, n, n}, sh_c[3] = {m - 1, n, 2 * n};
    if (get_array(all_obj, &va, 3, sh_a, 1, "jac_all") < 0) {
        PyBuffer_Release(&vj);
        return NULL;
    }
    if (get_array(cat_obj, &vc, 3, sh_c, 1, "cat") < 0) {
        PyBuffer_Release(&vj);
        PyBuffer_Release(&va);
        return NULL;
    }
    const char *jb = (const char *)vj.buf;
    const idx s0 = vj.strides[0], s1 = vj.strides[1], s2 = vj.strides[2], nn = n * n;
    double *all = (double *)va.buf, *cat = (double *)vc.buf;
    Py_BEGIN_ALLOW_THREADS
    for (idx a = 0; a < n; a++)
        for (idx b = 0; b < n; b++) {
            const char *src = jb + a * s0 + b * s1;
            double *dst = all + a * n + b;
            for (idx q = 0; q < big; q++)
                dst[q * nn] = *(const double *)(src + q * s2);
        }
    for (idx i = 0; i < m - 1; i++)
        for (idx a = 0; a < n; a++) {
            memcpy(cat + (i * n + a) * 2 * n, all + i * nn + a * n, (size_t)n * sizeof(double));
            memcpy(cat + (i * n + a) * 2 * n + n, all + (i + 1) * nn + a * n,
                   (size_t)n * sizeof(double));
        }
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&vj);
    PyBuffer_Release(&va);
    PyBuffer_Release(&vc);
    Py_RETURN_NONE;
}

/* cubic_blocks(jac_all, prod, h6, h12, d0, d1): jac_all (2m - 1, n, n), f_y at the m nodes
   then the m - 1 midpoints; prod (m - 1, n, 2n): J_mid,i [J_i, J_{i+1}]; h6, h12 (m - 1,):
   h_i / 6 and h_i^2 / 12 (any strides); into d0, d1 (m - 1, n, n):
       d0 = ((-I - h6 J_i) - (2 h6) J_mid) - h12 (J_mid J_i),
       d1 = (( I - h6 J_{i+1}) - (2 h6) J_mid) + h12 (J_mid J_{i+1}),
   left to right, each operation rounded: collocation.py's numpy formulas operation for
   operation (-I off the diagonal is -0.0, as numpy's -eye is). */
static PyObject *cubic_blocks(PyObject *self, PyObject *args)
{
    PyObject *jac_obj, *prod_obj, *h6_obj, *h12_obj, *d0_obj, *d1_obj;
    if (!PyArg_ParseTuple(args, "OOOOOO", &jac_obj, &prod_obj, &h6_obj, &h12_obj, &d0_obj,
                          &d1_obj))
        return NULL;
    Py_buffer vj, vp, v6, v12, v0, v1;
    idx sh_j[3] = {-1, -1, -1};
    if (get_array(jac_obj, &vj, 3, sh_j, 0, "jac_all") < 0)
        return NULL;
    const idx big = sh_j[0], n = sh_j[1], m = (big + 1) / 2;
    if (n < 1 || sh_j[2] != n || big < 3 || big % 2 == 0) {
        PyErr_SetString(PyExc_ValueError, "jac_all: (2m - 1, n, n) with m >= 2");
        PyBuffer_Release(&vj);
        return NULL;
    }
    idx sh_p[3] = {m - 1, n, 2 * n}, sh_h[1] = {m - 1}, sh_d[3] = {m - 1, n, n};
    Py_buffer *views[6] = {&vj, &vp, &v6, &v12, &v0, &v1};
    int got = 1;
    if (get_array(prod_obj, &vp, 3, sh_p, 0, "prod") == 0 && ++got
        && get_array(h6_obj, &v6, 1, sh_h, 0, "h6") == 0 && ++got
        && get_array(h12_obj, &v12, 1, sh_h, 0, "h12") == 0 && ++got
        && get_array(d0_obj, &v0, 3, sh_d, 1, "d0") == 0 && ++got
        && get_array(d1_obj, &v1, 3, sh_d, 1, "d1") == 0)
        got = 6;
    if (got < 6) {
        for (int i = 0; i < got; i++)
            PyBuffer_Release(views[i]);
        return NULL;
    }
    const field fj = {vj.buf, vj.strides[0], vj.strides[1], vj.strides[2]};
    const field fp = {vp.buf, vp.strides[0], vp.strides[1], vp.strides[2]};
    double *d0 = (double *)v0.buf, *d1 = (double *)v1.buf;
    Py_BEGIN_ALLOW_THREADS
    for (idx i = 0; i < m - 1; i++) {
        const double h6 = *(const double *)((const char *)v6.buf + i * v6.strides[0]);
        const double h12 = *(const double *)((const char *)v12.buf + i * v12.strides[0]);
        const double h3 = 2 * h6;
        for (idx a = 0; a < n; a++)
            for (idx b = 0; b < n; b++) {
                const double shared = h3 * at(&fj, m + i, a, b);
                const double p0 = at(&fp, i, a, b) * h12, p1 = at(&fp, i, a, n + b) * h12;
                double v0 = (a == b ? -1.0 : -0.0) - h6 * at(&fj, i, a, b);
                v0 -= shared;
                v0 -= p0;
                double v1 = (a == b ? 1.0 : 0.0) - h6 * at(&fj, i + 1, a, b);
                v1 -= shared;
                v1 += p1;
                d0[(i * n + a) * n + b] = v0;
                d1[(i * n + a) * n + b] = v1;
            }
    }
    Py_END_ALLOW_THREADS
    for (int i = 0; i < 6; i++)
        PyBuffer_Release(views[i]);
    Py_RETURN_NONE;
}

/* cubic_column(fp, mv, h6, h12, out): fp (n, 2m - 1), f_p at the m nodes then the m - 1
   midpoints; mv (m - 1, n, 1): J_mid,i (f_p,i+1 - f_p,i); h6, h12 (m - 1,) (any strides);
   into out (n, m - 1) the parameter's column
       dC_i/dp = (-h6 ((f_p,i + f_p,i+1) + 4 f_p,mid)) + h12 (J_mid (f_p,i+1 - f_p,i)),
   collocation.py's numpy formula operation for operation. */
static PyObject *cubic_column(PyObject *self, PyObject *args)
{
    PyObject *fp_obj, *mv_obj, *h6_obj, *h12_obj, *out_obj;
    if (!PyArg_ParseTuple(args, "OOOOO", &fp_obj, &mv_obj, &h6_obj, &h12_obj, &out_obj))
        return NULL;
    Py_buffer vf, vm, v6, v12, vo;
    idx sh_f[2] = {-1, -1};
    if (get_array(fp_obj, &vf, 2, sh_f, 0, "fp") < 0)
        return NULL;
    const idx n = sh_f[0], big = sh_f[1], m = (big + 1) / 2;
    if (n < 1 || big < 3 || big % 2 == 0) {
        PyErr_SetString(PyExc_ValueError, "fp: (n, 2m - 1) with m >= 2");
        PyBuffer_Release(&vf);
        return NULL;
    }
    idx sh_m[3] = {m - 1, n, 1}, sh_h[1] = {m - 1}, sh_o[2] = {n, m - 1};
    Py_buffer *views[5] = {&vf, &vm, &v6, &v12, &vo};
    int got = 1;
    if (get_array(mv_obj, &vm, 3, sh_m, 0, "mv") == 0 && ++got
        && get_array(h6_obj, &v6, 1, sh_h, 0, "h6") == 0 && ++got
        && get_array(h12_obj, &v12, 1, sh_h, 0, "h12") == 0 && ++got
        && get_array(out_obj, &vo, 2, sh_o, 1, "out") == 0)
        got = 5;
    if (got < 5) {
        for (int i = 0; i < got; i++)
            PyBuffer_Release(views[i]);
        return NULL;
    }
    const char *fb = (const char *)vf.buf, *mb = (const char *)vm.buf;
    double *out = (double *)vo.buf;
    Py_BEGIN_ALLOW_THREADS
    for (idx a = 0; a < n; a++)
        for (idx i = 0; i < m - 1; i++) {
            const double h6 = *(const double *)((const char *)v6.buf + i * v6.strides[0]);
            const double h12 = *(const double *)((const char *)v12.buf + i * v12.strides[0]);
            const char *row = fb + a * vf.strides[0];
            const double f0 = *(const double *)(row + i * vf.strides[1]),
                         f1 = *(const double *)(row + (i + 1) * vf.strides[1]),
                         fm = *(const double *)(row + (m + i) * vf.strides[1]),
                         jd = *(const double *)(mb + i * vm.strides[0] + a * vm.strides[1]);
            double sum = f0 + f1;
            sum += 4 * fm;
            out[a * (m - 1) + i] = (-h6 * sum) + h12 * jd;
        }
    Py_END_ALLOW_THREADS
    for (int i = 0; i < 5; i++)
        PyBuffer_Release(views[i]);
    Py_RETURN_NONE;
}

/* The negative eigenvalues of the symmetric n x n matrix a (row-major, both triangles held;
   overwritten) by its LDL^T factorisation with Bunch and Kaufman's diagonal pivoting (LAPACK's
   dsytf2, its lower form): 1 x 1 and 2 x 2 pivots D, a = P L D L^T P^T, whose negative
   eigenvalues are a's (Sylvester). -1 where a pivot is exactly zero (a singular a). Each
   step picks the pivot from the column's largest entry and its row's (alpha = (1 + sqrt 17)
   / 8 bounds the growth of the entries); a 2 x 2 pivot has one negative eigenvalue. */
static idx bk_negatives(double *a, idx n)
{
    const double alpha = (1.0 + sqrt(17.0)) / 8.0;
    idx negative = 0, k = 0;
    while (k < n) {
        const double absakk = fabs(a[k * n + k]);
        idx imax = k;
        double colmax = 0.0;
        for (idx i = k + 1; i < n; i++)
            if (fabs(a[i * n + k]) > colmax) {
                colmax = fabs(a[i * n + k]);
                imax = i;
            }
        if (absakk == 0.0 && colmax == 0.0)
            return -1;
        int two = 0;
        idx kp = k;
        if (absakk < alpha * colmax) {
            double rowmax = 0.0;
            for (idx j = k; j < n; j++)
                if (j != imax && fabs(a[imax * n + j]) > rowmax)
                    rowmax = fabs(a[imax * n + j]);
            if (absakk >= alpha * colmax * (colmax / rowmax))
                kp = k;
            else if (fabs(a[imax * n + imax]) >= alpha * rowmax)
                kp = imax;
            else {
                kp = imax;
                two = 1;
            }
        }
        const idx kk = k + two;           /* the row and column exchanged with kp */
        if (kp != kk) {
            for (idx j = 0; j < n; j++) {
                double t = a[kk * n + j];
                a[kk * n + j] = a[kp * n + j];
                a[kp * n + j] = t;
            }
            for (idx i = 0; i < n; i++) {
                double t = a[i * n + kk];
                a[i * n + kk] = a[i * n + kp];
                a[i * n + kp] = t;
            }
        }
        if (!two) {
            const double d = a[k * n + k];
            if (d == 0.0)
                return -1;
            if (d < 0.0)
                negative++;
            for (idx i = k + 1; i < n; i++) {   /* a_ij -= (a_ik / d) a_kj */
                const double l = a[i * n + k] / d;
                for (idx j = k + 1; j < n; j++)
                    a[i * n + j] -= l * a[k * n + j];
            }
            k += 1;
        }
        else {
            const double d11 = a[k * n + k], d21 = a[(k + 1) * n + k],
                         d22 = a[(k + 1) * n + k + 1];
            /* chosen only where |d11| < alpha |d21| |d21| / rowmax and |d22| < alpha rowmax:
               d11 d22 < alpha^2 d21^2 < d21^2, a negative determinant, one eigenvalue of
               each sign */
            const double det = d11 * d22 - d21 * d21;
            negative += 1;
            for (idx i = k + 2; i < n; i++) {   /* a_ij -= [a_ik, a_i,k+1] D^-1 [a_kj; a_k+1,j] */
                const double x = a[i * n + k], y = a[i * n + k + 1];
                const double w0 = (d22 * x - d21 * y) / det, w1 = (d11 * y - d21 * x) / det;
                for (idx j = k + 2; j < n; j++)
                    a[i * n + j] -= w0 * a[k * n + j] + w1 * a[(k + 1) * n + j];
            }
            k += 2;
        }
    }
    return negative;
}

/* window(m, tol) -> (below, above): n_-(m - tol I) and n_-(m + tol I) of the symmetric
   matrix m (n, n) (`bk_negatives`, -1 where one is singular): the numbers of its eigenvalues
   below tol and below -tol (Sylvester), so below - above of them lie in [-tol, tol).
   (-2, -2) where an entry of m is not finite (no comparison with NaN decides a pivot). */
static PyObject *window(PyObject *self, PyObject *args)
{
    PyObject *m_obj;
    double tol;
    if (!PyArg_ParseTuple(args, "Od", &m_obj, &tol))
        return NULL;
    Py_buffer vm;
    idx shape[2] = {-1, -1};
    if (get_array(m_obj, &vm, 2, shape, 0, "m") < 0)
        return NULL;
    const idx n = shape[0];
    if (shape[1] != n) {
        PyErr_SetString(PyExc_ValueError, "m: expected a square matrix");
        PyBuffer_Release(&vm);
        return NULL;
    }
    double *work = PyMem_Malloc(sizeof(double) * (size_t)(2 * n * n + 1));
    if (work == NULL) {
        PyBuffer_Release(&vm);
        return PyErr_NoMemory();
    }
    idx counts[2] = {-2, -2};
    int finite = 1;
    Py_BEGIN_ALLOW_THREADS
    for (idx i = 0; i < n; i++)
        for (idx j = 0; j < n; j++) {
            const double v = *(const double *)((const char *)vm.buf + i * vm.strides[0]
                                               + j * vm.strides[1]);
            finite &= isfinite(v) != 0;
            work[i * n + j] = v + (i == j ? -tol : 0.0);
            work[n * n + i * n + j] = v + (i == j ? tol : 0.0);
        }
    if (finite && isfinite(tol))
        for (int side = 0; side < 2; side++)
            counts[side] = bk_negatives(work + side * n * n, n);
    Py_END_ALLOW_THREADS
    PyMem_Free(work);
    PyBuffer_Release(&vm);
    return Py_BuildValue("(nn)", counts[0], counts[1]);
}

static PyMethodDef methods[] = {
    {"cubic_column", cubic_column, METH_VARARGS,
     "cubic_column(fp, mv, h6, h12, out): the cubic collocation's parameter column dC_i/dp "
     "into out (n, m - 1) from f_p (n, 2m - 1) and J_mid (f_p,i+1 - f_p,i) "
     "(collocation.Discretisation.blocks)."},
    {"cubic_gather", cubic_gather, METH_VARARGS,
     "cubic_gather(jac, jac_all, cat): f_y (n, n, 2m - 1) copied to contiguous blocks "
     "jac_all (2m - 1, n, n) and cat = [J_i, J_{i+1}] (m - 1, n, 2n) "
     "(collocation.Discretisation.blocks)."},
    {"cubic_blocks", cubic_blocks, METH_VARARGS,
     "cubic_blocks(jac_all, prod, h6, h12, d0, d1): the cubic collocation's blocks "
     "dC_i/dy_i, dC_i/dy_{i+1} into d0, d1 (m - 1, n, n) from f_y and the products "
     "J_mid [J_i, J_{i+1}] (collocation.Discretisation.blocks)."},
    {"condense", condense, METH_VARARGS,
     "condense(s, a, b, c, ulps, d, u, inv, y) -> (negative, scale): the P2 element matrices "
     "of the fields a, b, c (2N - 1, k, k) on the nodes s and their midpoints eliminated, "
     "the node matrix's blocks in d (N, k, k) and u (N - 1, k, k) (stability._inertia)."},
    {"rates", rates, METH_VARARGS,
     "rates(a, a_min, b, c, out): the refinement's wavenumber sqrt(|B - C^T A^-1 C| / a_min) "
     "+ |A^-1 C| at each point, k = 2 or 3 (stability.rates)."},
    {"window", window, METH_VARARGS,
     "window(m, tol) -> (below, above): the negative eigenvalues of m - tol I and m + tol I "
     "by LDL^T with Bunch-Kaufman pivoting, -1 where singular (stability._inertia's last "
     "nodes)."},
    {"reduce", reduce, METH_VARARGS,
     "reduce(d, u, f, scale, tail, total, size) -> (negative, n): the odd-even reduction "
     "of the block tridiagonal node matrix in place down to `tail` nodes or fewer "
     "(stability._inertia)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_blocks",
    "The direct count's element matrices, midpoint elimination and odd-even reduction for "
    "blocks of any size (numerics/stability.py), and the cubic collocation's Jacobian "
    "blocks (numerics/collocation.py).", -1, methods,
};

PyMODINIT_FUNC PyInit__blocks(void)
{
    return PyModule_Create(&module);
}
