"""Bordered collocation systems, factorised as banded matrices with partial pivoting.

Every linear system the engine solves has the form

    [ F_y  F_p ] [dy]   [r]          F_y: collocation and boundary rows (N = n m, block
    [ C    D   ] [dp] = [g]          bidiagonal, boundary rows coupling y_0 and y_{m-1}),

with k parameter columns ``F_p`` (dense: a parameter enters every interval) and k border rows
``C = (c_0, ..., c_{m-1})``, ``D`` (dense: an arclength condition, a normalisation, a test
function's gradient). F_y alone is singular exactly where the engine works hardest (folds and
branch points), so the border cannot be split off by block elimination; instead the whole
system is rewritten, exactly, as a banded one (the same idea as carrying parameters and
integrals as extra ODE states, here only in the linear algebra):

* each parameter is carried by a copy p_i per node, ``p_{i+1} - p_i = 0``;
* each border row by a running sum ``sigma_0 = c_0 y_0``, ``sigma_{i+1} = sigma_i +
  c_{i+1} y_{i+1}``, closed by ``sigma_{m-1} + D p = g``;
* a boundary condition that couples both ends (g_a and g_b rows both nonzero) likewise, by
  ``sigma_0 = g_a y_0`` carried unchanged to ``sigma_{m-1} + g_b y_{m-1} + g_p p = r``.

With unknowns ordered by node, ``z_i = (y_i, p_i, sigma_i)``, and rows ordered as the left
boundary conditions, the intervals, the right boundary conditions, the matrix is banded with
bandwidths of about twice the node block: LAPACK's banded LU (``dgbtf2``, written out in C in
``_banded.c``: at these bandwidths LAPACK's own spends most of its time in a BLAS call per
column) factorises it with partial pivoting in O(m) work, stably whether or not F_y is
singular. If ``M`` is the bordered
matrix and ``M'`` the banded one, ``M' T = E M`` (T expands (y, p) into z, E places the rows
of M among those of M'), so ``M^{-1} = P M'^{-1} E`` and ``M^{-T} = E^T M'^{-T} P^T`` with P
reading (y, p) out of z; ``det M' = +-det M`` with a sign fixed by the structure alone, so
sign changes of ``det M'`` along a branch, on one mesh, are sign changes of ``det M``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ._banded import lu as banded_lu, solve as banded_solve


def split_rows(ga, gb, tol=0.0):
    """Boundary rows by the end they involve: (left, right, mixed) index tuples. A row with
    neither (a condition on parameters alone) counts as left."""
    a = np.any(np.abs(ga) > tol, axis=1)
    b = np.any(np.abs(gb) > tol, axis=1)
    rows = np.arange(len(a))
    return (tuple(rows[~b].tolist()), tuple(rows[b & ~a].tolist()),
            tuple(rows[a & b].tolist()))


class Structure:
    """Where every entry of the banded form goes, for n states, m nodes, k parameter columns
    and as many border rows, and a split of the boundary rows."""

    def __init__(self, n: int, m: int, k: int, split):
        left, right, mixed = (np.asarray(r, dtype=int) for r in split)
        self.n, self.m, self.k = n, m, k
        self.left, self.right, self.mixed = left, right, mixed
        J = k + len(mixed)                      # running sums: border rows, then mixed rows
        nn = n + k + J                          # unknowns per node
        na, nb = len(left), len(right)
        L = na + J                              # rows before the first interval
        self.nn, self.J, self.L = nn, J, L
        self.N = m * nn
        i = np.arange(m - 1)[:, None, None]
        a = np.arange(n)[None, :, None]
        b = np.arange(n)[None, None, :]
        q = np.arange(k)[None, None, :]
        last = (m - 1) * nn                     # first unknown of the last node
        right_row = L + (m - 1) * nn            # first row after the intervals
        # (rows, cols) of each group of variable entries, in the order values are given
        groups = {
            "d0": (L + i * nn + a, i * nn + b),
            "d1": (L + i * nn + a, (i + 1) * nn + b),
            "pcol": (L + i * nn + a, i * nn + n + q),
            "acc": (L + i * nn + n + k + np.arange(k)[None, :, None], (i + 1) * nn + b),
            "left_y": (np.arange(na)[:, None], np.arange(n)[None, :]),
            "left_p": (np.arange(na)[:, None], n + np.arange(k)[None, :]),
            "init_y": (na + np.arange(J)[:, None], np.arange(n)[None, :]),
            "right_y": (right_row + np.arange(nb)[:, None], last + np.arange(n)[None, :]),
            "right_p": (right_row + np.arange(nb)[:, None], last + n + np.arange(k)[None, :]),
            "close_y": (right_row + nb + k + np.arange(len(mixed))[:, None],
                        last + np.arange(n)[None, :]),
            "close_p": (right_row + nb + np.arange(J)[:, None], last + n + np.arange(k)[None, :]),
        }
        groups = {g: np.broadcast_arrays(r, c) for g, (r, c) in groups.items()}
        # constant entries: +-1 of the parameter copies and the running sums
        ii = np.arange(m - 1)[:, None]
        qk, qJ = np.arange(k)[None, :], np.arange(J)[None, :]
        ones = [
            (L + ii * nn + n + qk, (ii + 1) * nn + n + qk, 1.0),
            (L + ii * nn + n + qk, ii * nn + n + qk, -1.0),
            (L + ii * nn + n + k + qJ, (ii + 1) * nn + n + k + qJ, 1.0),
            (L + ii * nn + n + k + qJ, ii * nn + n + k + qJ, -1.0),
            (na + qJ, n + k + qJ, 1.0),
            (right_row + nb + qJ, last + n + k + qJ, 1.0),
        ]
        all_r = np.concatenate([r.ravel() for r, _ in groups.values()]
                               + [np.broadcast_to(r, np.broadcast(r, c).shape).ravel()
                                  for r, c, _ in ones])
        all_c = np.concatenate([c.ravel() for _, c in groups.values()]
                               + [np.broadcast_to(c, np.broadcast(r, c).shape).ravel()
                                  for r, c, _ in ones])
        self.kl = int(max(np.max(all_r - all_c), 0))
        self.ku = int(max(np.max(all_c - all_r), 0))
        self.ldab = 2 * self.kl + self.ku + 1

        def flat(r, c):  # position in the (N, ldab) C-order array whose transpose LAPACK takes
            return (c * self.ldab + self.kl + self.ku + r - c).ravel()

        index = {g: flat(r, c) for g, (r, c) in groups.items()}
        # The interval blocks, most of the entries, lie on strided patterns of the band array:
        # an entry (r, c) is at c ldab + kv + r - c, so interval i's row L + i nn + a and
        # column i nn + b (d0) is at kv + L + i nn ldab + a + b (ldab - 1), and likewise for
        # the others. factor() writes them through views with these offsets and strides
        # (array copies) instead of scattering them through index arrays.
        ldab = self.ldab
        self.block_strides = (nn * ldab * 8, 8, (ldab - 1) * 8)
        self.block_views = {g: (int(index[g][0]), shape) for g, shape in (
            ("d0", (m - 1, n, n)), ("d1", (m - 1, n, n)), ("pcol", (m - 1, n, k)),
            ("acc", (m - 1, k, n))) if k or g in ("d0", "d1")}
        for g, (offset, shape) in self.block_views.items():     # the patterns, checked once
            pattern = (offset + np.arange(shape[0])[:, None, None] * nn * ldab
                       + np.arange(shape[1])[None, :, None]
                       + np.arange(shape[2])[None, None, :] * (ldab - 1))
            assert np.array_equal(pattern.ravel(), index[g]), g
        # the other variable entries (boundary rows, closures), in the order factor() lists
        # their values
        self.index_0 = np.concatenate([index[g] for g in (
            "left_y", "right_y", "init_y", "close_y")])
        self.index_k = np.concatenate([self.index_0] + [index[g] for g in (
            "left_p", "right_p", "close_p")])
        const = [(flat(*np.broadcast_arrays(r, c)), v) for r, c, v in ones]
        self.index_const = np.concatenate([f for f, _ in const])
        self.value_const = np.concatenate([np.full(len(f), v) for f, v in const])
        # rows of M' that hold the rows of M, and the unknowns of z that hold p (the
        # collocation rows of interval i are L + i nn + (0..n-1), node j's states
        # j nn + (0..n-1): `interval_rows`, `node_states`)
        self.row_left = np.arange(na)
        self.row_right = right_row + np.arange(nb)
        self.row_border = right_row + nb + np.arange(k)
        self.row_mixed = right_row + nb + k + np.arange(len(mixed))
        self.col_p = n + np.arange(k)

    def block_view(self, ab, group):
        """The entries of ``group`` (d0, d1: (m-1, n, n); pcol: (m-1, n, k); acc:
        (m-1, k, n)) as a writable view of the band array ab (N, ldab)."""
        offset, shape = self.block_views[group]
        return np.ndarray(shape, dtype=float, buffer=ab, offset=8 * offset,
                          strides=self.block_strides)

    def interval_rows(self, b):
        """The collocation rows of a banded-order vector b (N,), as a view (m-1, n): row i
        holds interval i's."""
        return b[self.L:self.L + (self.m - 1) * self.nn].reshape(self.m - 1, self.nn)[:, :self.n]

    def node_states(self, z):
        """The states (n, m) of a banded-order vector z (N,), a C-ordered copy."""
        return z.reshape(self.m, self.nn)[:, :self.n].T.copy()


