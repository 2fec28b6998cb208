"""Execute a plan: build each start, continue each branch, number labels, write the file.

The branch file is rewritten (atomically) after every branch, so an interrupted or failing run
leaves every completed branch on disk. Computed in this process (``jobs = 1``), the branch in
progress is kept up to its last point and ends with an MX label; on a Dask cluster
(`elastica_auto.execution.cluster`) the unfinished tasks are cancelled.
"""

from __future__ import annotations

import dataclasses
import json
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..analysis.equilibria import enumerate_equilibria, stable_side
from ..analysis.maps import stability_maps
from ..analysis.snaps import (copy_key, mirror_key, scan_key, scans, snap_points,
                              snap_targets)
from ..branches import codim2, pitchfork, restart
from ..branches.branch import Branch
from ..branches.stepper import INTERRUPTED, Origin
from ..branches.switching import kernel_plane, switch_direction
from ..core import labels
from ..core.errors import (ENGINE, EXIT_ANALYSIS_FAILED, EXIT_BRANCH_FAILED, EXIT_INTERNAL,
                           EXIT_INTERRUPTED, EXIT_OK, USER_ERRORS, ClusterLost, RunFileError,
                           StartError, WriteError, debugging, failure_record,
                           module_files)
from ..core.interrupts import Interruptions
from ..core.options import NCOL_AUTO
from ..core.solution import State, Tangent, inner, norm, trapezoid_weights
from ..core.values import same_value
from ..numerics.collocation import Discretisation
from ..numerics.correctors import CorrectorFailure, make_corrector
from ..storage import store
from .jobs import (NOT_COMPUTED, Callbacks, Job, cell, compute_branch, failed_branch,
                   mark_mirrors, usable_cores)
from .plan import BranchSpec, Plan, Start
from .schedule import Schedule


@dataclass
class RunResult:
    path: Path | None
    branches: list[Branch]
    seconds: float
    interrupted: bool = False
    snaps: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    maps: list = field(default_factory=list)
    landings: list = field(default_factory=list)
    kept: int = 0
    #: what the analysis after the branches could not make: one `failure_record` each, with
    #: ``what`` ("snaps", "landings", "maps") and ``message`` (a line); stored in the file
    missing: list = field(default_factory=list)
    #: the run stopped before its end (`_stopped`): its file holds the branches so far
    stopped: bool = False

    @property
    def failed(self) -> list[int]:
        return [k for k, b in enumerate(self.branches, 1) if b.end in labels.FAILED]

    @property
    def internal(self) -> list[str]:
        """The internal errors of the run: its branches' (``branch N``) and its analyses'."""
        return ([f"branch {k}" for k, b in enumerate(self.branches, 1) if b.internal_error]
                + [m["what"] for m in self.missing if m["kind"] == ENGINE])

    @property
    def status(self) -> int:
        """The exit status of the run (`elastica_auto.core.errors.EXIT_STATUSES`): the first of
        interrupted, an internal error, an analysis missing, a failed branch, success."""
        if self.interrupted:
            return EXIT_INTERRUPTED
        if self.internal:
            return EXIT_INTERNAL
        if self.missing:
            return EXIT_ANALYSIS_FAILED
        return EXIT_BRANCH_FAILED if self.failed else EXIT_OK


def build_start(plan: Plan, spec: BranchSpec) -> Job:
    """The start of a branch: an exact solution, a stored label (checked to solve the
    problem, then continued to the spec's parameter values where they change its own,
    `branches.restart`), or the other branch at a BP."""
    problem, opt = plan.problem, plan.options
    if spec.start.kind == "trivial":
        return _checked(plan, Job(spec, Origin(_from_values(plan, {**problem.defaults(),
                                                                   **spec.params}))))
    stored = spec.start.stored or store.BranchFile(spec.start.file).label(spec.start.label)
    # a damaged or edited stored solution would start a branch that is not one (hostile M5)
    curve = spec.start.kind in CURVES
    restart.check_stored(plan.base if curve else problem, stored,
                         (stored.tangent_parameter or plan.parameter) if curve else plan.parameter,
                         opt, str(spec.start))
    state, tangent = stored.state, stored.tangent
    ncol = stored_ncol(stored)
    if curve:
        return _checked(plan, Job(spec, Origin(_curve_start(plan, spec, stored), ncol=ncol)))
    if spec.start.kind == "switch":
        if labels.kind_of(spec.start.label) not in labels.SWITCHES:
            raise StartError(f"{spec.start}: switch needs a branch point (BP) label")
        return _switch_job(plan, spec, state, tangent, ncol)
    # free parameters are solved for: a value given to one is no place to move to, and
    # was ignored without a word (the run started at the label's own value)
    ignored = {q: v for q, v in spec.params.items()
               if q in problem.solved and v != state.params[q]}
    if ignored:
        q, v = next(iter(ignored.items()))
        raise StartError(f"{spec.start}: {q} = {v:.12g} is given, but {q} is a free parameter "
                         f"of this run, solved for (its value at {spec.start.label}: "
                         f"{state.params[q]:.12g}): remove it from [parameters] (or --set), or "
                         f"solve for another parameter in its place ([continuation] free)")
    targets = {q: v for q, v in spec.params.items()
               if q not in problem.solved and v != state.params[q]}
    if targets:  # by continuation: Newton at the new values fails at (and near) an LP, BP, CP
        kind = "singular" if labels.kind_of(spec.start.label) in labels.SINGULAR else "regular"
        state = restart.move(problem, Origin(state, tangent, kind, ncol), targets, opt,
                             tangent_parameter=stored.tangent_parameter, where=str(spec.start))
    if targets or stored.tangent_parameter != plan.parameter:
        tangent = None
    singular = labels.kind_of(spec.start.label) in labels.TURNS and not targets
    return _checked(plan, Job(spec, Origin(state, tangent,
                                           "singular" if singular else "regular", ncol)))


def stored_ncol(stored) -> int | None:
    """The ``ncol`` of the branch that computed the stored label ``stored`` (its options'),
    which a branch started from it keeps under ``ncol = "auto"``; None where the options
    hold no number (a label of a path's equilibria, or of a branch never started)."""
    value = (getattr(stored, "options", None) or {}).get("ncol")
    return value if isinstance(value, int) and not isinstance(value, bool) else None


#: The start kinds of two-parameter curves (`elastica_auto.execution.plan.Start`).
CURVES = ("fold", "bp", "pitchfork")


def _from_values(plan: Plan, params: dict) -> State:
    """The start at parameter values: the module's exact solution there; or, where it has
    none, its guess, solved from at those values (as is every start of a problem with
    integral conditions or free parameters, whose completed start is only approximate)."""
    problem, opt = plan.problem, plan.options
    s = np.linspace(0.0, 1.0, opt.ntst + 1)
    y = problem.exact_start(s, params)
    solve = y is None or problem.approximate_start
    what = "its exact start"
    if y is None:
        y, what = problem.guess(s, params), "its guess"
    fixed = ", ".join(f"{k}={v:g}" for k, v in params.items())
    if y is None:
        raise StartError(f"{problem.source} has no exact start or guess at {fixed}; "
                         "start from a label (start = \"FILE.h5:LABEL\")")
    _check_finite(problem, s, y, what, fixed)
    state = State.from_values(problem, s, y, params)
    if not solve:
        _check_exact(problem, state, opt.tol, fixed)
        return state
    try:
        state = make_corrector(problem, plan.parameter, opt).point(state).state
    except CorrectorFailure as exc:
        raise StartError(f"{problem.source}: no solution found from {what} at {fixed} "
                         f"({exc})") from None
    state.params = problem.point_params(state.params, state.y)
    return state


def _check_finite(problem, s, y, what: str, fixed: str) -> None:
    """StartError unless the module's start ``y`` (its exact start or guess, ``what``) is
    finite: a NaN in it (a 0/0 in the module's formula at those parameters) otherwise ended
    the branch at its start with a message about the tangent's error estimate, not the
    start, as a module failure (exit status 1) rather than the start's (2)."""
    bad = ~np.isfinite(np.asarray(y, dtype=float))
    if not bad.any():
        return
    k, i = np.unravel_index(int(np.argmax(bad)), bad.shape)
    rows = [*problem.states, *getattr(problem, "free", ())]
    row = rows[k] if k < len(rows) else f"row {k + 1}"
    hook = "exact_start" if what == "its exact start" else "guess"
    raise StartError(f"{problem.source}: {what} at {fixed} is not finite: {hook}(s, p) "
                     f"returned {y[k][i]} in {row} at s = {s[i]:.3g} ({int(bad.sum())} of "
                     f"its {bad.size} values); it must return finite values, or None where "
                     "it has no start")


