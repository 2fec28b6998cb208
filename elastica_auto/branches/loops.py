"""Where a branch comes back, as events: to its start point (a closed loop ends there, EP:
:class:`Closure`), or to its start translated by whole periods of the continued parameter
(the rest of the branch is its first period translated: :class:`Period`, whose action,
``repeat``, the walk carries out by copying that period).

Both compare the start with the step: the start (or its translate) ``x0`` projects onto the
step's unit secant ``t`` at ``sigma = <x0 - a, t>`` with ``0 < sigma <= dist``, lies within
``CLOSED_LOOP dist`` of the secant's line there (``|x0 - a - sigma t| <= CLOSED_LOOP dist``:
the chord of an arc that turns by at most ``max_angle``, 0.35 rad by default, stays within
about ``max_angle / 8`` of its length of the arc), and the branch passes it the way it left
it (the start's tangent and the secant have a cosine of at least ``CLOSED_LOOP_COS``).
"""

from __future__ import annotations

import math

from ..core import labels
from ..core.solution import State, Tangent, difference, inner, norm
from ..model.problem import periods_applied
from ..numerics.correctors import CorrectorFailure
from .events import Step
from .kinds import END, REPEAT, Event, Hit, Placement

#: A branch is back at its start point where the start lies within the next step along the
#: tangent (within this fraction of its distance along the tangent from that line), or
#: inside the step just taken along its secant (within this fraction of the step's length of
#: the chord).
CLOSED_LOOP = 0.2
#: ... and the secant points the way the branch left its start: their cosine is at least this.
CLOSED_LOOP_COS = 0.5
#: The largest gap (in norm, relative) between the branch's solution where it passes its
#: start translated by whole periods and the translate (:class:`Period`).
REPEAT_GAP = 1e-4


def turned(problem, name: str, state: State, k: int, value: float) -> State:
    """``state`` moved by ``k`` periods of parameter ``name`` to its ``value``."""
    return State(state.s, periods_applied(problem, name, state.y, k),
                 periods_applied(problem, name, state.yp, k, True), {**state.params,
                                                                     name: value})


def turned_tangent(problem, name: str, t: Tangent | None, k: int) -> Tangent | None:
    """The tangent ``t`` at a solution, at that solution moved by ``k`` periods."""
    if t is None:
        return None
    return Tangent(t.s, periods_applied(problem, name, t.y, k, True),
                   periods_applied(problem, name, t.yp, k, True), t.lam)


def far(walk, a, length: float) -> bool:
    """Whether the start is farther from ``a`` in the parameter alone than either check
    allows: both need |x0 - a| <= hypot(1, CLOSED_LOOP) ``length`` (the start within
    ``length`` along a line from a, within CLOSED_LOOP ``length`` of it), and the norm
    bounds the parameter's difference. (The checks interpolate the start onto a's mesh;
    this one costs nothing, and rules out nearly every step.)"""
    gap = abs(walk.start.state.params[walk.name] - a.state.params[walk.name])
    return gap > math.hypot(1.0, CLOSED_LOOP) * length


def closed(walk, arclength: float) -> str:
    """The message of a branch that closed its loop after ``arclength``."""
    return (f"closed loop: back at its start point ({walk.name} = {walk.start.lam:g}) "
            f"after arclength {arclength:.6g}")


def passes(walk, step: Step, there: State, tangent: Tangent) -> float | None:
    """The secant coordinate at which the step passes ``there`` (the start or a translate of
    it, with its tangent) the way the branch left it, or None where it does not."""
    s = step.b.mesh
    sigma = step.sigma(there)
    if not 0.0 < sigma <= step.dist:
        return None
    off = difference(there, step.a.state, walk.name, s)
    off = Tangent(s, off.y - sigma * step.secant.y, off.yp - sigma * step.secant.yp,
                  off.lam - sigma * step.secant.lam)
    if (norm(off) > CLOSED_LOOP * step.dist
            or inner(tangent.on(s), step.secant, s) < CLOSED_LOOP_COS):
        return None
    return sigma


def at_start(walk, step: Step, event: Hit, end: Hit) -> bool:
    """Whether ``event``, found in the step that closes the loop at ``end`` (or that passes
    the start's translate by a period), is the start itself found again (the fold or branch
    point the branch was started from, the UZ point at its translate, to 1e-6) or lies past
    it (an event that could not be located, placed at the step's end)."""
    if step.sigma(event.state) >= end.sigma:
        return True
    s = end.state.s
    gap = norm(difference(event.state, end.state, walk.name, s), s)
    return gap <= 1e-6 * (1.0 + norm(end.state, s) + abs(walk.start.lam))


