"""Branch switching at a branch point (AUTO-07p's ISW = -1).

At a simple branch point two solution curves cross and the kernel of ``[F_y, F_lam]`` (the
linearised collocation equations with the parameter free) is two-dimensional; the bordered
Jacobian ``[[F_y, F_lam], [t1]]`` with the first branch's tangent t1 as border row is then
singular, and its kernel is the direction in that plane orthogonal to t1. The other branch
leaves along it: exactly at a pitchfork of a branch whose tangent has only a parameter
component (the straight rod), to first order elsewhere, where the corrector pulls the first
step onto the branch.
"""

from __future__ import annotations

import numpy as np

from ..numerics.correctors import make_corrector
from ..numerics.newton import Row, kernel, unit
from ..core.options import ContinuationOptions
from ..model.problem import Problem
from ..core.solution import State, Tangent


def switch_direction(problem: Problem, state: State, t1: Tangent, name: str,
                     options: ContinuationOptions) -> Tangent | None:
    """Unit direction of the other branch at the branch point ``state`` (first branch's
    tangent ``t1``), or None if the bordered Jacobian there is not singular enough to have
    one (the point is not a branch point)."""
    corr = make_corrector(problem, name, options)
    disc = corr.disc(state.s)
    t = t1.on(disc.s)
    sol = corr.solution(disc, state.params, state.y, state.params[name],
                        Row(disc.weights * t.y, t.lam, 0.0))
    v, v_lam = kernel(sol.lin)
    direction = unit(disc, sol.lin.blocks, v, v_lam, name)
    # the kernel of a singular matrix satisfies the linearised equations; a regular one's
    # "kernel" from a random right-hand side does not
    col, bc = sol.lin.blocks.times(direction.y)
    col = col + sol.lin.blocks.dcol[name] * direction.lam
    bc = bc + sol.lin.blocks.dbc[name] * direction.lam
    if not np.isfinite(direction.lam) or max(np.max(np.abs(col)), np.max(np.abs(bc))) > 1e-6:
        return None
    return direction