def _check_exact(problem, state: State, tol: float, fixed: str) -> None:
    """StartError unless the module's exact start ``state`` solves its equations: the
    residuals of the collocation equations (``y_(i+1) - y_i`` less Simpson's integral of
    ``f`` over the interval, relative to ``1 + |y_i|``) and of the boundary conditions
    (relative to ``1 + max |y|``), the measure a restart's check reads, at most ``tol``. A
    solution sampled on the mesh leaves only the scheme's truncation, ``O(h^5)`` per interval
    (none for the straight rods' polynomials); an ``exact_start`` that does not solve the
    problem (an end condition changed in the module and not in its start) left the corrector
    to fail in the first step, with a message about the step, not the start. A module that
    raises in ``rhs`` or ``bc``, or returns what is not finite, is left to the branch, which
    records who failed and where (exit status 1), as without this check."""
    try:
        ev = Discretisation(problem, state.s).evaluate(state.y, state.params)
        col = np.abs(ev.col) / (1.0 + np.abs(state.y[:, :-1]))
        bc = np.abs(np.asarray(ev.bc, dtype=float)) / (1.0 + float(np.max(np.abs(state.y))))
    except Exception:  # noqa: BLE001 - the branch's first step meets it and records it
        return
    if not (np.all(np.isfinite(col)) and np.all(np.isfinite(bc))):
        return
    worst_col = float(np.max(col)) if col.size else 0.0
    worst_bc = float(np.max(bc)) if bc.size else 0.0
    if worst_col <= tol and worst_bc <= tol:
        return
    if worst_bc >= worst_col:
        where = f"row {int(np.argmax(bc)) + 1} of the {len(bc)} end conditions (bc)"
    else:
        k, i = np.unravel_index(int(np.argmax(col)), col.shape)
        where = f"the equation of {problem.states[k]} near s = {state.s[i]:.3g}"
    raise StartError(f"{problem.source}: its exact start at {fixed} does not solve the "
                     f"problem: the residual is {max(worst_bc, worst_col):.3g} in {where} (the "
                     f"tolerance: {tol:g}); exact_start(s, p) must return a solution of the "
                     "module's equations and end conditions, or None where it has none")


def _curve_start(plan: Plan, spec: BranchSpec, stored) -> State:
    """The first point of a fold or branch-point curve (`elastica_auto.branches.codim2`) through the
    LP or BP ``stored`` of the module's problem: its solution with the null vector there,
    solved at the spec's parameters. At an LP the null vector is the stored tangent (its
    parameter component is zero at a fold); at a BP of the exact family it is the second
    direction through the branch point less its component along the family. At a BP off the
    exact family, the pitchfork system's start from the plan's reference (its solution, the
    null vector of F_y alone, unfolding 0)."""
    base, problem, opt = plan.base, plan.problem, plan.options
    state, tangent = stored.state, stored.tangent
    if tangent is None:
        raise StartError(f"{spec.start}: no tangent stored with the label")
    if spec.start.kind == "pitchfork":
        start = pitchfork.pitchfork_start(problem, plan.reference, state.params)
    elif spec.start.kind == "fold":
        null = tangent.on(state.s).y
        start = codim2.fold_start(problem, state, null)
    else:
        lam = stored.tangent_parameter
        direction = switch_direction(base, state, tangent, lam, opt)
        if direction is None:
            raise StartError(f"{spec.start}: no null vector at the branch point")
        null = direction.on(state.s).y - direction.lam * codim2.family_slope(base, state, lam)
        start = codim2.branch_point_start(problem, state, null)
    start.params = {**start.params, **spec.params}
    try:
        start = make_corrector(problem, plan.parameter, opt).point(start).state
    except CorrectorFailure as exc:
        what = {"fold": "fold", "bp": "branch-point"}.get(spec.start.kind, spec.start.kind)
        raise StartError(f"{spec.start}: the {what} system has no solution there ({exc})") from None
    start.params = problem.point_params(start.params, start.y)
    return start


def start_job(plan: Plan, spec: BranchSpec) -> Job:
    """:func:`build_start`, with the equation module failing there (raising or exiting, or a
    numerical failure) reported as a StartError (one line) rather than a traceback; an
    internal error of the engine is raised as it is."""
    try:
        return build_start(plan, spec)
    except (StartError, *USER_ERRORS):
        raise
    except (Exception, SystemExit) as exc:
        record = failure_record(exc, module_files(plan.problem.module))
        if record["kind"] == ENGINE:
            raise
        raise StartError(f"{spec.start}: {record['exception']}: "
                         + " ".join(record["error"].split())
                         + f" ({record['where']})") from exc


def _switch_job(plan: Plan, spec: BranchSpec, state: State, tangent: Tangent | None,
                ncol: int | None) -> Job:
    if tangent is None:
        raise StartError(f"{spec.start}: no tangent stored with the branch point")
    # the other branch's direction by the scheme that computed the branch point (the
    # branch's ncol, under "auto"), on whose discrete equations it is a branch point
    options = plan.options
    if ncol is not None and options.ncol == NCOL_AUTO:
        options = dataclasses.replace(options, ncol=ncol)
    direction = switch_direction(plan.problem, state, tangent, plan.parameter, options)
    if direction is None:
        raise StartError(f"{spec.start}: no second direction at the branch point (null vector "
                         "of the linearised problem not found)")
    return _checked(plan, Job(spec, Origin(state, direction.scaled(spec.direction), "switch",
                                           ncol)))


def _checked(plan: Plan, job: Job) -> Job:
    lam = job.origin.state.params[plan.parameter]
    if not plan.stops.lower <= lam <= plan.stops.upper:
        raise StartError(f"{job.spec.start}: the start has {plan.parameter} = {lam:g}, outside "
                         f"the bounds [{plan.stops.lower:g}, {plan.stops.upper:g}]")
    return job


def number_labels(branches: list[Branch], first: int = 1, counters: dict | None = None):
    """Number the branches from ``first``, and labels per type through the file in branch and
    point order (LP1, LP2, ...), after the ``counters`` (type -> last number) of branches
    already in the file."""
    counters = dict(counters or {})
    for k, br in enumerate(branches, first):
        br.number = k
        for p in br.points:
            if p.type:
                counters[p.type] = counters.get(p.type, 0) + 1
                p.label = counters[p.type]


#: A branch point located exactly (where the determinant changes sign, or placed where the
#: module's symmetry holds, or where the index changes) is a solution to fold_tol on its
#: mesh: two located at one point on different branches (on different meshes, interpolated
#: onto one) agree to far better than SAME_POINT_RELATIVE of the solution's size (1 + its
#: norm, the measure of the corrector's tolerances), within which each counts as known.
SAME_POINT_RELATIVE = 1e-6
#: A branch point labelled where the parameter turns on a branch born at it ("turning point
#: without index change": a pitchfork passed along its other branch) is where the fold system
#: converged, which at a branch point is singular, or only the end of the step that passed
#: it where that system failed: it is known only to that step (its length), and its kernel
#: only through its tangent, which lies within that step's turn (at most max_angle) of the
#: branch point's kernel plane.
TURNING = "turning point without index change"
#: Two located branch points have the same kernel (the plane of the two branches' directions
#: there, from `switching.kernel_plane`) where the planes' largest principal angle is below
#: this (its sine): their kernels are computed to about the accuracy of the points.
SAME_KERNEL = 1e-3


@dataclass
class Site:
    """A branch point as `switch_jobs` compares it: the point, the distance within which it
    is known (``accuracy``), and, once computed, the directions of its kernel (``kernel``:
    an orthonormal pair, or for a turning-point BP its tangent alone; None where unknown)."""

    point: object
    accuracy: float
    located: bool
    kernel: list | None = None
    computed: bool = False


def _size(state, parameter: str) -> float:
    """1 + the norm of the solution in (y, lam), the scale of the corrector's tolerances."""
    w = trapezoid_weights(state.s)
    return 1.0 + float(np.sqrt(np.sum(w * np.sum(state.y * state.y, axis=0))
                               + state.params[parameter] ** 2))


def _site(plan: Plan, pts, i: int) -> Site:
    """The branch point ``pts[i]`` as a `Site`: located to SAME_POINT_RELATIVE of its size,
    or, labelled at a turning point (TURNING), to the step that reached it (the step of the
    first point after it that ends one, else of the one before)."""
    p = pts[i]
    if not p.note.startswith(TURNING):
        return Site(p, SAME_POINT_RELATIVE * _size(p.state, plan.parameter), True)
    after = [q.ds for q in pts[i + 1:] if q.ds > 0][:1]
    before = [q.ds for q in pts[i - 1::-1] if q.ds > 0][:1] if i else []
    return Site(p, (after or before or [0.0])[0], False)


def branch_points(plan: Plan, br: Branch) -> list[Site]:
    """The BPs of ``br`` in order, as `Site`s."""
    return [_site(plan, br.points, i) for i, p in enumerate(br.points) if p.type in labels.SWITCHES]


def _kernel(plan: Plan, site: Site) -> list | None:
    """The directions of the site's kernel (computed once): the plane of a located branch
    point, the tangent of a turning-point one; None where they cannot be had."""
    if not site.computed:
        p, site.computed = site.point, True
        if p.state is not None and p.tangent is not None:
            if site.located:
                site.kernel = kernel_plane(plan.problem, p.state, p.tangent, plan.parameter,
                                           plan.options)
            else:
                site.kernel = [p.tangent]
    return site.kernel