class Closure(Event):
    """EP at the branch's start point where the branch comes back to it (a closed loop, an
    isola, the two halves of a pitchfork's other branch): the end point is the start's own
    solution, so the loop closes exactly. Not in a walk that ends at a hyperplane
    (``until``: the refinement of one step), nor in its first step."""

    label, action = labels.EP, END

    def ahead(self, walk, ds: float) -> Hit | None:
        """The start, where it lies within the next step (ahead of a along its tangent by
        sigma <= ds, within ``CLOSED_LOOP`` sigma of the tangent's line, the tangent pointing
        the way the branch left it): a step that ends next to a singular start (a branch
        point it was switched from) would see the start's own fold or branch point there,
        and fail to locate it. (Measured against ds, which ``growth`` makes far longer than
        any step the branch has taken, the start of the rotating arm was "ahead" of points a
        period away: hostile M9.)"""
        start, a = walk.start, walk.a
        if start is None or walk.until is not None or walk.first or far(walk, a, ds):
            return None
        s = a.mesh
        t = a.tangent.on(s)
        off = difference(start.state, a.state, walk.name, s)
        sigma = inner(off, t, s)
        if not 0.0 < sigma <= ds:
            return None
        off = Tangent(s, off.y - sigma * t.y, off.yp - sigma * t.yp, off.lam - sigma * t.lam)
        if norm(off) > CLOSED_LOOP * sigma or inner(start.tangent.on(s), t, s) < CLOSED_LOOP_COS:
            return None
        return Hit(sigma, labels.EP, start.state, start.tangent,
                   message=closed(walk, walk.arclength + sigma),
                   direct=walk.branch.points[0].index_direct)

    def place(self, walk, placement: Placement) -> None:
        """The start, where the step passes it the way the branch left it (:func:`passes`)."""
        start, step = walk.start, placement.step
        if (start is None or walk.until is not None or walk.first
                or far(walk, step.a, step.dist)):
            return
        sigma = passes(walk, step, start.state, start.tangent)
        if sigma is not None:
            placement.end_at(self, Hit(sigma, labels.EP, start.state, start.tangent,
                                       message=closed(walk, step.position(sigma))))

    def keeps(self, walk, placement: Placement, hit: Hit) -> bool:
        """The points before the start, but the start itself found again (:func:`at_start`)."""
        return (hit.sigma < placement.end.sigma
                and not at_start(walk, placement.step, hit, placement.end))


class Period(Event):
    """The start translated by whole periods of the parameter, where the step passes it the
    way the branch left it (:func:`passes`) and the branch's own solution on that hyperplane
    is the translate: from there on the branch is its first period translated (action
    ``repeat``: the walk copies it). Only where the walk may repeat (``walk.period``, None
    where it may not), not in its first step.

    The translate is checked twice, since what follows copies it: the solution on the
    hyperplane through it differs from it by at most REPEAT_GAP (relative, in norm; the
    corrector's tolerance makes the two discrete solutions differ by about 1e-6), and its
    ordinates equal the start's to rounding (the module's ordinates are periodic in the
    parameter as its equations are; a module whose ordinates are not gets a warning, and
    no branch of it repeats: ``walk.period`` becomes None)."""

    # no label of its own: the translate is labelled as the start's point was (UZ where it is
    # a user value), by the walk's copy of the period
    label, action = "", REPEAT

    def begin(self, walk, course) -> None:
        """``walk.period``: the period of the continued parameter if the branch may be
        completed by translation once it passes its start one period on: a regular start,
        and nothing that a translate would have to decide afresh. Each UZ value recurs with
        a period that divides the parameter's (every translate of a user point is one, and
        no other point becomes one); no fold stop, no limit, no event the run asks for
        (``watch``: a module's ordinates need not be periodic), not a fold curve. (Nor the
        refinement of a step: :meth:`place` skips a walk with ``until``.)"""
        period = walk.problem.parameters[walk.name].period
        if (period is None or walk.singular_start or course.all_folds or course.stops.limits
                or course.stops.at_fold is not None or course.watch):
            return
        for spec in course.user_values:
            if spec.period is None:
                return
            ratio = period / spec.period
            if not abs(ratio - round(ratio)) <= 1e-12 * ratio:
                return
        walk.period = period

    def place(self, walk, placement: Placement) -> None:
        if walk.period is None or walk.until is not None or walk.first:
            return
        step = placement.step
        start, name, period = walk.start, walk.name, walk.period
        lo, hi = sorted((step.a.lam, step.b.lam))
        reach = math.hypot(1.0, CLOSED_LOOP) * step.dist
        s = step.b.mesh
        for k in range(math.ceil((lo - reach - start.lam) / period),
                       math.floor((hi + reach - start.lam) / period) + 1):
            if k == 0:
                continue
            there = turned(walk.problem, name, start.state, k, start.lam + k * period)
            tangent = turned_tangent(walk.problem, name, start.tangent, k)
            sigma = passes(walk, step, there, tangent)
            if sigma is None:
                continue
            try:
                sol = walk.corr.on_plane(step.a, step.secant, sigma, s, regrid=False)
            except CorrectorFailure:
                continue
            if norm(difference(sol.state, there, name, s), s) > REPEAT_GAP * (1.0 + norm(there, s)):
                continue
            ours = walk.problem.ordinate_values(there.s, there.y, there.params)
            first = walk.branch.points[0].ordinates
            if any(abs(v - first[q]) > 1e-9 * (1.0 + abs(first[q])) for q, v in ours.items()):
                walk.branch.warnings.append(
                    f"the branch passes its start translated by {k} periods of {name}, but "
                    "the ordinates there differ from the start's: not completed by translation")
                walk.period = None
                return
            placement.end_at(self, Hit(sigma, self.label, there, tangent))
            return

    def keeps(self, walk, placement: Placement, hit: Hit) -> bool:
        """The points before the translate, but the start's own found again there
        (:func:`at_start`)."""
        return (hit.sigma < placement.end.sigma
                and not at_start(walk, placement.step, hit, placement.end))
