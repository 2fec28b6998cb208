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
* :class:`UserValue`, UZ, continue, and :class:`Bound`, EP, end (both
  :class:`ParameterValue`): ``lam - value`` on each monotone piece of the step, solved at
  the value;
* :class:`Limit`, EP, end: ``sign (quantity - value)``, upward crossings only; ``along``;
* :class:`CourseEvents`: the walk's requested events and limits, placed in that order;
* :class:`FoldStop`, LP, end: the branch's n-th fold (``stop = ["LPn"]``);
* the closed loop and the repeat by a period, :mod:`elastica_auto.branches.loops`.

The turn kinds (folds and branch points, where the stability index may change) are driven
on every step as one set, the registry's ``DETECTION``, through :meth:`Event.crosses` and
:meth:`Event.detect` on the step's :class:`Scan`, in the order of the tuple, which is the
order of their reconciliation (a fold and a branch point together are one BP, or both where
they lie apart; the fold rule's check of the index comes last): the fold-pair probe, the
retries (:class:`Retry`), the symmetric-value and the even branch point are theirs. The
placed kinds then, the registry's ``PLACEMENT``, through :meth:`Event.place` on the step's
:class:`Placement`, in the order of that tuple: each puts its points in, or offers the point
where the branch ends (the earliest offered wins; its kind's :meth:`Event.keeps` says which
points before it stay); their solves, retries and warnings are theirs.

The kinds a run file or the API asks for by name (``events = [...]``) are each a module of
their own, registered in :mod:`elastica_auto.branches.registry`, as the shipped kinds' objects are:
``user_events`` (UZ where an ordinate or free parameter takes a value) and ``extrema`` (XT).
The stepper (:mod:`elastica_auto.branches.stepper`) drives the shipped kinds through the
registry's two sets and every requested one through :meth:`Event.place` (by default
:meth:`Event.find`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core import labels
from ..core.solution import State, Tangent, inner
from .branch import PROFILE_GRID, Point, new_point
from ..numerics.correctors import CorrectorFailure, FoldPoint, Solution
from .events import (TURN_NOISE, Located, Placed, Step, along, crossings, locate_branch_point,
                     locate_fold, locate_index_change, locate_limit, locate_value,
                     pair_suspected, parameter_turns, place_symmetric_branch_point,
                     tangent_between)
from ..numerics.stability import count, index_change, kernel_dimension

#: What a point does to its branch: the walk goes on past it; the branch ends there; the
#: walk goes on, and other branches may start there (``switch``); the branch is its first
#: period translated from there on (``repeat``: the walk copies that period and resumes).
CONTINUE, END, SWITCH, REPEAT = "continue", "end", "switch", "repeat"
#: A fold and a branch point located in one step are one point (a pitchfork met along its
#: bifurcating branch) where their secant coordinates differ by at most this fraction of
#: the step: both are located to rounding there.
SAME_EVENT = 1e-3
#: At most this many solves look for the minimum of the parameter's slope inside a step
#: where the cubic model suspects a fold pair (:meth:`Fold.probe`).
PROBES = 4
#: A fold's translate by a period is looked for where the branch passes it with ordinates
#: within TRANSLATE_NEAR (relative) of the fold's; it is reported missing within
#: TRANSLATE_SAME (:meth:`Fold.finish`).
TRANSLATE_NEAR, TRANSLATE_SAME = 0.05, 1e-3


class Retry(Exception):
    """The step is rejected: the walk retries it with ``ds``, for the reason in the message
    (``residual``: the corrector's last Newton correction, if it failed). ``spends``: one of
    the retries an event that cannot be located, or an index the fold rule does not give,
    may take (the stepper's RETRY_HALVINGS; they count until a step with an event is
    accepted), rather than a check of the step itself."""

    def __init__(self, message: str, ds: float, residual: float = float("nan"),
                 spends: bool = False):
        super().__init__(message)
        self.ds, self.residual, self.spends = ds, residual, spends


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
    direct: int | None = None


@dataclass
class Scan:
    """One step's detection of its turns (folds and branch points) in progress: what the
    stepper knows of the step, and what the turn kinds have found so far, read and written
    by each of them in the registry's order (`elastica_auto.branches.registry.DETECTION`).

    ``a_here``: the step's start on b's mesh; ``index_a``, ``index_b``: the direct counts at
    a and b (-1 where refused); ``skip``: no turn is looked for (the first step from a
    singular start, whose own would be found, or a walk without events); ``on``: label ->
    whether that kind is detected (the option ``detect``); ``can_retry``: whether the step
    may still be rejected for an event (the stepper's RETRY_HALVINGS); ``ordinate`` and
    ``enters``: the continued parameter's distinguished ordinate (or None) and how it enters
    the equations, which the fold rule reads. Filled in: ``crossed`` (label -> whether the
    kind's test function changed sign in the step, :meth:`Event.crosses`), the branch point
    ``located`` (or the warning ``unlocated`` where it could not be), and the points
    ``found``."""

    step: Step
    a_here: Solution
    index_a: int
    index_b: int
    skip: bool
    on: dict[str, bool]
    can_retry: bool
    ordinate: object | None
    enters: str
    crossed: dict[str, bool] = field(default_factory=dict)
    located: Located | Placed | None = None
    unlocated: str = ""
    found: list[Hit] = field(default_factory=list)


@dataclass
class Placement:
    """One step's points in the order of travel, in progress, after its turns: what the
    placed kinds (the registry's ``PLACEMENT``) read and write, each in turn.

    ``step``; ``turns``: the turn kinds' points (:attr:`Scan.found`); ``room``: the points
    the walk may still add (``max_points`` less those that count); ``can_retry``: whether the
    step may still be rejected for an event. Filled in: ``points`` (the points found, the
    turns' first) and ``end``, the point where the branch ends in the step (or repeats),
    the earliest any kind offered (:meth:`end_at`), with ``ender``, the kind that offered
    it, which decides which points found before it stay (:meth:`Event.keeps`)."""

    step: Step
    turns: list[Hit]
    room: int
    can_retry: bool
    points: list[Hit] = field(default_factory=list)
    end: Hit | None = None
    ender: Event | None = None

    def __post_init__(self):
        self.points = list(self.turns)

    def pieces(self) -> list[tuple[float, State, float, State]]:
        """The step split at its located folds into pieces (s0, x, s1, y) along which the
        continued parameter is monotone (secant coordinates s0 < s1 of the knots x, y)."""
        step = self.step
        inside = sorted((e for e in self.turns if e.kind == labels.LP and not e.note
                         and 0.0 < e.sigma < step.dist), key=lambda e: e.sigma)
        knots = ([(0.0, step.a.state)] + [(e.sigma, e.state) for e in inside]
                 + [(step.dist, step.b.state)])
        return [(s0, x, s1, y) for (s0, x), (s1, y) in zip(knots, knots[1:])]

    def end_at(self, event: Event, hit: Hit | None):
        """``hit`` ends the branch where it comes before the end found so far (the first
        offered of equals)."""
        if hit is not None and (self.end is None or hit.sigma < self.end.sigma):
            self.end, self.ender = hit, event


class Event:
    """One kind of special point: ``label`` (`elastica_auto.core.labels`), ``action``
    (CONTINUE, END or SWITCH), the test function :meth:`test`, and :meth:`find`, which
    locates its sign changes inside a step.

    The ``walk`` the methods are given is the stepper's continuation in progress; an event
    reads ``walk.problem``, ``walk.corr`` (the corrector), ``walk.name`` (the continued
    parameter) and ``walk.branch`` (for warnings and its folds); a shipped placed kind also
    the walk's course and where it stands: ``user_values``, ``stops``, ``watch`` and
    ``counts`` (whether a point counts toward ``max_points``); ``start``, ``a``,
    ``arclength``, ``first``, ``until`` and ``period`` (the return to the start), and
    ``refolded`` (the folds a kind labelled otherwise: :func:`branch_folds`); the failure
    (:class:`Failure`) also ``opt``, ``base_point`` and ``end_at_base``, the walk's way of
    ending the branch at its last accepted point; the fold's :meth:`finish` also ``refine``,
    the walk's way of walking one of its steps again with short steps. Nothing else.

    A **turn kind** (a fold, a branch point: where the stability index may change) is driven
    on every step through :meth:`crosses` and :meth:`detect` on the step's :class:`Scan`, in
    the order of the registry's ``DETECTION``, which is also the order in which they are
    reconciled; the **placed kinds** (the registry's ``PLACEMENT``: user values, bounds,
    the kinds a run asks for, limits, the return to the start) then, in their order, through
    :meth:`place` on the step's :class:`Placement`, by default the points :meth:`find`
    finds; before a step, :meth:`ahead` may end the branch, before the walk's first,
    :meth:`begin` reads its course, and after the walk, every kind of both sets, in their
    order, completes the branch as a whole through :meth:`finish` (the fold's translates)."""

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

    def crosses(self, walk, scan: Scan) -> bool | None:
        """For a turn kind with a test function of its own: whether it changed sign in the
        step (and the kind is looked for); the stepper keeps it as ``scan.crossed[label]``
        before any turn kind is located. None (the default): the kind has none of its own."""
        return None

    def detect(self, walk, scan: Scan) -> None:
        """For a turn kind: locate its points in the step, reconciled with those of the kinds
        before it in ``DETECTION``, into ``scan.found`` (or ``scan.located``); raise
        :class:`Retry` to retry the step shorter. The default: nothing (a kind driven
        through :meth:`find`)."""

    def begin(self, walk, course) -> None:
        """For a placed kind: read the walk's course before its first step (the default:
        nothing)."""

    def place(self, walk, placement: Placement) -> None:
        """For a placed kind: put its points in the step into ``placement.points``, or offer
        the point where the branch ends (:meth:`Placement.end_at`, its ``message`` saying
        why: the branch ends there with that point's label); raise :class:`Retry` to retry
        the step shorter. The default: the points :meth:`find` finds, which go on."""
        placement.points.extend(self.find(walk, placement.step))

    def keeps(self, walk, placement: Placement, hit: Hit) -> bool:
        """For the kind whose point ends the branch in the step (``placement.ender``):
        whether a point found in the step stays, the default: those before the end."""
        return hit.sigma < placement.end.sigma

    def ahead(self, walk, ds: float) -> Hit | None:
        """Before a step of length ``ds``: the point at which the branch ends without taking
        it (``sigma``: its distance from the last point accepted), or None (the default)."""
        return None

    def finish(self, walk) -> None:
        """After the walk, once the branch has ended: complete what the branch as a whole
        owes this kind, which no single step could see (the fold's translates by a period:
        :meth:`Fold.finish`), with the walk's ``refine`` where a step must be walked again.
        The default: nothing."""

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


def branch_folds(walk, located: bool = False) -> list[int]:
    """The indices of the branch's folds so far, where the continued parameter turned back:
    its LP points, and the folds a placed kind gave another label in the walk
    (``walk.refolded``: id of the fold's solution -> (that solution, whether the fold was
    located); a fold curve's cusps and branch points,
    `elastica_auto.branches.codim2.FoldCurvePoint`), which stay folds for the walk: the
    fold before the next one (:meth:`Fold.points`), the count of the fold stop, a fold's
    translates by a period. ``located``: only those located (an LP without a note)."""
    out = []
    for k, p in enumerate(walk.branch.points):
        mark = walk.refolded.get(id(p.state)) if p.state is not None else None
        if mark is not None and mark[0] is p.state:
            if mark[1] or not located:
                out.append(k)
        elif p.type in labels.FOLDS and not (located and p.note):
            out.append(k)
    return out


class Failure(Event):
    """MX: the branch could not go on, and ends at its last accepted point (a point already
    labelled keeps its label and is followed by an MX of its own). No test function and no
    locator: the failure is the event, and the stepper hands it to this kind where it
    happens; the kind ends the branch with its label, its message (what failed, where:
    ``branch.message``) and the failure's record (``branch.diagnostics``):

    - :meth:`at_start`: the start has no tangent (the bordered system is singular there);
    - :meth:`step_failed`: the step was rejected down to ``ds_min``;
    - :meth:`ended_early`: the equation module or the engine raised, or the user
      interrupted (the stepper writes the message from the exception)."""

    label, action = labels.MX, END

    def at_start(self, branch, problem, state: State, exc: Exception) -> None:
        """No tangent at the start ``state`` (``exc``, the corrector's failure): the branch
        is its start alone, noted singular."""
        branch.insert(new_point(problem, state, type=self.label, arclength=0.0,
                                note="singular start"))
        branch.end, branch.message = self.label, f"no tangent at the start point ({exc})"

    def step_failed(self, walk, retry: Retry, history: list[dict]) -> None:
        """The step from ``walk.a`` was rejected down to ``ds_min`` (``retry``: the last
        rejection; ``history``: each attempt's ds, residual, nodes and message): the branch
        ends at the last accepted point (``walk.end_at_base``), the message saying why, the
        diagnostics holding the last 12 attempts."""
        opt, branch = walk.opt, walk.branch
        # an infinite residual is Newton's mark for residuals that are not finite, which only
        # the module's functions can make from a finite guess
        why = (" (the equation module returned NaN or inf there)"
               if math.isinf(retry.residual) else "")
        if any(h["nodes"] >= opt.max_nodes for h in history):
            # no mesh met tol: what is left of the residual is not the mesh's (the tail of the
            # Bratu branch, where lam ~ 1e-20 is known only to the corrector's absolute
            # accuracy and lam exp(u) is not small)
            why += (f" (the step's mesh reached max_nodes = {opt.max_nodes} "
                    "without meeting tol)")
        walk.end_at_base(self.label, f"corrector failed at ds < ds_min = {opt.ds_min:g} "
                                     f"after point {len(branch.points)} "
                                     f"({walk.name} = {walk.a.lam:.6g}): {retry}{why}")
        branch.diagnostics = {"step": len(branch.points), "ds": history[-1]["ds"],
                              "nodes": len(walk.a.mesh), "history": history[-12:]}

    def ended_early(self, branch, problem, walk, origin, message: str,
                    record: dict | None = None) -> None:
        """End ``branch`` early with ``message`` (``record``: the exception's failure record,
        `elastica_auto.core.errors.failure_record`, kept as the diagnostics with the points'
        count): its last point becomes MX (a labelled one keeps its label and is followed by
        an MX of its own). A branch without points gets its start ``origin`` (a solution and
        a tangent), labelled MX, so that every branch has a point to show and restart from
        (without calling the module, which may be what failed, if it fails there:
        :func:`start_point`). ``walk``: the walk in progress, or None before it began."""
        branch.end, branch.message = self.label, message
        if not branch.points:
            try:
                branch.insert(new_point(problem, origin.state, type=self.label,
                                        arclength=0.0, tangent=origin.tangent))
            except Exception:  # the module fails at the start itself
                branch.insert(start_point(branch, origin))
        else:
            base = walk.base_point if walk is not None else None
            # a step interrupted while it was being accepted may have put in its end point
            # before the walk moved on to it: the branch ends at the last point accepted whole
            while (base is not None and branch.points[-1] is not base
                   and not branch.points[-1].type):
                branch.points.pop()
            last = branch.points[-1]
            if last.type:  # keep its label (the start's EP, say); end with an MX of its own
                branch.insert(new_point(problem, last.state, type=self.label,
                                        arclength=last.arclength, tangent=last.tangent,
                                        direct=last.index_direct))
            else:  # the last accepted point, whose solution the walk still has
                walk.end_at_base(self.label, message)
        if record is not None:
            branch.diagnostics = {**record, "step": len(branch.points)}


def start_point(branch, origin) -> Point:
    """The start ``origin`` (its ``state`` and ``tangent``) as an MX point of ``branch``,
    without calling the equation module: NaN ordinates, an unknown index, and the profile
    interpolated linearly from the values alone (the derivatives may be what is broken)."""
    state = origin.state
    return Point(params=dict(state.params), ordinates=dict.fromkeys(branch.ordinate_names,
                                                                    float("nan")),
                 arclength=0.0, ds=0.0, niter=0, nodes=len(state.s), type=labels.MX,
                 profile=np.array([np.interp(PROFILE_GRID, state.s, v) for v in state.y]),
                 state=state, tangent=origin.tangent)


def quantity(problem, name: str, state: State) -> float:
    """The ordinate or parameter (free, continued or fixed) ``name`` at ``state``."""
    p = problem.point_params(state.params, state.y)
    return p[name] if name in p else \
        problem.ordinate_values(state.s, state.y, state.params)[name]


def _vertex(points) -> float | None:
    """The abscissa of the vertex of the parabola through three (u, f) points, if it is a
    minimum inside (0, 1); else None."""
    (u0, f0), (u1, f1), (u2, f2) = points
    if not u0 < u1 < u2:
        return None
    d01, d12 = (f1 - f0) / (u1 - u0), (f2 - f1) / (u2 - u1)
    curvature = (d12 - d01) / (u2 - u0)
    if not curvature > 0:
        return None
    u = (u0 + u1) / 2 - d01 / (2 * curvature)
    return u if 0.0 < u < 1.0 else None


def kernel_check(walk, state: State, index_a: int, index_b: int) -> str:
    """At a branch point crossed by the branch, the index changes by the dimension of the
    second variation's kernel there (an eigenvalue crosses zero for each kernel direction):
    '' where it does, else a note, also kept as a warning."""
    if index_a < 0 or index_b < 0 or not walk.problem.has_second_variation:
        return ""
    kernel = kernel_dimension(walk.problem, state)
    if kernel == abs(index_b - index_a):
        return ""
    note = (f"index {index_a} -> {index_b} across the branch point, whose kernel has "
            f"dimension {kernel if kernel >= 0 else 'unknown'}")
    walk.branch.warnings.append(f"{note} (near {walk.name} = "
                                f"{state.params[walk.name]:.6g})")
    return note


class Fold(Event):
    """LP: the continued parameter turns back. Test function: the unit tangent's parameter
    component, whose sign change counts only beyond its accuracy
    (:func:`~elastica_auto.branches.events.parameter_turns`); located by bordered Newton on
    the fold system (:func:`~elastica_auto.branches.events.locate_fold`) and reconciled with
    a branch point located in the same step (:meth:`detect`). A step whose end tangents
    agree in sign but whose parameter's slope dips inside it is probed for a fold pair
    (:meth:`probe`)."""

    label = labels.LP

    def test(self, walk, sol: Solution) -> float:
        return sol.tangent.lam

    def crossed(self, step: Step) -> bool:
        """Whether the parameter turns between a and b."""
        return parameter_turns(step.a.tangent.lam, step.b.tangent.lam)

    def crosses(self, walk, scan: Scan) -> bool:
        return self.crossed(scan.step) and not scan.skip and scan.on[labels.LP]

    def locate(self, walk, step: Step, before: State | None) -> FoldPoint:
        """The fold in the step (not the branch's previous one, ``before``)."""
        return locate_fold(walk.corr, step, before)

    def detect(self, walk, scan: Scan) -> None:
        """Where the parameter turns in the step: the fold located (:meth:`points`, an LP, or
        a BP where the determinant changed sign too). A fold that cannot be located retries
        the step (spending a retry); once retries are spent, a turn without an index change
        is a branch point (a pitchfork passed along its other branch, where the fold system
        is singular: labelled BP, its note says why, and the unlocated branch point's
        warning is dropped for it), any other an LP noted and warned as not located. A
        branch point that could not be located (``scan.unlocated``) is warned of here, after
        the fold's warnings. Where neither kind crossed, a fold pair suspected inside the
        step is probed (:meth:`probe`)."""
        step = scan.step
        if not scan.crossed[labels.LP]:
            if (not scan.crossed[labels.BP] and scan.can_retry and not scan.skip
                    and scan.on[labels.LP]):
                u = pair_suspected(step)
                if u is not None:
                    self.probe(walk, scan, u)
            return
        try:
            scan.found.extend(self.points(walk, scan))
        except CorrectorFailure as exc:
            if scan.can_retry:
                raise Retry(f"fold not located ({exc})", step.ds / 2, exc.residual,
                            spends=True) from None
            b = step.b
            if 0 <= scan.index_a == scan.index_b and scan.on[labels.BP]:
                # the parameter turns, the fold system is singular and no eigenvalue
                # crossed zero: not a simple fold (where the index changes by one) but a
                # pitchfork passed along its other branch
                scan.found.append(Hit(step.dist / 2, labels.BP, b.state, b.tangent,
                                      note="turning point without index change (the fold "
                                           f"system fails: {exc})"))
                scan.unlocated = ""   # that is the branch point, labelled, its note says why
            else:
                walk.branch.warnings.append(f"fold near {walk.name} = {step.a.lam:.6g} not "
                                            f"located: {exc}")
                scan.found.append(Hit(step.dist / 2, labels.LP, b.state, b.tangent,
                                      note=f"fold not located: {exc}"))
        if scan.unlocated:
            walk.branch.warnings.append(scan.unlocated)

    def points(self, walk, scan: Scan) -> list[Hit]:
        """The fold in the step, located: an LP, or where the determinant changed sign too, a
        BP at the fold (the parameter turns at a branch point: a pitchfork met along its
        bifurcating branch; also where that branch point was not located), unless the
        branch point located (``scan.located``) lies apart from the fold (more than
        SAME_EVENT of the step): then both, the fold and a branch point of
        its own (the isotropic rod's symmetric points lie 0.02 in psi from folds, and a step
        can pass both; as one BP the fold was missing, and the walk for its translates went
        on for thousands of points). CorrectorFailure where the fold is not located."""
        step, located = scan.step, scan.located
        pts = walk.branch.points
        before = [pts[k].state for k in branch_folds(walk)[-1:] if pts[k].state is not None]
        fp = self.locate(walk, step, before[0] if before else None)
        phi = fp.phi
        if inner(phi, step.secant, phi.s) < 0:
            phi = phi.scaled(-1.0)
        sigma = min(max(step.sigma(fp.state), 0.0), step.dist)
        fold = Hit(sigma, labels.LP, fp.state, phi, fp.residual)
        if not scan.crossed[labels.BP]:
            return [fold]
        if located is not None and abs(located.sigma - sigma) > SAME_EVENT * step.dist:
            return [fold, Hit(located.sigma, labels.BP, located.state, step.secant,
                              abs(located.value))]
        return [Hit(sigma, labels.BP, fp.state, step.secant, fp.residual,
                    note="turning point without index change")]

    def probe(self, walk, scan: Scan, u: float):
        """The slope of the parameter dips inside the step, at ``u`` of it by the cubic model:
        look for the slope's minimum along the step. Each probe solves on the hyperplane at
        u and reads the tangent and index there; a tangent turned over (or an index that
        differs from a's) means a fold pair: retry with a step that ends before it (not
        spending a retry). Else the next u is the vertex of the parabola through the three
        lowest slopes known (the ends' and the probes'), up to PROBES probes or until u
        moves by less than 1e-3: a pair narrower than the model's error (near a cusp) is
        found all the same."""
        step, index_a, ds = scan.step, scan.index_a, scan.step.ds
        sign = math.copysign(1.0, step.a.tangent.lam)
        known = [(0.0, abs(step.a.tangent.lam)), (1.0, abs(step.b.tangent.lam))]
        for _ in range(PROBES):
            try:
                mid = walk.corr.on_plane(step.a, step.secant, u * step.dist, step.b.mesh)
            except CorrectorFailure:
                raise Retry("could not probe a dip of the parameter's slope", ds / 2) from None
            t = mid.tangent
            if inner(t, step.secant, mid.mesh) < 0:
                t = t.scaled(-1.0)
            if sign * t.lam <= 0 or (
                    index_a >= 0 and count(walk.problem, mid.state).index != index_a):
                raise Retry(f"a fold pair inside the step (at {u:.2f} of it)",
                            max(u * ds / 2, ds / 8))
            known.append((u, sign * t.lam))
            nxt = _vertex(sorted(sorted(known, key=lambda k: k[1])[:3]))
            if nxt is None or abs(nxt - u) < 1e-3:
                return
            u = nxt

    def finish(self, walk) -> None:
        """For a parameter with a period, every fold at each of its translates. The solution
        set is periodic in such a parameter, so a fold found at ``lam`` recurs wherever the
        branch passes ``lam + k period`` with the same ordinates. Where it passes without
        one (a fold pair stepped over), the step there is walked again (``walk.refine``, with
        steps of at most 1/32 of its length), up to three rounds; a translate still missing
        is a warning. Not in the refinement of a step (``walk.until``), nor on a branch a
        fold stop ended (at its n-th fold: the folds past it are not the branch's)."""
        period = walk.problem.parameters[walk.name].period
        if period is None or walk.until is not None or walk.branch.end == labels.LP:
            return
        for _ in range(3):
            gaps = missing_translates(walk, period, TRANSLATE_NEAR)
            if not gaps or not any([walk.refine(i) for i in sorted(gaps, reverse=True)]):
                break
        for i, lam in sorted(missing_translates(walk, period, TRANSLATE_SAME).items()):
            walk.branch.warnings.append(f"no fold where the branch passes {walk.name} = "
                                        f"{lam:.6g}, a translate of a fold by a period")


def missing_translates(walk, period: float, tol: float) -> dict[int, float]:
    """{i: translate} for the branch's steps i -> i+1 that pass a translate of a located
    fold (by whole periods, within the range the branch travelled) where the branch has no
    fold: the steps whose ends bracket the translate's parameter and the fold's ordinates,
    within ``tol`` (relative)."""
    pts = walk.branch.points
    lam = np.array([p.params[walk.name] for p in pts])
    ords = np.array([list(p.ordinates.values()) for p in pts]).reshape(len(pts), -1)
    folds = branch_folds(walk, located=True)
    out = {}
    for k in folds:
        scale = 1.0 + np.abs(ords[k])
        for j in range(math.ceil((lam.min() - lam[k]) / period),
                       math.floor((lam.max() - lam[k]) / period) + 1):
            target = lam[k] + j * period
            if j == 0 or any(abs(lam[g] - target) <= 1e-6 * (1 + abs(target))
                             and np.all(np.abs(ords[g] - ords[k]) <= 1e-4 * scale)
                             for g in folds):
                continue
            # steps whose ends bracket the fold's parameter and ordinates, within tol: a
            # fold's parameter is an extreme value, which the branch touches, not crosses
            near = ((np.minimum(lam[:-1], lam[1:]) - tol * (1 + abs(target)) <= target)
                    & (target <= np.maximum(lam[:-1], lam[1:]) + tol * (1 + abs(target)))
                    & np.all(np.minimum(ords[:-1], ords[1:]) - tol * scale <= ords[k], axis=1)
                    & np.all(ords[k] <= np.maximum(ords[:-1], ords[1:]) + tol * scale, axis=1))
            for i in np.flatnonzero(near):
                out[int(i)] = float(target)
    return out


def rule_index(scan: Scan) -> int | None:
    """The index at b by the fold rule from a's and the folds found in the step (None where
    the rule does not apply: no distinguished ordinate, a point found that is not a located
    fold, or a fold whose direction of index change the rule cannot tell)."""
    if scan.ordinate is None:
        return None
    step, fn = scan.step, scan.ordinate.fn

    def ordinate(state: State) -> float:
        return float(fn(state.s, state.y, state.params))

    out = scan.index_a
    for e in sorted(scan.found, key=lambda e: e.sigma):
        if e.kind != labels.LP or e.note:
            return None
        # xi'' from the tangents (robust at any step length), dB/dtau across the step
        change = index_change(scan.enters, step.b.tangent.lam - step.a.tangent.lam,
                              ordinate(step.b.state) - ordinate(step.a.state))
        if change == 0:
            return None
        out += change
    return out


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

    def crosses(self, walk, scan: Scan) -> bool:
        # none from a start at a branch point (the other branch's direction, ``singular``)
        return (self.crossed(scan.a_here, scan.step.b) and not scan.skip
                and not scan.step.a.extra.get("singular") and scan.on[labels.BP])

    def locate(self, walk, step: Step) -> Located:
        """The branch point in the step; CorrectorFailure where it is not located."""
        return locate_branch_point(walk.corr, step)

    def detect(self, walk, scan: Scan) -> None:
        """Where the determinant changed sign: the branch point located, unless
        :class:`SymmetricBranchPoint` placed it. One that cannot be located retries the step
        (spending a retry): where the step jumped to a nearby branch (an imperfect
        bifurcation's other half, whose determinant has the other sign), the solutions on
        the hyperplanes between the two branches fail or the sign change does not survive a
        finer mesh, and a shorter step follows the branch round its corner; once retries
        are spent, ``scan.unlocated`` says so. Where the parameter does not turn in the
        step, the point is the step's BP (its note: the kernel's check against the index
        change, :func:`kernel_check`), or the warning; where it turns, :class:`Fold`
        reconciles the two."""
        step = scan.step
        if not scan.crossed[labels.BP]:
            return
        if scan.located is None:
            try:
                scan.located = self.locate(walk, step)
            except CorrectorFailure as exc:
                if scan.can_retry:
                    raise Retry(f"branch point not located ({exc})", step.ds / 2,
                                exc.residual, spends=True) from None
                scan.unlocated = (f"branch point between {walk.name} = {step.a.lam:.6g} and "
                                  f"{step.b.lam:.6g} not located: {exc}")
        if scan.crossed[labels.LP]:
            return
        located = scan.located
        if located is not None:
            note = kernel_check(walk, located.state, scan.index_a, scan.index_b)
            scan.found.append(Hit(located.sigma, labels.BP, located.state, step.secant,
                                  abs(located.value), note=note))
        elif scan.unlocated:
            walk.branch.warnings.append(scan.unlocated)


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

    def detect(self, walk, scan: Scan) -> None:
        """Where :class:`BranchPoint`'s determinant changed sign: the point placed at the
        symmetric value, as ``scan.located``, for it to label."""
        if scan.crossed[labels.BP]:
            scan.located = self.locate(walk, scan.step)


class EvenBranchPoint(Event):
    """BP of even multiplicity: the index changes by an even number with neither a fold nor
    a sign change of the determinant (a double zero eigenvalue, as a symmetry makes). Test
    function: the stability index (a step function); located by bisection
    (:func:`~elastica_auto.branches.events.locate_index_change`). Its :meth:`detect` is the
    fold rule's check of the index at the step's end."""

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

    def detect(self, walk, scan: Scan) -> None:
        """The index at b against the fold rule's (:func:`rule_index`, from the points found
        before), where both counts are known and both folds and branch points are looked
        for. A mismatch retries the step (spending a retry); once retries are spent, an
        even change with nothing found is this kind's point (:meth:`point`), any other
        mismatch a warning."""
        index_a, index_b, step = scan.index_a, scan.index_b, scan.step
        if not (index_a >= 0 and index_b >= 0 and not scan.skip and scan.on[labels.LP]
                and scan.on[labels.BP]):
            return
        expected = rule_index(scan)
        if (expected is not None and expected != index_b and not scan.found
                and not scan.can_retry and (index_b - index_a) % 2 == 0):
            scan.found.append(self.point(walk, scan))
            expected = None
        if expected is not None and expected != index_b:
            if scan.can_retry:
                raise Retry(f"index {index_b} at the new point, the fold rule gives "
                            f"{expected}", step.ds / 2, spends=True)
            walk.branch.warnings.append(
                f"index {index_a} -> {index_b} between {walk.name} = {step.a.lam:.6g} and "
                f"{step.b.lam:.6g}, the fold rule gives {expected}, also at ds = "
                f"{step.ds:.3g}")

    def point(self, walk, scan: Scan) -> Hit:
        """A branch point where the index changed by an even number with neither a fold nor
        a change of sign of the determinant, down to the shortest step: eigenvalues crossed
        zero in pairs (a double zero eigenvalue, as a symmetry makes), which the determinant
        does not see. Located where the index changes (bisection)."""
        index_a, index_b, step = scan.index_a, scan.index_b, scan.step
        at = self.locate(walk, step, index_a)
        state = at.solution.state
        note = (f"index {index_a} -> {index_b} without a change of sign of the determinant "
                "(a branch point of even multiplicity)")
        kernel = kernel_check(walk, state, index_a, index_b)
        return Hit(at.sigma, labels.BP, state, step.secant,
                   note="; ".join(filter(None, (note, kernel))))


class ParameterValue(Event):
    """A value of the continued parameter: test function ``lam - value``; the step is split
    at its folds into monotone pieces (:meth:`Placement.pieces`) and each value is solved
    exactly on the piece whose ends bracket it
    (:func:`~elastica_auto.branches.events.locate_value`), so that a value crossed on both
    sides of a fold within one step is labelled on both. The pieces looked at are those the
    branch travels: up to the first that passes a bound (:meth:`travelled`)."""

    what = ""

    def test(self, walk, sol: Solution) -> float:
        return sol.lam

    def locate(self, walk, step: Step, x: State, y: State, s0: float, s1: float,
               value: float) -> Hit:
        """The point at ``value`` between the knots x and y (secant coordinates s0 < s1);
        CorrectorFailure where it is not found there."""
        state, sigma = locate_value(walk.corr, step, x, y, s0, s1, value)
        return Hit(sigma, self.label, state, tangent_between(step, sigma))

    def solve(self, walk, placement: Placement, x: State, y: State, s0: float, s1: float,
              value: float) -> Hit | None:
        """The point at ``value`` between the knots x and y. Where it is not found there
        although the knots' values bracket it, the branch does not pass from x to y through
        the solutions between them (a step that jumped to another branch, hostile M9): the
        step is retried (spending a retry, as for an event that cannot be located), then
        accepted with a warning and no point."""
        step = placement.step
        try:
            return self.locate(walk, step, x, y, s0, s1, value)
        except CorrectorFailure as exc:
            what = f"{self.what} {walk.name} = {value:.6g} not located"
            if placement.can_retry:
                raise Retry(f"{what} ({exc})", step.ds / 2, exc.residual,
                            spends=True) from None
            walk.branch.warnings.append(f"{what}: {exc}")
            return None

    @staticmethod
    def bound(walk, lx: float, ly: float) -> float | None:
        """The bound (``stops.lower``, ``upper``) passed from ``lx`` to ``ly``, or None."""
        stops = walk.stops
        return stops.upper if lx <= stops.upper < ly else \
            stops.lower if ly < stops.lower <= lx else None

    def travelled(self, walk, placement: Placement) -> list[tuple[float, State, float, State]]:
        """The step's monotone pieces the branch travels: up to the first that passes a
        bound, where it ends."""
        pieces = placement.pieces()
        for i, (_, x, _, y) in enumerate(pieces):
            if self.bound(walk, x.params[walk.name], y.params[walk.name]) is not None:
                return pieces[:i + 1]
        return pieces


class UserValue(ParameterValue):
    """UZ at the values of the continued parameter the run asks for (``uz``: the walk's
    ``user_values``, each with its period), in the order of travel; past the first ``room``
    points that count (`Walk.counts`) of a spec's values, none could be added, and none is
    solved for."""

    label, action, what = labels.UZ, CONTINUE, "user point"

    def place(self, walk, placement: Placement) -> None:
        specs = walk.user_values
        if not specs:
            return
        solved = [0] * len(specs)
        for s0, x, s1, y in self.travelled(walk, placement):
            lx, ly = x.params[walk.name], y.params[walk.name]
            for k, spec in enumerate(specs):
                for c in crossings(lx, ly, spec):
                    if solved[k] >= placement.room:
                        break
                    hit = self.solve(walk, placement, x, y, s0, s1, c)
                    if hit is not None:
                        placement.points.append(hit)
                        solved[k] += walk.counts(labels.UZ, hit.state.params)


class Bound(ParameterValue):
    """EP where the continued parameter reaches a bound (``bounds``: the walk's ``stops``),
    on the first monotone piece of the step that passes one: the branch ends there (a bound
    that cannot be located, at the piece's end, noted so)."""

    label, action, what = labels.EP, END, "bound"

    def place(self, walk, placement: Placement) -> None:
        s0, x, s1, y = self.travelled(walk, placement)[-1]
        value = self.bound(walk, x.params[walk.name], y.params[walk.name])
        if value is None:
            return
        hit = self.solve(walk, placement, x, y, s0, s1, value)
        if hit is None:
            hit = Hit(s1, labels.EP, y, placement.step.b.tangent, note="bound not located")
        hit.message = f"reached {walk.name} = {hit.state.params[walk.name]:g}"
        placement.end_at(self, hit)

    def ahead(self, walk, ds: float) -> Hit | None:
        """Before the first step, a start on a bound (to 1e-9 (1 + |bound|)) whose tangent
        leaves the bounds (its parameter component beyond its accuracy, TURN_NOISE, out of
        them): the branch ends at its start, the start's own point (sigma 0), with no step.
        Stepped, it would end there anyway, the bound located at the start again, a second
        EP at the same place."""
        if not walk.first or walk.until is not None:
            return None
        a, stops = walk.a, walk.stops
        lam, out = a.lam, a.tangent.lam
        for value, side, sign in ((stops.lower, "lower", -1.0), (stops.upper, "upper", 1.0)):
            if (math.isfinite(value) and abs(lam - value) <= 1e-9 * (1.0 + abs(value))
                    and sign * out > TURN_NOISE):
                return Hit(0.0, labels.EP, a.state, a.tangent,
                           message=f"left the bounds at its start ({walk.name} = {lam:g} is "
                                   f"the {side} bound, and this direction "
                                   f"{'decreases' if sign < 0 else 'increases'} {walk.name})",
                           direct=walk.branch.points[0].index_direct)
        return None


class FoldStop(Event):
    """``stop = ["LPn"]``: the branch ends at its n-th fold (``walk.stops.at_fold``), which
    keeps its label, LP. Placed last, once the other ends are known: of the step's points
    that stay before the end found so far (all, where there is none), in the order of
    travel, the fold that makes n with the branch's folds before the step becomes the end
    (it lies before the other), and the points after it go."""

    label, action = labels.LP, END

    def place(self, walk, placement: Placement) -> None:
        n = walk.stops.at_fold
        if n is None:
            return
        kept = [e for e in placement.points
                if placement.end is None or placement.ender.keeps(walk, placement, e)]
        order = sorted(kept, key=lambda e: e.sigma)
        before = len(branch_folds(walk))
        folds = [i for i, e in enumerate(order) if e.kind in labels.FOLDS]
        k = max(n - before, 1)
        if len(folds) < k:
            return
        i = folds[k - 1]
        fold = order[i]
        fold.message = f"stopped at fold {before + k} (stop = LP{before + k})"
        placement.points = order[:i]
        placement.end, placement.ender = fold, self

    def keeps(self, walk, placement: Placement, hit: Hit) -> bool:
        """Every point :meth:`place` left: those before the fold."""
        return True


class CourseEvents(Event):
    """The events of the walk's own course, in this order: the kinds the run asks for
    (``events = [...]``, the walk's ``watch``: each places its points, by default
    :meth:`Event.find`) and its limits on ordinates (``stop``, :class:`Limit`)."""

    def place(self, walk, placement: Placement) -> None:
        for event in (*walk.watch, *walk.stops.limits):
            event.place(walk, placement)


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

    def place(self, walk, placement: Placement) -> None:
        """Where the step passes the limit: the branch ends there, located by ``along``
        (not located: at the step's end, with a warning)."""
        step = placement.step
        if not self.passed(walk.problem, step):
            return
        try:
            at = locate_limit(walk.corr, walk.problem, step, self)
        except CorrectorFailure as exc:
            walk.branch.warnings.append(f"stop {self} not located: {exc}")
            at = None
        sigma = step.dist if at is None else at.sigma
        state = step.b.state if at is None else at.solution.state
        value = self.value + self.sign * (0.0 if at is None else at.value)
        placement.end_at(self, Hit(sigma, self.label, state, tangent_between(step, sigma),
                                   message=f"reached {self.name} = {value:.6g} (stop {self})"))

