"""A branch computed as the mirror image of another (a module's ``MIRROR``).

If a reflection maps the solutions at parameters p to solutions at p' (`Mirror`: y -> S y,
the continued parameter lam -> -lam, others negated or kept), and the start (y0, p0) of a
continuation is its own image, then the image of the branch that leaves the start one way
is a branch through the start too, leaving it the other way: the branch the continuation
computes in the other direction. At a regular start one curve of solutions passes, the
reflection maps it onto itself, and its tangent (ydot, lamdot) onto (S ydot, -lamdot) =
-(ydot, lamdot) (lamdot changes sign, so the image is the opposite direction, not the same).
The stepper's arithmetic commutes with the reflection too (the images of its Newton systems
are the same systems with rows and columns permuted and negated, and negation is exact in
floating point), so the image is the computation's, step for step (to rounding): every
point's parameters, ordinates (negated as the module declares), profile, labelled solution
and tangent are the images of the ``+`` branch's, its index and labels the same (the
energy, hence the second variation, is the same at both).

The branch's course must be symmetric too: bounds -b and b, no stops on an ordinate
(`symmetric_course`; a fold stop is symmetric), and UZ values that are the negatives of UZ
values. The paper's runs
ask for UZ values that are not (psi = pi/12, not -pi/12): the ``+`` branch is computed with
the negatives added (`mirror_course`), and its points at the values not asked for are set
aside for its image (`set_aside`), whose UZ points they give. Set aside, the ``+`` branch is
the one its own course gives, bit for bit (a UZ point is located within a step and changes
no step); its image is the ``-`` branch computed along `mirror_course` with the points at
the added values left out, to rounding. (The ``-`` branch computed along the run's own
course places some of its steps elsewhere, where a UZ value ends a step: its labels are
the same to the location's accuracy.)

So a run that continues a symmetric start both ways (the paper's rotating arm from the
straight rod, planar and in 3D) computes one branch of each pair. The image is used only
where nothing in the branch depends on the direction in a way the reflection does not say:
`symmetric_start` (the module's own problem, no free parameters or phase condition, a
regular start equal to its image, its given tangent if any the negative of its image) and
`image_of` (a ``+`` branch that ended EP at a bound, or at its fold stop, with no warnings
and no note about a location that failed; its image checked at a few labelled points
(`_witnesses`): the image solves the mirrored collocation equations and its ordinates are
those declared, within MIRROR_TOL).
Elsewhere the ``-`` branch is computed.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core import labels
from ..core.solution import State, Tangent
from .branch import Branch, Point, uncounted_parts
from .events import UserValues, is_user_value

#: The check of a mirrored point: its residual and recomputed ordinates within this of the
#: ``+`` branch's (relative to 1 + their size).
MIRROR_TOL = 1e-9


def symmetric_start(problem, parameter: str, origin) -> bool:
    """Whether the ``-`` branch from ``origin`` is the mirror image of the ``+`` one (the
    module docstring): ``problem`` is a module's own with a ``MIRROR`` that negates
    ``parameter``, the start is regular and its own image (exactly), and its tangent, if
    given, the negative of its image."""
    mirror = getattr(problem, "mirror", None)
    if mirror is None or parameter not in mirror[2].parameters or origin.kind != "regular":
        return False
    state = origin.state
    y, params = problem.mirrored(state.y, state.params)
    if not (np.array_equal(y, state.y) and params == state.params):
        return False
    t = origin.tangent
    if t is None:
        return True
    ty, _ = problem.mirrored(t.y, {})
    return bool(np.allclose(ty, -t.y, rtol=0.0, atol=1e-12 * (1.0 + np.max(np.abs(t.y)))))


def symmetric_course(course) -> bool:
    """Whether ``course`` ends branches where their mirror images end: bounds -b and b, and
    no stops on an ordinate (a fold stop, ``stop = "LP3"``, counts folds along the branch,
    which its image meets in the same order; a fold curve's course is not one); and labels
    the same points on both: no events asked for (``events``: an ordinate's value need not
    be its image's)."""
    stops = course.stops
    return (stops.lower == -stops.upper and not stops.limits and not course.all_folds
            and not course.watch)


def mirror_course(course):
    """``course`` with the negative of each UZ value added: the ``+`` branch's, whose image
    then has a point at each UZ value asked for. Their points do not count toward the
    branch's ``max_points`` (``counted_values``): set aside, the branch has the points its
    own course gives."""
    values = tuple(UserValues(tuple(sorted(set(u.values) | {-v for v in u.values})), u.period)
                   for u in course.user_values)
    # the added values' points are set aside (`set_aside`): not the branch's, nor counted
    return dataclasses.replace(course, user_values=values, counted_values=course.user_values)


def set_aside(branch: Branch, course) -> None:
    """Move the UZ points of ``branch`` at values ``course`` does not ask for (the negatives
    `mirror_course` added) out of its points into ``branch.mirror_points``: located within
    steps, they change no other point, and their images are the image's UZ points where
    ``course`` asks for them (`image_of`)."""
    name = course.parameter
    aside = [p for p in branch.points
             if p.type == labels.UZ and not is_user_value(p.params[name], course.user_values)]
    branch.points = [p for p in branch.points if all(p is not q for q in aside)]
    branch.mirror_points = aside


def image_of(problem, source: Branch, new: Branch, course) -> Branch | None:
    """``new`` (the empty ``-`` branch) filled with the mirror images of ``source``'s points
    and ``mirror_points`` (computed along `mirror_course`, `set_aside`) but those UZ points
    whose images ``course`` does not ask for; or None where the image is not used (the
    module docstring): then the ``-`` branch is computed."""
    name = source.parameter
    last = source.points[-1] if source.points else None
    at_bound = (source.end == labels.EP and last is not None
                and source.message == f"reached {name} = {last.params[name]:g}")
    at_fold = source.end == labels.LP and source.message.startswith("stopped at fold ")
    if (last is None or not (at_bound or at_fold) or source.interrupted or source.warnings
            or source.diagnostics or last.state is None
            or any("not located" in p.note for p in source.points)):
        return None
    if not all(_checked(problem, p) for p in _witnesses(problem, source)):
        return None
    for p in source.points:
        if not (p.type == labels.UZ and not is_user_value(-p.params[name], course.user_values)):
            new.points.append(_point_image(problem, p))
    for p in source.mirror_points:
        new.insert(_point_image(problem, p))
    if len(new.points) > source.options["max_points"]:
        # more UZ values on this side: the branch computed would end at max_points first
        new.points.clear()
        return None
    new.end = source.end
    new.message = (f"reached {name} = {new.points[-1].params[name]:g}" if at_bound
                   else source.message)
    return new


def _point_image(problem, p: Point) -> Point:
    _, params = problem.mirrored(p.profile[:, :0], p.params)
    ordinates = problem.mirrored_ordinates(p.ordinates)
    state = tangent = None
    if p.state is not None:
        s = p.state
        y, _ = problem.mirrored(s.y, {})
        yp, _ = problem.mirrored(s.yp, {})
        state = State(s.s, y, yp, params)
    if p.tangent is not None:
        t = p.tangent
        y, _ = problem.mirrored(t.y, {})
        yp, _ = problem.mirrored(t.yp, {})
        tangent = Tangent(t.s, y, yp, -t.lam)
    profile, _ = problem.mirrored(p.profile, {})
    return dataclasses.replace(p, params=params, ordinates=ordinates, profile=profile,
                               state=state, tangent=tangent, label=0)


def _witnesses(problem, branch: Branch) -> list[Point]:
    """The labelled points at which the image is checked: for each ordinate, the one where
    it is largest (a wrong sign shows where it is not zero), and the one farthest from its
    own image (a wrong map of the states shows there)."""
    pts = [p for p in branch.points if p.state is not None]
    chosen = {id(pts[-1]): pts[-1]}

    def size(v):
        return abs(v) if np.isfinite(v) else -1.0

    for k in problem.ordinate_names:
        p = max(pts, key=lambda p: size(p.ordinates[k]))
        chosen[id(p)] = p
    p = max(pts, key=lambda p: float(np.max(np.abs(problem.mirrored(p.state.y, {})[0]
                                                   - p.state.y))))
    chosen[id(p)] = p
    return list(chosen.values())


def _checked(problem, p: Point) -> bool:
    """Whether the image of the labelled point ``p`` solves the mirrored problem as ``p``
    solves its own (the collocation residual y' - f at the nodes and the boundary
    conditions) and has the ordinates the mirror declares."""
    s = p.state
    y, params = problem.mirrored(s.y, s.params)
    yp, _ = problem.mirrored(s.yp, {})

    def residual(y, yp, params):
        return max(float(np.max(np.abs(yp - problem.rhs(s.s, y, params)))),
                   float(np.max(np.abs(problem.bc(y[:, 0], y[:, -1], params)))))

    own, image = residual(s.y, s.yp, s.params), residual(y, yp, params)
    if image > 2 * own + MIRROR_TOL * (1.0 + float(np.max(np.abs(s.y)))):
        return False
    # (a fold's or branch point's parts are not counted: `new_point`)
    got = problem.ordinate_values(s.s, y, params, uncounted_parts(problem, s)
                                  if p.type in labels.TURNS and problem.has_second_variation
                                  else None)
    for k, want in problem.mirrored_ordinates(p.ordinates).items():
        if not (got[k] == want or abs(got[k] - want) <= MIRROR_TOL * (1.0 + abs(want))):
            return False
    return True
