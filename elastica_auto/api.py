"""The Python API: continue a problem's solutions, restart from labels, save branch files.

    import elastica_auto as ea

    problem = ea.load_problem("elastica_lever_arm")
    branches = ea.continuation(problem, {"eps": 0.5, "P": 9 * math.pi**2 / 4}, "psi",
                               bounds=(-2 * math.pi, 2 * math.pi), directions="both",
                               ds_max=0.3)
    branches[0].columns["psi"], branches[0].columns["index"]
    again = ea.continuation(problem, branches.label("LP1"), "eps", bounds=(0, 1))
    ea.save(branches, "out/mine.h5")

A run file is the same call written in TOML (:mod:`execution.runfile`); both go through
:func:`elastica_auto.execution.plan.make_plan` and give the same branches.
"""

from __future__ import annotations

import dataclasses
import json
import numbers
import time
from pathlib import Path
from typing import Iterable, Mapping

from .storage import store
from .branches.branch import Branch
from .core import labels
from .core.errors import CallbackError, ClusterLost, PlanError, StoreError
from .core.options import ContinuationOptions
from .core.values import real_number
from .execution.plan import Request, StartLike, make_plan
from .model.problem import Problem
from .execution.jobs import Callbacks, Progress
from .execution.run import RunResult, Workers, compute, number_labels, start_job
from .storage.store import StoredLabel


class Branches(list):
    """The branches of one :func:`continuation`, in order: a list of
    :class:`~elastica_auto.branches.branch.Branch`, with labels numbered through all of them as in a
    branch file (LP1, LP2, ... in branch and point order).

    Attributes
    ----------
    problem : Problem
        The problem continued (with its free parameters, if any).
    snaps : list of dict
        Snap-back targets (as ``elastica-auto snaps`` lists them), if the module has the
        ``shooting`` and ``second_variation`` hooks.
    warnings : list of str
        Branch points where switching failed, a failed snap-back scan.
    maps : list of StabilityMap
        With ``map=True``: the stability map of each plane of the fold curves
        (`elastica_auto.analysis.maps`).
    landings : list of dict
        With ``damping``: where the damped model lands, a row per fold and damping value
        (`elastica_auto.analysis.landing.damping_sweep`).
    missing : list of dict
        What the analysis after the branches could not make (the snap-back scan, landings or
        maps failed), one record each: ``what``, ``message``, ``kind`` ("module",
        "numerical", "engine": an internal error, with its traceback in ``text``); empty if
        nothing is missing. The command line's exit status 3 (docs/cli.md).
    seconds : float
        Wall-clock time of the whole computation.
    """

    def __init__(self, branches: Iterable[Branch] = (), problem: Problem | None = None,
                 snaps: Iterable[dict] = (), warnings: Iterable[str] = (), seconds: float = 0.0,
                 maps: Iterable = (), landings: Iterable[dict] = (),
                 missing: Iterable[dict] = ()):
        super().__init__(branches)
        self.problem = problem
        self.snaps, self.warnings, self.seconds = list(snaps), list(warnings), seconds
        self.maps, self.landings, self.missing = list(maps), list(landings), list(missing)

    def __add__(self, other: Iterable[Branch]) -> Branches | list:
        """Branches of one problem put together (``arm + load``): still of that problem."""
        if isinstance(other, Branches) and other.problem is self.problem:
            return Branches([*self, *other], self.problem)
        return list(self) + list(other)

    def label(self, name: str) -> StoredLabel:
        """The solution labelled ``name`` (``"LP1"``), to restart from or switch at."""
        for br in self:
            if any(p.name == name and p.type for p in br.points):
                return br.label(name)
        names = sorted((p.name for br in self for p in br.points if p.type),
                       key=labels.label_order)
        raise KeyError(f"no label {name!r}; labels: {labels.compact(names) or 'none'}")


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`continuation`. ``branches`` holds what was computed: every
    finished branch, and the ones in progress up to their last point (ending MX)."""

    def __init__(self, branches: Branches):
        super().__init__("continuation interrupted")
        self.branches = branches


def _as_callback(progress: Progress | None) -> Progress | None:
    """``progress`` calling through: what it raises is the caller's (`CallbackError`, the
    branch's diagnostics of kind "caller" naming its line), not an internal error."""
    if progress is None:
        return None

    def call(branch, points, folds, value):
        try:
            progress(branch, points, folds, value)
        except Exception as exc:
            raise CallbackError("progress") from exc
    return call


