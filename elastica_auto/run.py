"""Execute a plan: build each start, continue each branch, number labels, write the file.

The branch file is rewritten (atomically) after every branch, so an interrupted or failing run
leaves every completed branch on disk; the branch in progress is kept up to its last point
and ends with an MX label.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from . import store
from .branch import Branch
from .corrector import State, solve_fixed
from .runfile import BranchSpec, Plan, RunFileError
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


def execute(plan: Plan, out_dir: Path,
            progress: Callable[[int, Branch, float], None] | None = None,
            on_branch: Callable[[int, Branch], None] | None = None) -> RunResult:
    """Run every branch of ``plan`` and write ``out_dir/<run>.h5`` after each one."""
    out = Path(out_dir) / plan.output_name
    branches: list[Branch] = []
    t_run = time.perf_counter()

    writer = store.Writer(out, plan.name, plan.problem, plan.text)

    def save():
        number_labels(branches)
        writer.save(branches)

    for k, spec in enumerate(plan.branches, start=1):
        state, tangent = build_start(plan, spec)
        br = Branch(plan.problem, plan.parameter, spec.direction, str(spec.start),
                    plan.options.to_dict())
        branches.append(br)
        t0 = time.perf_counter()
        try:
            continue_branch(br, state, plan.options, plan.stops, plan.user_values, tangent,
                            None if progress is None else
                            (lambda b, lam, k=k: progress(k, b, lam)))
        except KeyboardInterrupt:
            br.seconds = time.perf_counter() - t0
            br.end, br.message = "MX", "interrupted by the user"
            if br.points and not br.points[-1].type and br.last is not None:
                br.relabel(br.points[-1], "MX", *br.last)
            save()
            return RunResult(out, branches, time.perf_counter() - t_run, interrupted=True)
        br.seconds = time.perf_counter() - t0
        save()
        if on_branch is not None:
            on_branch(k, br)
    return RunResult(out, branches, time.perf_counter() - t_run)


__all__ = ["execute", "build_start", "RunResult", "StartError", "RunFileError"]
