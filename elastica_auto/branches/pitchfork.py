"""Pitchfork curves: a symmetry-breaking branch point of any branch followed in two parameters.

At a branch point (BP) where a branch of symmetric solutions y (the planar lift of the tendon
robot) loses stability to an antisymmetric mode v (out of its plane), F_y v = 0. The plain
fold system of `elastica_auto.branches.codim2` on (y, v, lam),

    F(y, lam) = 0,    F_y v = 0,    int_0^1 |v|^2 ds = 1,

is singular there: psi^T F_yy[v, v] = 0 by the symmetry (psi the left null vector, also
antisymmetric), so with F_y w = -F_yy[v, v] the direction (v, w, 0) is in its kernel (moving
y along v stays a solution to first order: the buckled branch leaves along v). The regular
system used here adds an unfolding parameter beta (``unfolding``) and one condition:

    y' = f(s, y; p) + beta phi(s),   g(y(0), y(1); p) = 0,
    v' = f_y(s, y; p) v,             g_a v(0) + g_b v(1) = 0,
    int_0^1 |v|^2 ds = 1,            int_0^1 v.(y - y_ref) ds = 0,

solved for (y, v, lam, beta) as the second parameter is continued. y_ref is the BP's solution.
phi is the left null vector psi at the start (the ODE rows' multipliers of the collocation
equations there, held fixed along the curve): the Jacobian is regular where psi^T phi != 0
and the eigenvalue crosses transversally, psi^T (F_yy[v, t] + F_ylam v) != 0 (t the symmetric
branch's tangent). The symmetric solution with its antisymmetric null vector and beta = 0
solves the system exactly, so beta stays 0 to rounding: the column shows it.

Why not phi = v: for the equations of an energy (a Hamiltonian system, v' = J H v) the
left null vector is psi = J v, and psi.v = 0 at every s: the unfolding would not unfold.
The derivation is in docs/two-parameter.md ("Pitchfork curves").
"""

from __future__ import annotations

import dataclasses
import types

import numpy as np

from . import codim2
from .switching import kernel_plane
from ..core.errors import PlanError, StartError
from ..core.solution import State, Tangent
from ..model.problem import Parameter, Problem
from ..numerics.correctors import make_corrector

#: The unfolding parameter (solved for; 0 along a pitchfork curve).
UNFOLDING = "unfolding"
#: The integral conditions: the null vector's normalisation and its phase condition.
NORM, PHASE = codim2.NORM, "null_phase"


@dataclasses.dataclass
class Reference:
    """What a pitchfork curve is built on, found at its BP: the BP's solution ``state``, the
    null vector ``null`` of F_y alone on ``state.s`` (unit in the L2 norm) and the unfolding
    direction ``phi`` (n, m - 1) at the midpoints ``mid`` of ``state.s``'s intervals."""

    state: State
    null: np.ndarray
    mid: np.ndarray
    phi: np.ndarray

    def unfolding(self, s) -> np.ndarray:
        """phi at the points ``s`` (piecewise linear between the midpoints, constant beyond)."""
        s = np.asarray(s, dtype=float)
        return np.array([np.interp(s, self.mid, row) for row in self.phi])


def reference(base: Problem, state: State, tangent: Tangent, lam: str, options) -> Reference:
    """The :class:`Reference` at the BP ``state`` (``tangent`` its branch's tangent, in ``lam``).

    The kernel of [F_y, F_lam] there is a plane (`switching.kernel_plane`): the combination
    of its two directions d, e with no ``lam`` component, e_lam d - d_lam e, is the null vector
    of F_y alone. The left null vector is the corrector's `left_kernel` of the bordered
    Jacobian there: the collocation row of interval i is the integral of y' - f over it, so
    its multiplier is psi at the interval's middle, up to one common factor."""
    plane = kernel_plane(base, state, tangent, lam, options)
    if plane is None:
        raise StartError("no kernel plane of [F_y, F_lam] at the branch point (not a simple "
                         "branch point to the corrector's accuracy)")
    d, e = (x.on(state.s) for x in plane)
    v = e.lam * d.y - d.lam * e.y
    norm2 = np.trapezoid(np.sum(v ** 2, axis=0), state.s)
    if not norm2 > 0:
        raise StartError("the null vector of F_y at the branch point is zero")
    corr = make_corrector(base, lam, options)
    w_col = corr.left_kernel(corr.linearize(state, tangent))
    size = np.sqrt(np.sum(w_col ** 2) / w_col.shape[1])
    if not (np.isfinite(size) and size > 0):
        raise StartError("no left null vector at the branch point")
    return Reference(state, v / np.sqrt(norm2), 0.5 * (state.s[:-1] + state.s[1:]),
                     w_col / size)


