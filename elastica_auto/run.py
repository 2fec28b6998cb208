"""Execute a plan: build each start, continue each branch, number labels, write the file.

The branch file is rewritten (atomically) after every branch, so an interrupted or failing run
leaves every completed branch on disk; the branch in progress is kept up to its last point
and ends with an MX label.
"""

from __future__ import annotations

import multiprocessing as mp
import signal
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from . import store
from .branch import Branch
from .corrector import State, solve_fixed
from .runfile import BranchSpec, Plan, RunFileError
from .stability import label_stability
from .stepper import continue_branch


class StartError(RuntimeError):
    """A start point that cannot be built (no exact solution, corrector failure)."""


@dataclass
class RunResult:
    path: Path
    branches: list[Branch]
    seconds: float
    interrupted: bool = False

    @property
    def failed(self) -> list[int]:
        return [k for k, b in enumerate(self.branches, 1) if b.end == "MX"]


def build_start(plan: Plan, spec: BranchSpec):
    """The start State for a branch and, on a restart, the stored tangent (or None)."""
    problem, opt = plan.problem, plan.options
    if spec.start.kind == "trivial":
        params = {**problem.defaults(), **spec.params}
        s = np.linspace(0.0, 1.0, opt.ntst + 1)
        y = problem.exact_start(s, params)
        if y is None:
            fixed = ", ".join(f"{k}={v:g}" for k, v in params.items())
            raise StartError(f"{problem.source} has no exact start at {fixed}; "
                             "start from a label (start = \"FILE.h5:LABEL\")")
        return State.from_values(problem, s, y, params), None
    stored = store.BranchFile(spec.start.file).label(spec.start.label)
    state, tangent = stored.state, stored.tangent
    if stored.tangent_parameter != plan.parameter:
        tangent = None
    params = {**state.params, **spec.params}
    if params != state.params:
        res = solve_fixed(problem, state, params, opt.tol, opt.max_nodes)
        if not res.success:
            raise StartError(f"{spec.start}: no solution at the changed parameters "
                             f"({res.message})")
        state, tangent = res.state, None
    return state, tangent


def number_labels(branches: list[Branch]):
    """Number labels per type through the file in branch and point order (LP1, LP2, ...)."""
    counters = {}
    for br in branches:
        for p in br.points:
            if p.type:
                counters[p.type] = counters.get(p.type, 0) + 1
                p.label = counters[p.type]


#: Progress callback: (branch number, points so far, folds so far, current parameter value).
Progress = Callable[[int, int, int, float], None]


def compute_branch(plan: Plan, k: int, start, progress: Progress | None = None,
                   should_stop: Callable[[], bool] | None = None) -> Branch:
    """Continue branch ``k`` (1-based) of ``plan`` from ``start = (state, tangent)``.

    Ctrl-C (or ``should_stop()`` turning true) ends the branch early: it keeps every point
    computed so far, its last point is labelled MX and ``branch.interrupted`` is set.
    """
    spec = plan.branches[k - 1]
    br = Branch(plan.problem, plan.parameter, spec.direction, str(spec.start),
                plan.options.to_dict())

    def on_step(b, lam):
        if should_stop is not None and should_stop():
            raise KeyboardInterrupt
        if progress is not None:
            progress(k, len(b.points), len(b.folds), lam)

    t0 = time.perf_counter()
    try:
        continue_branch(br, start[0], plan.options, plan.stops, plan.user_values, start[1],
                        on_step)
    except KeyboardInterrupt:
        br.end, br.message, br.interrupted = "MX", "interrupted by the user", True
        if br.points and not br.points[-1].type and br.last is not None:
            br.relabel(br.points[-1], "MX", *br.last)
    label_stability(br)
    br.seconds = time.perf_counter() - t0
    return br


def execute(plan: Plan, out_dir: Path, progress: Progress | None = None,
            on_branch: Callable[[int, Branch], None] | None = None, jobs: int = 1) -> RunResult:
    """Run every branch of ``plan``, ``jobs`` at a time, writing ``out_dir/<run>.h5``.

    Every start is built (and so validated) before any branch is computed. The file is
    rewritten after each branch completes, in plan order, so labels are numbered the same way
    whatever ``jobs`` is. An interrupted run saves every branch computed so far, the ones in
    progress up to their last point.
    """
    out = Path(out_dir) / plan.output_name
    t_run = time.perf_counter()
    starts = [build_start(plan, spec) for spec in plan.branches]
    writer = store.Writer(out, plan.name, plan.problem, plan.text)
    branches: list[Branch] = []

    def save():
        number_labels(branches)
        writer.save(branches)

    jobs = max(1, min(jobs, len(plan.branches)))
    if jobs == 1 or "fork" not in mp.get_all_start_methods():
        for k in range(1, len(plan.branches) + 1):
            br = compute_branch(plan, k, starts[k - 1], progress)
            branches.append(br)
            save()
            if br.interrupted:
                return RunResult(out, branches, time.perf_counter() - t_run, interrupted=True)
            if on_branch is not None:
                on_branch(k, br)
        return RunResult(out, branches, time.perf_counter() - t_run)
    return _execute_parallel(plan, starts, jobs, branches, save, progress, on_branch, out,
                             t_run)


_WORKER: dict = {}


def _init_worker(plan, starts, queue, stop):
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    _WORKER.update(plan=plan, starts=starts, queue=queue, stop=stop)


def _worker_branch(k: int) -> Branch:
    plan, queue, stop = _WORKER["plan"], _WORKER["queue"], _WORKER["stop"]
    last = [0.0]

    def progress(k, npts, nfolds, lam):
        now = time.perf_counter()
        if now - last[0] > 0.2:
            last[0] = now
            queue.put((k, npts, nfolds, lam))

    br = compute_branch(plan, k, _WORKER["starts"][k - 1], progress, stop.is_set)
    br.problem = None  # modules do not pickle; the parent puts its own back
    br.last = None
    return br


def _execute_parallel(plan, starts, jobs, branches, save, progress, on_branch, out, t_run):
    """Branches in worker processes (fork); results are saved in plan order as they arrive."""
    ctx = mp.get_context("fork")
    queue, stop = ctx.Queue(), ctx.Event()
    done: dict[int, Branch] = {}
    interrupted = False
    with ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_init_worker,
                             initargs=(plan, starts, queue, stop)) as pool:
        futures = {pool.submit(_worker_branch, k): k for k in range(1, len(plan.branches) + 1)}
        pending = set(futures)
        while pending:
            try:
                finished, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                while not queue.empty():
                    msg = queue.get_nowait()
                    if progress is not None:
                        progress(*msg)
            except KeyboardInterrupt:
                interrupted = True
                stop.set()
                for f in pending:
                    f.cancel()
                finished, pending = wait(pending)
            for f in finished:
                if f.cancelled():
                    continue
                br = f.result()
                br.problem = plan.problem
                done[futures[f]] = br
            while len(branches) + 1 in done:
                k = len(branches) + 1
                branches.append(done.pop(k))
                save()
                if on_branch is not None and not branches[-1].interrupted:
                    on_branch(k, branches[-1])
    if done:  # after an interruption: branches that finished beyond a gap
        branches.extend(done[k] for k in sorted(done))
        save()
    interrupted = interrupted or any(b.interrupted for b in branches)
    return RunResult(out, branches, time.perf_counter() - t_run, interrupted=interrupted)


__all__ = ["execute", "compute_branch", "build_start", "RunResult", "StartError",
           "RunFileError"]
