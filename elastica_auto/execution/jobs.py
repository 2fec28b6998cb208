"""One branch of a plan as a job: where it starts, and computing it.

What the run in this process (`run`) and the cluster's tasks (`cluster`) share: a worker
computes a branch with `compute_branch`, and a task that failed becomes an empty branch of
the plan (`new_branch`) ending MX.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from typing import Callable

from ..branches import codim2
from ..branches.branch import Branch
from ..branches.stepper import Origin, continue_branch
from ..core.interrupts import Interruptions
from ..numerics.stability import label_stability
from .plan import BranchSpec, Plan


@dataclass
class Job:
    """One branch to compute: its spec and where it starts."""

    spec: BranchSpec
    origin: Origin


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
                   should_stop: Callable[[], bool] | None = None) -> Branch:
    """Continue branch number ``k`` of the file from ``job``'s start, then label its
    stability. Ctrl-C (or ``should_stop()`` turning true) or a failure ends the branch early
    with MX, keeping every point computed so far (`elastica_auto.branches.stepper.continue_branch`):
    one failing branch does not cost the run its other branches. A Ctrl-C once the
    continuation is over waits for the labelling, and sets ``interrupted`` on the branch,
    which is kept whole."""
    br = new_branch(plan, job)

    def on_step(b, lam):
        if should_stop is not None and should_stop():
            raise KeyboardInterrupt
        if progress is not None:
            progress(k, len(b.points), len(b.folds), lam)

    t0 = time.perf_counter()
    # raised after the continuation, a signal would throw the computed branch away: one
    # context raises during the continuation (which ends the branch at its last point) and
    # only records after it
    with Interruptions(raising=True) as late:
        try:
            continue_branch(br, plan.problem, plan.course, job.origin, on_step)
        except KeyboardInterrupt:  # after the continuation's own handling: the branch is whole
            pass
        late.raising = False
        if plan.curve == "fold":
            codim2.label_fold_curve(br, plan.problem, plan.base)
        label_stability(br, plan.problem)
        if plan.problem.has_second_variation and plan.curve is None and not br.interrupted:
            from ..analysis.snaps import mark_subcritical
            mark_subcritical(plan.problem, br)
    br.interrupted = br.interrupted or late.stop.is_set()
    br.seconds = time.perf_counter() - t0
    return br


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
