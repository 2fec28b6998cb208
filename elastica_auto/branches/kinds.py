"""Special points as events: the one type every kind of labelled point is, and the shipped
kinds.

An **event** is a test function evaluated along the branch, how its sign change inside a
step is located, the label and note the point it makes gets, and what that point does to
the branch (:data:`CONTINUE`, :data:`END` it, or mark where other branches :data:`SWITCH` off).
Its default :meth:`Event.find` is the whole recipe for a kind that needs nothing else: the
test function ``g`` at both ends of the step, a, b; where ``g(a) != 0`` and
``g(a) g(b) <= 0`` (a crossing in (a, b]), the one locator of the events,
:func:`~elastica_auto.branches.events.along` (Brent's method on the hyperplanes
``<x - a, secant> = sigma``), puts the point where ``g`` vanishes, to 1e-12 of the step, each
trial point solved by the corrector to its tolerance. A kind whose test function is not
smooth along the branch, or has a better locator, overrides :meth:`Event.find` or adds its
own locating method, as the shipped ones do:

* :class:`Fold`, LP, continue: the tangent's parameter component; the fold system (bordered
  Newton, :func:`~elastica_auto.branches.events.locate_fold`);
* :class:`BranchPoint`, BP, switch: the sign of the bordered Jacobian's determinant; Brent's
  method on two meshes;
* :class:`SymmetricBranchPoint`, BP, switch: the same sign change, placed at the module's
  symmetric value of the parameter inside the step where it has one;
* :class:`EvenBranchPoint`, BP, switch: the stability index; bisection;
* :class:`ParameterValue`, UZ (continue) or EP (end): ``lam - value`` on each monotone piece
  of the step, solved at the value;
* :class:`Limit`, EP, end: ``sign (quantity - value)``, upward crossings only; ``along``.

The kinds a run file or the API asks for by name (``events = [...]``) are each a module of
their own, registered in :mod:`elastica_auto.branches.registry`, as the shipped kinds' objects are:
``user_events`` (UZ where an ordinate or free parameter takes a value) and ``extrema`` (XT).
The stepper (:mod:`elastica_auto.branches.stepper`) drives the shipped kinds through the
registry's objects and every requested one through :meth:`Event.find` alone.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..core import labels
from ..core.solution import State, Tangent
from ..numerics.correctors import CorrectorFailure, FoldPoint, Solution
from .events import (Located, Placed, Step, along, locate_branch_point, locate_fold,
                     locate_index_change, locate_value, parameter_turns,
                     place_symmetric_branch_point, tangent_between)
from ..numerics.stability import count

#: What a point does to its branch: the walk goes on past it; the branch ends there; the
#: walk goes on, and other branches may start there (``switch``).
CONTINUE, END, SWITCH = "continue", "end", "switch"


@dataclass
class Hit:
    """A point an event put inside a step: its coordinate ``sigma`` along the secant, its
    label (``kind``), solution and tangent, the error estimate of a located fold or branch
    point (``residual``), its note, and, for an end point, why the branch ends there."""

    sigma: float
    kind: str
    state: State
    tangent: Tangent | None
    residual: float = float("nan")
    note: str = ""
    message: str = ""


class Event:
    """One kind of special point: ``label`` (`elastica_auto.core.labels`), ``action``
    (CONTINUE, END or SWITCH), the test function :meth:`test`, and :meth:`find`, which
    locates its sign changes inside a step.

    The ``walk`` the methods are given is the stepper's continuation in progress; an event
    reads ``walk.problem``, ``walk.corr`` (the corrector), ``walk.name`` (the continued
    parameter) and ``walk.branch`` (for warnings), nothing else."""

    label: str = ""
    action: str = CONTINUE

    def test(self, walk, sol: Solution) -> float:
        """The test function at a solution on the branch (with its unit tangent, oriented
        along the direction of travel): it changes sign where a point of this kind is."""
        raise NotImplementedError

    def note(self, walk, sol: Solution, rising: bool) -> str:
        """The note of a point found at ``sol``, where the test function passes zero
        upwards (``rising``) or downwards."""
        return ""

    def describe(self) -> str:
        """The event as the warnings name it."""
        return self.label

    def find(self, walk, step: Step) -> list[Hit]:
        """The points of this kind in the step: where the test function changes sign
        between a and b (a crossing in (a, b]: nonzero at a), located by
        :func:`~elastica_auto.branches.events.along`; the point's tangent is its own, which
        the hyperplane's linearisation orients along the secant. One sign change is one
        point: a test function that crosses zero twice within one step is not seen there
        (a step turns by at most ``max_angle``, so this takes a function that varies on a
        shorter scale than the branch). A point that cannot be located is a warning."""
        fa, fb = self.test(walk, step.a), self.test(walk, step.b)
        if fa == 0.0 or fa * fb > 0.0:
            return []
        try:
            at = along(walk.corr, step, lambda sol: self.test(walk, sol), ends=(fa, fb))
        except CorrectorFailure as exc:
            walk.branch.warnings.append(f"{self.describe()} near {walk.name} = "
                                        f"{step.a.lam:.6g} not located: {exc}")
            return []
        sol = at.solution
        return [Hit(at.sigma, self.label, sol.state, sol.tangent,
                    note=self.note(walk, sol, fb > fa))]


def quantity(problem, name: str, state: State) -> float:
    """The ordinate or parameter (free, continued or fixed) ``name`` at ``state``."""
    p = problem.point_params(state.params, state.y)
    return p[name] if name in p else \
        problem.ordinate_values(state.s, state.y, state.params)[name]


class Fold(Event):
    """LP: the continued parameter turns back. Test function: the unit tangent's parameter
    component, whose sign change counts only beyond its accuracy
    (:func:`~elastica_auto.branches.events.parameter_turns`); located by bordered Newton on
    the fold system (:func:`~elastica_auto.branches.events.locate_fold`), which
    :meth:`locate` returns whole for the stepper to reconcile with a branch point there."""

    label = labels.LP

    def test(self, walk, sol: Solution) -> float:
        return sol.tangent.lam

    def crossed(self, step: Step) -> bool:
        """Whether the parameter turns between a and b."""
        return parameter_turns(step.a.tangent.lam, step.b.tangent.lam)

    def locate(self, walk, step: Step, before: State | None) -> FoldPoint:
        """The fold in the step (not the branch's previous one, ``before``)."""
        return locate_fold(walk.corr, step, before)


class BranchPoint(Event):
    """BP: another branch crosses. Test function: the sign of the bordered Jacobian's
    determinant (AUTO-07p's for boundary value problems; it keeps its sign at a fold), at a
    on b's mesh (``a_here``) and at b. Located as the root of the scaled determinant on two
    meshes (:func:`~elastica_auto.branches.events.locate_branch_point`), where
    :class:`SymmetricBranchPoint` does not place it."""

    label, action = labels.BP, SWITCH

    def test(self, walk, sol: Solution) -> float:
        return float(sol.sign)

    def crossed(self, a_here: Solution, b: Solution) -> bool:
        """Whether the determinant changes sign between a (on b's mesh) and b."""
        return a_here.sign * b.sign < 0

    def locate(self, walk, step: Step) -> Located:
        """The branch point in the step; CorrectorFailure where it is not located."""
        return locate_branch_point(walk.corr, step)


class SymmetricBranchPoint(Event):
    """BP where the module's symmetry holds: the determinant changed sign in the step, and
    the module's ``symmetric_values`` give one value ``v`` of the parameter inside it, at
    which the group moves the state. Test function ``lam - v``; placed by a solve at ``v``
    (:func:`~elastica_auto.branches.events.place_symmetric_branch_point`), exact on every
    mesh, since the discretised problem keeps the symmetry."""

    label, action = labels.BP, SWITCH

    def test(self, walk, sol: Solution) -> float:
        return sol.lam

    def locate(self, walk, step: Step) -> Placed | None:
        """The branch point placed at the symmetric value, or None where the module gives
        none (or more than one) in the step, the solve fails, or the group fixes the state
        there (then :class:`BranchPoint` locates it)."""
        return place_symmetric_branch_point(walk.corr, walk.problem, step)


class EvenBranchPoint(Event):
    """BP of even multiplicity: the index changes by an even number with neither a fold nor
    a sign change of the determinant (a double zero eigenvalue, as a symmetry makes). Test
    function: the stability index (a step function); located by bisection
    (:func:`~elastica_auto.branches.events.locate_index_change`)."""

    label, action = labels.BP, SWITCH

    def index(self, walk, state: State) -> int:
        """The direct count at ``state`` (-1 where it is refused)."""
        return count(walk.problem, state).index

    def test(self, walk, sol: Solution) -> float:
        return float(self.index(walk, sol.state))

    def locate(self, walk, step: Step, index_a: int) -> Located:
        """Where the index leaves ``index_a`` along the step (``value``: the index past it)."""
        return locate_index_change(walk.corr, step, lambda state: self.index(walk, state),
                                   index_a)


class ParameterValue(Event):
    """UZ at a value of the continued parameter (``uz``), or EP at a bound (``bounds``).
    Test function ``lam - value``; the step is split at its folds into monotone pieces and
    each value is solved exactly on the piece whose ends bracket it
    (:func:`~elastica_auto.branches.events.locate_value`), so that a value crossed on both
    sides of a fold within one step is labelled on both."""

    def __init__(self, label: str):
        self.label = label
        self.action = END if label == labels.EP else CONTINUE

    def test(self, walk, sol: Solution) -> float:
        return sol.lam

    def locate(self, walk, step: Step, x: State, y: State, s0: float, s1: float,
               value: float) -> Hit:
        """The point at ``value`` between the knots x and y (secant coordinates s0 < s1);
        CorrectorFailure where it is not found there."""
        state, sigma = locate_value(walk.corr, step, x, y, s0, s1, value)
        return Hit(sigma, self.label, state, tangent_between(step, sigma))


@dataclass(frozen=True)
class Limit(Event):
    """``stop = ["norm > 100"]``: the branch ends (EP) where ``name`` (an ordinate or a free
    parameter) passes ``value`` upwards (``sign`` +1, ``>``) or downwards (-1, ``<``). Test
    function: :meth:`excess`; only a crossing from below counts."""

    name: str
    sign: int
    value: float

    label = labels.EP
    action = END

    def __str__(self):
        return f"{self.name} {'>' if self.sign > 0 else '<'} {self.value:g}"

    def excess(self, problem, state: State) -> float:
        """sign (quantity - value) at ``state``: positive once the limit is passed."""
        return self.sign * (quantity(problem, self.name, state) - self.value)

    def test(self, walk, sol: Solution) -> float:
        return self.excess(walk.problem, sol.state)

    def passed(self, problem, step: Step) -> bool:
        """Whether the step passes the limit (excess < 0 at a, >= 0 at b)."""
        return self.excess(problem, step.a.state) < 0 <= self.excess(problem, step.b.state)

