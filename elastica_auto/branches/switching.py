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


def switch_direction(problem: Problem, state: State, t1: Tangent, name: str,
                     options: ContinuationOptions) -> Tangent | None:
    """Unit direction of the other branch at the branch point ``state`` (first branch's
    tangent ``t1``), or None if the bordered Jacobian there is not singular enough to have
    one (the point is not a branch point: KERNEL_RTOL)."""
    corr = make_corrector(problem, name, options)
    direction, residual = corr.kernel(corr.linearize(state, t1))
    # the kernel of a singular matrix satisfies the linearised equations; a regular one's
    # "kernel" from a random right-hand side does not
    if not np.isfinite(direction.lam) or not residual <= KERNEL_RTOL:
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