#: The Sherman-Morrison update of :meth:`Factorization.solve_with_border` divides by
#: ``1 + <delta, u>``. Where that is not above UPDATE_RTOL times the size of the terms it is
#: summed from (``1 + sum |delta_i u_i|``), the division amplifies their rounding by more
#: than 1 / UPDATE_RTOL: half the digits or more are lost (the new border row makes the
#: matrix nearly singular, or differs from the factorised one by far more than the matrix
#: can absorb; a denominator of exactly 0 divided by zero). The update is then refused
#: (:class:`IllConditionedUpdate`) and the caller factorises the system with its new row,
#: whose LU with partial pivoting is stable whatever the border.
UPDATE_RTOL = 1e-8


class IllConditionedUpdate(ArithmeticError):
    """A border row exchanged by Sherman-Morrison whose update would lose most of its
    digits (UPDATE_RTOL): factorise the system with the new row instead."""


@lru_cache(maxsize=128)   # meshes change size as they adapt: keep many, each is small
def structure(n: int, m: int, k: int, split) -> Structure:
    return Structure(n, m, k, split)


class Factorization:
    """The LU factors of one bordered system; solves it, its transpose, and variants of it
    with another border row (Sherman-Morrison)."""

    def __init__(self, st: Structure, ab, piv, border=None):
        # ab (N, ldab): the factors by columns (`_banded.lu`); lu = ab.T is LAPACK's view of
        # them, (ldab, N), whose row kl + ku is U's diagonal
        self.st, self.ab, self.lu, self.piv = st, ab, ab.T, piv
        self.border = border                    # [(c (n, m), d (k,))] as factorised
        self._u = None

    @property
    def sign(self) -> int:
        """The sign of the determinant of the banded matrix (+-1, or 0 if singular)."""
        diag = self.lu[self.st.kl + self.st.ku]
        if not diag.all():
            return 0
        flips = np.count_nonzero(self.piv != np.arange(len(self.piv))) \
            + np.count_nonzero(diag < 0)
        return -1 if flips % 2 else 1

    @property
    def logdet(self) -> float:
        """log |det| (equal for the banded and the bordered matrix); -inf where a pivot is
        exactly zero (the matrix is singular: a branch point met exactly)."""
        with np.errstate(divide="ignore"):
            return float(np.sum(np.log(np.abs(self.lu[self.st.kl + self.st.ku]))))

    # -- natural-order vectors <-> banded-order vectors ---------------------------------------
    def _rhs(self, col, bc, border):
        st = self.st
        b = np.zeros(st.N)
        st.interval_rows(b)[...] = col.T
        bc = np.asarray(bc, dtype=float)
        b[st.row_left] = bc[st.left]
        b[st.row_right] = bc[st.right]
        b[st.row_mixed] = bc[st.mixed]
        b[st.row_border] = border
        return b

    def solve(self, col, bc, border=()):
        """(dy (n, m), dp (k,)) solving the system with right-hand side (col, bc, border)."""
        st = self.st
        z = self._rhs(col, bc, border)
        banded_solve(self.ab, st.kl, st.ku, self.piv, z, False)
        return st.node_states(z), z[st.col_p]

    def solve_transpose(self, ey, ep):
        """The solution w of ``M^T w = (ey, ep)``, as (w_col (n, m-1), w_bc (n,),
        w_border (k,)): the multipliers of the collocation, boundary and border rows."""
        st = self.st
        b = np.zeros(st.N)
        b.reshape(st.m, st.nn)[:, :st.n] = ey.T
        b[st.col_p] = ep
        banded_solve(self.ab, st.kl, st.ku, self.piv, b, True)
        w = b
        w_bc = np.empty(st.n)
        w_bc[st.left] = w[st.row_left]
        w_bc[st.right] = w[st.row_right]
        w_bc[st.mixed] = w[st.row_mixed]
        return st.interval_rows(w).T.copy(), w_bc, w[st.row_border]

    # -- another last border row ---------------------------------------------------------------
    def null_direction(self):
        """``u = M^{-1} e`` for e the last border row's unit vector: with one parameter
        column and a border row c, the (unnormalised) tangent with ``<c, u> = 1``."""
        if self._u is None:
            st = self.st
            e = np.zeros(st.k)
            e[-1] = 1.0
            self._u = self.solve(np.zeros((st.n, st.m - 1)), np.zeros(st.n), e)
        return self._u

    def solve_with_border(self, c, d, col, bc, border):
        """Solve the system whose last border row is ``(c, d)`` instead of the factorised one:
        ``(M + e (delta)^T)^{-1} b = x - u <delta, x> / (1 + <delta, u>)`` with
        ``x = M^{-1} b``, ``u = M^{-1} e``. :class:`IllConditionedUpdate` where the
        denominator is too small for that (UPDATE_RTOL)."""
        c0, d0 = self.border[-1]
        x_y, x_p = self.solve(col, bc, border)
        u_y, u_p = self.null_direction()
        dc, dd = c - c0, np.asarray(d, dtype=float) - d0

        def delta(vy, vp):
            return float((dc * vy).sum() + np.dot(dd, vp))

        denominator = 1.0 + delta(u_y, u_p)
        size = 1.0 + float(np.abs(dc * u_y).sum() + np.abs(dd * u_p).sum())
        if not abs(denominator) > UPDATE_RTOL * size:
            raise IllConditionedUpdate(f"border update denominator {denominator:.3g} of "
                                       f"terms of size {size:.3g}")
        scale = delta(x_y, x_p) / denominator
        return x_y - scale * u_y, x_p - scale * u_p