def _same_kernel(plan: Plan, one: Site, other: Site, s) -> bool:
    """Whether the kernels of two sites at one place agree, on the mesh ``s``: two planes
    within SAME_KERNEL of each other; a turning point's tangent within max_angle of a plane;
    where either is unknown, or both are turning points' tangents (two directions of one
    plane, which need not be parallel), their places decide alone."""
    ka, kb = _kernel(plan, one), _kernel(plan, other)
    if ka is None or kb is None or (len(ka) == 1 and len(kb) == 1):
        return True
    if len(ka) == 1:
        ka, kb = kb, ka
    basis = _orthonormal(ka, s)
    if len(kb) == 1:
        t = _orthonormal(kb, s)[0]
        along = np.hypot(inner(t, basis[0], s), inner(t, basis[1], s))
        return along >= np.cos(plan.options.max_angle)
    gram = np.array([[inner(e, f, s) for f in _orthonormal(kb, s)] for e in basis])
    cos_largest = float(np.linalg.svd(gram, compute_uv=False).min())
    return np.sqrt(max(1.0 - cos_largest ** 2, 0.0)) <= SAME_KERNEL


def _orthonormal(directions, s) -> list[Tangent]:
    """``directions`` on the mesh ``s``, made orthonormal there (Gram-Schmidt in the
    continuation's inner product)."""
    out = []
    for d in directions:
        v = d.on(s)
        for e in out:
            v = Tangent(s, v.y - inner(v, e, s) * e.y, v.yp - inner(v, e, s) * e.yp,
                        v.lam - inner(v, e, s) * e.lam)
        out.append(v.scaled(1.0 / norm(v, s)))
    return out


def same_point(plan: Plan, one: Site, other: Site) -> bool:
    """Two branch points are the same point: at the same values of the parameters held fixed
    (`core.values.same_value`), within the sum of their accuracies of each other in the
    continuation's norm (sqrt(|dy|^2 + dlam^2)), and with the same kernel (`_same_kernel`).
    Never by step length alone: two branch points of one branch one step apart are two."""
    p, q, parameter = one.point, other.point, plan.parameter
    solved = (parameter, *plan.problem.solved)
    periods = {k: v.period for k, v in plan.problem.parameters.items()}
    if not all(same_value(p.params[k], q.params[k], periods.get(k)) for k in p.params
               if k not in solved):
        return False
    a, b = p.state, q.state
    dy = a.y - b(a.s)
    dist = float(np.sqrt(np.sum(trapezoid_weights(a.s) * np.sum(dy * dy, axis=0))
                         + (p.params[parameter] - q.params[parameter]) ** 2))
    if dist > one.accuracy + other.accuracy:
        return False
    return bool(_same_kernel(plan, one, other, a.s))


def switch_jobs(plan: Plan, branches: list[Branch], warnings: list[str],
                seen: list | None = None, sources: list | None = None) -> list[Job]:
    """``switch = N``: both directions of the other branch at the first N BPs of each branch;
    BPs where that fails are reported in ``warnings``. A BP that is the same point
    (`same_point`) as one in ``seen`` (`Site`s of `branch_points`) is passed over; each BP
    switched at is added to it. ``sources``, if given, gets each job's BP (its site)."""
    jobs = []
    seen = [] if seen is None else seen
    for br in branches:
        for bp in branch_points(plan, br)[: plan.switch_count]:
            if any(same_point(plan, bp, q) for q in seen):
                continue
            seen.append(bp)
            p = bp.point
            for d in (1, -1):
                spec = BranchSpec(Start("switch", None, p.name), {}, d)
                try:
                    jobs.append(_switch_job(plan, spec, p.state, p.tangent, stored_ncol(br)))
                except StartError as exc:
                    warnings.append(str(exc))
                    continue
                except (Exception, SystemExit) as exc:  # the module failing at the BP
                    record = failure_record(exc, module_files(plan.problem.module))
                    if record["kind"] == ENGINE:
                        raise
                    warnings.append(f"switch at {p.name}: {record['exception']}: "
                                    + " ".join(record["error"].split()))
                    continue
                if sources is not None:
                    sources.append(bp)
    return jobs


def _loop_points(plan: Plan, br: Branch) -> list[Site]:
    """Where a closed loop ``br`` meets other branches: its start (the BP it was switched
    at, its solution exactly) and the BPs along it, as `Site`s for `same_point`."""
    start = br.points[0]
    return [Site(start, SAME_POINT_RELATIVE * _size(start.state, plan.parameter), True),
            *branch_points(plan, br)]


def switch_levels(plan: Plan, branches: list[Branch], warnings: list[str], run) -> bool:
    """``switch = N`` to ``plan.switch_depth`` levels, after the run's own ``branches``: the
    other branches at the first N BPs of each of them (`switch_jobs`), then at the first N of
    each branch so found, and so on. From the second level on, a BP that is the same point
    as a BP of an earlier level's branch, or as one already switched at, is passed over: at
    a simple branch point two branches cross, so both are computed already (a switched
    branch that closes through the mirror image of its start, say).

    Within a level, a job whose BP is the same point as the start or a BP of a closed loop
    switched before it in the level's order is passed over: that loop is the other branch
    there, computed whole (both orientations of a loop from its start; the loop from the
    other BP it joins). The decision reads only the branches before the job, so the kept
    branches are the same whichever process computed them. ``run(jobs, skip)`` computes the
    jobs, appending their branches to ``branches`` in order except those for which
    ``skip(i, branches)`` is true when their turn comes (left out then: not started after
    that, cancelled or dropped if a worker has it); True if it was interrupted."""
    level, seen = list(branches), []
    for depth in range(plan.switch_depth):
        sources: list[tuple] = []
        jobs = switch_jobs(plan, level, warnings, seen, sources)
        if not jobs:
            break
        before = len(branches)

        def skip(i, done, before=before, sources=sources):
            return any(same_point(plan, sources[i], q) for br in done[before:]
                       if br.closed for q in _loop_points(plan, br))

        if run(jobs, skip):
            return True
        seen.extend(bp for br in level for bp in branch_points(plan, br))
        level = branches[before:]
    return False