def continuation(problem: Problem, start: StartLike | Iterable[StartLike], parameter: str, *,
                 params: Mapping[str, float | Iterable[float]] | None = None,
                 bounds: tuple[float, float] | None = None, directions: str = "+",
                 uz: Iterable[float] = (), uz_period: float | None = None,
                 stop: Iterable[str] = (), events: Iterable[str] = (), switch: int = 0,
                 switch_depth: int = 1,
                 free: Iterable[str] | None = None,
                 map: bool = False, landing: bool = False, damping: Iterable[float] = (),
                 damping_folds: Iterable[str] | None = None, jobs: int = 1,
                 scheduler: str | None = None, worker_timeout: float | None = None,
                 progress: Progress | None = None, **options) -> Branches:
    """Continue solutions of ``problem`` in ``parameter`` by pseudo-arclength.

    Parameters
    ----------
    problem : Problem
        From :func:`load_problem`.
    start : dict, StoredLabel, Switch, or a list of them
        A dict of parameter values starts from the module's exact solution there (the
        others at their defaults); a label (``BranchFile(path).label("UZ3")`` or
        ``branches.label("LP1")``) restarts from its solution; ``Switch(label)`` follows the
        other branch through a branch point, both ways.
    parameter : str
        The continued parameter.
    params : dict, optional
        Parameter values applied to every start; a list of values gives one set of branches
        per value (restarting from a label at other values first solves there).
    bounds : (lower, upper), optional
        A branch ends (EP) where the parameter leaves them.
    directions : {"+", "-", "both"}
        The direction(s) of travel from each start.
    uz, uz_period : optional
        Values of the parameter to label UZ; with a period, every value + k * period.
    stop : list of str, optional
        ``["LP4"]`` ends each branch at its 4th fold; ``["u_max > 100"]`` where an ordinate
        (or a free parameter) passes a value (EP, located exactly).
    events : list of str, optional
        Points to label without ending the branch: ``"NAME = VALUE"`` a UZ point wherever
        the ordinate, free parameter or continued parameter NAME takes VALUE (AUTO-07p's
        UZR); ``"extremum NAME"`` an XT point wherever the ordinate or free parameter NAME
        has a maximum or minimum along the branch. Located to the corrector's tolerance;
        the note says which (``m0 = 0 (rising)``, ``maximum of m1``).
    switch : int
        Also follow the other branch, both ways, at the first ``switch`` branch points of
        each branch (AUTO-07p's ISW=-1). A closed loop is followed once: a branch point it
        passes through (its own start included) is not switched at again.
    switch_depth : int
        Levels of switching (default 1): 2 also switches at the first ``switch`` branch
        points of the switched branches, and so on; a branch point met again (the same
        point on a branch already computed) is not switched at twice.
    free : list of str, optional
        The parameters solved for where the module has more conditions than states (extra
        boundary conditions, integral conditions); default: the module's ``FREE``.
    map : bool
        With two parameters and LP starts: also the stability map of each plane of the
        fold curves (``branches.maps``; `elastica_auto.analysis.maps`). Only meaningful when the
        starts give every fold curve of the plane.
    landing : bool
        Also where each snap lands: the rod's dynamics from every fold that ends a stable
        branch, to the snap-back target it reaches (``branches.snaps``, column ``landed``;
        `elastica_auto.analysis.landing`). Needs the module's ``gradient_flow`` hook.
    damping : list of float, optional
        With ``landing``: also where the damped model ``u_tt + c u_t = -grad E`` lands, for
        each ``c``, from each fold ending a stable branch (``branches.landings``, a row per
        fold and ``c``). Each costs 2-10 s on the elastica.
    damping_folds : list of str, optional
        The folds (``["LP6"]``) the damped model starts from; default every fold ending a
        stable branch.
    jobs : int
        Branches computed at once, as tasks of a local Dask cluster of ``jobs`` worker
        processes (1: in this process; a script needs ``if __name__ == "__main__":``).
    scheduler : str, optional
        The address of a Dask scheduler (``tcp://host:port``): the branches are computed as
        tasks of its cluster instead (`elastica_auto.execution.cluster`); ``jobs`` is then unused.
    worker_timeout : float, optional
        Seconds the cluster (the scheduler's, or the local one of ``jobs``) may have no worker
        before the continuation ends with ClusterLost (default 60: a worker that dies is
        replaced within seconds; workers that reached a batch system's walltime are not).
    progress : callable, optional
        Called as ``progress(branch, points, folds, value)`` during the continuation; what
        it raises ends that branch (MX, diagnostics of kind "caller"), KeyboardInterrupt
        the run (`Interrupted`).
    **options
        :class:`~elastica_auto.core.options.ContinuationOptions` by name: ``ds``, ``ds_min``,
        ``ds_max``, ``max_points``, ``ntst``, ``tol``, ``corrector``, ...

    Returns
    -------
    Branches
        One :class:`~elastica_auto.branches.branch.Branch` per start, value and direction (starts in
        order, each in each direction), then the switched ones. A branch that failed ends
        with an MX label and says why in ``branch.message``.

    Raises
    ------
    PlanError
        An argument that cannot be used (``exc.key`` names it).
    StartError
        A start that cannot be built (no exact solution there, a changed parameter value
        that the continuation from the label does not reach).
    Interrupted
        Ctrl-C; ``exc.branches`` holds what was computed.
    ClusterError
        A scheduler that cannot be used: a malformed address, unreachable, without workers.
    ClusterLost
        The cluster had no worker for ``worker_timeout`` seconds; ``exc.branches`` holds
        every branch, those not computed ending MX with the message "not computed: ...".
    """
    if isinstance(jobs, bool) or not isinstance(jobs, numbers.Integral) or jobs < 1:
        raise PlanError("jobs", f"expected a positive integer, got {jobs!r}")
    jobs = int(jobs)
    if worker_timeout is not None and (not real_number(worker_timeout)
                                       or not 0 < worker_timeout < float("inf")):
        raise PlanError("worker_timeout", f"expected a positive number of seconds, got "
                                          f"{worker_timeout!r}")
    if progress is not None and not callable(progress):
        # refused here: called at the first step, it would end the branch MX as an internal
        # error (a bug of the engine) rather than the argument's
        raise PlanError("progress", f"expected a function progress(branch, points, folds, "
                                    f"value), got {progress!r}")
    request = Request(params=params, bounds=bounds, directions=directions, uz=uz,
                      uz_period=uz_period, stop=stop, events=events, switch=switch,
                      switch_depth=switch_depth, free=free, map=map,
                      landing=landing, damping=damping, damping_folds=damping_folds)
    plan = make_plan(problem, start, parameter, request, options)
    t0 = time.perf_counter()
    try:
        first = [start_job(plan, spec) for spec in plan.branches]
    except KeyboardInterrupt:  # while a start was built (a restart's continuation, say)
        raise Interrupted(Branches([], plan.problem, [], [], time.perf_counter() - t0, [],
                                   [])) from None
    result = RunResult(None, [], 0.0)
    lost = None
    try:
        # labels numbered as each branch is done (as a saved run's): a switched branch's
        # start names its BP
        compute(plan, first, result, lambda: number_labels(result.branches),
                Callbacks(progress=_as_callback(progress)),
                Workers(jobs, scheduler, worker_timeout=worker_timeout))
    except KeyboardInterrupt:  # between branches: the finished ones are kept
        result.interrupted = True
    except ClusterLost as exc:  # the finished branches, and those not computed (MX)
        lost = exc
    number_labels(result.branches)
    out = Branches(result.branches, plan.problem, result.snaps, result.warnings,
                   time.perf_counter() - t0, result.maps, result.landings, result.missing)
    if result.interrupted:
        raise Interrupted(out)
    if lost is not None:
        lost.branches = out
        raise lost
    return out