def pitchfork_problem(base: Problem, lam: str, ref: Reference) -> Problem:
    """The pitchfork system (module docstring) of ``base`` in ``lam`` at ``ref``: states
    (y, v), the integral conditions ``null_norm`` and ``null_phase``, ``lam`` and
    ``unfolding`` free; the ordinates are ``base``'s, of y."""
    if base.solved or base.extra_conditions:
        raise PlanError("start", f"{base.source}: pitchfork curves of a module with integral "
                        "conditions or free parameters are not built (fold curves are)")
    codim2._check_base(base, lam, "a pitchfork curve")
    if UNFOLDING in base.parameters or UNFOLDING in base.ordinates:
        raise PlanError("start", f"{base.source} has a parameter or ordinate named "
                        f"{UNFOLDING!r}, the pitchfork system's unfolding parameter")
    n = base.n
    fold = codim2._fold_hooks(base)

    def rhs(s, Y, p):
        out = fold["rhs"](s, Y, p)
        out[:n] += p[UNFOLDING] * ref.unfolding(s)
        return out

    def rhs_dp(s, Y, p, name):
        if name == UNFOLDING:
            out = np.zeros(Y.shape)
            out[:n] = ref.unfolding(s)
            return out
        return fold["rhs_dp"](s, Y, p, name)

    def bc_dp(Ya, Yb, p, name):
        return np.zeros(2 * n) if name == UNFOLDING else fold["bc_dp"](Ya, Yb, p, name)

    def integrals(s, Y, p):
        y, v = Y[:n], Y[n:]
        return np.vstack((np.sum(v ** 2, axis=0) - 1.0, np.sum(v * (y - ref.state(s)), axis=0)))

    def integrals_jac(s, Y, p):
        y, v = Y[:n], Y[n:]
        out = np.zeros((2, 2 * n, Y.shape[1]))
        out[0, n:] = 2 * v
        out[1, :n] = v
        out[1, n:] = y - ref.state(s)
        return out

    def integrals_dp(s, Y, p, name):
        return np.zeros((2, Y.shape[1]))

    states = (*base.states, *codim2._null_states(base))
    parameters = [*codim2._extended_parameters(base, states),
                  Parameter(UNFOLDING, 0.0, r"\beta", "ode",
                            doc="the unfolding parameter of a pitchfork curve (0 along it)")]
    module = types.SimpleNamespace(
        __doc__=f"Pitchfork points of {base.source} in {lam}.", STATES=states,
        PARAMETERS=parameters, ORDINATES=[codim2._on_y(o, base) for o in base.ordinates.values()],
        **{**fold, "rhs": rhs, "rhs_dp": rhs_dp, "bc_dp": bc_dp},
        INTEGRALS=(NORM, PHASE), integrals=integrals, integrals_jac=integrals_jac,
        integrals_dp=integrals_dp, FREE=(lam, UNFOLDING))
    return Problem(module, base.source).with_free((lam, UNFOLDING))


def warn_unfolded(branch, ref: Reference, tol: float) -> None:
    """Warn, on ``branch`` (a pitchfork curve computed on ``ref``), where its points are not
    branch points of the problem: where the unfolding term ``beta phi`` added to ``y' = f``
    exceeds the tolerance ``tol`` that bounds the equations' relative residual, the point
    solves an unfolded problem, not the module's. Along a curve of symmetry-breaking branch
    points beta is 0 to rounding (1e-16 on the tendon robot's); from a branch point that is
    not a symmetry's (a transcritical one) it grows with the distance from the start, since
    there is no curve of branch points there (docs/two-parameter.md, Limits)."""
    size = float(np.max(np.abs(ref.phi))) if ref.phi.size else 0.0
    away = [k for k, p in enumerate(branch.points)
            if not abs(p.params[UNFOLDING]) * size <= tol]
    if away:
        worst = max(abs(branch.points[k].params[UNFOLDING]) for k in away)
        branch.warnings.append(
            f"{len(away)} of {len(branch.points)} points are not branch points: the unfolding "
            f"term |unfolding| max|phi| exceeds tol = {tol:g} from point {away[0] + 1} on "
            f"(|unfolding| up to {worst:.3g}); the start is not a symmetry-breaking branch "
            "point (a transcritical one has no curve of branch points)")


def pitchfork_start(problem, ref: Reference, params: dict) -> State:
    """The pitchfork system's state at the BP (approximate: solve from it): the BP's solution,
    its null vector, ``unfolding`` 0, at ``params``."""
    s = ref.state.s
    params = {**params, UNFOLDING: 0.0}
    y = np.vstack((ref.state.y, ref.null))
    return State.from_values(problem, s, problem.complete(s, y, params), params)