def execute(plan: Plan, out_dir: Path, callbacks: Callbacks = Callbacks(), jobs: int = 1,
            scheduler: str | None = None, resume: bool = False,
            worker_timeout: float | None = None) -> RunResult:
    """Run every branch of ``plan``, ``jobs`` at a time, writing ``out_dir/<run>.h5``.

    Before any branch is computed: a start read from the file this run writes is refused
    (RunFileError), every start is built (and so validated), and the output is checked and
    locked for the whole run (`store.Writer`: StoreError if it cannot be written or another
    run is writing it). Branches switched at this run's own branch points (``switch = N``)
    follow once their parents are done. The file is rewritten after each branch completes, in
    plan order, so labels are numbered the same way whatever ``jobs`` is, or whichever Dask
    cluster computed them (``scheduler``, default the run file's; see `compute`).
    ``callbacks.on_start`` is called once these checks have passed, before the first
    branch; the others report as `compute` says.

    A run that ends, with failed branches (MX) or not, leaves its complete file as
    ``<run>.h5``, replacing any earlier one. An interrupted run (Ctrl-C, SIGTERM) keeps every
    branch computed so far (in process, also the one in progress up to its last point): in
    ``<run>.h5`` if there was none, else in ``<run>.partial.h5``, leaving the earlier
    ``<run>.h5`` as it was. A cluster without a worker for ``worker_timeout`` seconds
    (default the run file's, else `cluster.WORKER_TIMEOUT`) ends the run as an interruption
    does, the branches not computed recorded at the file's end (`NOT_COMPUTED`), and raises
    ClusterLost (one line: what was saved where).
    ``result.path`` is the file written and ``result.branches`` the branches it holds.

    ``resume``: continue the run's file (``<run>.partial.h5`` if an interrupted rerun left
    one, else ``<run>.h5``): the cells of the plan already in it (`cell`) are not computed
    again, the others follow its branches. ``result.kept`` is the number of branches kept.
    """
    out = Path(out_dir) / plan.output_name
    writer = store.Writer(out, plan.name, plan.problem, plan.text)
    writer.extra["settings"] = json.dumps(plan.settings(), sort_keys=True)
    kept = _resumed(plan, writer) if resume else None
    for spec in plan.branches:
        # the start is read before the run writes, but the run would destroy its own input
        own = next((p for p in (writer.target, writer.partial)
                    if spec.start.file is not None and store.same_file(spec.start.file, p)),
                   None)
        if own is not None:
            key = "switch" if spec.start.kind == "switch" else "start"
            raise RunFileError(f"{plan.path}: {key}: {spec.start.file} is the file this run "
                               f"writes ({own}); restart from a copy, or write elsewhere")
    t_run = time.perf_counter()
    # an interrupted run's file ends with its interrupted branches, one that lost its cluster
    # with those not computed: computed again
    count = len(kept.branches) if kept is not None else 0
    while count and kept.branches[count - 1].attrs["message"] in (INTERRUPTED, NOT_COMPUTED):
        count -= 1
    done = {b.attrs.get("cell", "") for b in kept.branches[:count]} if kept else set()
    first = [start_job(plan, spec) for spec in plan.branches if cell(spec) not in done]
    result = RunResult(writer.path, [], 0.0, kept=count)
    if count:   # the branches are reported by their numbers in the file
        callbacks = dataclasses.replace(
            callbacks,
            progress=callbacks.progress and (lambda k, *a, f=callbacks.progress: f(k + count,
                                                                                   *a)),
            on_branch=callbacks.on_branch and (lambda k, br, f=callbacks.on_branch: f(k + count,
                                                                                      br)))
    if kept is not None and not first and count == len(kept.branches):  # all there already
        # what the analyses of its branches could not make is still missing from the file
        result.missing = [m for m in kept.missing if m["what"] != "branches"]
        result.path, result.seconds = kept.path, time.perf_counter() - t_run
        return result
    # the kept branches as they were computed, read now (the run's saves may write their
    # file again): analysed with the new ones, as a whole run analyses its branches
    held = _held(plan, kept, count) if kept is not None else None
    scheduler = scheduler if scheduler is not None else plan.scheduler
    if worker_timeout is None:
        worker_timeout = plan.worker_timeout
    client = None
    if scheduler is not None:  # before the output is opened: an error leaves nothing
        from .cluster import connect
        client = connect(scheduler)

    def save():
        number_labels(result.branches, result.kept + 1, _label_counters(kept, result.kept))
        writer.save(result.branches)

    lost = None
    try:
        with writer:
            if kept is not None:
                writer.resume(kept, count)
            if callbacks.on_start is not None:
                callbacks.on_start()
            try:
                compute(plan, first, result, save, callbacks,
                        Workers(jobs, client=client, worker_timeout=worker_timeout), kept, held)
                if not result.interrupted:
                    writer.extra["missing"] = json.dumps(result.missing)
                    writer.save(result.branches, result.snaps, result.maps, result.landings)
                    writer.finish()
            except KeyboardInterrupt:  # outside a branch (saving, say): the last save stands
                result.interrupted = True
                del result.branches[writer.written - result.kept:]
            except ClusterLost as exc:  # the branches it finished are saved, the rest recorded
                lost = exc
                result.missing.append({"what": "branches", "kind": "cluster",
                                       "exception": "ClusterLost", "error": str(exc),
                                       "message": f"the run stopped: {exc}"})
                writer.extra["missing"] = json.dumps(result.missing)
                save()
            except (WriteError, *USER_ERRORS):
                raise
            except (Exception, SystemExit) as exc:   # escaped: the branches so far are kept
                _stopped(plan, result, writer, save, exc)
    finally:
        if client is not None:
            from .cluster import close
            close(client)
    result.path, result.seconds = writer.path, time.perf_counter() - t_run
    if lost is not None:
        missing = sum(b.message == NOT_COMPUTED for b in result.branches)
        again = ("a run with switch cannot be resumed: run it again" if plan.switch_count
                 else "run it again with --resume to compute them")
        saved = result.kept + len(result.branches) - missing
        raise ClusterLost(f"{lost}: {saved} branches saved to {writer.path}, {missing} not "
                          f"computed ({again})") from None
    return result


def _held(plan: Plan, kept: store.BranchFile, count: int) -> tuple[list, BaseException | None]:
    """The first ``count`` branches of the file ``kept`` read back as computed
    (`BranchFile.in_memory`), for the snap-back targets and landings of a resumed run; ([],
    the exception) if they cannot be read (a file damaged since it was opened): then the
    analyses of the branches computed now are made, and the kept branches' are recorded as
    missing (`_analyse`). None read where no analysis uses them: a problem without the
    snap-back scan (`snap_targets` needs the shooting and second-variation hooks) and no
    damped landings."""
    problem = plan.problem
    if not (problem.has_shooting and problem.has_second_variation or plan.damping):
        return [], None
    try:
        return [kept.in_memory(b, problem) for b in kept.branches[:count]], None
    except store.StoreError as exc:
        return [], exc


def _stopped(plan: Plan, result: RunResult, writer, save: Callable[[], None],
             exc: BaseException):
    """An exception escaped the computation (an internal error, or the module failing
    outside any branch): the branches computed so far are saved, with a record of what
    stopped the run in the file's ``missing`` (as ``what = "branches"``), and the run ends
    as an interrupted one does: an earlier ``<run>.h5`` is left as it was (`store.Writer`).
    With ``--debug`` an internal error is raised once the branches are saved."""
    record = failure_record(exc, module_files(plan.problem.module))
    internal = "internal error: " if record["kind"] == ENGINE else ""
    record.update(what="branches", message=(
        f"the run stopped: {internal}{record['exception']}: "
        + " ".join(record["error"].split()) + f" ({record['where']}); "
        f"{len(result.branches)} branches computed"))
    result.missing.append(record)
    result.stopped = True
    writer.extra["missing"] = json.dumps(result.missing)
    save()
    if record["kind"] == ENGINE and debugging():
        raise exc


def _resumed(plan: Plan, writer) -> store.BranchFile | None:
    """The file a ``--resume`` continues, opened and checked to be this run's (None if there
    is none yet). Its branches interrupted by the user (at its end) are computed again."""
    source = next((p for p in (writer.partial, writer.target) if p.is_file()), None)
    if source is None:
        return None
    if plan.switch_count:
        raise RunFileError(f"{plan.path}: switch: a run that switches at its branch points "
                           "cannot be resumed; run it again whole")
    bf = store.BranchFile(source)
    bf.maps  # read now: entering the writer may write the file again (`store.Writer`)
    if bf.run != plan.name or Path(bf.equation).stem != plan.problem.name:
        raise RunFileError(f"{source}: --resume: written by run {bf.run!r} of {bf.equation!r}, "
                           f"not {plan.name!r} of {plan.problem.source!r}")
    differ = _settings_differ(plan, bf)
    if differ:
        raise RunFileError(f"{source}: --resume continues the same run only, and this one "
                           f"differs from the run that wrote the file in {differ}; only the "
                           "cells (starts, parameter values, directions) may change: run it "
                           "without --resume, or write elsewhere (--out)")
    return bf


def _settings_differ(plan: Plan, bf: store.BranchFile) -> str:
    """What of ``plan``'s settings (`Plan.settings`) differs from those stored in ``bf``, as
    ``"bounds, options.ds_max"`` ("" if nothing). A file written before the settings were
    stored (version 0.1) has only its run file's text to compare: it must be the same."""
    if "settings" not in bf.attrs:
        return "" if bf.attrs.get("run_file", "") == plan.text else (
            "its run file's text (the file was written by elastica-auto "
            f"{bf.attrs.get('version', '?')}, which stored no more to compare)")
    try:
        stored = json.loads(bf.attrs["settings"])
    except ValueError:
        raise store.StoreError(f"{bf.path}: damaged branch file: attribute 'settings' is not "
                               "JSON") from None
    new = json.loads(json.dumps(plan.settings(), sort_keys=True))   # as stored: lists, not tuples
    names = {"module_sha256": "the equation module's text",
             "parameter": "the continued parameter", "stop": "stop"}
    out = []
    for key in sorted(set(stored) | set(new)):
        a, b = stored.get(key), new.get(key)
        if a == b:
            continue
        if isinstance(a, dict) and isinstance(b, dict):
            out += [f"{key}.{k}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)
                    and not (key == "options" and k == "ncol"
                             and _same_scheme(plan, a.get(k), b.get(k)))]
        else:
            out.append(names.get(key, key))
    if "options.ncol" in out:
        # the values, and where the run left ncol at its default "auto" and the file has 0
        # (the default when it was written), the way to resume it; a run that asks for
        # another ncol itself is told the two values only
        was, now = stored.get("options", {}).get("ncol"), new.get("options", {}).get("ncol")
        hint = ("; 0, the cubic scheme, was the default before \"auto\": --set ncol=0 "
                "resumes it" if was == 0 and now == NCOL_AUTO else "")
        out[out.index("options.ncol")] = (f"options.ncol (the file's {json.dumps(was)}, this "
                                          f"run's {json.dumps(now)}{hint})")
    return ", ".join(out)


def _same_scheme(plan: Plan, stored, new) -> bool:
    """Whether ``ncol`` ``stored`` (a file's) and ``new`` (the plan's) compute the same: a
    file written when the cubic scheme (0) was the default, resumed under the default
    ``"auto"`` by a problem that ``"auto"`` never turns to Gauss (one with an index count:
    `correctors.may_turn_to_gauss`): the same run, and its files stay resumable."""
    from ..numerics.correctors import may_turn_to_gauss
    return {stored, new} == {0, NCOL_AUTO} and not may_turn_to_gauss(plan.problem)


