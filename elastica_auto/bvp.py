"""The boundary value problems handed to `scipy.integrate.solve_bvp`.

All of them are the module's BVP ``y' = f(s, y; p)``, ``g(y(0), y(1); p) = 0`` (n states,
n conditions), augmented so that the continued parameter ``lam = p[name]`` is a solve_bvp
unknown parameter:

* :func:`solve_fixed` -- the BVP at fixed parameters (starts, user points, end points);
* :func:`solve_arclength` -- Keller's pseudo-arclength system: the BVP plus
  ``int_0^1 (y - y0).ydot0 ds + (lam - lam0) lamdot0 = ds``, the integral carried by an extra
  state ``z' = (y - y0).ydot0``, ``z(0) = 0`` (DESIGN section 4);
* :func:`solve_tangent` -- the tangent ``(ydot, lamdot)``: the linearised BVP
  ``ydot' = f_y ydot + f_lam lamdot`` with linearised boundary conditions, bordered by
  ``<(ydot, lamdot), guess> = 1``, then normalised to ``int |ydot|^2 ds + lamdot^2 = 1``;
* :func:`solve_fold` -- the fold (LP) extended system: the BVP, its null vector
  ``phi' = f_y phi`` with homogeneous linearised boundary conditions and ``int |phi|^2 ds = 1``
  (carried by ``w' = |phi|^2``, ``w(0) = 0, w(1) = 1``), with lam free.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_bvp
from scipy.interpolate import CubicHermiteSpline

from .problem import Problem


class Curve:
    """Values ``y`` (n, m) and derivatives ``yp`` (n, m) on a mesh ``s`` (m,), evaluated
    anywhere by cubic Hermite interpolation (the interpolant solve_bvp itself returns)."""

    def __init__(self, s, y, yp):
        self.s = np.asarray(s, dtype=float)
        self.y = np.asarray(y, dtype=float)
        self.yp = np.asarray(yp, dtype=float)
        self._spline = None
        self._memo = {}

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k not in ("_spline", "_memo")}

    def __setstate__(self, state):
        self.__dict__.update(state, _spline=None, _memo={})

    def _eval(self, x, nu):
        if self._spline is None:
            self._spline = CubicHermiteSpline(self.s, self.y, self.yp, axis=1)
        return self._spline(x, nu)

    def __call__(self, x):
        """Values at ``x``. solve_bvp evaluates its right-hand side on the same mesh and
        midpoints in every Newton iteration, so the last few evaluations are memoised."""
        if x is self.s:
            return self.y
        x = np.asarray(x, dtype=float)
        key = x.tobytes()
        out = self._memo.get(key)
        if out is None:
            if len(self._memo) >= 8:
                self._memo.clear()
            out = self._memo[key] = self._eval(x, 0)
        return out

    def derivative(self, x):
        return self._eval(np.asarray(x, dtype=float), 1)


class State(Curve):
    """A solution of the BVP together with all its parameter values."""

    def __init__(self, s, y, yp, params: dict[str, float]):
        super().__init__(s, y, yp)
        self.params = dict(params)

    @classmethod
    def from_values(cls, problem: Problem, s, y, params):
        """Build a State from mesh values, with derivatives from the right-hand side."""
        y = np.asarray(y, dtype=float)
        return cls(s, y, problem.rhs(np.asarray(s, dtype=float), y, params), params)


class Tangent(Curve):
    """A tangent (or any direction) ``(ydot(s), lamdot)`` in the space (y, lam)."""

    def __init__(self, s, y, yp, lam: float):
        super().__init__(s, y, yp)
        self.lam = float(lam)


def trapezoid_weights(s):
    """Weights of the trapezoidal rule on the mesh ``s``."""
    h = np.diff(np.asarray(s, dtype=float))
    w = np.zeros(len(h) + 1)
    w[:-1] += h / 2
    w[1:] += h / 2
    return w


def inner(a: Tangent, b: Tangent, s=None) -> float:
    """``int_0^1 a.y . b.y ds + a.lam b.lam`` by the trapezoidal rule on ``s`` (default: a's
    mesh). Used for normalising directions and measuring angles between them, where O(h^2)
    is ample; the arclength condition itself is integrated by the collocation."""
    x = a.s if s is None else s
    return float(np.sum(trapezoid_weights(x) * np.sum(a(x) * b(x), axis=0)) + a.lam * b.lam)


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
    lam: float
    niter: int
    residual: float
    nodes: int
    message: str
    extra: dict = field(default_factory=dict)


def _result(sol, params, lam, n, bc_residual):
    residual = float(max(np.max(sol.rms_residuals), np.max(np.abs(bc_residual))))
    state = None
    if sol.success:
        state = State(sol.x, sol.y[:n], sol.yp[:n], params)
    return SolveResult(bool(sol.success), state, lam, int(sol.niter), residual, len(sol.x),
                       sol.message, {"rms_residuals": sol.rms_residuals})


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

    sol = solve_bvp(fun, bc, guess.s, guess(guess.s), fun_jac=fun_jac, bc_jac=bc_jac, tol=tol, bc_tol=bc_tol(tol),
                    max_nodes=max_nodes)
    res = bc(sol.y[:, 0], sol.y[:, -1])
    return _result(sol, params, float("nan"), problem.n, res)


def solve_arclength(problem: Problem, base: State, tangent: Tangent, name: str, ds: float,
                    tol: float, max_nodes: int, mesh=None) -> SolveResult:
    """One Keller pseudo-arclength corrector solve from ``base`` along ``tangent``.

    Unknowns: y(s) and lam = p[name]. Equations: the BVP and the arclength condition
    ``int (y - y0).ydot0 ds + (lam - lam0) lamdot0 = ds``. The initial guess is the Euler
    predictor ``(y0 + ds ydot0, lam0 + ds lamdot0)`` on ``mesh`` (default: the base mesh).
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
    y_guess = base(s) + ds * tangent(s)
    z_guess = np.zeros((1, len(s)))
    sol = solve_bvp(fun, bc, s, np.vstack((y_guess, z_guess)), p=[lam0 + ds * tangent.lam],
                    fun_jac=fun_jac, bc_jac=bc_jac, tol=tol, bc_tol=bc_tol(tol),
                    max_nodes=max_nodes)
    res = bc(sol.y[:, 0], sol.y[:, -1], sol.p)
    return _result(sol, prm(sol.p), float(sol.p[0]), n, res)


