"""Continuation along a family of solutions that a continuous symmetry maps into each other:
a phase condition and an unfolding parameter (docs/stability.md, "Continuous symmetry").

An equation module whose problem is invariant under a one-parameter group T_theta acting on
the states (T_theta maps solutions to solutions at the same parameters) declares the hook
``symmetry(s, y, p)``, returning a :class:`Symmetry` (or None where ``p`` breaks the
symmetry):

* ``generator`` g(y) = d/dtheta T_theta y at theta = 0, on the points: every solution y that
  the group moves (g(y) != 0) lies on a circle of solutions, so g(y) is in the kernel of the
  linearised problem and its Jacobian is singular all along the branch;
* ``unfolding`` b(y), a field outside the range of the linearisation: with a conserved
  quantity J (f.grad J = 0 for every state) whose end values the boundary conditions equate
  (J(1) = J(0)), b = grad J makes every solution of ``y' = f(y) + mu b(y)`` have mu = 0
  exactly: ``0 = J(1) - J(0) = mu int |grad J|^2 ds`` (for a variational problem Noether's
  theorem gives J, and grad J solves the adjoint equation: it is the cokernel).

The engine then continues the square problem (AUTO-07p's way for periodic orbits: a phase
condition fixes the position on the group orbit, a parameter unfolds the equation it
replaces)::

    y' = f(s, y; p) + mu b(s, y; p),           g(y(0), y(1); p) = 0,
    w' = (y - y_ref(s)).g_ref(s),              w(0) = 0,  w(1) = 0,
    mu' = 0,

y_ref the branch's start and g_ref = g(y_ref): the phase condition int (y - y_ref).g_ref ds =
0 picks the solution of each circle nearest the reference's orbit direction, and it is
transversal to the circles while int g(y).g_ref ds > 0. Its Jacobian is regular where the
kernel is the generator's alone (the bordered matrix [[F_y, b], [g_ref^T, 0]] with b outside
the range and g_ref not orthogonal to the kernel). The unfolding parameter mu stays at
rounding level (it is zero at every solution); each point's note reports it. The Jacobian
leaves out mu db/dy, which vanishes at the solutions: Newton's method converges as fast.

A branch is continued so when the hook gives a generator whose size is more than
FIXED_POINT of the state's at its start: at a state the group fixes (the straight rod of
an axisymmetric problem) there is no circle and no phase condition to impose. A branch
switched at a branch point on such states (where eigenvalues cross zero in pairs) starts at a
fixed point but leaves it along a tangent t the group moves: its phase condition uses
g_ref = g'(y_ref) t, the orbit's direction at the first points off the fixed points.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .interface import Wrapper
from ..core.errors import ProblemError
from ..core.solution import State, Tangent, trapezoid_weights

#: A start whose generator is at most this (L2, relative to 1 + |y|) is a fixed point of the
#: group: it is continued without the phase condition.
FIXED_POINT = 1e-8
#: The step along the tangent for the generator's derivative at a fixed point (exact for the
#: linear actions of the examples, whatever its size).
PIVOT = 1e-3


class Symmetry(NamedTuple):
    """The module's answer to ``symmetry(s, y, p)``: the group's generator g(y) and the
    unfolding field b(y), each (n, m) on the points (module docstring)."""

    generator: object
    unfolding: object


def _size(s, y) -> float:
    return math.sqrt(float(np.sum(trapezoid_weights(s) * np.sum(y * y, axis=0))))


class Phased(Wrapper):
    """``base`` (a :class:`~elastica_auto.model.problem.Problem`) with the phase condition on the
    generator at ``reference`` and the unfolding parameter: states (y, w, mu), the module's
    states, the running phase integral and mu (module docstring). It forwards the module's
    drawing and refuses the hooks the phase condition changes (`REFUSED`)."""

    REFUSED = {
        "shooting": "a branch continued along the symmetry's circles is one of its circles' "
                    "points; the scan at fixed parameters is the module's",
        "gradient_flow": "the dynamics are the module's, without the phase condition",
        "symmetry": "its circles are this problem's own: the phase condition fixes the point "
                    "on each, the unfolding parameter is a state",
        "symmetric_values": "along the circles the symmetry holds at every value of the "
                            "parameter: no branch point is placed at the module's values",
        "mirror": "the phase condition is taken at one reference state, which the reflection "
                  "moves",
    }

    def __init__(self, base, reference: State, direction: Tangent | None = None):
        self.base, self.reference, self.direction = base, reference, direction
        self.module, self.source, self.name = base.module, base.source, base.name
        self.parameters, self.ordinates = base.parameters, base.ordinates
        self.n0 = base.n
        self.states = (*base.states, "int:phase", "free:unfolding")
        self.n = self.nbc = self.n0 + 2
        self.integral_names = ()
        self.doc = base.doc
        self._g_ref = {}

    extra_conditions = 0

    def with_free(self, free=None):
        """This problem: its unknowns beyond the module's states are the phase integral and
        the unfolding parameter, which no run frees."""
        if free:
            raise ProblemError(f"{self.source}: a branch along the symmetry's circles takes "
                               "no free parameters")
        return self

    def exact_start(self, s, p):
        """None: a branch along the circles starts from a state of the module, lifted
        (`lift`)."""
        return None

    def guess(self, s, p):
        """None, as `exact_start`."""
        return None

    def point_params(self, params, y):
        return self.base.point_params(params, y[: self.n0])

    # -- the square problem -------------------------------------------------------------------
    def _symmetry(self, s, y0, p) -> Symmetry:
        sym = self.base.symmetry(s, y0, p)
        if sym is None:
            raise ProblemError(f"{self.source}: symmetry(s, y, p) returned None at parameters "
                               "of a branch continued along its symmetry's circles (a "
                               "parameter that breaks the symmetry cannot be continued so)")
        return sym

    def generator_ref(self, s):
        """g(y_ref) on the points ``s`` (cached: the same point sets recur)."""
        key = np.asarray(s, dtype=float).tobytes()
        g = self._g_ref.get(key)
        if g is None:
            if len(self._g_ref) > 32:
                self._g_ref.clear()
            ref, t = self.reference, self.direction
            g = self._symmetry(s, ref(s), ref.params).generator
            if t is not None:   # the generator's derivative along t (exact for a linear action)
                g = (self._symmetry(s, ref(s) + PIVOT * t(s), ref.params).generator - g) / PIVOT
            self._g_ref[key] = g
        return g

    def _mu(self, y):
        return float(y[self.n0 + 1, 0]) if np.ndim(y) == 2 else float(y[self.n0 + 1])

    def rhs(self, s, y, p):
        y0, n0 = y[: self.n0], self.n0
        out = np.zeros_like(y, dtype=float)
        out[:n0] = self.base.rhs(s, y0, p)
        mu = self._mu(y)
        if mu:
            out[:n0] += mu * self._symmetry(s, y0, p).unfolding
        out[n0] = np.sum((y0 - self.reference(s)) * self.generator_ref(s), axis=0)
        return out

    def rhs_jac(self, s, y, p):
        y0, n0 = y[: self.n0], self.n0
        jac = np.zeros((self.n, self.n, y.shape[1]))
        jac[:n0, :n0] = self.base.rhs_jac(s, y0, p)      # mu db/dy left out: zero at solutions
        jac[:n0, n0 + 1] = self._symmetry(s, y0, p).unfolding
        jac[n0, :n0] = self.generator_ref(s)
        return jac

    def rhs_dp(self, s, y, p, name):
        out = np.zeros(y.shape)
        out[: self.n0] = self.base.rhs_dp(s, y[: self.n0], p, name)
        return out

    def bc(self, ya, yb, p):
        n0 = self.n0
        return np.concatenate((self.base.bc(ya[:n0], yb[:n0], p), ya[n0:n0 + 1], yb[n0:n0 + 1]))

    def bc_jac(self, ya, yb, p):
        n0, n = self.n0, self.n
        da, db = np.zeros((n, n)), np.zeros((n, n))
        ga, gb = self.base.bc_jac(ya[:n0], yb[:n0], p)
        da[:n0, :n0], db[:n0, :n0] = ga, gb
        da[n0, n0] = 1.0
        db[n0 + 1, n0] = 1.0
        return da, db

    def bc_dp(self, ya, yb, p, name):
        n0 = self.n0
        return np.concatenate((self.base.bc_dp(ya[:n0], yb[:n0], p, name), np.zeros(2)))

    # -- what sees the module's own states ----------------------------------------------------
    def ordinate_values(self, s, y, p, known=None):
        return self.base.ordinate_values(s, y[: self.n0], p, known)

    @property
    def has_second_variation(self) -> bool:
        return self.base.has_second_variation

    def second_variation(self, s, y, p):
        return self.base.second_variation(s, y[: self.n0], p)

    # -- to and from the module's states ------------------------------------------------------
    def lift(self, state: State) -> State:
        """A state of the module as a state of this problem: the phase integral's running
        value (trapezoidal) and mu = 0."""
        s, y = state.s, state.y
        phase = np.sum((y - self.reference(s)) * self.generator_ref(s), axis=0)
        w = np.concatenate(([0.0], np.cumsum(np.diff(s) * (phase[1:] + phase[:-1]) / 2)))
        return State.from_values(self, s, np.vstack((y, w, np.zeros_like(s))), state.params)

    def lift_tangent(self, t: Tangent | None) -> Tangent | None:
        if t is None:
            return None
        zero = np.zeros((2, len(t.s)))
        return Tangent(t.s, np.vstack((t.y, zero)), np.vstack((t.yp, zero)), t.lam)

    def unfolding(self, profile) -> float:
        """mu of a point, from its stored profile."""
        return float(profile[self.n0 + 1, 0])

    def drop(self, branch):
        """The module's states back on every point of ``branch`` (profiles, labelled
        solutions and tangents), each point's note reporting its unfolding parameter."""
        n0 = self.n0
        for p in branch.points:
            mu = self.unfolding(p.profile)
            p.note = "; ".join(filter(None, (p.note, f"phase condition, unfolding {mu:.1e}")))
            p.profile = p.profile[:n0]
            if p.state is not None:
                st = p.state
                p.state = State(st.s, st.y[:n0], st.yp[:n0], st.params)
            if p.tangent is not None:
                t = p.tangent
                p.tangent = Tangent(t.s, t.y[:n0], t.yp[:n0], t.lam)