def _label_counters(kept, count: int) -> dict[str, int]:
    """Type -> the last label number on the first ``count`` branches of the kept file (the
    labels of the branches computed now continue after them)."""
    out: dict[str, int] = {}
    for name, (br, _) in (kept.labels.items() if kept is not None else ()):
        if br <= count:
            out[name[:2]] = max(out.get(name[:2], 0), int(name[2:]))
    return out


@dataclass(frozen=True)
class Workers:
    """Where `compute` computes the branches: the Dask cluster of ``client`` (open, and left
    open), else the one at the ``scheduler`` address, else ``jobs`` local worker processes
    (1: this process; 0: this process, joined by a local cluster started alongside)."""

    jobs: int = 1
    scheduler: str | None = None
    client: object = None
    #: seconds the cluster may have no worker (None: `cluster.WORKER_TIMEOUT`)
    worker_timeout: float | None = None


def compute(plan: Plan, first: list[Job], result: RunResult, save: Callable[[], None],
            callbacks: Callbacks = Callbacks(), workers: Workers = Workers(), kept=None,
            held=None):
    """Compute the branches from ``first``, then the switches ``plan.switch_count`` asks
    for, then the snap-back targets (and, if the plan asks, the stability maps of the
    fold curves' planes, `elastica_auto.analysis.maps`, and the damped model's landings,
    `elastica_auto.analysis.landing.damping_sweep`, each reported to
    ``callbacks.on_landing``), into ``result`` (labels numbered); ``save()`` after each
    branch. An interruption ends it with ``result.interrupted`` set.

    The branches are computed as tasks of a Dask cluster (`elastica_auto.execution.cluster`;
    ``callbacks.on_tasks`` reports their progress), as ``workers`` says: the one of its
    ``client`` (left open), or of its ``scheduler`` address, or else a local one of ``jobs``
    worker processes, at most one per core this process may use (`usable_cores`), and no
    more than the branches without switching. With ``jobs = 1``
    (or one branch) they are computed in this process, with no cluster. ``jobs = 0`` (the
    command's default): in this process from the start, and also, once it is up, on a local
    cluster of one worker per other core started meanwhile in the background (`Alongside`);
    with one branch (and no switching), or one core, in this process only. A cluster with
    no worker for ``workers.worker_timeout`` seconds ends the computation of the branches
    with ClusterLost (`cluster.run_on_cluster`); after them, the tasks it has not done are
    computed here (`cluster.map_tasks`)."""
    branches = result.branches
    mark_mirrors(plan, first)
    progress, on_branch, on_tasks = callbacks.progress, callbacks.on_branch, callbacks.on_tasks
    jobs, scheduler, client = workers.jobs, workers.scheduler, workers.client
    timeout = workers.worker_timeout
    pool = None
    if jobs == 0 and client is None and scheduler is None:
        alongside = usable_cores() - 1 if plan.switch_count or len(first) > 1 else 0
        if alongside > 0:
            pool = _alongside(plan, first, result, save, progress, on_branch, alongside)
            first = None
        jobs = 1
    # more worker processes than cores only share them, each with its own memory
    count = min(jobs, usable_cores())
    count = count if plan.switch_count else min(count, len(first or ()))
    own = client is None and (scheduler is not None or count > 1)
    if own:
        from . import cluster
        client = cluster.connect(scheduler) if scheduler is not None else cluster.local(count)

    if first is None:
        interrupted = result.interrupted
    elif client is None:
        interrupted = in_process(plan, first, branches, save, progress, on_branch)
        if not interrupted and plan.switch_count:
            interrupted = switch_levels(plan, branches, result.warnings, lambda jobs_list, skip: (
                in_process(plan, jobs_list, branches, save, progress, on_branch, skip)))
    else:
        from .cluster import close, run_on_cluster
        interrupted = True      # until the jobs have run
        with Interruptions() as signals:   # until the cluster is closed
            try:
                interrupted = run_on_cluster(client, plan, first, branches, save, on_branch,
                                             on_tasks, signals.stop, worker_timeout=timeout)
                if not interrupted and plan.switch_count:
                    interrupted = switch_levels(
                        plan, branches, result.warnings, lambda jobs_list, skip: run_on_cluster(
                            client, plan, jobs_list, branches, save, on_branch, on_tasks,
                            signals.stop, skip, timeout))
            finally:
                # kept open for the landings and the maps, its tasks too
                if own and (interrupted or not _tasks_after(plan)):
                    close(client, interrupted)
                    own = False
    number_labels(branches, result.kept + 1, _label_counters(kept, result.kept))
    result.interrupted = interrupted
    mapper = None
    if pool is not None:
        mapper = pool.map
    elif client is not None and not interrupted and _tasks_after(plan):
        from functools import partial

        from .cluster import map_tasks
        mapper = partial(map_tasks, client, warnings=result.warnings, worker_timeout=timeout)
    broken = True           # until the analysis is done (a Ctrl-C in it ends the workers)
    try:
        if not interrupted:
            _analyse(plan, result, kept, pool, callbacks.on_landing, mapper, held)
        broken = False
    finally:
        if pool is not None:
            pool.background.close(wait=5.0)
        if own:
            from .cluster import close
            close(client, broken)


def _shooting_unused(problem) -> str | None:
    """Why the module's own ``shooting`` hook is not used for ``problem``, or None: a problem
    with free parameters refuses it (`Augmented.REFUSED`), so that a fold bounding a stable
    segment gets no snap-back targets; the run says so rather than leave the table empty."""
    refusal = getattr(problem, "refusal", None)
    why = refusal("shooting") if refusal is not None else None
    if why is None or not callable(getattr(problem.module, "shooting", None)):
        return None
    free = ", ".join(getattr(problem, "free", ()))
    return (f"the module's shooting hook is not used "
            f"{f'with the free parameters {free}' if free else 'here'} ({why})")


def _tasks_after(plan: Plan) -> bool:
    """Whether the analysis after the branches has tasks for workers: the landings (snap
    targets, damped model) and the stability maps' enumerations."""
    return bool(plan.landing or plan.damping or plan.maps)


def _analyse(plan: Plan, result: RunResult, kept, pool: Alongside | None,
             on_landing: Callable[[int, int, dict], None] | None, mapper=None, held=None):
    """The branches' snap-back targets, and as the plan asks, the damped model's landings
    and the stability maps, into ``result``. A resumed run (``kept``: the file it continues,
    its first ``result.kept`` branches kept) analyses the kept branches with those computed
    now, as a whole run does: the kept file's tables are not reused (an interrupted file,
    or one that lost its cluster, has none, and a kept branch's target may lie on a branch
    computed now: its ``on_branch``). ``held``: `_held`'s, the kept branches read back, or
    the reason they could not be: then the kept branches' targets and landings are recorded
    as missing (kind ``file``), their rows in the kept file, if any, kept. An analysis that
    fails (the module raising or exiting in it, a numerical failure, an internal error)
    leaves the branches standing: it is recorded in ``result.missing`` (and stored in the
    file), and the run's exit status says so.
    ``pool``: a default run's (`Alongside`): its workers' equilibrium scans
    (`snap_targets`'s ``cache``). ``mapper``: computes the landings (overdamped and
    damped) and the maps' enumerations as tasks (the default run's `Alongside.map`, a
    cluster's `cluster.map_tasks`; default here, one after the other)."""
    held, unread = held if held is not None else ([], None)
    whole = kept is None or unread is None      # every branch of the file analysed here
    branches = [*held, *result.branches] if whole else result.branches
    shift = 0 if whole else result.kept         # the numbers of these branches in the file

    def failed(what: str, name: str, exc: BaseException):
        record = failure_record(exc, module_files(plan.problem.module))
        if record["kind"] == ENGINE and debugging():
            raise exc
        internal = "internal error: " if record["kind"] == ENGINE else ""
        record.update(what=what, message=f"{name} failed: {internal}{record['exception']}: "
                      + " ".join(record["error"].split()) + f" ({record['where']})")
        result.missing.append(record)
        result.warnings.append(record["message"])

    def partly(what: str, failures: list):   # the landings of some folds failed: the table
        # stands without them
        for record in failures:
            result.missing.append({**record, "what": what})

    if not whole:   # (kind "file": neither the module's failure nor the engine's)
        for what, name in (("snaps", "snap-back targets"), ("landings", "damped landings")):
            if what == "snaps" or plan.damping:
                message = (f"{name} of the kept branches 1-{result.kept} not computed: they "
                           f"could not be read back ({' '.join(str(unread).split())})")
                result.missing.append({"what": what, "kind": "file",
                                       "exception": type(unread).__name__,
                                       "error": str(unread), "where": "?", "traceback": [],
                                       "message": message})
                result.warnings.append(message)

    unused = _shooting_unused(plan.problem)
    if unused and any(snap_points(b) for b in branches):
        result.warnings.append(f"no snap-back targets: {unused}")
    failures: list[dict] = []
    try:
        snaps = snap_targets(plan.problem, branches, result.warnings, landing=plan.landing,
                             cache=pool.scans if pool is not None else None,
                             mapper=mapper, mirror=plan.options.mirror, failures=failures)
        partly("snaps", failures)       # the overdamped landings of some folds
    except (Exception, SystemExit) as exc:   # the module failing in the scan: keep the branches
        failed("snaps", "snap-back scan", exc)
    else:
        for row in snaps:           # numbered in the file
            row["branch"] += shift
            row["on_branch"] += shift if row["on_branch"] else 0
        result.snaps = snaps
    if not whole:
        result.snaps = [r for r in kept.snaps if r["branch"] <= result.kept] + result.snaps
    if plan.damping:
        from ..analysis.landing import damping_sweep
        failures = []
        try:
            landings = damping_sweep(plan.problem, branches, plan.damping, plan.damping_folds,
                                     result.warnings, on_landing, mapper=mapper,
                                     failures=failures)
            partly("landings", failures)
        except (Exception, SystemExit) as exc:
            failed("landings", "damped landings", exc)
        else:
            for row in landings:
                row["branch"] += shift
            result.landings = landings
        if not whole:
            result.landings = ([r for r in kept.landings if r["branch"] <= result.kept]
                               + result.landings)
    if plan.maps:
        every = [*(kept.branches[:result.kept] if kept is not None else ()), *result.branches]
        try:
            result.maps = stability_maps(plan.base, every, plan.problem.free[0],
                                         plan.parameter,
                                         (plan.stops.lower, plan.stops.upper), mapper=mapper)
        except (Exception, SystemExit) as exc:
            failed("maps", "stability map", exc)


