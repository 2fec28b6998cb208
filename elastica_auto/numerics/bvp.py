"""The solve_bvp corrector (``corrector = "solve_bvp"``): the same BVPs handed to
`scipy.integrate.solve_bvp`, kept as an independent second corrector to check the collocation
corrector against (the discretisation is the same; mesh refinement, the Newton method and the
fold's extended system are scipy's).

All of them are the module's BVP ``y' = f(s, y; p)``, ``g(y(0), y(1); p) = 0`` (n states,
n conditions), augmented so that the continued parameter ``lam = p[name]`` is a solve_bvp
unknown parameter:

* :func:`solve_fixed` -- the BVP at fixed parameters;
* :func:`solve_arclength` -- Keller's pseudo-arclength system: the BVP plus
  ``int_0^1 (y - y0).ydot0 ds + (lam - lam0) lamdot0 = ds``, the integral carried by an extra
  state ``z' = (y - y0).ydot0``, ``z(0) = 0`` (solve_bvp's boundary conditions see end values
  only);
* :func:`solve_fold` -- the fold (LP) extended system: the BVP, its null vector
  ``phi' = f_y phi`` with homogeneous linearised boundary conditions and ``int |phi|^2 ds = 1``
  (carried by ``w' = |phi|^2``, ``w(0) = 0, w(1) = 1``), with lam free.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_bvp

from ..model.problem import Problem
from ..core.solution import Curve, State, Tangent, trapezoid_weights


def bc_tol(tol: float) -> float:
    """Tolerance on boundary residuals: solve_bvp's default (= tol) would leave the boundary
    conditions, e.g. the free-end moment balance, satisfied only to ~tol; Newton converges
    quadratically, so a tighter one costs at most one more iteration."""
    return tol * 1e-4


@dataclass
class SolveResult:
    """Outcome of one solve_bvp call: ``state`` is None unless ``success``."""

    success: bool
    state: State | None
    niter: int
    residual: float
    message: str
    extra: dict = field(default_factory=dict)


def _result(sol, params, n, bc_residual):
    residual = float(max(np.max(sol.rms_residuals), np.max(np.abs(bc_residual))))
    state = None
    if sol.success:
        state = State(sol.x, sol.y[:n], sol.yp[:n], params)
    return SolveResult(bool(sol.success), state, int(sol.niter), residual, sol.message,
                       {"rms_residuals": sol.rms_residuals})


def solve_fixed(problem: Problem, guess: Curve, params: dict, tol: float,
                max_nodes: int) -> SolveResult:
    """Solve the BVP at the fixed parameter values ``params`` from the initial guess."""
    def fun(s, y):
        return problem.rhs(s, y, params)

    def bc(ya, yb):
        return problem.bc(ya, yb, params)

    def fun_jac(s, y):
        return problem.rhs_jac(s, y, params)

    def bc_jac(ya, yb):
        return problem.bc_jac(ya, yb, params)

    sol = solve_bvp(fun, bc, guess.s, guess(guess.s), fun_jac=fun_jac, bc_jac=bc_jac, tol=tol,
                    bc_tol=bc_tol(tol), max_nodes=max_nodes)
    res = bc(sol.y[:, 0], sol.y[:, -1])
    return _result(sol, params, problem.n, res)


def solve_arclength(problem: Problem, base: State, tangent: Tangent, name: str, ds: float,
                    tol: float, max_nodes: int, mesh=None,
                    predictor: Tangent | None = None) -> SolveResult:
    """One Keller pseudo-arclength corrector solve from ``base`` along ``tangent``.

    Unknowns: y(s) and lam = p[name]. Equations: the BVP and the arclength condition
    ``int (y - y0).ydot0 ds + (lam - lam0) lamdot0 = ds``. The initial guess is the Euler
    predictor ``(y0 + ds ydot0, lam0 + ds lamdot0)`` on ``mesh`` (default: the base mesh), or
    ``base + ds predictor`` where a ``predictor`` direction is given (the stepper's, which
    includes the curve's curvature).
    """
    n = problem.n
    fixed = base.params
    lam0 = fixed[name]

    def prm(p):
        return {**fixed, name: p[0]}

    def fun(s, Y, p):
        q = prm(p)
        y = Y[:n]
        dz = np.sum((y - base(s)) * tangent(s), axis=0)
        return np.vstack((problem.rhs(s, y, q), dz))

    def fun_jac(s, Y, p):
        q = prm(p)
        y = Y[:n]
        m = len(s)
        dfdy = np.zeros((n + 1, n + 1, m))
        dfdy[:n, :n] = problem.rhs_jac(s, y, q)
        dfdy[n, :n] = tangent(s)
        dfdp = np.zeros((n + 1, 1, m))
        dfdp[:n, 0] = problem.rhs_dp(s, y, q, name)
        return dfdy, dfdp

    def bc(Ya, Yb, p):
        q = prm(p)
        return np.concatenate((problem.bc(Ya[:n], Yb[:n], q),
                               (Ya[n], Yb[n] + (p[0] - lam0) * tangent.lam - ds)))

    def bc_jac(Ya, Yb, p):
        q = prm(p)
        da, db = problem.bc_jac(Ya[:n], Yb[:n], q)
        dya = np.zeros((n + 2, n + 1))
        dyb = np.zeros((n + 2, n + 1))
        dp = np.zeros((n + 2, 1))
        dya[:n, :n] = da
        dyb[:n, :n] = db
        dya[n, n] = 1.0
        dyb[n + 1, n] = 1.0
        dp[:n, 0] = problem.bc_dp(Ya[:n], Yb[:n], q, name)
        dp[n + 1, 0] = tangent.lam
        return dya, dyb, dp

    s = base.s if mesh is None else np.asarray(mesh, dtype=float)
    guess = tangent if predictor is None else predictor
    y_guess = base(s) + ds * guess(s)
    z_guess = np.zeros((1, len(s)))
    sol = solve_bvp(fun, bc, s, np.vstack((y_guess, z_guess)), p=[lam0 + ds * guess.lam],
                    fun_jac=fun_jac, bc_jac=bc_jac, tol=tol, bc_tol=bc_tol(tol),
                    max_nodes=max_nodes)
    res = bc(sol.y[:, 0], sol.y[:, -1], sol.p)
    return _result(sol, prm(sol.p), n, res)


def solve_fold(problem: Problem, base: State, phi: Curve, name: str, tol: float,
               max_nodes: int) -> SolveResult:
    """Locate a fold from ``base`` with null-vector guess ``phi`` (normalised here).

    Unknowns y, phi, w and lam; on success ``extra["phi"]`` holds the null vector and
    ``residual`` the largest of solve_bvp's rms collocation residuals and the boundary residuals
    of the extended system (the fold-condition residual stored with every LP).
    """
    n = problem.n
    fixed = base.params

    def prm(p):
        return {**fixed, name: p[0]}

    def fun(s, Y, p):
        q = prm(p)
        y, ph = Y[:n], Y[n:2 * n]
        jac = problem.rhs_jac(s, y, q)
        return np.vstack((problem.rhs(s, y, q), np.einsum("ijm,jm->im", jac, ph),
                          np.sum(ph * ph, axis=0)))

    def bc(Ya, Yb, p):
        q = prm(p)
        da, db = problem.bc_jac(Ya[:n], Yb[:n], q)
        return np.concatenate((problem.bc(Ya[:n], Yb[:n], q),
                               da @ Ya[n:2 * n] + db @ Yb[n:2 * n], (Ya[2 * n], Yb[2 * n] - 1.0)))

    def fun_jac(s, Y, p):
        q = prm(p)
        y, ph = Y[:n], Y[n:2 * n]
        m = len(s)
        jac = problem.rhs_jac(s, y, q)
        dfdy = np.zeros((2 * n + 1, 2 * n + 1, m))
        dfdy[:n, :n] = jac
        dfdy[n:2 * n, n:2 * n] = jac
        dfdy[2 * n, n:2 * n] = 2 * ph
        for j in range(n):  # d(f_y phi)/dy_j by central differences of the module's f_y
            h = 1e-6 * (1.0 + np.abs(y[j]))
            yp, ym = y.copy(), y.copy()
            yp[j] += h
            ym[j] -= h
            dfdy[n:2 * n, j] = np.einsum("ijm,jm->im", problem.rhs_jac(s, yp, q)
                                         - problem.rhs_jac(s, ym, q), ph) / (2 * h)
        dfdp = np.zeros((2 * n + 1, 1, m))
        dfdp[:n, 0] = problem.rhs_dp(s, y, q, name)
        h = 1e-6 * (1.0 + abs(p[0]))
        dfdp[n:2 * n, 0] = np.einsum("ijm,jm->im", problem.rhs_jac(s, y, {**q, name: p[0] + h})
                                     - problem.rhs_jac(s, y, {**q, name: p[0] - h}), ph) / (2 * h)
        return dfdy, dfdp

    s = base.s
    ph = phi(s)
    w = trapezoid_weights(s)
    ph = ph / np.sqrt(np.sum(w * np.sum(ph ** 2, axis=0)))
    cum = np.concatenate(([0.0], np.cumsum(np.diff(s) * 0.5 * (np.sum(ph[:, 1:] ** 2, axis=0)
                                                              + np.sum(ph[:, :-1] ** 2, axis=0)))))
    Y0 = np.vstack((base.y, ph, cum[None, :] / cum[-1]))
    sol = solve_bvp(fun, bc, s, Y0, p=[fixed[name]], fun_jac=fun_jac, tol=tol, bc_tol=bc_tol(tol),
                    max_nodes=max_nodes)
    res = bc(sol.y[:, 0], sol.y[:, -1], sol.p)
    out = _result(sol, prm(sol.p), n, res)
    if out.success:
        out.extra["phi"] = Curve(sol.x, sol.y[n:2 * n], sol.yp[n:2 * n])
    return out


def coarsen(s, rms_residuals, tol, min_nodes):
    """Drop every other node where both neighbouring intervals have residual < tol / 100.

    solve_bvp's collocation residual grows like h^3, so a merged interval stays below ~tol / 12
    and the next solve rarely needs to refine again; solve_bvp itself only ever adds nodes.
    """
    s = np.asarray(s)
    if len(s) <= min_nodes:
        return s
    keep = np.ones(len(s), dtype=bool)
    small = np.asarray(rms_residuals) < tol / 100
    pair = small[0:-1:2] & small[1::2]
    keep[1:-1:2][pair[: len(keep[1:-1:2])]] = False
    return s[keep] if keep.sum() >= min_nodes else s
