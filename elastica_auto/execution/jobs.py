"""One branch of a plan as a job: where it starts, and computing it.

What the run in this process (`run`) and the cluster's tasks (`cluster`) share: a worker
computes a branch with `compute_branch`, and a task that failed (`TaskFailure`) becomes an
empty branch of the plan ending MX (`failed_branch`).
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from dataclasses import dataclass
from typing import Callable

from ..branches import pitchfork
from ..branches.branch import Branch
from ..branches.mirror import (image_of, mirror_course, set_aside, symmetric_course,
                               symmetric_start)
from ..branches.kinds import start_point
from ..branches.stepper import Origin, continue_branch
from ..core import labels
from ..core.errors import ENGINE, debugging, failure_record, module_files
from ..core.interrupts import Interruptions
from ..numerics.stability import label_stability
from .plan import BranchSpec, Plan


@dataclass
class Job:
    """One branch to compute: its spec and where it starts. ``mirror``: the branch is the
    mirror image of the job's before it in its list (`mark_mirrors`), taken from it once
    that one is done (`mirrored_branch`) rather than computed."""

    spec: BranchSpec
    origin: Origin
    mirror: bool = False
    #: the next job is this one's mirror image: computed along `mirror_course`
    mirrored: bool = False


def mark_mirrors(plan: Plan, jobs_list: list[Job]) -> None:
    """Set ``mirror`` on each job of ``jobs_list`` that continues the start of the job before
    it, at the same parameter values, in the direction ``-`` where that one goes ``+``, from
    a start that is its own mirror image (`elastica_auto.branches.mirror.symmetric_start`);
    not for fold curves, nor with the option ``mirror`` off."""
    if plan.curve is not None or not plan.options.mirror or not symmetric_course(plan.course):
        return
    for before, job in zip(jobs_list, jobs_list[1:]):
        a, b = before.spec, job.spec
        job.mirror = (not before.mirror and (a.direction, b.direction) == (1, -1)
                      and str(a.start) == str(b.start) and a.params == b.params
                      and symmetric_start(plan.problem, plan.parameter, job.origin))
        before.mirrored = job.mirror


#: Progress callback: (branch number, points so far, folds so far, current parameter value).
Progress = Callable[[int, int, int, float], None]


@dataclass(frozen=True)
class Callbacks:
    """How a run reports as it goes; each is called only if given.

    ``progress(branch, points, folds, value)`` during a branch computed in this process;
    ``on_branch(number, branch)`` as each branch is done, in plan order; ``on_start()`` once
    a run's checks have passed, before its first branch; ``on_tasks(finished, tasks,
    points, workers)`` while a Dask cluster computes; ``on_landing(done, total, row)`` after
    each of the damped model's landings."""

    progress: Progress | None = None
    on_branch: Callable[[int, Branch], None] | None = None
    on_start: Callable[[], None] | None = None
    on_tasks: Callable[[int, int, int, int], None] | None = None
    on_landing: Callable[[int, int, dict], None] | None = None



def compute_branch(plan: Plan, k: int, job: Job, progress: Progress | None = None,
                   should_stop: Callable[[], bool] | None = None,
                   watch: Callable[[Branch], None] | None = None) -> Branch:
    """Continue branch number ``k`` of the file from ``job``'s start, then label its
    stability. Ctrl-C (or ``should_stop()`` turning true) or a failure ends the branch early
    with MX, keeping every point computed so far (`elastica_auto.branches.stepper.continue_branch`):
    one failing branch does not cost the run its other branches. A Ctrl-C once the
    continuation is over waits for the labelling, and sets ``interrupted`` on the branch,
    which is kept whole. A job whose mirror image is the next is continued with the negatives
    of the UZ values too, and the points there set aside for the image
    (`elastica_auto.branches.mirror.mirror_course`, `set_aside`). ``watch(branch)`` is
    called after each step with the branch so far (unlabelled: the points' ``index_direct``
    is the direct count)."""
    br = new_branch(plan, job)

    def on_step(b, lam):
        if should_stop is not None and should_stop():
            raise KeyboardInterrupt
        if progress is not None:
            progress(k, len(b.points), len(b.folds), lam)
        if watch is not None:
            watch(b)

    t0 = time.perf_counter()
    # raised after the continuation, a signal would throw the computed branch away: one
    # context raises during the continuation (which ends the branch at its last point) and
    # only records after it
    with Interruptions(raising=True) as late:
        try:
            course = mirror_course(plan.course) if job.mirrored else plan.course
            continue_branch(br, plan.problem, course, job.origin, on_step)
        except KeyboardInterrupt:  # after the continuation's own handling: the branch is whole
            pass
        late.raising = False
        try:
            if plan.curve == "pitchfork":
                pitchfork.warn_unfolded(br, plan.reference, plan.options.tol)
            label_stability(br, plan.problem)
            if job.mirrored:
                set_aside(br, plan.course)
            if plan.problem.has_second_variation and plan.curve is None and not br.interrupted:
                from ..analysis.snaps import mark_subcritical
                mark_subcritical(plan.problem, br)
        except (Exception, SystemExit) as exc:   # as a failure in the continuation would
            _labelling_failed(br, plan.problem, exc)
    br.interrupted = br.interrupted or late.stop.is_set()
    br.seconds = time.perf_counter() - t0
    return br