def _alongside(plan, first, result, save, progress, on_branch, workers) -> Alongside:
    """The default run: `Alongside` with a background cluster of ``workers``, for the
    branches from ``first``, then the switched ones; sets ``result.interrupted``. Returns
    the pool: its ``scans`` are those its workers computed (`snap_targets`'s ``cache``)."""
    from .cluster import Background
    with Interruptions() as signals:
        pool = Alongside(plan, workers, Background, pays=CLUSTER_PAYS,
                          warnings=result.warnings)
        interrupted = True        # until the branches are in: whatever escapes closes the pool
        try:
            interrupted = pool.run(first, result.branches, save, progress, on_branch,
                                   signals.stop)
            if not interrupted and plan.switch_count:
                interrupted = switch_levels(
                    plan, result.branches, result.warnings, lambda jobs_list, skip: pool.run(
                        jobs_list, result.branches, save, progress, on_branch, signals.stop,
                        skip))
            if not interrupted:
                interrupted = not pool.wait_for_scans(signals.stop)
        finally:
            if interrupted:
                pool.background.close()
            elif not _tasks_after(plan):   # the landings and maps need it; else its
                pool.background.finish()   # helper ends its cluster while this process goes on
    result.interrupted = interrupted
    return pool


# -- the default run: this process computes at once, a local cluster joins when it pays ------
#
# `Alongside` is made of five parts, each a class with the state it reads and writes (which
# `Alongside.__init__` makes): when the cluster is started (`_Starting`), the messages to
# and from it (`_Messages`), the branches (`_Branches`, taken in the plan's order by the
# `Schedule`), the snap-back scans (`_Scans`) and the analysis' other tasks (`_Tasks`). They
# share the lock, the queue of results and the background cluster.

#: The default run starts its local cluster only once the work left for it is estimated at
#: more than this many seconds (`Alongside`): its start-up takes about 1.6 s of wall time
#: and as much CPU as three interpreters importing distributed, which on 2 cores is taken
#: from the branches computed meanwhile. With the cluster started at once, rotating_arm (4
#: branches computed of 8, about 0.5 s each) took 0.95-1.13x the time of --jobs 1 (medians
#: of three sittings): never the 0.65x a second core could give. The estimate (the mean of
#: the branches done times those left) is low on a grid whose last branches are the longest:
#: at 3 s rotating_arm_3d (branches of 0.3-0.6 s, then two of 2.3 and 3.8 s) started none
#: and took its --jobs 1 time; at 2 s it starts one after its third branch (0.82x), and
#: load_magnitude too (0.73x), the other runs of `make runs` as before (docs/benchmarks.md).
CLUSTER_PAYS = 2.0


class _Idle:
    """The background cluster of a default run before it is started (`Alongside`): never
    up, no worker, takes nothing."""

    workers = 0

    def __init__(self):
        self.ready = threading.Event()

    def submit(self, tag, function, args) -> bool:
        return False

    def finish(self):
        pass

    def close(self, wait: float = 0.0):
        pass


class _Starting:
    """When the cluster is started: when it pays (``pays`` seconds, `CLUSTER_PAYS`; at once
    for 0), that is once the work of a kind (branches, scans, tasks) not taken yet, each
    estimated at the mean time of those this process finished, or at the time the one in
    hand has taken so far if longer, comes to more than ``pays``. (Mirror images, made here
    at their turn, are not counted: they cost nothing.) Its state: ``pays``, ``started``,
    ``spent`` (kind -> [seconds, count] of the work this process finished) and
    ``background`` (`_Idle` until started)."""

    def _start(self):
        """Start the cluster (once)."""
        with self.lock:
            if not self.started:
                self.started = True
                self.background = self._make()
                self._feed()

    def _consider(self, kind: str, left: int, running: float = 0.0):
        """Start the cluster if it pays: ``left`` items of ``kind`` not taken yet, each
        estimated at the mean of those finished here (``running``: the seconds of the one
        in hand, at least that long)."""
        if self.started or left <= 0:
            return
        seconds, count = self.spent.get(kind, (0.0, 0))
        mean = seconds / count if count else 0.0
        if max(mean, running) * left > self.pays:
            self._start()

    def _timed(self, kind: str, left: Callable[[], int], function, *args):
        """``function(*args)`` computed here, its seconds added to ``spent[kind]``."""
        t0 = time.perf_counter()
        out = function(*args)
        cost = self.spent.setdefault(kind, [0.0, 0])
        cost[0] += time.perf_counter() - t0
        cost[1] += 1
        self._consider(kind, left())
        return out


class _Messages:
    """The messages to and from the background cluster: results arrive on its reading
    thread (`_on_result`), which queues them (``results``) and feeds the cluster again;
    `_feed` hands each idle worker the next piece of work, in the order branches, wanted
    scans, the analysis' tasks, guessed scans; the main thread files each result where it
    belongs (`_take`). A worker that ended hands its work back (``returned``,
    ``task_returned``); the scans it had are computed by `snap_targets` instead."""

    def _on_result(self, tag, ok, value):
        """From the background's reading thread: a result, or the cluster up (tag None, ok)
        or ended (tag None, not ok)."""
        with self.lock:
            if tag is None and not ok:
                self.returned += sorted(i for level, i in self.claimed if level == self.level)
                self.claimed.clear()
                self.asked.clear()
                self.task_returned += sorted(self.task_claimed)
                self.task_claimed.clear()
                self.guessing.clear()             # snap_targets computes the awaited ones
                self.awaited.clear()
            elif tag is not None:
                self.results.put((tag, ok, value))
                if tag[0] == "branch":
                    self.claimed.discard(tag[1])
                elif tag[0] == "task":
                    self.task_claimed.discard(tag[1])
                elif tag[0] == "guess":
                    self.guessing.discard(tag[1])
                else:
                    self.asked.discard(tag[1])
            self._feed()
        if tag is None and not ok:
            self.results.put(None)               # wake the waiting main thread

    def _feed(self):
        """Under the lock, if the cluster is up: a task for each idle worker, the next
        branch, else a scan, else a task of `map`, else a guessed scan."""
        bg = self.background
        while bg.ready.is_set() and (len(self.claimed) + len(self.asked) + len(self.guessing)
                                     + len(self.task_claimed)) < bg.workers:
            if self.front <= self.back:
                i = self.front
                if self.jobs[i].mirror:          # taken from the branch before it, here
                    self.front += 1
                    continue
                if not bg.submit(("branch", (self.level, i)), compute_branch,
                                 (self.plan, self.offset + i + 1, self.jobs[i])):
                    return
                self.front += 1
                self.claimed.add((self.level, i))
            elif self.unsent:
                if not self._hand_scan(bg, "scan", self.unsent, self.asked):
                    return
            elif self.task_front < len(self.tasks):
                i = self.task_front
                if not bg.submit(("task", i), self.task_fn, self.tasks[i]):
                    return
                self.task_front += 1
                self.task_claimed.add(i)
            elif self.early:
                if not self._hand_scan(bg, "guess", self.early, self.guessing):
                    return
            else:
                return

    def _hand_scan(self, bg, kind: str, waiting: list, on_cluster: set) -> bool:
        """Hand the first of ``waiting`` (key, parameters) to ``bg`` as a task of ``kind``
        ("scan" or "guess"), moving its key to ``on_cluster``; False if it refused it."""
        key, params = waiting[0]
        if not bg.submit((kind, key), enumerate_equilibria, (self.plan.problem, params)):
            return False
        waiting.pop(0)
        on_cluster.add(key)
        return True

    def _take(self, message, done: dict):
        """A result from the cluster into ``done`` (a branch) or ``scans``. A scan or a task
        that raised there (not lost with its worker) is reported in ``warnings``, and
        computed here: a scan by `snap_targets` (not sent again), a task by `map`."""
        if message is None:
            return
        (kind, what), ok, value = message
        raised = not ok and not value.lost
        if kind in ("scan", "guess") and raised:
            with self.lock:
                params = (self.pending_params.get(what) or self.awaited.get(what)
                          or self.guesses.get(what, (None, {}))[1])
                self.failed.add(what)
            at = ", ".join(f"{k}={v:.6g}" for k, v in params.items())
            self.warnings.append(f"the snap-back scan at {at} raised on a worker: {value}; "
                                 "computed here where the run needs it")
        if kind == "scan":
            if ok:
                self.scans[what] = (self.pending_params[what], value[0])
            return
        if kind == "guess":
            with self.lock:
                if what in self.awaited:
                    params = self.awaited.pop(what)
                    if ok:
                        self.scans[what] = (params, value[0])
                    elif not raised:   # its worker died: computed here (`wait_for_scans`)
                        self.unsent.append((what, params))
                elif ok and what in self.guesses:
                    self.spare[what] = value[0]
                elif what in self.guesses:   # failed: `_scan` sends it again if wanted
                    del self.guesses[what]
            return
        if kind == "task":
            if ok:
                done[what] = value[0]
            else:  # computed here instead, and if it raised there, said so
                if raised:
                    name = getattr(self.task_fn, "__name__", "task")
                    self.warnings.append(f"task {what + 1} of {len(self.tasks)} ({name}) "
                                         f"raised on a worker: {value}; computed here instead")
                with self.lock:
                    self.task_returned.append(what)
            return
        level, what = what
        if level != self.level:
            return
        job = self.jobs[what]
        if ok:
            br, worker = value
            br.worker = worker
        else:  # the task raised, or its workers died beyond the scheduler's retries
            br = failed_branch(self.plan, job, value)
        done[what] = br