def moves(problem, state: State) -> bool:
    """Whether the module's symmetry holds at ``state``'s parameters and the group moves the
    state (its generator larger than FIXED_POINT of it): the state then lies on a circle of
    solutions, the generator in its linearisation's kernel."""
    if not getattr(problem, "has_symmetry", False):
        return False
    sym = problem.symmetry(state.s, state.y, state.params)
    return sym is not None and (_size(state.s, sym.generator)
                                > FIXED_POINT * (1.0 + _size(state.s, state.y)))


def phased(problem, state: State, tangent: Tangent | None = None) -> Phased | None:
    """The phase-conditioned problem for a branch starting at ``state`` (along ``tangent``,
    if given), or None where the module declares no symmetry, the parameters break it, or
    the group fixes the start and the direction of travel alike.

    A start the group fixes (a branch point on the fixed points, switched at along
    ``tangent``) takes as the orbit's direction the generator's derivative along the
    tangent, g'(y_ref) t: the first point off the fixed points moves along it."""
    if moves(problem, state):
        return Phased(problem, state)
    if tangent is None or not getattr(problem, "has_symmetry", False):
        return None
    sym = problem.symmetry(state.s, state.y, state.params)
    if sym is None:
        return None
    t = tangent.on(state.s)
    moved = problem.symmetry(state.s, state.y + PIVOT * t.y, state.params).generator
    if _size(state.s, moved - sym.generator) <= FIXED_POINT * PIVOT * _size(state.s, t.y):
        return None
    return Phased(problem, state, t)