def solve_tangent(problem: Problem, state: State, name: str, guess: Tangent | None,
                  tol: float, max_nodes: int) -> Tangent | None:
    """The unit tangent of the solution curve at ``state`` in (y, lam), or None if singular.

    Solves the linearised BVP bordered by ``<t, guess> = 1`` (``guess = None`` means the pure
    parameter direction, i.e. lamdot = 1, which is singular exactly at a fold), normalises to
    ``int |ydot|^2 ds + lamdot^2 = 1`` and orients it along the guess.
    """
    n = problem.n
    q = state.params
    g_lam = 1.0 if guess is None else guess.lam

    def g(s):
        return np.zeros((n, len(s))) if guess is None else guess(s)

    def fun(s, Y, p):
        y = state(s)
        v = Y[:n]
        jac = problem.rhs_jac(s, y, q)
        dv = np.einsum("ijm,jm->im", jac, v) + problem.rhs_dp(s, y, q, name) * p[0]
        return np.vstack((dv, np.sum(v * g(s), axis=0)))

    def fun_jac(s, Y, p):
        y = state(s)
        m = len(s)
        dfdy = np.zeros((n + 1, n + 1, m))
        dfdy[:n, :n] = problem.rhs_jac(s, y, q)
        dfdy[n, :n] = g(s)
        dfdp = np.zeros((n + 1, 1, m))
        dfdp[:n, 0] = problem.rhs_dp(s, y, q, name)
        return dfdy, dfdp

    da, db = problem.bc_jac(state.y[:, 0], state.y[:, -1], q)
    dlam = problem.bc_dp(state.y[:, 0], state.y[:, -1], q, name)

    def bc(Ya, Yb, p):
        return np.concatenate((da @ Ya[:n] + db @ Yb[:n] + dlam * p[0],
                               (Ya[n], Yb[n] + p[0] * g_lam - 1.0)))

    dya = np.zeros((n + 2, n + 1))
    dyb = np.zeros((n + 2, n + 1))
    dp = np.zeros((n + 2, 1))
    dya[:n, :n], dyb[:n, :n], dp[:n, 0] = da, db, dlam
    dya[n, n] = 1.0
    dyb[n + 1, n] = 1.0
    dp[n + 1, 0] = g_lam

    def bc_jac(Ya, Yb, p):
        return dya, dyb, dp

    s = state.s
    Y0 = np.zeros((n + 1, len(s)))
    if guess is not None:
        Y0[:n] = guess(s)
    sol = solve_bvp(fun, bc, s, Y0, p=[g_lam], fun_jac=fun_jac, bc_jac=bc_jac, tol=tol, bc_tol=bc_tol(tol),
                    max_nodes=max_nodes)
    if not sol.success:
        return None
    t = Tangent(sol.x, sol.y[:n], sol.yp[:n], sol.p[0])
    norm = np.sqrt(inner(t, t))
    if not np.isfinite(norm) or norm == 0:
        return None
    sign = 1.0 if guess is None else np.sign(inner(t, guess)) or 1.0
    return Tangent(t.s, sign * t.y / norm, sign * t.yp / norm, sign * t.lam / norm)


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
    out = _result(sol, prm(sol.p), float(sol.p[0]), n, res)
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


def secant(a: State, b: State, name: str) -> tuple[Tangent, float]:
    """The unit secant from ``a`` to ``b`` in (y, lam), on b's mesh, and the distance |b - a|."""
    t = Tangent(b.s, b.y - a(b.s), b.yp - a.derivative(b.s), b.params[name] - a.params[name])
    norm = np.sqrt(inner(t, t))
    return Tangent(t.s, t.y / norm, t.yp / norm, t.lam / norm), float(norm)