class _Branches:
    """The branches: this process takes the next job from the front of the plan (or one
    handed back), the cluster's workers likewise (`_Messages._feed`), and the `Schedule`
    takes their branches into the file in the plan's order. Its state: the jobs of the
    current `run` (``jobs``, its ``level``: a result of an earlier level, left out while
    its worker computed it, is dropped), the next to take (``front``, up to ``back``), those
    on the cluster as (level, job) (``claimed``), and those handed back (``returned``)."""

    def run(self, jobs_list, branches, save, progress, on_branch, stop, skip=None) -> bool:
        """Compute ``jobs_list``, appending the branches to ``branches`` in order and calling
        ``save()`` after each, but those for which ``skip(i, branches)`` is true when their
        turn comes (left out then, computed or not: no one starts them after that); True if
        interrupted (``stop`` set, or the branch in progress here interrupted: it is
        kept up to its last point)."""
        import queue
        with self.lock:
            self.jobs, self.front, self.back = jobs_list, 0, len(jobs_list) - 1
            self.level += 1
            self.returned.clear()                # an earlier level's, left out
            self.offset = len(branches)
            self._feed()
        done: dict[int, Branch] = {}
        schedule = Schedule(self.plan, jobs_list, branches, save, on_branch, skip, progress)

        def branches_left():
            with self.lock:
                ahead = range(self.front, self.back + 1)
                return sum(not jobs_list[i].mirror for i in ahead) + len(self.returned)

        def left_out(i):        # not handed out after its turn
            with self.lock:
                self.front = max(self.front, i + 1)

        def flush():
            while True:
                try:
                    self._take(self.results.get_nowait(), done)
                except queue.Empty:
                    break
            # the cluster's result for a job left out, if it had it, is dropped; a mirror
            # job is made at its turn, from the branch before it (a signal meanwhile ends
            # the run)
            if schedule.take(done, stop=stop.is_set, on_skip=left_out, on_taken=self._scan):
                stop.set()
            for i in [i for i in done if i < schedule.taken]:
                del done[i]

        while not stop.is_set() and not schedule.finished:
            with self.lock:
                if self.returned:
                    i = self.returned.pop(0)
                elif self.front <= self.back:
                    i, self.front = self.front, self.front + 1
                else:
                    i = None
            if i is None:      # the rest is on the cluster: a scan meanwhile, or wait
                if not self._scan_here():
                    try:
                        self._take(self.results.get(timeout=0.05), done)
                    except queue.Empty:
                        pass
                flush()
                continue
            if i < schedule.taken or jobs_list[i].mirror:   # left out meanwhile (given back
                continue                         # by the cluster), or made at its turn
            t0 = time.perf_counter()

            def watched(*args, t0=t0):
                if progress is not None:
                    progress(*args)
                if not self.started:
                    self._consider("branch", branches_left(), time.perf_counter() - t0)
            br = self._timed("branch", branches_left, compute_branch, self.plan,
                             schedule.number(i), jobs_list[i], watched, stop.is_set,
                             self._guess)
            done[i] = br
            flush()
            if br.interrupted:
                stop.set()
        if stop.is_set():
            self.background.close()
            flush()
            schedule.rest(done)    # finished beyond a gap in the plan's order
            return True
        return False


class _Scans:
    """The snap-back scans: as each branch is taken, those its folds need
    (`analysis.snaps.scans`) go to the cluster (`_scan`); those of a branch computed here
    are guessed while it is computed (`_guess`), for a worker that would otherwise wait; a
    scan still waiting for a worker when this process has nothing else to do is computed
    here (`_scan_here`); `wait_for_scans` collects the rest. Their results, ``scans``, are
    `snap_targets`'s ``cache``."""

    def _scan(self, br: Branch):
        """The scans ``br``'s folds need that no earlier branch needed, to the cluster; not
        those at the mirror images of scans sent (`snap_targets` makes them from those).
        One guessed while ``br`` was computed (`_guess`) at the same parameters is taken
        as it stands (done, on the cluster or waiting to be handed out); ``br``'s other
        guesses are dropped."""
        problem = self.plan.problem
        name = br.parameter
        for key, params in scans(problem, br).items():
            with self.lock:
                guess = self.guesses.pop(key, None)
                done = self.spare.pop(key, None)
                queued = any(e[0] == key for e in self.early)
            if key in self.seen:
                continue
            self.seen.add(key)
            if key in self.failed:
                continue
            if (self.plan.options.mirror
                    and mirror_key(problem, name, params) in self.sent):
                continue
            self.sent.add(copy_key(problem, name, params))
            self.pending_params[key] = params
            taken = guess is not None and guess[1] == params
            with self.lock:
                if taken and done is not None:
                    self.scans[key] = (params, done)
                elif taken and not queued:          # handed out: its result is on its way
                    self.awaited[key] = params
                else:
                    self.early = [e for e in self.early if e[0] != key]
                    self.unsent.append((key, params))
                    self._feed()
        with self.lock:
            for key in [k for k, g in self.guesses.items() if g[0] is br]:
                del self.guesses[key]
                self.spare.pop(key, None)
            self.early = [e for e in self.early if e[0] in self.guesses]

    def _guess(self, br: Branch):
        """After each step of a branch computed here: a new fold or branch point with index 0
        (the direct count) on one side and a positive index on the other may end a stable
        segment, and then `_scan` will want the scan at its parameters once the branch is
        labelled and saved. Queued now for a worker that has nothing else to do (after
        every other kind of task), the worker has it done or under way by then: the scans
        of a long branch no longer wait for its end (`rotating_arm_3d`'s last branch ran
        alone for seconds, then its scans). Not where `_scan` will not send one: a scan
        seen or guessed already, or at the mirror image of one sent or guessed."""
        problem = self.plan.problem
        if self.plan.curve is not None or not (problem.has_shooting
                                               and problem.has_second_variation):
            return
        pts, (reading, j) = br.points, self.cursor
        j = j if reading is br and j <= len(pts) else 1
        name = br.parameter
        for k in range(j, len(pts) - 1):
            p = pts[k]
            if p.type not in labels.TURNS or stable_side(pts[k - 1].index_direct,
                                                         pts[k + 1].index_direct) is None:
                continue
            key = scan_key(problem, name, p.params)
            if key in self.seen or key in self.guesses:
                continue
            params = dict(p.params)
            if self.plan.options.mirror:
                image = mirror_key(problem, name, params)
                if image in self.sent or any(g[2] == image for g in self.guesses.values()):
                    continue
            with self.lock:
                self.guesses[key] = (br, params, copy_key(problem, name, params))
                self.early.append((key, params))
                self._feed()
        self.cursor = (br, max(j, len(pts) - 1))

    def _scan_here(self) -> bool:
        """A scan waiting for a worker computed here, by a main thread that has nothing else
        to do: the first wanted one (``unsent``), else the first guess (``early``, its result
        kept for `_scan` as a worker's is); False if none waits. (`rotating_arm_3d`: this
        process, done with its last branch while the one worker computed another for
        seconds, waited with its branch's scans queued behind it.)"""
        with self.lock:
            if self.unsent:
                kind, (key, params) = "scan", self.unsent.pop(0)
            elif self.early:
                kind, (key, params) = "guess", self.early.pop(0)
            else:
                return False
        try:
            value = self._timed("scan", lambda: len(self.unsent) + len(self.early),
                                enumerate_equilibria, self.plan.problem, params)
        except (Exception, SystemExit):
            # the module failing in its scan: not kept, so that `snap_targets` computes it
            # at the run's end, where the failure is recorded as the analysis's (`_analyse`)
            return True
        with self.lock:
            if kind == "scan":
                self.scans[key] = (params, value)
            elif key in self.guesses:
                self.spare[key] = value
        return True

    def wait_for_scans(self, stop) -> bool:
        """The scans not done yet: this process takes those not sent to the cluster (no
        import; tens of ms for the planar rod, half a second for the spatial one) and waits
        for those sent; False if interrupted meanwhile. A scan leaves ``asked`` once its
        result is in the queue, so the results still there are taken before returning
        (dropped, one finished as this process finished its own was computed again by
        `snap_targets`)."""
        import queue
        with self.lock:
            self.early.clear()                   # every branch is in: no more guesses
        while not stop.is_set():
            with self.lock:
                if not self.background.ready.is_set():   # ended: none will come back
                    self.awaited.clear()
                finished = not self.asked and not self.unsent and not self.awaited
                if not finished:
                    self._feed()
            if finished:
                while True:
                    try:
                        self._take(self.results.get_nowait(), {})
                    except queue.Empty:
                        return True
            if self._scan_here():
                continue
            try:
                self._take(self.results.get(timeout=0.05), {})
            except queue.Empty:
                pass
        return False


