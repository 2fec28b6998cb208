"""Branch switching at a branch point (AUTO-07p's ISW = -1).

At a simple branch point two solution curves cross. The linearised operator ``f_y`` (with the
linearised boundary conditions) has a null vector phi there; ``(phi, 0)`` and the branch
tangent ``t1`` span the null space of ``[f_y, f_lam]``. The other branch leaves along the part
of ``(phi, 0)`` orthogonal to ``t1`` -- exactly its direction at a pitchfork of a trivial
branch (where ``t1 = (0, 1)``), a first approximation at a transcritical point that the
corrector then pulls onto the branch.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_bvp

from .corrector import Curve, State, Tangent, inner, solve_fold, trapezoid_weights
from .options import ContinuationOptions
from .problem import Problem


def null_vector_guess(problem: Problem, state: State, tol: float, max_nodes: int,
                      iterations: int = 2) -> Curve | None:
    """Inverse iteration on the linearised BVP: solve ``v' = f_y v + w`` with homogeneous
    linearised boundary conditions, ``w`` the previous (normalised) iterate; near a singular
    ``f_y`` the solution is dominated by the null vector."""
    n, q = problem.n, state.params
    da, db = problem.bc_jac(state.y[:, 0], state.y[:, -1], q)
    w = Curve(state.s, np.ones((n, len(state.s))), np.zeros((n, len(state.s))))
    for _ in range(iterations):
        def fun(s, v, w=w):
            return np.einsum("ijm,jm->im", problem.rhs_jac(s, state(s), q), v) + w(s)

        def bc(va, vb):
            return da @ va + db @ vb

        sol = solve_bvp(fun, bc, state.s, np.zeros((n, len(state.s))), tol=tol,
                        max_nodes=max_nodes)
        norm = np.sqrt(np.sum(trapezoid_weights(sol.x) * np.sum(sol.y ** 2, axis=0)))
        if not np.isfinite(norm) or norm == 0:
            return None
        w = Curve(sol.x, sol.y / norm, sol.yp / norm)
    return w


def switch_direction(problem: Problem, state: State, t1: Tangent, name: str,
                     options: ContinuationOptions) -> Tangent | None:
    """Unit direction of the other branch at the branch point ``state`` (tangent ``t1``), or
    None if no null vector is found."""
    guess = null_vector_guess(problem, state, options.tol, options.max_nodes)
    if guess is None:
        return None
    res = solve_fold(problem, state, guess, name, options.fold_tol, options.max_nodes)
    if not res.success:
        return None
    phi = res.extra["phi"]
    p = Tangent(phi.s, phi(phi.s), phi.yp, 0.0)
    along = inner(p, t1, phi.s)
    t = Tangent(phi.s, p.y - along * t1(phi.s), p.yp - along * t1.derivative(phi.s),
                -along * t1.lam)
    norm = np.sqrt(inner(t, t))
    if not np.isfinite(norm) or norm < 1e-8:
        return None
    return Tangent(t.s, t.y / norm, t.yp / norm, t.lam / norm)
