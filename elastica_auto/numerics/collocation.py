"""The discretised boundary value problem: collocation equations, Jacobian blocks, error
estimate, and the choice of mesh.

The discretisation is the one ``scipy.integrate.solve_bvp`` uses (4th-order Lobatto IIIA
collocation; Kierzenka and Shampine, ACM TOMS 27, 2001). On the mesh
``0 = s_0 < ... < s_{m-1} = 1`` (``h_i = s_{i+1} - s_i``) the unknowns are the node values
``y_i``; with ``f_i = f(s_i, y_i; p)`` the solution is the C1 cubic with values ``y_i`` and
slopes ``f_i``, and the equations are

    C_i = y_{i+1} - y_i - h_i/6 (f_i + 4 f(s_i + h_i/2, y_mid,i) + f_{i+1}) = 0,
    y_mid,i = (y_i + y_{i+1})/2 - h_i/8 (f_{i+1} - f_i)          (i = 0 .. m-2)

(the cubic's slope equals f at the interval's midpoint) and the n boundary conditions
``g(y_0, y_{m-1}; p) = 0``. Their Jacobian is block bidiagonal, with

    dC_i/dy_i     = -I - h/6 (J_i + 2 J_mid) - h^2/12 J_mid J_i,
    dC_i/dy_{i+1} =  I - h/6 (J_{i+1} + 2 J_mid) + h^2/12 J_mid J_{i+1},
    dC_i/dp       = -h/6 (f_p,i + 4 f_p,mid + f_p,i+1) + h^2/12 J_mid (f_p,i+1 - f_p,i),

``J = f_y``, ``f_p = df/dp`` evaluated by the equation module once over the whole mesh.

Error control is solve_bvp's, so that ``tol`` means the same for both correctors: the
relative residual ``r = (S' - f(S)) / (1 + |f(S)|)`` of the cubic S, integrated over each
interval by 5-point Lobatto quadrature (it vanishes at the nodes and, once the collocation
equations hold, at the midpoint), gives an rms value per interval. The residual of a
4th-order method scales like h^3, so :func:`equidistributed_mesh` places nodes where the
density ``rms_i^(1/3) / h_i`` equidistributes and chooses their number to meet a target.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.solution import at_fractions, trapezoid_weights
from ._blocks import cubic_blocks, cubic_column, cubic_gather

#: Lobatto points inside an interval other than its midpoint, as fractions of its length.
_LOBATTO = (0.5 - 0.5 * np.sqrt(3.0 / 7.0), 0.5 + 0.5 * np.sqrt(3.0 / 7.0))


@dataclass
class Evaluation:
    """The collocation equations at (y, p): residuals and what their Jacobian reuses."""

    y: np.ndarray          # (n, m) node values
    f: np.ndarray          # (n, m) right-hand side at the nodes
    y_mid: np.ndarray      # (n, m-1)
    f_mid: np.ndarray      # (n, m-1)
    col: np.ndarray        # (n, m-1) collocation residuals C_i
    bc: np.ndarray         # (n,) boundary residuals
    K = None               # no interior unknowns (Gauss collocation has them)


@dataclass
class Blocks:
    """The Jacobian of the collocation equations and boundary conditions at one point.

    ``d0[i]``, ``d1[i]``: dC_i/dy_i and dC_i/dy_{i+1}, shape (m-1, n, n); ``ga``, ``gb``:
    dg/dy_0 and dg/dy_{m-1}; ``dcol[name]`` (n, m-1) and ``dbc[name]`` (n,): derivatives in
    the parameters asked for."""

    d0: np.ndarray
    d1: np.ndarray
    ga: np.ndarray
    gb: np.ndarray
    dcol: dict
    dbc: dict
    jac: np.ndarray        # (m, n, n) f_y at the nodes
    fp: dict               # name -> (n, m) f_p at the nodes

    def condense(self, ev: Evaluation):
        """The node residual the banded system is solved for: ``col`` itself (no interior
        unknowns to condense; :class:`~elastica_auto.numerics.gauss.GaussBlocks` has them)."""
        return ev.col

    def interior(self, ev, dY, dp, name):
        """The correction of the interior unknowns: none."""
        return None

    def slopes(self, v, v_lam=0.0, name=None):
        """Node slopes ``f_y v + f_p v_lam`` of a solution v of the linearised equation."""
        out = np.einsum("iab,bi->ai", self.jac, v)
        if name is not None and v_lam:
            out = out + v_lam * self.fp[name]
        return out

    def transpose_times(self, w_col, w_bc):
        """``F_y^T w`` for w = (w_col (n, m-1), w_bc (n,)): shape (n, m)."""
        n, m = w_col.shape[0], w_col.shape[1] + 1
        out = np.zeros((n, m))
        out[:, :-1] += np.einsum("iab,ai->bi", self.d0, w_col)
        out[:, 1:] += np.einsum("iab,ai->bi", self.d1, w_col)
        out[:, 0] += self.ga.T @ w_bc
        out[:, -1] += self.gb.T @ w_bc
        return out

    def times(self, v):
        """``F_y v`` for node values v (n, m): (collocation part (n, m-1), boundary part (n,))."""
        col = (np.einsum("iab,bi->ai", self.d0, v[:, :-1])
               + np.einsum("iab,bi->ai", self.d1, v[:, 1:]))
        return col, self.ga @ v[:, 0] + self.gb @ v[:, -1]


class Discretisation:
    """The collocation equations of ``problem`` on the mesh ``s``."""

    def __init__(self, problem, s):
        self.problem = problem
        self.s = np.asarray(s, dtype=float)
        if self.s.ndim != 1 or len(self.s) < 2 or np.any(np.diff(self.s) <= 0):
            raise ValueError("a mesh needs at least 2 strictly increasing nodes")
        self.n, self.m = problem.n, len(self.s)
        self.h = np.diff(self.s)
        self.s_mid = self.s[:-1] + self.h / 2
        self.s_all = np.concatenate((self.s, self.s_mid))
        self._h6, self._h8, self._h12 = self.h / 6, self.h / 8, self.h * self.h / 12
        self.x_lobatto = (self.s[:-1] + np.multiply.outer(_LOBATTO, self.h)).ravel()
        self.weights = trapezoid_weights(self.s)

    #: the residual estimate scales like h^order (equidistributed_mesh)
    order = 3

    def stages(self, y, p):
        """Initial interior unknowns for node values y: there are none."""
        return None

    def evaluate(self, y, p, interior=None) -> Evaluation:
        """Residuals of the collocation equations and boundary conditions at (y, p)
        (``interior``: for the interface of Gauss collocation; there is none)."""
        problem = self.problem
        f = problem.rhs(self.s, y, p)
        y_mid = y[:, 1:] + y[:, :-1]
        y_mid *= 0.5
        y_mid -= self._h8 * (f[:, 1:] - f[:, :-1])
        f_mid = problem.rhs(self.s_mid, y_mid, p)
        simpson = f[:, :-1] + f[:, 1:]
        simpson += 4 * f_mid
        simpson *= self._h6
        col = y[:, 1:] - y[:, :-1]
        col -= simpson
        return Evaluation(y, f, y_mid, f_mid, col, problem.bc(y[:, 0], y[:, -1], p))

    def blocks(self, ev: Evaluation, p, names=()) -> Blocks:
        """The Jacobian at the evaluated point, with columns for the parameters ``names``.

        The blocks are the formulas of the module docstring, evaluated left to right:
        ``d0 = ((-I - h/6 J_i) - (2 h/6) J_mid) - h^2/12 (J_mid J_i)`` and
        ``d1 = ((I - h/6 J_{i+1}) - (2 h/6) J_mid) + h^2/12 (J_mid J_{i+1})``, and a
        parameter's column ``(-h/6 ((f_p,i + f_p,i+1) + 4 f_p,mid)) + h^2/12 (J_mid (f_p,i+1 -
        f_p,i))``. Their element-wise part is compiled (numerics/_blocks.c ``cubic_gather``,
        ``cubic_blocks``, ``cubic_column``): on 100 intervals of small blocks a dozen numpy
        passes, each with its temporary, cost more than their arithmetic (about half of this
        call for 13 x 13 blocks). The loops do the same IEEE operations in the same order, so
        the results are the same bits as those numpy formulas'. The products with ``J_mid``
        stay numpy's batched matmul: BLAS rounds their sums its own way, kernel by kernel
        (OPENBLAS_CORETYPE), which a loop summing in index order would not reproduce."""
        problem, m, n = self.problem, self.m, self.n
        y_all = np.concatenate((ev.y, ev.y_mid), axis=1)
        # f_y (n, n, 2m - 1) copied to contiguous (point, row, column) blocks, the products'
        # operands: the blocks at the nodes and midpoints, and [J_i, J_{i+1}] side by side
        jac_all = np.empty((2 * m - 1, n, n))
        cat = np.empty((m - 1, n, 2 * n))
        cubic_gather(np.asarray(problem.rhs_jac(self.s_all, y_all, p), dtype=float),
                             jac_all, cat)
        jac, jac_mid = jac_all[:m], jac_all[m:]
        # J_mid J_i and J_mid J_{i+1} in one batched product
        prod = jac_mid @ cat
        d0, d1 = np.empty((m - 1, n, n)), np.empty((m - 1, n, n))
        cubic_blocks(jac_all, prod, self._h6, self._h12, d0, d1)
        ga, gb = problem.bc_jac(ev.y[:, 0], ev.y[:, -1], p)
        dcol, dbc, fps = {}, {}, {}
        for name in names:
            fp_all = np.asarray(problem.rhs_dp(self.s_all, y_all, p, name), dtype=float)
            fp = fps[name] = fp_all[:, :m]
            # J_mid (f_p,i+1 - f_p,i), numpy's batched product as for the blocks
            mv = jac_mid @ (fp[:, 1:] - fp[:, :-1]).T[:, :, None]
            dcol[name] = np.empty((n, m - 1))
            cubic_column(fp_all, mv, self._h6, self._h12, dcol[name])
            dbc[name] = problem.bc_dp(ev.y[:, 0], ev.y[:, -1], p, name)
        return Blocks(d0, d1, np.asarray(ga, dtype=float), np.asarray(gb, dtype=float),
                      dcol, dbc, jac, fps)

    def rms_residuals(self, y, yp, p, ev: Evaluation | None = None):
        """solve_bvp's error estimate: the rms relative residual on each interval (m-1,).

        ``yp`` are the slopes at the nodes (f there for a solution); the midpoint term uses
        the collocation residual of ``ev`` if given (zero for a converged solution)."""
        sy, dy = at_fractions(self.s, y, yp, _LOBATTO, derivative=True)
        f = self.problem.rhs(self.x_lobatto, sy.reshape(self.n, -1), p).reshape(sy.shape)
        total = 49 / 90 * (((dy - f) / (1 + np.abs(f))) ** 2).sum(axis=(0, 1))
        if ev is not None:
            mid = 1.5 * ev.col / self.h / (1 + np.abs(ev.f_mid))
            total = total + 32 / 45 * (mid * mid).sum(axis=0)
        return np.sqrt(0.5 * total)

    def linear_rms_residuals(self, y, p, v, v_lam=0.0, name=None):
        """The same estimate for a solution v of the linearised equation
        ``v' = f_y(s, y) v + f_p v_lam`` (a tangent or null vector; y a solution), whose
        node slopes are that right-hand side: it measures how well the mesh resolves v."""
        problem = self.problem

        def lin(x, yx, vx):
            out = np.einsum("abk,bk->ak", problem.rhs_jac(x, yx, p), vx)
            if v_lam and name is not None:
                out = out + v_lam * problem.rhs_dp(x, yx, p, name)
            return out

        n = self.n
        f = problem.rhs(self.s, y, p)
        vp = lin(self.s, y, v)
        yx = at_fractions(self.s, y, f, _LOBATTO).reshape(n, -1)
        sv, dv = at_fractions(self.s, v, vp, _LOBATTO, derivative=True)
        g = lin(self.x_lobatto, yx, sv.reshape(n, -1)).reshape(sv.shape)
        scale = max(1.0, float(np.max(np.abs(v))))
        return np.sqrt(0.5 * 49 / 90 * (((dv - g) / (scale + np.abs(g))) ** 2).sum(axis=(0, 1)))


def equidistributed_mesh(s, rms, target: float, min_intervals: int, max_intervals: int,
                         order: int = 3):
    """A new mesh on which the error estimates ``rms`` (per interval of ``s``) are predicted
    to be about ``target``.

    The estimate on an interval of length h scales like (rho h)^order with a local density
    rho (order 3 for the residual of the cubic scheme, k + 1 for Gauss collocation at k
    points); rho_i = rms_i^(1/order) / h_i is estimated per interval (smoothed over
    neighbours and bounded below by a tenth of its mean, so that a locally exact polynomial
    does not empty a region), and the new nodes equidistribute it:
    ``N = sum(rho_i h_i) / target^(1/order)`` intervals, clipped to [min_intervals,
    max_intervals] (AUTO-07p's adaptive mesh idea)."""
    s = np.asarray(s, dtype=float)
    h = np.diff(s)
    def root(x):
        return np.cbrt(x) if order == 3 else np.asarray(x, dtype=float) ** (1.0 / order)

    rho = root(np.asarray(rms, dtype=float)) / h
    if len(rho) > 2:
        rho = np.maximum(rho, np.maximum(np.r_[rho[1:], 0.0], np.r_[0.0, rho[:-1]]))
    total = float(np.sum(rho * h))
    # a multiple of 8 intervals: a few more nodes, and far fewer distinct mesh sizes (the
    # banded solver's index maps are made once per size)
    count = 8 * int(np.ceil(1.1 * total / root(target) / 8))
    count = int(np.clip(count, min_intervals, max_intervals))
    rho = np.maximum(rho, 0.1 * total / (s[-1] - s[0]) if total > 0 else 1.0)
    phi = np.concatenate(([0.0], np.cumsum(rho * h)))
    new = np.interp(np.linspace(0.0, phi[-1], count + 1), phi, s)
    new[0], new[-1] = s[0], s[-1]
    return new