class _Tasks:
    """The analysis' other tasks (the landings, the maps' enumerations), shared with the
    cluster's idle workers as the branches are (`map`): ``task_fn``, ``tasks``, the next to
    take (``task_front``), those on the cluster (``task_claimed``) and those handed back
    (``task_returned``)."""

    def map(self, function, args_list, on_done) -> list:
        """``function(*args)`` for each of ``args_list``, in this process and on the
        cluster's idle workers (once it is up), each taking the next from the front of the
        list, as the branches are shared; their results in order, and ``on_done(i, result)``
        called here as each arrives. A task the cluster fails or gives back is computed
        here. (The landings of `analysis.snaps.snap_targets` and
        `analysis.landing.damping_sweep`, the enumerations of `analysis.maps.stability_maps`:
        up to seconds each, the same result whoever computes it.)"""
        import queue
        n = len(args_list)
        with self.lock:
            self.task_fn, self.tasks, self.task_front = function, list(args_list), 0
            self.task_claimed.clear()
            self.task_returned.clear()
            self._feed()
        done: dict[int, object] = {}
        reported = set()

        def tasks_left():
            with self.lock:
                return n - self.task_front + len(self.task_returned)

        def report():
            for i in sorted(set(done) - reported):
                reported.add(i)
                on_done(i, done[i])

        while len(reported) < n:
            with self.lock:
                if self.task_returned:
                    i = self.task_returned.pop(0)
                elif self.task_front < n:
                    i, self.task_front = self.task_front, self.task_front + 1
                else:
                    i = None
            if i is not None:
                done[i] = self._timed("task", tasks_left, function, *self.tasks[i])
            else:                                # the rest is on the cluster: wait for it
                try:
                    self._take(self.results.get(timeout=0.05), done)
                except queue.Empty:
                    pass
            while True:
                try:
                    self._take(self.results.get_nowait(), done)
                except queue.Empty:
                    break
            report()
        with self.lock:
            self.task_fn, self.tasks = None, []
        return [done[i] for i in range(n)]


class Alongside(_Starting, _Messages, _Branches, _Scans, _Tasks):
    """Branches computed in this process from the start, and by a local Dask cluster
    (`elastica_auto.execution.cluster.Background`) once it has started in the background,
    one task per worker at a time, each taking the next branch of the plan: nothing waits
    for the cluster, and a run done before it is up never uses it. (Taken in plan order, the
    long branches of a grid listed by increasing load go last to both; handed from the end
    of the list, the two longest of rotating_arm went to the cluster one after the other
    while this process, done with the rest, waited for them: 4.0 s of branches there
    against 3.0 s here.) The branches are saved in the plan's order as they
    complete, so the file is the one ``jobs = 1`` writes (but for each branch's ``worker``).
    As each branch is saved, the snap-back scans its folds need (`analysis.snaps.scans`)
    go to the cluster too, if it is up; those of a branch computed here are guessed while
    it is computed, for a worker that would otherwise wait (`_guess`); a scan still waiting
    for a worker when this process has no branch left to take is computed here
    (`_scan_here`). If the cluster ends (or never starts), this process computes what it
    had been given.

    The cluster is started when it pays (`_Starting`). A task whose worker died is computed
    here quietly; one that raised on the cluster (`jobs.TaskFailure`) gives a branch ending
    MX with the exception, or, a scan or another task, is computed here with a line in
    ``warnings`` naming the exception."""

    def __init__(self, plan, workers: int, background, pays: float = 0.0,
                 warnings: list[str] | None = None):
        """The pool of ``plan``, its cluster of ``workers`` made by ``background(workers,
        on_result)`` (`cluster.Background`) when it pays (`_Starting`); a task that raised
        on it is reported in ``warnings``. The state of each part, as its docstring says."""
        import queue
        # shared: the lock (the reading thread's messages), their queue, the warnings
        self.plan, self.lock, self.results = plan, threading.Lock(), queue.Queue()
        self.warnings = [] if warnings is None else warnings
        # _Starting
        self.pays, self.started = pays, False
        self._make = lambda: background(workers, self._on_result)
        # the seconds this process spent on each kind of work ("branch", "scan", "task") and
        # how many of it it finished
        self.spent: dict[str, list[float]] = {}
        self.background = _Idle()
        # _Branches: the jobs of the current `run` (its ``level``: a result of an earlier
        # one, left out while its worker computed it, is dropped), the next to take from
        # each end, those on the cluster as (level, job), and those handed back
        self.jobs, self.front, self.back, self.offset, self.level = [], 0, -1, 0, 0
        self.claimed, self.returned = set(), []
        # _Scans: the results, the keys seen, those waiting for a worker, those on it
        self.scans, self.seen, self.unsent, self.asked = {}, set(), [], set()
        self.sent: set[tuple] = set()      # the parameters of the scans sent (`copy_key`)
        self.pending_params: dict[tuple, dict] = {}
        # the scans that raised on the cluster: not sent again (`snap_targets` computes
        # them here)
        self.failed: set[tuple] = set()
        # scans guessed while this process computes a branch (`_guess`): key -> (branch,
        # parameters, copy_key), those not handed out yet (key, parameters), those on the
        # cluster, their results not wanted (yet), and the wanted ones still on the cluster
        self.guesses: dict[tuple, tuple] = {}
        self.early: list[tuple] = []
        self.guessing: set[tuple] = set()
        self.spare: dict[tuple, object] = {}
        self.awaited: dict[tuple, dict] = {}
        self.cursor: tuple = (None, 1)    # the branch `_guess` reads, its next point
        # _Tasks: the function, its arguments, the next to take, those on the cluster, and
        # those handed back (the cluster ended, or the task failed there)
        self.task_fn, self.tasks, self.task_front = None, [], 0
        self.task_claimed, self.task_returned = set(), []
        if pays <= 0:
            self._start()


def in_process(plan: Plan, jobs_list: list[Job], branches: list[Branch],
               save: Callable[[], None], progress=None, on_branch=None, skip=None) -> bool:
    """Compute ``jobs_list`` one after the other in this process, each at its turn of the
    `Schedule` (appended to ``branches``, ``save()`` after each, reported to ``on_branch``),
    but the jobs for which ``skip(i, branches)`` is true when their turn comes
    (`switch_levels`); True if interrupted (the branch in progress is kept up to its last
    point). A Ctrl-C while a computed branch is saved and reported waits for them."""
    schedule = Schedule(plan, jobs_list, branches, save, on_branch, skip, progress)
    while not schedule.finished:
        # one context from a branch's start to its save: compute_branch's own raises in the
        # continuation, and this one records a signal wherever else it lands
        with Interruptions() as late:
            interrupted = schedule.take({}, here=True, stop=late.stop.is_set, limit=1)
        if interrupted or late.stop.is_set():
            return True
    return False


__all__ = ["execute", "compute", "compute_branch", "build_start", "switch_jobs", "switch_levels",
           "in_process", "Job", "RunResult",
           "StartError", "RunFileError"]
