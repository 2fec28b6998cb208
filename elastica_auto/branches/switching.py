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

#: A direction is the kernel's where it satisfies the linearised equations to this, relative
#: to the size of their terms (``|F_y| |v| + |F_lam| |v_lam|``, row by row, at their largest):
#: a scale-free test, the same for a module whose states are scaled by any factor. At the
#: branch points of the shipped runs and examples (located to 1e-12 of their step) the
#: relative residual is 2e-16 to 4e-12; where the bordered Jacobian is regular, the "kernel"
#: of a solve with a pseudo-random right-hand side leaves 1e-2 to 0.5 (measured at every LP,
#: UZ and EP of those files that is not itself singular).
KERNEL_RTOL = 1e-8


def kernel_residual(blocks, v, v_lam: float, name: str) -> float:
    """The residual of ``(v, v_lam)`` in the linearised equations ``F_y v + F_lam v_lam = 0``
    of ``blocks``, relative to the size of their terms (the largest row of
    ``|F_y| |v| + |F_lam| |v_lam|``); 0 for a zero vector of a zero Jacobian."""
    col, bc = blocks.times(v)
    col = col + blocks.dcol[name] * v_lam
    bc = bc + blocks.dbc[name] * v_lam
    a = np.abs(v)
    size_col = (np.einsum("iab,bi->ai", np.abs(blocks.d0), a[:, :-1])
                + np.einsum("iab,bi->ai", np.abs(blocks.d1), a[:, 1:])
                + np.abs(blocks.dcol[name]) * abs(v_lam))
    size_bc = (np.abs(blocks.ga) @ a[:, 0] + np.abs(blocks.gb) @ a[:, -1]
               + np.abs(blocks.dbc[name]) * abs(v_lam))
    size = max(float(np.max(size_col)), float(np.max(size_bc)))
    residual = max(float(np.max(np.abs(col))), float(np.max(np.abs(bc))))
    return residual / size if size > 0 else (0.0 if residual == 0 else np.inf)


def switch_direction(problem: Problem, state: State, t1: Tangent, name: str,
                     options: ContinuationOptions) -> Tangent | None:
    """Unit direction of the other branch at the branch point ``state`` (first branch's
    tangent ``t1``), or None if the bordered Jacobian there is not singular enough to have
    one (the point is not a branch point: KERNEL_RTOL)."""
    corr = make_corrector(problem, name, options)
    disc = corr.disc(state.s)
    t = t1.on(disc.s)
    sol = corr.solution(disc, state.params, state.y, state.params[name],
                        Row(disc.weights * t.y, t.lam, 0.0))
    v, v_lam = kernel(sol.lin)
    direction = unit(disc, sol.lin.blocks, v, v_lam, name)
    # the kernel of a singular matrix satisfies the linearised equations; a regular one's
    # "kernel" from a random right-hand side does not
    if not np.isfinite(direction.lam) or not kernel_residual(
            sol.lin.blocks, direction.y, direction.lam, name) <= KERNEL_RTOL:
        return None
    return direction


def kernel_plane(problem: Problem, state: State, t1: Tangent, name: str,
                 options: ContinuationOptions) -> list[Tangent] | None:
    """The kernel of ``[F_y, F_lam]`` at the branch point ``state`` as two orthonormal
    directions: the other branch's (:func:`switch_direction`, orthogonal to ``t1``), and the
    kernel's direction orthogonal to that one (the first branch's, exactly: ``t1`` may be a
    secant of the step that found the point). None where either is not found."""
    d = switch_direction(problem, state, t1, name, options)
    if d is None:
        return None
    e = switch_direction(problem, state, d, name, options)
    return None if e is None else [d, e]