def _labelling_failed(br: Branch, problem, exc: BaseException):
    """The labelling of the computed branch ``br`` failed (the module's second variation
    raising, say): the branch ends MX there, its points kept, the failure recorded as a
    failure in the continuation is (`elastica_auto.branches.stepper.continue_branch`); the
    last point, if labelled already, is followed by an MX copy of itself (no module call)."""
    record = failure_record(exc, module_files(problem.module))
    if record["kind"] == ENGINE and debugging():
        raise exc
    internal = "internal error: " if record["kind"] == ENGINE else ""
    br.end = labels.MX
    br.message = (f"{internal}labelling the branch failed: {record['exception']}: "
                  + " ".join(record["error"].split()) + f" ({record['where']})")
    br.diagnostics = {**record, "step": len(br.points)}
    last = br.points[-1] if br.points else None
    if last is not None and last.type not in labels.FAILED and last.state is not None:
        br.points.append(dataclasses.replace(last, type=labels.MX, label=0, note=""))


def mirrored_branch(plan: Plan, k: int, job: Job, source: Branch,
                    progress: Progress | None = None,
                    should_stop: Callable[[], bool] | None = None) -> Branch:
    """Branch number ``k``, of the ``mirror`` job ``job``: the mirror image of ``source``,
    the branch of the job before it (`elastica_auto.branches.mirror.image_of`), computed
    (`compute_branch`) where the image is not used. A Ctrl-C while the image is checked
    (the module is called there) ends it as one at the branch's first step does."""
    t0 = time.perf_counter()
    try:
        with Interruptions(raising=True):
            # the image of the source's points: its scheme, as chosen for the source
            blank = new_branch(plan, job)
            blank.options = {**blank.options, "ncol": source.options.get("ncol")}
            br = image_of(plan.problem, source, blank, plan.course)
    except KeyboardInterrupt:
        return compute_branch(plan, k, job, progress, lambda: True)
    finally:
        source.mirror_points = []
    if br is None:
        return compute_branch(plan, k, job, progress, should_stop)
    br.worker = f"mirror of {source.worker}"
    br.seconds = time.perf_counter() - t0
    return br


#: The message of a branch that a run's cluster never computed: it had no worker for the
#: run's ``worker_timeout`` (`elastica_auto.execution.cluster`). Such branches end the file
#: that run leaves, and ``--resume`` computes them (as it does the interrupted ones).
NOT_COMPUTED = "not computed: the cluster had no worker (--resume computes it)"


@dataclass(frozen=True)
class TaskFailure:
    """Why a task of a cluster brought no result. ``lost``: its workers died, or the cluster
    ended (the task itself may be sound: it is computed again, quietly); else the task
    raised ``exception`` (the type's name) with the message ``error`` on a worker,
    ``traceback`` its frames there ("file:line in function", innermost last)."""

    exception: str
    error: str
    lost: bool = False
    traceback: tuple[str, ...] = ()

    def __str__(self) -> str:
        """One line: the exception, and the frame it was raised in."""
        where = f" ({self.traceback[-1]})" if self.traceback else ""
        return f"{self.exception}: {self.error}{where}"


def failed_branch(plan: Plan, job: Job, failure: TaskFailure) -> Branch:
    """The branch of ``job`` whose task failed (``failure``): its start, labelled MX, and
    why in its message and diagnostics, as a branch whose module raised in this process
    has them (`elastica_auto.branches.stepper`)."""
    br = new_branch(plan, job)
    br.end = labels.MX
    br.message = (f"not computed: {failure}" if failure.lost
                  else f"raised on a worker: {failure}")
    br.diagnostics = {"exception": failure.exception, "error": failure.error,
                      "traceback": list(failure.traceback)}
    if failure.traceback:
        br.diagnostics["where"] = failure.traceback[-1]
    br.points.append(start_point(br, job.origin))
    return br


def usable_cores() -> int:
    """The cores this process may run on: its CPU affinity (a batch job's share of a node,
    ``taskset``), which ``os.cpu_count()`` (the machine's) ignores; the machine's where
    there is no affinity to read (not on Linux)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def new_branch(plan: Plan, job: Job) -> Branch:
    """An empty branch of ``plan`` for ``job``: its attributes, no points yet."""
    spec = job.spec
    return Branch.of(plan.problem, plan.parameter, spec.direction, str(spec.start),
                     plan.options.to_dict(), singular_start=job.origin.kind != "regular",
                     cell=cell(spec))


def cell(spec: BranchSpec) -> str:
    """The cell of the plan a branch computes, as stored with it (``--resume`` skips the
    cells already in the file): its start, the parameter values given to it, its direction."""
    return json.dumps({"start": str(spec.start), "direction": spec.direction,
                       "params": {k: spec.params[k] for k in sorted(spec.params)}})
