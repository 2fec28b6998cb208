"""Gauss collocation (``ncol`` = k = 2..7): AUTO-07p's discretisation, with the interior
unknowns of every interval condensed so that the global system keeps one block row per node.

On the interval ``[s_i, s_i + h]`` the solution is the polynomial u of degree k with
``u(s_i) = y_i`` whose derivative equals f at the k Gauss-Legendre points
``s_i + tau_j h`` of the interval. Its unknowns are the stage values ``K_j = u(s_i + tau_j h)``
(n k per interval) besides the node values; with ``F_j = f(s_i + tau_j h, K_j; p)``,
``a_jl = int_0^tau_j l_l``, ``b_l = int_0^1 l_l`` (``l_l`` the Lagrange basis on the tau's),

    G_j = K_j - y_i - h sum_l a_jl F_l = 0             (stage equations, j = 1 .. k)
    C_i = y_{i+1} - y_i - h sum_l b_l F_l = 0          (one block row per interval)

-- the k-stage Gauss-Legendre Runge-Kutta method. The node values converge like h^(2k)
(superconvergence), u between them like h^(k+1).

Condensation. With ``J_j = f_y``, ``P_j = f_p`` at the stages, the Newton system of one
interval is ``G_K dK - E dy_i + G_p dp = r_G``, ``C_K dK - dy_i + dy_{i+1} + C_p dp = r_C`` with
``E = (I, ..., I)^T``, ``G_K = I - h (A x I) diag(J_j)``, ``G_p = -h (A x I) P``,
``C_K = -h (b^T x I) diag(J_j)``, ``C_p = -h sum_l b_l P_l``. Eliminating
``dK = G_K^{-1} (r_G + E dy_i - G_p dp)`` leaves, with ``W = C_K G_K^{-1}``,

    (W E - I) dy_i + dy_{i+1} + (C_p - W G_p) dp = r_C - W r_G,

blocks ``d0 = W E - I``, ``d1 = I``, ``dcol = C_p - W G_p`` of exactly the shape the Lobatto
scheme gives (:mod:`numerics.collocation`), so the bordered banded machinery is the same.
Newton carries the stage values as unknowns (:meth:`GaussBlocks.condense`,
:meth:`GaussBlocks.interior`); where only node values are known the stage equations are
solved on each interval for them, which makes the node residual ``C(Y)`` a function of the
node values alone whose Jacobian is the condensed one.

Error estimate (AUTO-07p's idea): u^(k) is constant on each interval,
``D_i = h^(1-k) sum_l F_l l_l^(k-1)``; differences of it between neighbouring intervals give
u^(k+1) at the nodes, and the error of the collocation polynomial inside an interval is
``e(tau) = h^(k+1) u^(k+1) / k! int_0^tau prod_j (t - tau_j) dt`` to leading order (the
residual ``u' - f(u)`` is f's interpolation error at the tau's), so the estimate per interval
is ``c_k h^(k+1) |u^(k+1)|`` with ``c_k = max_tau |int_0^tau prod_j (t - tau_j)| / k!``, relative
to ``1 + |y|`` per component and the Euclidean norm over components: an estimate of the
largest relative error of the solution between the nodes (the nodes themselves are far more
accurate). The mesh equidistributes ``|u^(k+1)|^(1/(k+1))``
(:func:`~elastica_auto.numerics.collocation.equidistributed_mesh` with ``order = k + 1``).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from .collocation import Blocks
from ..core.solution import at_fractions, trapezoid_weights

#: The stage equations solved for given node values: Newton until the correction is below
#: this (relative), at most STAGE_ITER iterations.
STAGE_TOL, STAGE_ITER = 1e-14, 12


@lru_cache(maxsize=8)
def tableau(k: int):
    """(tau (k,), A (k, k), b (k,), dk (k,), c_k): Gauss-Legendre points on [0, 1], the
    collocation (Runge-Kutta) coefficients, ``dk_l = l_l^(k-1)`` and the error constant."""
    x, w = np.polynomial.legendre.leggauss(k)
    tau, b = (x + 1) / 2, w / 2
    # the Lagrange basis l_l(t) = prod_{m != l} (t - tau_m) / (tau_l - tau_m) by its product
    # (the inverse of the Vandermonde matrix, cond ~1e5 at k = 7, gave the coefficients to
    # 1e-13 only, and how near depended on the BLAS kernel); a_jl = int_0^tau_j l_l by the
    # rule itself scaled to [0, tau_j] (exact: l_l has degree k - 1)
    gaps = tau[:, None] - tau[None, :]
    np.fill_diagonal(gaps, 1.0)
    denominators = np.prod(gaps, axis=1)             # prod_{m != l} (tau_l - tau_m)

    def basis(t):             # l_l(t), shape (len(t), k)
        d = np.asarray(t, dtype=float)[:, None] - tau[None, :]
        return np.stack([np.prod(np.delete(d, j, axis=1), axis=1) for j in range(k)],
                        axis=1) / denominators

    A = np.array([tj * (b @ basis(tj * tau)) for tj in tau])
    dk = math.factorial(k - 1) / denominators
    # c_k: the largest |int_0^tau prod (t - tau_j) dt| on [0, 1], on a fine grid
    t = np.linspace(0.0, 1.0, 2001)
    prod = np.polynomial.polynomial.polyfromroots(tau)
    c = float(np.max(np.abs(np.polynomial.polynomial.polyval(
        t, np.polynomial.polynomial.polyint(prod))))) / math.factorial(k)
    return tau, A, b, dk, c


class GaussEvaluation:
    """The Gauss collocation equations at (y, K, p): node residuals ``col`` (n, m-1), stage
    residuals ``stage`` (n, k, m-1), boundary residuals ``bc``; ``F`` = f at the stages;
    ``f`` (f at the nodes, for the solution's slopes) is computed when first asked for."""

    def __init__(self, disc, y, K, F, col, stage, bc, p):
        self.disc, self.y, self.K, self.F = disc, y, K, F
        self.col, self.stage, self.bc, self.p = col, stage, bc, p
        self._f = None

    @property
    def f(self):
        if self._f is None:
            self._f = self.disc.problem.rhs(self.disc.s, self.y, self.p)
        return self._f


class GaussBlocks(Blocks):
    """:class:`~elastica_auto.numerics.collocation.Blocks` of the condensed system, with what the
    condensation needs: ``ginv`` (m-1, nk, nk) = G_K^{-1}, ``w`` (m-1, n, nk) = W and
    ``gp[name]`` (m-1, nk) = G_p; ``stage_jac`` (m-1, k, n, n) = f_y at the stages (set by
    :meth:`GaussDiscretisation.blocks`)."""

    def condense(self, ev: GaussEvaluation):
        """The condensed node residual ``r_C - W r_G`` (n, m-1)."""
        rg = _stacked(ev.stage)
        return ev.col - _matvec(self.w, rg).T

    def interior(self, ev: GaussEvaluation, dY, dp, name):
        """The stage correction ``G_K^{-1} (r_G + E dy_i - G_p dp)`` (n, k, m-1) that goes
        with the node correction dY and parameter correction dp."""
        rg = _stacked(ev.stage)
        k = rg.shape[1] // dY.shape[0]
        rhs = rg + np.tile(dY[:, :-1].T, (1, k))
        if dp:
            rhs = rhs - dp * self.gp[name]
        dK = _matvec(self.ginv, rhs)
        return _unstacked(dK, dY.shape[0], k)


def _matvec(a, x):
    """Batched matrix-vector products: a (..., p, q), x (..., q) -> (..., p)."""
    return np.matmul(a, x[..., None])[..., 0]


def _stacked(a):
    """(n, k, m-1) -> (m-1, k n), stage-major within an interval."""
    return a.transpose(2, 1, 0).reshape(a.shape[2], -1)


def _unstacked(a, n, k):
    """(m-1, k n) -> (n, k, m-1)."""
    return a.reshape(a.shape[0], k, n).transpose(2, 1, 0)


class GaussDiscretisation:
    """The Gauss collocation equations of ``problem`` with ``ncol`` points per interval on
    the mesh ``s`` (the interface of :class:`~numerics.collocation.Discretisation`)."""

    def __init__(self, problem, s, ncol: int):
        self.problem = problem
        self.s = np.asarray(s, dtype=float)
        if self.s.ndim != 1 or len(self.s) < 2 or np.any(np.diff(self.s) <= 0):
            raise ValueError("a mesh needs at least 2 strictly increasing nodes")
        self.ncol = k = int(ncol)
        self.n, self.m = problem.n, len(self.s)
        self.h = np.diff(self.s)
        self.tau, self.A, self.b, self.dk, self.c_err = tableau(k)
        self.s_stage = (self.s[:-1] + np.multiply.outer(self.tau, self.h)).ravel()
        self.weights = trapezoid_weights(self.s)
        self.order = k + 1     # the error estimate scales like h^order
        n = self.n
        # G_K = I - h (A x I) diag(J): the (j, l) block is -h a_jl J_l
        # -h a_jl and -h b_l, broadcast for the blocks (m-1, k, 1, k, 1) and (m-1, 1, k, 1)
        self._hA = -(self.h[:, None, None, None, None] * self.A[None, :, None, :, None])
        self._hb = -(self.h[:, None, None, None] * self.b[None, None, :, None])
        self._eye = np.eye(k * n)

    # -- the equations ------------------------------------------------------------------------
    def stages(self, y, p):
        """Initial stage values from node values: the cubic Hermite interpolant of (y, f(y))."""
        return at_fractions(self.s, y, self.problem.rhs(self.s, y, p), self.tau)

    def _rhs_stages(self, K, p):
        n, k = self.n, self.ncol
        return self.problem.rhs(self.s_stage, K.reshape(n, -1), p).reshape(n, k, -1)

    def _times_A(self, F):
        """``h sum_l a_jl F_l`` for stage values (n, k, m-1)."""
        return np.matmul(self.A, F) * self.h

    def _times_b(self, F):
        """``h sum_l b_l F_l``: (n, m-1)."""
        return (self.b @ F) * self.h

    def _residuals(self, y, K, F):
        stage = K - y[:, None, :-1] - self._times_A(F)
        col = y[:, 1:] - y[:, :-1] - self._times_b(F)
        return col, stage

    def evaluate(self, y, p, interior=None) -> GaussEvaluation:
        """Residuals at node values y and stage values ``interior`` (n, k, m-1); without
        them, the stage equations are solved for the given node values first."""
        if interior is None:
            K = self.solve_stages(y, p)
        else:
            K = interior
        F = self._rhs_stages(K, p)
        col, stage = self._residuals(y, K, F)
        return GaussEvaluation(self, y, K, F, col, stage,
                               self.problem.bc(y[:, 0], y[:, -1], p), p)

    def _stage_matrix(self, K, p):
        """(J at the stages (m-1, k, n, n), G_K (m-1, kn, kn))."""
        n, k = self.n, self.ncol
        J = self.problem.rhs_jac(self.s_stage, K.reshape(n, -1), p).reshape(n, n, k, -1)
        J = J.transpose(3, 2, 0, 1)                                       # (m-1, k, n, n)
        G = (self._hA * J.transpose(0, 2, 1, 3)[:, None]).reshape(len(self.h), k * n, k * n)
        G += self._eye
        return J, G

    def solve_stages(self, y, p):
        """The stage values for node values y: Newton on the stage equations of each
        interval (from the Hermite interpolant), vectorised over the intervals."""
        n, k = self.n, self.ncol
        K = self.stages(y, p)
        with np.errstate(over="ignore", invalid="ignore"):
            for _ in range(STAGE_ITER):
                F = self._rhs_stages(K, p)
                _, stage = self._residuals(y, K, F)
                _, G = self._stage_matrix(K, p)
                try:
                    dK = np.linalg.solve(G, _stacked(stage)[..., None])[..., 0]
                except np.linalg.LinAlgError:
                    break
                dK = _unstacked(dK, n, k)
                K = K - dK
                if not np.all(np.abs(dK) <= STAGE_TOL * (1 + np.abs(K))):
                    continue
                break
        return K

    def blocks(self, ev: GaussEvaluation, p, names=()) -> GaussBlocks:
        """The condensed Jacobian at the evaluated point, with columns for ``names``."""
        problem, n, k = self.problem, self.n, self.ncol
        mi = len(self.h)
        J, G = self._stage_matrix(ev.K, p)
        ginv = np.linalg.inv(G)
        # C_K = -h (b^T x I) diag(J): the l-th block -h b_l J_l
        CK = (self._hb * J.transpose(0, 2, 1, 3)).reshape(mi, n, k * n)
        w = CK @ ginv
        d0 = w.reshape(mi, n, k, n).sum(axis=2) - np.eye(n)
        d1 = np.broadcast_to(np.eye(n), (mi, n, n))
        jac = problem.rhs_jac(self.s, ev.y, p).transpose(2, 0, 1)
        ga, gb = problem.bc_jac(ev.y[:, 0], ev.y[:, -1], p)
        dcol, dbc, fps, gps = {}, {}, {}, {}
        for name in names:
            P = problem.rhs_dp(self.s_stage, ev.K.reshape(n, -1), p, name).reshape(n, k, -1)
            gp = _stacked(-self._times_A(P))                                 # (m-1, kn)
            cp = -self._times_b(P)                                            # (n, m-1)
            dcol[name] = cp - _matvec(w, gp).T
            dbc[name] = problem.bc_dp(ev.y[:, 0], ev.y[:, -1], p, name)
            fps[name] = problem.rhs_dp(self.s, ev.y, p, name)
            gps[name] = gp
        out = GaussBlocks(d0, d1, np.asarray(ga, dtype=float), np.asarray(gb, dtype=float),
                          dcol, dbc, jac, fps)
        out.ginv, out.w, out.gp = ginv, w, gps
        out.stage_jac = J
        return out

    # -- error estimate -----------------------------------------------------------------------
    def _estimate(self, slopes, y, scale=None):
        """``c_k h^(k+1) |u^(k+1)|`` per interval from the stage slopes (n, k, m-1) of a
        collocation polynomial, relative to ``1 + |y|`` (or ``scale + |y|``)."""
        k, h = self.ncol, self.h
        D = (self.dk @ slopes) / h ** (k - 1)                             # u^(k), (n, m-1)
        if D.shape[1] < 2:
            return np.zeros(D.shape[1])
        node = np.abs(np.diff(D, axis=1)) / (0.5 * (h[1:] + h[:-1]))      # (n, m-2)
        both = np.concatenate((node[:, :1], node, node[:, -1:]), axis=1)  # (n, m)
        d = np.maximum(both[:, :-1], both[:, 1:])
        ref = np.maximum(np.abs(y[:, :-1]), np.abs(y[:, 1:]))
        rel = self.c_err * h ** (k + 1) * d / ((1.0 if scale is None else scale) + ref)
        return np.sqrt(np.sum(rel * rel, axis=0))

    def rms_residuals(self, y, yp, p, ev: GaussEvaluation | None = None):
        """The error estimate per interval (m-1,) (the module docstring); ``yp`` unused
        (the stage slopes of ``ev``, or of the stages solved for y, carry the polynomial)."""
        if ev is None:
            ev = self.evaluate(y, p)
        return self._estimate(ev.F, y)

    def linear_rms_residuals(self, y, p, v, v_lam=0.0, name=None):
        """The same estimate for the collocation solution v of the linearised equation
        ``v' = f_y v + f_p v_lam`` with node values v (y a solution): its stage values from
        the linearised stage equations ``G_K V = E v_i - G_p v_lam``."""
        n, k = self.n, self.ncol
        ev = self.evaluate(y, p)
        blocks = self.blocks(ev, p, (name,) if (v_lam and name is not None) else ())
        rhs = np.tile(v[:, :-1].T, (1, k))
        if v_lam and name is not None:
            rhs = rhs - v_lam * blocks.gp[name]
        V = _unstacked(_matvec(blocks.ginv, rhs), n, k)
        slopes = _matvec(blocks.stage_jac, V.transpose(2, 1, 0)).transpose(2, 1, 0)
        if v_lam and name is not None:
            P = self.problem.rhs_dp(self.s_stage, ev.K.reshape(n, -1), p, name)
            slopes = slopes + v_lam * P.reshape(n, k, -1)
        return self._estimate(slopes, v, max(1.0, float(np.max(np.abs(v)))))
