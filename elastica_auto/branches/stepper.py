"""The pseudo-arclength loop: predict, correct, check, detect, locate, accept.

One call of :func:`continue_branch` fills one :class:`~elastica_auto.branches.branch.Branch`: from a
start solution, in one direction, until a parameter bound (EP), the point limit (EP), the
n-th fold (``stop = ["LP4"]``), its own start point again (EP: a closed loop), or a
failure (MX: a corrector failure at ``ds_min``, an exception, an interruption), which the
walk hands to the failure kind (``registry.FAILURE``,
:class:`~elastica_auto.branches.kinds.Failure`): that kind ends the branch and says why.

Each step from a solution a (with its unit tangent t_a, oriented along the direction of
travel):

1. **predict and correct**: Keller's system ``<x - a, t_a> = ds`` from ``a + ds t_a``
   (:mod:`elastica_auto.numerics.correctors`), on a's mesh or a coarser one; the corrector regrids b
   if its error estimate exceeds ``tol``;
2. **check** (a failed check halves ds and retries; below ``ds_min`` the branch ends MX):
   the tangent turned by more than ``max_angle``, or the correction moved b farther than
   ``ds / 2`` from the predictor (it would have jumped to another branch), or, for a step
   more than LONG_STEP times the last one accepted, the branch does not reach b along an
   arc (checked halfway: :meth:`Walk._arc_checked`);
3. **detect** on one mesh: a fold where the tangent's parameter component changes sign (by
   more than its accuracy: :func:`~elastica_auto.branches.events.parameter_turns`), a
   branch point where the bordered Jacobian's determinant does, a hidden fold pair where the
   parameter's slope dips inside the step (:func:`~elastica_auto.branches.events.pair_suspected`;
   the step is probed for the slope's minimum, and retried shorter if a fold is there);
   either kind can be switched off (the option ``detect``, AUTO-07p's ILP and ISP);
4. **locate** each, exactly (:mod:`elastica_auto.branches.events`); a fold or branch point that
   cannot be located, or a stability index at b that the fold rule does not predict, or a
   UZ value the ends bracket that no solution between them crosses, rejects the step (a
   fold pair or a jump to another branch), down to 1/64 of the last step accepted and then
   with a warning;
5. **accept**: the placed kinds put the step's other points in (user points, UZ, and bounds,
   EP, solved on the monotone pieces between the folds; the events the run asks for,
   ``events = [...]``; the limits of ``stop``; the start again, a closed loop; the start
   translated by a period, where the branch repeats); b is added, ds grows by ``growth``
   after an easy step.

Every kind of special point is an event object (:mod:`elastica_auto.branches.kinds`), the
shipped ones created in :mod:`elastica_auto.branches.registry`, which the walk drives in two
ordered sets and imports none of: steps 3 and 4 are the turn kinds of ``registry.DETECTION``
(folds, branch points), each on the step's :class:`~elastica_auto.branches.kinds.Scan` in
that order, which is the order of their reconciliation (the fold-pair probe, the retries
they ask for and the fold rule's check are theirs); step 5 is the placed kinds of
``registry.PLACEMENT``, each on the step's :class:`~elastica_auto.branches.kinds.Placement`
(their solves, retries, warnings and ends are theirs; the walk adds the points in order and
carries out the end: ``end``, or ``repeat``). The walk is one class made of named parts: the
points and their room (``_Points``), detection (``_Detection``), the step's points in order
(``_Placement``), the repeat by a period (``_Return``), a step walked again with short steps
(``_Refinement``, for a kind that finds after the walk that a step passed over its points:
``Event.finish``, the fold's translates by a period), and the loop (``Walk``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .branch import PROFILE_GRID, Branch, Point, new_point
from ..numerics.correctors import (AUTO_GAUSS, GAUSS_PAYS, CorrectorFailure, Solution,
                                   choose_ncol, gauss_pays, make_corrector,
                                   may_turn_to_gauss)
from .events import Step, UserValues, is_user_value
from .kinds import REPEAT, Event, Hit, Placement, Retry, Scan
from .loops import turned, turned_tangent
from .switching import KERNEL_RTOL
from . import registry
from ..core import labels
from ..core.errors import ENGINE, debugging, failure_record, module_files
from ..core.options import NCOL_AUTO, ContinuationOptions
from ..core.solution import State, Tangent, difference, inner, norm, secant
from ..model.problem import periods_applied
from ..numerics.stability import Count, count

#: A step whose fold rule, fold or branch point or UZ value location (an event that cannot be
#: located) fails is retried down to 1 / 2**RETRY_HALVINGS of the last step accepted (or of
#: its own first length, if shorter).
RETRY_HALVINGS = 6
#: ds grows after a step whose Newton iteration contracted at least this fast (and whose
#: tangent turned by less than half of max_angle).
EASY_CONTRACTION = 0.3
#: A unit tangent whose parameter component is at most this leaves the parameter stationary
#: to first order: its orientation is then decided by :func:`_orientation`.
STATIONARY = 1e-6
#: A probe's rise of the parameter below this (relative) is the corrector's noise, not a side.
RISE_NOISE = 1e-10
#: A step longer than LONG_STEP times the last one accepted (one grown by ``growth`` > 1.5)
#: has not been shown to stay on the branch at that length: a
#: branch that lies near the tangent's line farther on (the rotating arm's translates by a
#: period, the rod turned rigidly) can catch the corrector with every other check passed,
#: the tangent turned by 12 degrees and b within a twentieth of ds of the predictor (hostile
#: M9: ds grown by 100 from 0.16 to 7.8). Its arc is checked (`Walk._arc_checked`). With
#: growth <= 1.5 (the default 1.4) no step is: the check costs one solve where it is made.
LONG_STEP = 1.5


@dataclass(frozen=True)
class Stops:
    """Where a branch ends: bounds on the continued parameter, the n-th fold (or None), and
    limits on ordinates or free parameters (`elastica_auto.branches.kinds.Limit`)."""

    lower: float = -math.inf
    upper: float = math.inf
    at_fold: int | None = None
    limits: tuple[Event, ...] = ()


class _Reject(Retry):
    """The step is rejected by the walk's own checks: retry with ``ds``, for the reason in
    the message (``residual``: the corrector's last Newton correction, if it failed)."""


def start_solution(corr, start: State, direction: int, guess: Tangent | None,
                   exact: bool) -> Solution:
    """The start as a linearised solution, its tangent oriented so that the parameter moves in
    ``direction`` (along a stored tangent ``guess`` where the parameter is stationary).
    ``exact``: ``guess`` is the direction to follow as it is (the other branch at a branch
    point, where the bordered Jacobian is singular).

    The two directions always leave along +t and -t of one tangent t. Where the parameter is
    stationary to first order (|t_lam| <= STATIONARY: a fold, a cusp, a hysteresis point),
    the sign of t_lam is rounding and says nothing; t is then oriented along ``guess``, or
    else by :func:`_orientation`, which does not depend on the sign the solver returned."""
    if exact:
        sol = corr.linearize(start, guess)
        sol.tangent = guess.on(sol.mesh)
        sol.extra["singular"] = True
        return sol
    t = _tangent_of(corr.linearize(start, guess)).tangent
    if abs(t.lam) > STATIONARY:
        sign = 1.0 if t.lam * direction > 0 else -1.0
    elif guess is not None:  # t is oriented along the stored tangent: <guess, t> > 0
        sign = float(direction)
    else:
        sign = direction * _orientation(corr, start, t)
    sol = _tangent_of(corr.linearize(start, t.scaled(sign)))
    if guess is None and corr.kernel(sol)[1] <= KERNEL_RTOL:
        # a start from values whose bordered Jacobian along its own tangent is singular: the
        # kernel of [F_y, F_lam] has a second direction, which no tangent picks. Exact zero
        # pivots once made its tangent NaN here; whether a pivot is exactly zero or of the
        # size of rounding is rounding's choice, so the kernel is tested (its residual:
        # rounding where singular, 1e-2 or more where regular; `switching.KERNEL_RTOL`)
        raise CorrectorFailure(SINGULAR_START)
    return sol


#: Why a start has no tangent where its linearisation gives none that is finite.
SINGULAR_START = ("the linearised problem is singular there: its Jacobian has a null "
                  "direction that the parameter does not fix, as a missing or dependent end "
                  "condition leaves; check the module's end conditions")


def _tangent_of(sol: Solution) -> Solution:
    """``sol``, whose tangent (the solve of the bordered Jacobian) is finite; CorrectorFailure
    (SINGULAR_START) where it is not. A singular bordered matrix gives a tangent of NaN or inf
    from the elimination, not an error; stepped along, the predictor would be non-finite and
    every corrector fail as if the module had returned NaN."""
    t = sol.tangent
    if not (math.isfinite(t.lam) and np.isfinite(t.y).all()):
        raise CorrectorFailure(SINGULAR_START)
    return sol


def _orientation(corr, start: State, t: Tangent) -> float:
    """+1 if t, else -1 (-t), is the way a stationary start goes up in the parameter.

    A probe on the hyperplanes at +-ds along t (ds the options' first step): at a cusp or
    hysteresis point, lam - lam_0 ~ c sigma^3, and the side where the parameter rose is
    +. Where both sides agree (a fold or a pitchfork, lam - lam_0 ~ c sigma^2) or a probe
    fails, or a rise is within RISE_NOISE, the side of t whose largest component (in absolute
    value, over every state and node; the first of equals) is positive: a choice made by the
    solution, not by the sign the solver returned."""
    sol = corr.linearize(start, t)
    ds = abs(corr.options.ds)
    try:
        rise = [corr.on_plane(sol, t, side * ds, regrid=False).lam - sol.lam
                for side in (1.0, -1.0)]
    except CorrectorFailure:
        rise = [0.0, 0.0]
    noise = RISE_NOISE * (1.0 + abs(sol.lam))
    if rise[0] * rise[1] < 0 and min(abs(r) for r in rise) > noise:
        return 1.0 if rise[0] > 0 else -1.0
    # the first of the largest components (an antisymmetric kernel has two of one size)
    size = np.abs(t.y.ravel())
    first = int(np.argmax(size >= (1.0 - 1e-8) * size.max()))
    return 1.0 if t.y.ravel()[first] > 0 else -1.0


#: The message of a branch ended by Ctrl-C or SIGTERM (a ``--resume`` computes it again).
INTERRUPTED = "interrupted by the user"


@dataclass(frozen=True)
class Origin:
    """Where a branch starts: a solution, a tangent to start along (or None: the bordered
    tangent there), and what kind of point it is: ``"regular"``; ``"singular"`` (a fold or a
    branch point: none is sought in the first step, where the start's own would be found);
    ``"switch"`` (the other branch at a branch point: ``tangent`` is its direction, already
    oriented, used as it is, since the bordered tangent system is singular there).
    ``ncol``: the discretisation that computed ``state`` where it is a stored label's (its
    branch's ``ncol``; None: not stored, or not chosen), which a branch under ``ncol =
    "auto"`` keeps (`elastica_auto.numerics.correctors.choose_ncol`)."""

    state: State
    tangent: Tangent | None = None
    kind: str = "regular"
    ncol: int | None = None

    def __post_init__(self):
        if self.kind not in ("regular", "singular", "switch"):
            raise ValueError(f"unknown kind of start {self.kind!r}")
        if self.kind == "switch" and self.tangent is None:
            raise ValueError("a switch needs the direction of the other branch")


@dataclass(frozen=True)
class Course:
    """How a branch is continued: the parameter, the options, where it ends, its UZ values.
    ``all_folds``: every point is a fold (a fold curve), and its ``fold_residual`` is the
    point's largest error estimate, of the solution and its null vector together.
    ``events``: folds and branch points are located; False: the points alone, each with its
    directly counted index (what `analysis.snaps.subcritical` asks of the branches born at a
    branch point: on the isotropic rod's they keep the parameter constant, and every step
    met a turn of its rounding that could not be located: 8% of a 3D run's time).
    ``counted_values``: the UZ values whose points count toward ``max_points`` (None: all of
    ``user_values``); the others are set aside for the branch's mirror image
    (`elastica_auto.branches.mirror.mirror_course`) and are no points of this branch.
    ``watch``: the events the run asks for (``events = [...]``,
    `elastica_auto.branches.registry.parse_events`), each found in every step by its own
    test function (:meth:`~elastica_auto.branches.kinds.Event.find`)."""

    parameter: str
    options: ContinuationOptions
    stops: Stops = Stops()
    user_values: tuple[UserValues, ...] = ()
    all_folds: bool = False
    events: bool = True
    counted_values: tuple[UserValues, ...] | None = None
    watch: tuple[Event, ...] = ()


def continue_branch(branch: Branch, problem, course: Course, origin: Origin,
                    progress: Callable[[Branch, float], None] | None = None) -> Branch:
    """Continue from ``origin`` in ``course.parameter`` in ``branch.direction``; fills
    ``branch``.

    Points are added as they are accepted. Nothing escapes: Ctrl-C, or an exception (the
    equation module raising, exiting or returning what the engine cannot use, a numerical
    failure, or an internal error of the engine), ends the branch at its last accepted
    point, labelled MX, with ``branch.interrupted`` set or the exception's type, message,
    place and kind (`elastica_auto.core.errors.failure_record`; an internal error's message
    starts "internal error:" and its diagnostics keep the whole traceback) in
    ``branch.message`` and ``branch.diagnostics``. With ``--debug`` an internal error is
    raised instead.

    Where the module declares a symmetry that moves the start (a circle of solutions), the
    branch is continued with a phase condition and an unfolding parameter
    (`elastica_auto.model.symmetry`); its points hold the module's states, their notes the
    unfolding parameter.
    """
    from ..model.symmetry import phased
    phase = phased(problem, origin.state, origin.tangent if origin.kind == "switch" else None)
    if phase is not None:   # a family of solutions the symmetry turns: continued with a phase
        problem = phase     # condition (elastica_auto.model.symmetry)
        origin = Origin(phase.lift(origin.state), phase.lift_tangent(origin.tangent),
                        origin.kind, origin.ncol)
    _continue(branch, problem, course, origin, progress)
    if phase is not None:
        phase.drop(branch)
    _warn_undefined_index(branch)
    return branch


#: the end of the note of a point whose second variation has no index (`count` refused it:
#: A not positive definite, numerics/stability.py)
UNDEFINED_INDEX = "the stability index is not defined"


def _warn_undefined_index(branch: Branch) -> None:
    """One warning for the points whose stability index the second variation does not
    define (the Legendre condition fails: A not positive definite), with the first one's
    reason. Each such point's note says so, but a note is read by nothing a user sees
    (`show`, the run's lines): the index column was only empty there, and the run said
    nothing of a hook whose A is wrong."""
    where = [(k, p) for k, p in enumerate(branch.points, 1) if UNDEFINED_INDEX in p.note]
    if not where:
        return
    name = branch.parameter
    values = [p.params[name] for _, p in where]
    reason = next(part for part in where[0][1].note.split("; ") if UNDEFINED_INDEX in part)
    branch.warnings.append(
        f"no stability index at {len(where)} points (pt {where[0][0]} to {where[-1][0]}, "
        f"{name} from {min(values):.6g} to {max(values):.6g}): {reason}")


def _continue(branch: Branch, problem, course: Course, origin: Origin, progress):
    walk = None
    try:
        # the discretisation, chosen from the start under ncol = "auto" and recorded as the
        # number chosen: the branch's points are that scheme's, and a restart from them
        # keeps it
        auto = course.options.ncol == NCOL_AUTO and course.options.corrector == "collocation"
        ncol = choose_ncol(problem, course.parameter, course.options, origin.state,
                           origin.ncol)
        if ncol != course.options.ncol:
            course = dataclasses.replace(
                course, options=dataclasses.replace(course.options, ncol=ncol))
        branch.options = {**branch.options, "ncol": ncol}
        corr = make_corrector(problem, course.parameter, course.options)
        try:
            a = start_solution(corr, origin.state, branch.direction, origin.tangent,
                               origin.kind == "switch")
        except CorrectorFailure as exc:
            registry.FAILURE.at_start(branch, problem, origin.state, exc)
            return branch
        walk = Walk(branch, problem, corr, course, progress, origin.kind != "regular")
        # under ncol = "auto" a cubic branch may still turn to Gauss collocation where its
        # meshes grow (`Walk._choose_scheme`); one from a stored label (a restart, a switch,
        # a fold curve) keeps the label's scheme throughout, as does a problem with an index
        walk.scheme_open = (auto and ncol == 0 and origin.ncol is None
                            and may_turn_to_gauss(problem))
        walk.run(a)
    except KeyboardInterrupt:
        branch.interrupted = True
        registry.FAILURE.ended_early(branch, problem, walk, origin, INTERRUPTED)
    except (Exception, SystemExit) as exc:   # whatever fails fails this branch only
        # (SystemExit: the module calling sys.exit, which would end the command with status 0)
        record = failure_record(exc, module_files(problem.module))
        if record["kind"] == ENGINE and debugging():
            raise
        error = " ".join(record["error"].split())  # one line, as every message of a branch
        last = walk.a.state if walk is not None and walk.a is not None else origin.state
        when = f"after point {len(branch.points)}" if branch.points else "at the start"
        internal = "internal error: " if record["kind"] == ENGINE else ""
        registry.FAILURE.ended_early(
            branch, problem, walk, origin,
            f"{internal}{record['exception']}: {error} ({record['where']}) {when} "
            f"({course.parameter} = {last.params[course.parameter]:g})", record)
    return branch


class _Points:
    """The branch's points and the room for them: adding a point, ending the branch at the last
    one accepted, and ``max_points`` (the points that count toward it, a UZ point set aside for
    a mirror image does not: :meth:`counts`, which the placed kinds ask too). Reads ``branch``,
    ``problem``, ``corr``, ``opt``, ``a``, ``base_point``, ``arclength``, ``all_folds``,
    ``counted_values``."""

    def _add(self, state: State, **fields) -> Point:
        if self.all_folds and not math.isfinite(fields.get("fold_residual", math.nan)):
            # a start, user or end point of a fold curve: its error estimate, as for a step
            fields["fold_residual"] = float(np.max(self.corr.error_estimate(state)))
        return self.branch.insert(new_point(self.problem, state, **fields))

    def end_at_base(self, kind: str, message: str):
        """End the branch at the last accepted point, labelled ``kind`` (a point already
        labelled keeps its label, and ``kind`` follows as a point of its own)."""
        branch, a = self.branch, self.a
        if self.base_point.type:
            self._add(a.state, type=kind, arclength=self.arclength, tangent=a.tangent,
                      direct=self.base_point.index_direct)
        else:
            branch.relabel(self.base_point, kind, a.state, a.tangent)
        branch.end, branch.message = kind, message

    def counts(self, kind: str, params: dict) -> bool:
        """Whether a point of this ``kind`` at parameters ``params`` counts toward
        ``max_points``: all but UZ points at values set aside for the branch's mirror image
        (not among ``counted_values``)."""
        return (kind != labels.UZ or self.counted_values is None
                or is_user_value(params[self.name], self.counted_values))

    def _room(self) -> int:
        """``max_points`` less the points that count toward it."""
        pts = self.branch.points
        if self.counted_values is None:
            return self.opt.max_points - len(pts)
        # the points not counted, kept for the points checked so far while the branch only
        # grows at its end (recounted where it changed before the last one checked)
        n, aside, last = self._aside
        if n > len(pts) or (n and pts[n - 1] is not last):
            n, aside = 0, 0
        aside += sum(1 for p in pts[n:] if not self.counts(p.type, p.params))
        self._aside = (len(pts), aside, pts[-1] if pts else None)
        return self.opt.max_points - len(pts) + aside

    def _full(self) -> str:
        return f"reached max_points = {self.opt.max_points}"

    def _end_full(self, last: Point | None, following: str = ""):
        """End the branch at ``max_points`` inside a step: at the last point it added (a
        labelled one, followed by an EP of its own), or at the step's start if none. Where
        that leaves one point unused, the message says why: the ``following`` point (its
        label) would have needed the EP after it as well."""
        if last is None:
            self.end_at_base(labels.EP, self._full())
        else:
            self._add(last.state, type=labels.EP, arclength=last.arclength, tangent=last.tangent,
                      direct=last.index_direct)
            self.branch.end, self.branch.message = labels.EP, self._full()
        if following and self._room() > 0:
            self.branch.message += (f" (the next point, {following}, and the EP after it would "
                                    "exceed it)")


class _Detection:
    """The step's turns (folds and branch points), detected and located by the turn kinds of
    the registry (`elastica_auto.branches.registry.DETECTION`), each on the step's
    :class:`~elastica_auto.branches.kinds.Scan`, in that order; a kind's ``Retry``
    rejects the step (``_walk`` retries it shorter)."""

    def _detect(self, step: Step, retries: int) -> tuple[list[Hit], Count]:
        """The folds and branch points in the step, located, and the index at b, checked
        against the fold rule; a fold pair suspected inside the step, a fold that cannot be
        located or an index the rule does not give rejects it (up to RETRY_HALVINGS times,
        then with a warning). Returns the events and b's count.

        Every turn kind first says whether its test function changed sign in the step
        (``crosses``), then each locates its points (``detect``) in the order of
        ``DETECTION``, which is the order of their reconciliation (docs/design.md, "Special
        points as events")."""
        corr, a, b = self.corr, step.a, step.b
        s = b.mesh
        skip = (self.first and self.singular_start) or not self.events
        a_here = a if len(a.mesh) == len(s) and (a.mesh == s).all() else corr.relinearize(a, s)
        counted = count(self.problem, b.state)
        # retries for a fold that cannot be located or a fold rule that fails count until a
        # step with a fold is accepted: shorter steps that stop before the fold do not reset
        # them (they would approach the fold for ever)
        self.can_retry = max(retries, self.event_retries) < RETRY_HALVINGS
        scan = Scan(step, a_here, self.base_point.index_direct, counted.index, skip,
                    self.detected, self.can_retry,
                    self.ordinate, self.enters)
        turns = registry.DETECTION     # read here: a kind registered there is driven too
        for event in turns:
            crossed = event.crosses(self, scan)
            if crossed is not None:
                scan.crossed[event.label] = crossed
        try:
            for event in turns:
                event.detect(self, scan)
        except Retry as rej:
            self.event_retries += rej.spends
            raise
        if scan.found:
            self.event_retries = 0
        return scan.found, counted


class _Placement:
    """The step's points in the order of travel, after its turns: the placed kinds of the
    registry (`elastica_auto.branches.registry.PLACEMENT`: user values, the bound, the
    course's requested events and limits, the return to the start), each asked in that order
    to place its points on the step's :class:`~elastica_auto.branches.kinds.Placement`; a
    kind's ``Retry`` rejects the step. Then the points past the end dropped (as the kind that
    ended the branch says), the rest added in order, and the end carried out (``end``: the
    branch ends at it, with its label and message; ``repeat``: :meth:`_repeat`)."""

    def _add_events(self, step: Step, found: list[Hit]) -> str:
        """Add the turns' points ``found`` in the step and those the placed kinds put there,
        in order; return "ended" if the branch ends in this step, "moved" if it came back to
        its start one period on and the walk moved past the translates of that period
        (:meth:`_repeat`), else "".

        The points never exceed ``max_points``: an event is added while the points that
        count (`counts`) leave room for one more, the EP that ends the branch after it (or
        while they reach ``max_points`` with it, where it ends the branch itself: a bound, a
        limit, a fold stop); where the step has more, the branch ends at the last one added
        (the user values past those the room can take are not solved for)."""
        branch = self.branch
        placement = Placement(step, found, self._room(), self.can_retry)
        try:
            for event in registry.PLACEMENT:    # read here: a kind registered there is placed
                event.place(self, placement)
        except Retry as rej:
            self.event_retries += rej.spends
            raise
        events, end = placement.points, placement.end
        if end is not None:
            events = [e for e in events if placement.ender.keeps(self, placement, e)] + [end]
        events.sort(key=lambda e: e.sigma)
        last = None
        for e in events:
            if e is end and placement.ender.action == REPEAT:
                return self._repeat(step, e)
            # room for the point, and for the EP after it unless it ends the branch (a point
            # set aside for the mirror image takes none, but may be the last before that EP)
            need = (1 if e is end else 2) if self.counts(e.kind, e.state.params) else 1
            if self._room() < need:
                self._end_full(last, e.kind)
                return "ended"
            last = self._add(e.state, type=e.kind, arclength=step.position(e.sigma),
                             tangent=e.tangent, fold_residual=e.residual, note=e.note)
            if e is end:    # the branch ends there, with the label and message of its point
                branch.end, branch.message = e.kind, e.message
                return "ended"
        return ""

    def _ended_ahead(self, ds: float) -> bool:
        """End the branch without a step where a placed kind says so before it (``ahead``:
        the start within the next step, a closed loop): its point added, labelled as the
        kind says, and the branch ended with its message (at the last point itself, sigma 0,
        labelled so already: no point of its own, a start that leaves the bounds)."""
        for event in registry.PLACEMENT:
            hit = event.ahead(self, ds)
            if hit is not None:
                if hit.sigma > 0.0 or hit.kind != self.base_point.type:
                    self._add(hit.state, type=hit.kind, arclength=self.arclength + hit.sigma,
                              tangent=hit.tangent, direct=hit.direct)
                self.branch.end, self.branch.message = hit.kind, hit.message
                return True
        return False


class _Return:
    """Where the branch comes back to its start translated by whole periods of the parameter
    (a ``repeat`` end, `elastica_auto.branches.loops.Period`): the rest is the first period
    translated, copied, then the walk resumes."""

    def _repeat(self, step: Step, hit: Hit) -> str:
        """The branch passes ``hit``, its start translated by whole periods of the parameter,
        the way it left the start: from there on it is its first period translated (the
        solution set and the ordinates are periodic, and a continuation through a regular
        point in a given direction is unique). Add the translate and then copies of the
        period's points, each period shifted by the same amount in the parameter and in
        arclength, while they stay within the bounds and ``max_points``; then resume the
        walk from the last copy that is not a fold or a branch point (solved again from its
        profile, or the last translate of the start, which is exact), for what remains.
        Returns "moved" (where the copies filled the branch to ``max_points``, the walk ends
        at its next turn, as it would have there; a labelled copy is made only with room for
        the EP after it), or "ended" where there is no room for the translate."""
        branch, name, stops, problem = self.branch, self.name, self.stops, self.problem
        shift = hit.state.params[name] - self.start.lam
        turns = round(shift / self.period)      # the periods from the start to ``hit``
        uz = is_user_value(hit.state.params[name], self.user_values)
        # room for the translate, and for the EP that follows it where it is labelled
        if self._room() < (2 if uz else 1):
            self._end_full(None, labels.UZ if uz else "")
            return "ended"
        translate = self._add(hit.state, type=labels.UZ if uz else "",
                              arclength=step.position(hit.sigma), tangent=hit.tangent,
                              direct=branch.points[0].index_direct)
        period = branch.points[1:]
        length = translate.arclength - branch.points[0].arclength
        exact = {id(translate): hit.state}     # the translates of the start: their solutions
        j = 1
        while True:
            for p in period:
                lam = p.params[name] + j * shift
                counts = self.counts(p.type, {**p.params, name: lam})
                if not stops.lower < lam < stops.upper or self._room() < (
                        (2 if p.type else 1) if counts else 1):
                    return self._resume(exact)
                k = j * turns
                copy = dataclasses.replace(
                    p, params={**p.params, name: lam}, arclength=p.arclength + j * length,
                    profile=np.array(periods_applied(problem, name, p.profile, k)))
                if p.state is not None:
                    copy.state = turned(problem, name, p.state, k, lam)
                    copy.tangent = turned_tangent(problem, name, p.tangent, k)
                if p is translate:
                    exact[id(copy)] = turned(problem, name, hit.state, k, lam)
                branch.points.append(copy)
            j += 1

    def _resume(self, exact: dict) -> str:
        """Go on from the last copy :meth:`_repeat` made that is not a turn (a fold or a
        branch point, `labels.TURNS`: its tangent is not unique), the later copies removed:
        its solution, solved again from its profile where it is not a translate of the
        start, with the tangent along the branch."""
        branch, name = self.branch, self.name
        pts = branch.points
        while pts[-1].type in labels.TURNS:
            pts.pop()
        point = pts[-1]
        sol = None
        if id(point) not in exact:
            try:
                sol = self._resolve(point)
            except CorrectorFailure:
                while id(pts[-1]) not in exact:
                    pts.pop()
                point = pts[-1]
        if sol is None:
            sol = self.corr.point(exact[id(point)])
        prev = pts[-2]
        grid = PROFILE_GRID
        t = sol.tangent
        along = (float(np.sum(np.gradient(grid) * np.sum(t(grid) * (point.profile - prev.profile),
                                                           axis=0)))
                 + t.lam * (point.params[name] - prev.params[name]))
        if along < 0:
            t = t.scaled(-1.0)
        sol = self.corr.linearize(sol.state, t)
        self.base_point, self.a, self.arclength, self.curvature, self.first = \
            point, sol, point.arclength, None, False
        self.period = None
        following = [p.ds for p in pts if p.ds > 0]
        self.resume_ds = min(following[-1] if following else abs(self.opt.ds), self.opt.ds_max)
        self.accepted_ds = self.resume_ds
        if self.progress is not None:
            self.progress(branch, sol.lam)
        return "moved"


class _Refinement:
    """A step of the branch walked again with short steps, for a kind that finds after the
    walk that one step passed over what it looks for (`Event.finish`: the fold's
    translates by a period, `elastica_auto.branches.kinds.Fold.finish`)."""

    def refine(self, i: int) -> bool:
        """Walk the step from point i to point i+1 again with small steps, and put the points
        (and any folds, branch points, user points) it finds between them. False if it could
        not be done (the two points could not be solved again from their profiles, or there
        is no room for the new points within ``max_points``)."""
        pts, corr, name = self.branch.points, self.corr, self.name
        try:
            p, q = (self._resolve(pts[j]) for j in (i, i + 1))
        except CorrectorFailure:
            return False
        sec, dist = secant(p.state, q.state, name)
        if inner(p.tangent, sec, sec.s) < 0:
            p = corr.linearize(p.state, p.tangent.scaled(-1.0))
        opt = dataclasses.replace(self.opt, ds=dist / 64, ds_max=dist / 32,
                                  ds_min=min(self.opt.ds_min, dist / 1e4), max_points=10 ** 4)
        sub = Branch.of(self.problem, name, self.branch.direction, "refinement", {})
        walk = Walk(sub, self.problem, corr, Course(name, opt, Stops(), self.user_values,
                                                     watch=self.watch), None, False)
        walk.until = (p.state, sec, dist * (1 - 1e-7))
        walk.run(p)
        if sub.end != labels.EP:
            return False
        grid = PROFILE_GRID
        w = np.gradient(grid)
        origin = p.state(grid)

        def sigma(pt):
            return float(np.sum(w * np.sum((pt.profile - origin) * sec(grid), axis=0))
                         + (pt.params[name] - p.lam) * sec.lam)

        new = [pt for pt in sub.points[1:] if sigma(pt) < dist * (1 - 1e-6)]
        if self._room() < len(new):      # the branch's points stay within max_points
            return False
        total = sub.points[-1].arclength
        a0, a1 = pts[i].arclength, pts[i + 1].arclength
        for pt in new:
            pt.arclength = a0 + (a1 - a0) * pt.arclength / total
        pts[i + 1:i + 1] = new
        self.branch.warnings.extend(sub.warnings)
        self.refolded.update(walk.refolded)
        return True

    def _resolve(self, point) -> Solution:
        """A point of the branch as a linearised solution: its stored solution if labelled,
        else solved again at its parameters from its profile."""
        state = point.state
        if state is None:
            state = State.from_values(self.problem, PROFILE_GRID, point.profile, point.params)
        return self.corr.point(state)


class Walk(_Points, _Detection, _Placement, _Return, _Refinement):
    """The state of one continuation (the last accepted solution, ds, the arclength) and its
    loop: predict and correct a step, check it, detect and place its points (the parts it is
    made of, each a class above), accept it."""

    def __init__(self, branch, problem, corr, course: Course, progress, singular_start):
        self.branch, self.problem, self.corr, self.opt = branch, problem, corr, course.options
        self.stops, self.user_values = course.stops, course.user_values
        self.counted_values, self.watch = course.counted_values, course.watch
        self._aside = (0, 0, None)     # (points checked, those not counted, the last): _room
        self.all_folds, self.events = course.all_folds, course.events
        # label -> whether its kind is looked for (the option ``detect``; none without events)
        self.detected = {label: course.events and on for label, on in self.opt.detect.items()}
        self.progress, self.singular_start = progress, singular_start
        self.name = branch.parameter
        self.a, self.base_point = None, None
        self.ordinate = next((o for o in self.problem.ordinates.values()
                              if o.parameter == self.name), None)
        self.enters = self.problem.parameters[self.name].enters
        self.until = None   # (origin, unit direction, distance): end once past that hyperplane
        self.start = None   # the first solution: the branch ends where it comes back to it
        self.event_retries = 0
        self.can_retry = True   # whether the step may still be retried for an event (_detect)
        # the length of the last step accepted (inf before the first): the retries an event
        # may take are halvings below it (`_walk`)
        self.accepted_ds = math.inf
        # the period a branch may repeat with, None where it may not: set by the kind that
        # places the repeat (`loops.Period.begin`), as every placed kind reads the course
        self.period = None
        # the folds a placed kind labelled otherwise, which stay folds for the walk
        # (`kinds.branch_folds`): id of the solution -> (the solution, whether located)
        self.refolded = {}
        # whether the cubic scheme may still give way to Gauss collocation (ncol = "auto":
        # `_choose_scheme`), and the mesh size it was last weighed at
        self.scheme_open, self.scheme_weighed = False, 0
        for event in registry.PLACEMENT:
            event.begin(self, course)

    def run(self, a: Solution):
        """Continue from ``a`` until the branch ends; then every kind of the registry's two
        sets, in their order, completes the branch as a whole (`Event.finish`: the fold's
        translates by a period, walked again where missing with :meth:`refine`)."""
        self._walk(a)
        for event in registry.DETECTION + registry.PLACEMENT:
            event.finish(self)

    def _walk(self, a: Solution):
        opt = self.opt
        self.base_point = self._add(a.state, type=labels.EP, arclength=0.0, tangent=a.tangent)
        if self.singular_start:
            self.base_point.note = ""
        self.a, self.arclength, self.first = a, 0.0, True
        self.start = a
        self.curvature = None
        ds = abs(opt.ds)
        history = []
        # the step's rejections, and those that left it shorter than the last step accepted:
        # a step grown past that length (by ``growth``, up to 100) is no step the branch is
        # known to resolve, and its halvings down to it do not spend the retries that an
        # event that cannot be located, or an index the fold rule does not give, may take
        # (RETRY_HALVINGS: spent there, a step that jumped to another branch was accepted
        # with a warning, hostile M9). With growth < 2 every halving is below it.
        retries = below = 0
        while True:
            # the branch ends at its last point, which an EP of its own follows if labelled
            if self._room() <= (1 if self.base_point.type else 0):
                self.end_at_base(labels.EP, self._full())
                return
            try:
                ds_next, ended = self._step(ds, retries, below)
            except Retry as rej:
                history.append({"ds": ds, "residual": rej.residual,
                                "nodes": len(self.a.mesh), "message": str(rej)})
                retries += 1
                below += rej.ds < self.accepted_ds
                ds = rej.ds
                if ds < opt.ds_min:     # the failure ends the branch: its kind says how
                    registry.FAILURE.step_failed(self, rej, history)
                    return
                continue
            if ended:
                return
            history.clear()
            retries = below = 0
            ds = ds_next
            self._choose_scheme()

    def _choose_scheme(self):
        """Under ``ncol = "auto"``, a cubic branch whose meshes have grown (a boundary layer
        forming along it: AUTO's kar from its trivial start; not a branch from a stored
        label, nor one of a problem with an index: ``scheme_open``, `_continue`) is
        continued by Gauss collocation at AUTO_GAUSS points from its last accepted point on,
        where `~elastica_auto.numerics.correctors.gauss_pays` at that point: the rule that
        chose the start's scheme (`choose_ncol`), applied again. It is weighed only where the
        accepted point's mesh has more than GAUSS_PAYS times the fewest nodes (below, Gauss
        cannot pay) and a quarter more nodes than where it was last weighed (so that a mesh
        that stays large is not weighed at every step), and at most once switched. The
        point is solved again by Gauss collocation at its parameters, on its own mesh, and
        linearised along its tangent: the next step starts from it, and compares its test
        functions with it (the determinant's sign and the tangent are Gauss's). The
        branch records ``ncol`` as the scheme of its last points (a restart from it keeps
        Gauss). A function of the points alone: deterministic."""
        if not self.scheme_open:
            return
        nodes = len(self.a.mesh)
        if nodes <= GAUSS_PAYS * (self.opt.ntst + 1) or nodes <= 1.25 * self.scheme_weighed:
            return
        self.scheme_weighed = nodes
        if not gauss_pays(self.problem, self.name, self.opt, self.a.state):
            return
        opt = dataclasses.replace(self.opt, ncol=AUTO_GAUSS)
        corr = make_corrector(self.problem, self.name, opt)
        try:
            sol = corr.linearize(corr.point(self.a.state).state, self.a.tangent)
        except CorrectorFailure:
            self.scheme_open = False     # kept cubic: the Gauss solve did not converge here
            return
        self.corr, self.opt, self.a, self.curvature = corr, opt, sol, None
        self.scheme_open = False
        self.branch.options = {**self.branch.options, "ncol": AUTO_GAUSS}

    def _step(self, ds: float, retries: int, below: int) -> tuple[float, bool]:
        """One step of length ds from self.a: returns (next ds, whether the branch ended);
        raises _Reject to retry with a smaller ds. ``retries``: the step's rejections so far,
        ``below``: those that left it shorter than the last step accepted (`_walk`)."""
        if self._ended_ahead(ds):
            return ds, True
        step, cos_turn = self._correct(ds)
        found, counted = self._detect(step, below)
        return self._accept(step, found, counted, retries, cos_turn)

    def _correct(self, ds: float) -> tuple[Step, float]:
        """Predict and correct (on the mesh chosen for the step), then check the new point:
        a turn of the tangent beyond max_angle, or a correction that moved it more than
        ds / 2 from the predictor (a jump to another branch), rejects the step."""
        opt, corr, a, name = self.opt, self.corr, self.a, self.name
        mesh = corr.next_mesh(a)
        if mesh is not a.mesh:  # the step's mesh: linearise a there once, for both uses
            a = self.a = corr.relinearize(a, mesh)
        try:
            b = corr.step(a, ds, self.curvature)
        except CorrectorFailure as exc:
            raise _Reject(str(exc), ds / 2, exc.residual) from None
        s = b.mesh
        # the cosine of the turn in the one metric of b's mesh: a's tangent is unit on its own
        # mesh, and moved onto another (a regrid) it need not be, where the trapezoid rule on
        # the nodes integrates it differently (a boundary layer across a few Gauss intervals
        # whose nodes the regrid moved: norm^2 0.64 measured, and a turn of 0.1 degree read as
        # 37, at every ds, which ended the branch MX)
        ta = a.tangent.on(s)
        cos_turn = inner(ta, b.tangent, s) / (norm(ta, s) * norm(b.tangent, s))
        if cos_turn < math.cos(opt.max_angle):
            raise _Reject(f"tangent turned by {math.degrees(math.acos(max(-1.0, cos_turn))):.1f}"
                          " deg > max_angle", ds / 2)
        sec, dist = secant(a.state, b.state, name)
        if not self.first or not a.extra.get("singular"):
            pred = Tangent(s, a.state(s) + ds * a.tangent.on(s).y - b.state.y,
                           a.state.derivative(s) + ds * a.tangent.on(s).yp - b.state.yp,
                           a.lam + ds * a.tangent.lam - b.lam)
            jump = norm(pred)
            if jump > 0.5 * ds:
                raise _Reject(f"the corrector moved {jump:.3g} from the predictor "
                              f"(ds = {ds:.3g})", ds / 2)
        if ds > LONG_STEP * self.accepted_ds:
            self._arc_checked(a, b, sec, dist, ds)
        return Step(a, b, sec, dist, self.arclength, ds, name), cos_turn

    def _arc_checked(self, a: Solution, b: Solution, sec: Tangent, dist: float, ds: float):
        """Reject a long step (LONG_STEP) whose end the branch does not reach along an arc:
        the solution on the hyperplane halfway along the chord, solved from the chord's
        midpoint, must lie within ``dist tan(max_angle / 4)`` of it, and its tangent within
        max_angle of the chord. An arc that turns by at most max_angle lies within
        ``dist tan(turn / 4) / 2`` of its chord's midpoint (a circle's; twice that is allowed
        for arcs that are not circles), where its tangent is parallel to the chord (a
        circle's; within the turn, for others). Where b is on another branch, the branch from
        a crosses that hyperplane elsewhere, or not at all, and what is found there is a
        solution of yet another branch, crossing it at an angle (the straight rod, halfway
        between a buckled rod and its mirror image, at the rotating arm's P = 9 pi^2 / 4)."""
        name = self.name
        try:
            mid = self.corr.on_plane(a, sec, dist / 2, b.mesh, regrid=False)
        except CorrectorFailure:
            raise _Reject("the branch does not reach the step's end along an arc (no "
                          "solution halfway)", ds / 2) from None
        s = b.mesh
        d = difference(mid.state, a.state, name, s)
        off = norm(Tangent(s, d.y - dist / 2 * sec.y, d.yp - dist / 2 * sec.yp,
                           d.lam - dist / 2 * sec.lam))
        if off > dist * math.tan(self.opt.max_angle / 4):
            raise _Reject(f"the branch does not reach the step's end along an arc (halfway, "
                          f"{off:.3g} from the chord, ds = {ds:.3g})", ds / 2)
        cos_mid = inner(mid.tangent.on(s), sec, s)
        if cos_mid < math.cos(self.opt.max_angle):
            raise _Reject(f"the branch does not reach the step's end along an arc (halfway, "
                          f"its tangent at {math.degrees(math.acos(max(-1.0, cos_mid))):.1f} "
                          f"deg to the chord, ds = {ds:.3g})", ds / 2)

    def _accept(self, step: Step, found: list[Hit], counted: Count, retries: int,
                cos_turn: float) -> tuple[float, bool]:
        """Add the step's events and its end point b; the next ds (grown after an easy step)
        and whether the branch ended."""
        opt, a, b, ds = self.opt, step.a, step.b, step.ds
        outcome = self._add_events(step, found)
        if outcome == "moved":      # the branch repeats: the walk goes on past its translates
            return self.resume_ds, False
        if outcome:
            return ds, True
        arclength = self.arclength + ds
        residual = float(b.rms.max()) if self.all_folds else math.nan
        tb, ta = b.tangent.on(b.mesh), a.tangent.on(b.mesh)
        curvature = Tangent(b.mesh, (tb.y - ta.y) / step.dist, (tb.yp - ta.yp) / step.dist,
                            (tb.lam - ta.lam) / step.dist)
        point = self._add(b.state, arclength=arclength, ds=ds, niter=b.niter,
                          direct=counted.index, parts=counted.parts, fold_residual=residual,
                          note=counted.reason if counted.refused else "")
        # the walk moves on to b in one statement that calls nothing (no signal lands inside)
        self.base_point, self.a, self.arclength, self.curvature, self.first = \
            point, b, arclength, curvature, False
        self.accepted_ds = ds
        if self.progress is not None:
            self.progress(self.branch, b.lam)
        if self.until is not None:
            origin, direction, distance = self.until
            s = b.mesh
            if inner(difference(b.state, origin, self.name, s), direction, s) >= distance:
                self.branch.end, self.branch.message = labels.EP, "reached the end of the segment"
                return ds, True
        if (retries == 0 and cos_turn > math.cos(opt.max_angle / 2)
                and b.extra.get("contraction", 0.0) < EASY_CONTRACTION):
            ds = min(ds * opt.growth, opt.ds_max)
        return ds, False