def factor(blocks, names, border=(), split=None) -> Factorization:
    """Factorise the bordered Jacobian: ``blocks`` (:class:`~numerics.collocation.Blocks`)
    with columns for the parameters ``names`` and ``len(names)`` border rows ``border`` =
    [(c (n, m), d (k,))]. ``split``: the boundary rows' (left, right, mixed), default from
    the blocks themselves."""
    d0 = blocks.d0
    m, n = d0.shape[0] + 1, d0.shape[1]
    k = len(names)
    if len(border) != k:
        raise ValueError(f"{k} parameter columns need {k} border rows, got {len(border)}")
    if split is None:
        split = split_rows(blocks.ga, blocks.gb)
    st = structure(n, m, k, split)
    ga, gb = blocks.ga, blocks.gb
    ab = np.zeros((st.N, st.ldab))
    flat = ab.reshape(-1)
    flat[st.index_const] = st.value_const
    st.block_view(ab, "d0")[...] = d0
    st.block_view(ab, "d1")[...] = blocks.d1
    values = [ga[st.left].ravel(), gb[st.right].ravel(),
              *(-c[:, 0] for c, _ in border), *(-ga[r] for r in st.mixed),
              gb[st.mixed].ravel()]
    if k:
        pcol, acc = st.block_view(ab, "pcol"), st.block_view(ab, "acc")
        for q, nm in enumerate(names):
            pcol[:, :, q] = blocks.dcol[nm].T
        for j, (c, _) in enumerate(border):
            np.negative(c[:, 1:].T, out=acc[:, j, :])
        gp = (blocks.dbc[names[0]][:, None] if k == 1          # (n, k)
              else np.stack([blocks.dbc[nm] for nm in names], axis=-1))
        values += [gp[st.left].ravel(), gp[st.right].ravel(),
                   *(np.asarray(d, dtype=float).reshape(k) for _, d in border),
                   *(gp[r] for r in st.mixed)]
    flat[st.index_k if k else st.index_0] = np.concatenate(values)
    piv = np.empty(st.N, dtype=np.intp)
    info = banded_lu(ab, st.kl, st.ku, piv)
    if info > 0:
        # exactly singular (a branch point hit exactly): a pivot of the size of rounding
        # keeps the solves finite, as inverse iteration for the kernel needs
        diag = ab[:, st.kl + st.ku]
        diag[info - 1] = np.finfo(float).eps * max(float(np.max(np.abs(diag))), 1.0)
    return Factorization(st, ab, piv, [(np.asarray(c), np.asarray(d, dtype=float))
                                      for c, d in border])
