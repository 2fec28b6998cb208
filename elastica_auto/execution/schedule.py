"""The order in which a run's branches are taken: one schedule for every way of computing them.

A plan's jobs may be computed in this process one after the other (`run.in_process`), as
tasks of a Dask cluster (`cluster.run_on_cluster`), or both at once (the default run's
`run.Alongside`):
their branches finish in any order. The file is the same whichever computed them because they
are *taken* in the plan's order, here: job ``i``'s turn comes once every job before it is
taken, and at its turn

1. it is left out if ``skip(i, branches)`` says so (`run.switch_levels`: a branch point
   that a closed loop switched before it already reaches), whether computed or not; the
   decision reads only the branches before it, which no longer change;
2. else its branch is appended to ``branches``: the one finished elsewhere, or one made
   here, the mirror image of the branch before it for a ``mirror`` job (`jobs.mark_mirrors`),
   or, for the in-process run, computed here;
3. the file is saved (``save()``) and the branch reported (``on_branch(number, branch)``;
   not an interrupted one).

A branch made here that is interrupted (Ctrl-C) is appended and saved as it stands (up to its
last point), where this process computes branches (in process, alongside a cluster); the
schedule then makes nothing more, and takes only the branches finished already. A run on a
cluster keeps only finished branches: there the interrupted one is dropped, as the
branches in progress on its workers are.
"""

from __future__ import annotations

from typing import Callable

from ..branches.branch import Branch
from .jobs import Job, Progress, compute_branch, mirrored_branch
from .plan import Plan


class Schedule:
    """The jobs ``jobs`` of ``plan`` taken in order into ``branches`` (module docstring).
    ``progress`` reports a branch made here; ``skip(i, branches)``, ``save()`` and
    ``on_branch(number, branch)`` as the module docstring says. `take` is called with the
    branches finished so far, whenever one finishes; `rest` once the run stops early."""

    def __init__(self, plan: Plan, jobs: list[Job], branches: list[Branch],
                 save: Callable[[], None],
                 on_branch: Callable[[int, Branch], None] | None = None,
                 skip: Callable[[int, list[Branch]], bool] | None = None,
                 progress: Progress | None = None):
        self.plan, self.jobs, self.branches, self.save = plan, jobs, branches, save
        self.on_branch, self.skip, self.progress = on_branch, skip, progress
        #: the number of the branch a job hands out ahead of its turn: its place in the plan
        #: after the branches there before (those left out before it are not yet known)
        self.offset = len(branches)
        #: the jobs taken (appended or left out), in order: the next job's turn
        self.taken = 0
        self._decided: dict[int, bool] = {}
        self._made: dict[int, Branch] = {}     # the jobs' branches, for their mirror images

    def number(self, i: int) -> int:
        """The branch number job ``i`` is computed under when it is handed out ahead of its
        turn (a worker's task, this process's next branch): the plan's order after the
        branches before; a branch made at its turn gets its number in the file instead."""
        return self.offset + i + 1

    @property
    def finished(self) -> bool:
        """Every job taken."""
        return self.taken >= len(self.jobs)

    def skipped(self, i: int) -> bool:
        """Whether job ``i`` is left out: ``skip(i, branches)``, asked once, at its turn or
        later (the branches it reads do not change after that)."""
        if i not in self._decided:
            self._decided[i] = self.skip is not None and self.skip(i, self.branches)
        return self._decided[i]

    def take(self, done: dict[int, Branch], here: bool = False,
             stop: Callable[[], bool] | None = None, limit: int | None = None,
             on_skip: Callable[[int], None] | None = None,
             on_taken: Callable[[Branch], None] | None = None,
             keep_interrupted: bool = True) -> bool:
        """Take every job whose turn has come and whose branch is at hand, in order: left
        out (``on_skip(i)``, its branch in ``done`` dropped), or appended from ``done``, or
        made here (a mirror image; with ``here``, any job, computed), saved, reported, and
        passed to ``on_taken``. At most ``limit`` branches are appended. ``stop()`` ends a
        branch made here early (Ctrl-C). True if a branch made here was interrupted: it is
        appended (not with ``keep_interrupted`` false: then taking ends there), and after it
        only branches already in ``done`` are."""
        interrupted, appended = False, 0
        while not self.finished and (limit is None or appended < limit):
            i = self.taken
            if self.skipped(i):
                if on_skip is not None:
                    on_skip(i)
                done.pop(i, None)
            elif i in done or (not interrupted and (here or self.jobs[i].mirror)):
                br = done.pop(i, None)
                if br is None:
                    br = self._make(i, stop)
                    interrupted = interrupted or br.interrupted
                    if br.interrupted and not keep_interrupted:
                        break
                self._made[i] = br
                self.branches.append(br)
                self.save()
                if self.on_branch is not None and not br.interrupted:
                    self.on_branch(len(self.branches), br)
                if on_taken is not None:
                    on_taken(br)
                appended += 1
            else:
                break
            self.taken += 1
        return interrupted

    def _make(self, i: int, stop: Callable[[], bool] | None) -> Branch:
        """Job ``i``'s branch made here at its turn, numbered as it will be in the file: the
        mirror image of the branch before it (`jobs.mirrored_branch`), or computed."""
        job, k = self.jobs[i], len(self.branches) + 1
        source = self._made.get(i - 1) if job.mirror else None
        if source is not None:
            return mirrored_branch(self.plan, k, job, source, self.progress, stop)
        return compute_branch(self.plan, k, job, self.progress, stop)

    def rest(self, done: dict[int, Branch], missing: list[Branch] = ()) -> None:
        """The run stops early: the branches finished beyond a gap in the plan's order
        (``done``) are appended as they stand, in order, then ``missing`` (the branches of
        jobs not done, recorded as such: at the end, where ``--resume`` finds them), and
        saved; ``done`` is emptied."""
        if done or missing:
            self.branches.extend(done[i] for i in sorted(done))
            self.branches.extend(missing)
            done.clear()
            self.save()