def save(branches: Iterable[Branch], path: str | Path, *, problem: Problem | None = None,
         run: str | None = None) -> Path:
    """Write ``branches`` to the branch file ``path`` (HDF5, as ``elastica-auto run``
    writes; read it back with :class:`~elastica_auto.storage.store.BranchFile`).

    The file is written to a temporary name and renamed over ``path``. Labels are numbered
    through the file in branch and point order (the branches keep their own numbering).
    ``problem``: the branches' (default: that of the :func:`continuation` they came from; a
    list put together from several needs it). ``run`` names the run in the file (default:
    the file's stem). Snap-back targets, damped landings, stability maps and what the
    analysis could not make (``missing``) are saved if ``branches`` is one continuation's.
    """
    if isinstance(branches, Branch):
        raise PlanError("branches", "expected a list of branches, got one Branch: save the "
                        "continuation's result whole, or [branch] with problem=")
    if not isinstance(branches, Iterable) or isinstance(branches, (str, bytes)):
        raise PlanError("branches", f"expected a non-empty list of branches, got "
                        f"{type(branches).__name__}")
    given, branches = branches, list(branches)
    if not branches or not all(isinstance(b, Branch) for b in branches):
        raise PlanError("branches", "expected a non-empty list of branches")
    problem = problem if problem is not None else getattr(given, "problem", None)
    if problem is None:
        raise PlanError("problem", "a list of branches needs problem= (the problem they "
                        "were computed for)")
    names = (tuple(problem.parameter_names), tuple(problem.ordinate_names))
    if any(b.equation != problem.source or (b.parameter_names, b.ordinate_names) != names
           for b in branches):
        raise PlanError("branches", f"all branches of a file must be of {problem.source}")
    path = Path(path)
    if path.suffix != ".h5":
        raise StoreError(f"{path}: a branch file is named <name>.h5")
    copies = [dataclasses.replace(b, points=[dataclasses.replace(p) for p in b.points])
              for b in branches]
    number_labels(copies)
    whole = isinstance(given, Branches)                  # a whole continuation's
    snaps, maps, landings = ((given.snaps, given.maps, given.landings) if whole
                             else (None, None, None))
    writer = store.Writer(path, run or path.stem, problem)
    if whole:
        writer.extra["missing"] = json.dumps(given.missing)
    with writer:
        writer.save(copies, snaps, maps, landings)
        writer.finish()
    return writer.path


def snaps_along(base: Problem, a: dict, b: dict, **options):
    """The snaps on the segment from ``a`` to ``b`` (parameter values; the others at the
    module's defaults), in order of t, and the branches followed: ``(snaps, branches)``
    (`elastica_auto.analysis.path`: every equilibrium at ``a`` continued in the path's
    parameter ``t`` over [0, 1], then each fold where a stable stretch ends as t increases,
    with the stable equilibria there). ``options`` are :func:`continuation`'s (``ds_max``,
    ...)."""
    from .analysis.path import PATH, path_snaps, path_starts
    problem, starts = path_starts(base, a, b)
    branches = continuation(problem, starts, PATH, bounds=(0.0, 1.0), directions="+",
                            **options)
    return path_snaps(problem, branches), branches


__all__ = ["continuation", "save", "snaps_along", "Branches", "Interrupted",
           "ContinuationOptions"]
