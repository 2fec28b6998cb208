"""What to compute: the validated arguments of one continuation, as a plan of branches.

:func:`make_plan` is the single place where the arguments of
:func:`elastica_auto.continuation` are checked, for calls from Python and for run files
alike (:mod:`elastica_auto.execution.runfile` parses TOML into these arguments). It raises
:class:`PlanError`, whose ``key`` names the argument at fault, so that each front end can
report it in its own terms (a keyword, or a run-file key).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Iterable, Mapping, Union

import numpy as np

from ..branches import restart
from ..core import labels
from ..core.errors import PlanError, ProblemError, StartError
from ..branches.events import UserValues, is_user_value
from ..branches.kinds import Event, Limit
from ..branches.registry import parse_events
from ..core.expressions import evaluate
from ..core.options import ContinuationOptions, OptionsError
from ..core.values import real_number
from ..model.interface import ProblemInterface
from ..model.problem import Problem
from ..branches.stepper import Course, Stops
from ..core.solution import State
from ..storage.store import StoredLabel

#: ``directions``: the signs of the steps from each start.
DIRECTIONS = {"both": (1, -1), "+": (1,), "-": (-1,), "forward": (1,), "backward": (-1,)}

#: The most branches a plan may have (the cells of ``params`` times the starts times the
#: directions), and so the most values of one range in a run file. Each branch is a task, a
#: group of its file (tens of kilobytes at the least) and a second or more of computing: 1e5
#: is a day on a few cores and gigabytes of file, far beyond the shipped runs (tens), and
#: well below what a typo makes (a range of 1e9 values, or two of 1e4, took all memory
#: building the plan's list). Checked before anything is listed.
MAX_BRANCHES = 100_000

#: The most user points one branch may meet: ``uz``'s values, each every ``uz_period``,
#: over the span of ``bounds`` (or, without bounds, ``max_points * ds_max``, as far as the
#: parameter can move in a branch: a step moves it by at most about ``ds_max``). Each is a
#: labelled point whose solution is kept (about 11 kB for the elastica on its usual meshes):
#: 1e5 of them are a gigabyte of memory and of file; ``uz_period = 1e-300`` listed the
#: crossings of a single step until memory ran out.
MAX_USER_POINTS = 100_000


@dataclass(frozen=True)
class Switch:
    """Start on the other branch through a branch point (AUTO-07p's ``ISW=-1``).

    ``label`` is a BP label, from a branch file (``BranchFile(path).label("BP1")``) or from
    branches in memory (``branches.label("BP1")``)."""

    label: StoredLabel


#: What a branch can start from: the module's exact solution at these parameter values, a
#: labelled solution, or the other branch at a labelled branch point.
StartLike = Union[Mapping[str, float], StoredLabel, Switch]


@dataclass(frozen=True)
class Start:
    """Where a branch starts: the module's exact solution (``trivial``), a labelled solution
    (``label``), the other branch at a branch point (``switch``), or the fold or branch-point
    curve through a labelled LP or BP of the module's problem (``fold``, ``bp``; ``pitchfork``
    for a BP that is not on the module's exact family)."""

    kind: str
    file: Path | None = None
    label: str = ""
    stored: StoredLabel | None = field(default=None, compare=False, repr=False)

    def __str__(self):
        if self.kind == "trivial":
            return "trivial"
        where = f"{self.file.name}:{self.label}" if self.file is not None else self.label
        return f"switch at {where}" if self.kind == "switch" else where


@dataclass(frozen=True)
class BranchSpec:
    """One branch to compute: start, parameter values, direction."""

    start: Start
    params: dict
    direction: int


@dataclass
class Plan:
    """A validated continuation: the problem, the branches and what applies to all of them.

    ``name``, ``path`` and ``text`` describe the run file, if there is one (they are stored
    in the branch file); a plan made from Python has the name ``continuation``. ``curve`` is
    ``"fold"`` or ``"bp"`` for a two-parameter continuation (`elastica_auto.branches.codim2`): the
    problem is then the fold or branch-point system, ``base`` the module's own problem;
    ``"pitchfork"`` from a BP off the exact family (`elastica_auto.branches.pitchfork`), whose
    :class:`~elastica_auto.branches.pitchfork.Reference` is ``reference``."""

    problem: Problem
    parameter: str
    options: ContinuationOptions
    stops: Stops
    user_values: list[UserValues]
    branches: list[BranchSpec] = field(default_factory=list)
    #: the events the run asks for (``events``), and the entries as written
    watch: tuple[Event, ...] = ()
    events: tuple[str, ...] = ()
    varying: list[str] = field(default_factory=list)
    switch_count: int = 0
    switch_depth: int = 1
    maps: bool = False
    landing: bool = False
    damping: tuple[float, ...] = ()
    damping_folds: tuple[str, ...] | None = None
    curve: str | None = None
    name: str = "continuation"
    path: Path | None = None
    text: str = ""
    base: Problem | None = None
    reference: object = None
    scheduler: str | None = None
    #: seconds the cluster may have no worker before the run ends (None: the default,
    #: `elastica_auto.execution.cluster.WORKER_TIMEOUT`)
    worker_timeout: float | None = None

    @property
    def output_name(self) -> str:
        return f"{self.name}.h5"

    def settings(self) -> dict:
        """Everything of the plan that decides its branches but the cells (start, parameter
        values, direction): the equation module (its source, and a digest of its text), the
        continued and free parameters, the options, stops, UZ values and what is computed
        after the branches. Stored with the branch file (attribute ``settings``), so that
        ``--resume`` continues the same run only (`elastica_auto.execution.run`)."""
        import hashlib
        module = self.problem
        while getattr(module, "_text", None) is None and getattr(module, "base", None):
            module = module.base
        text = getattr(module, "_text", None)
        return {"equation": self.problem.source,
                "module_sha256": (hashlib.sha256(text.encode()).hexdigest()
                                  if text is not None else None),
                "parameter": self.parameter, "curve": self.curve,
                "free": list(getattr(self.problem, "free", ())),
                "options": self.options.to_dict(),
                "bounds": [self.stops.lower, self.stops.upper],
                "stop": {"at_fold": self.stops.at_fold,
                         "limits": [dataclasses.asdict(m) for m in self.stops.limits]},
                "uz": [dataclasses.asdict(u) for u in self.user_values],
                "switch": [self.switch_count, self.switch_depth],
                "maps": self.maps, "landing": self.landing, "damping": list(self.damping),
                "damping_folds": (list(self.damping_folds)
                                  if self.damping_folds is not None else None),
                # only where given: the settings of a run without events are those stored
                # before there were any, so that --resume continues such a file
                **({"events": list(self.events)} if self.events else {})}

    @property
    def course(self) -> Course:
        return Course(self.parameter, self.options, self.stops, tuple(self.user_values),
                      all_folds=self.curve == "fold", watch=self.watch)


@dataclass(frozen=True)
class Request:
    """What one continuation is asked to compute, beyond where it starts and in what: the
    keywords of :func:`elastica_auto.continuation` from ``params`` to ``damping_folds``
    (same names, same meanings), checked on construction.

    What can be checked without the problem is checked here, raising the :class:`PlanError`
    a call with that keyword gets (``key`` names it); the values are kept in one form
    (tuples of floats, ``None`` for "not given"). What needs the problem (parameter names,
    ordinates, hooks) :func:`make_plan` checks. One object is built by each front end
    (``continuation()``, a run file, a benchmark) and passed on whole.
    """

    params: Mapping[str, float | Iterable[float]] | None = None
    bounds: tuple[float, float] | None = None
    directions: str = "+"
    uz: tuple[float, ...] = ()
    uz_period: float | None = None
    stop: tuple[str, ...] = ()
    events: tuple[str, ...] = ()
    switch: int = 0
    switch_depth: int = 1
    free: tuple[str, ...] | None = None
    map: bool = False
    landing: bool = False
    damping: tuple[float, ...] = ()
    damping_folds: tuple[str, ...] | None = None

    def __post_init__(self):
        if not isinstance(self.map, bool):
            raise PlanError("map", f"expected true or false, got {self.map!r}")
        if not isinstance(self.landing, bool):
            raise PlanError("landing", f"expected true or false, got {self.landing!r}")
        damping, folds = _damping(self.damping, self.damping_folds, self.landing)
        free = self.free
        if free is not None:
            if isinstance(free, (str, bytes)) or not isinstance(free, Iterable):
                raise PlanError("free", f"expected a list of parameter names, got {free!r}")
            free = tuple(free)
            if not all(isinstance(q, str) for q in free):
                raise PlanError("free", f"expected a list of parameter names, got {self.free!r}")
        if not isinstance(self.directions, str) or self.directions not in DIRECTIONS:
            raise PlanError("directions", f"expected one of {', '.join(map(repr, DIRECTIONS))}, "
                            f"got {self.directions!r}")
        bounds = None if self.bounds is None else _bounds(self.bounds)
        uz, uz_period = _uz(self.uz, self.uz_period)
        if isinstance(self.switch, bool) or not isinstance(self.switch, int) or self.switch < 0:
            raise PlanError("switch", f"expected a count >= 0 of branch points to switch at, "
                            f"got {self.switch!r}")
        if isinstance(self.switch_depth, bool) or not isinstance(self.switch_depth, int) \
                or self.switch_depth < 1:
            raise PlanError("switch_depth", f"expected a count >= 1 of levels of switching, "
                            f"got {self.switch_depth!r}")
        if self.switch_depth > 1 and not self.switch:
            raise PlanError("switch_depth", "levels of switching need switch = N > 0 (the "
                            "count of branch points to switch at on each branch)")
        if isinstance(self.stop, (str, bytes)) or not isinstance(self.stop, Iterable):
            raise PlanError("stop", f"expected a list such as [\"LP4\"], got {self.stop!r}")
        if isinstance(self.events, (str, bytes)) or not isinstance(self.events, Iterable):
            raise PlanError("events", f"expected a list such as [\"m0 = 0\"], "
                            f"got {self.events!r}")
        for name, value in (("damping", damping), ("damping_folds", folds), ("free", free),
                            ("bounds", bounds), ("uz", uz), ("uz_period", uz_period),
                            ("stop", tuple(self.stop)), ("events", tuple(self.events))):
            object.__setattr__(self, name, value)  # frozen: the checked form, set once

    @property
    def limits(self) -> tuple[float, float]:
        """``bounds``, or no bounds: (-inf, inf)."""
        return self.bounds if self.bounds is not None else (-math.inf, math.inf)

    @property
    def user_values(self) -> list[UserValues]:
        return [UserValues(self.uz, self.uz_period)] if self.uz else []


def make_plan(problem: Problem, start: StartLike | Iterable[StartLike], parameter: str,
              request: Request,
              options: Mapping[str, object] | ContinuationOptions | None = None, *,
              _starts: list | None = None) -> Plan:
    """Check the arguments of :func:`elastica_auto.continuation` and list its branches.

    ``request`` holds the checked keywords (:class:`Request`); here they are checked against
    the problem. The branches are, for each combination of the ``params`` values (a list
    gives one set of branches per value; the first parameter varies slowest), each start in
    order, each direction. ``free`` names the parameters solved for where the module has
    more conditions than states (default: its ``FREE``); the plan's problem then carries
    them (`elastica_auto.model.augmented`). ``map``: for fold curves, also the stability
    maps of their planes (`elastica_auto.analysis.maps`). ``landing``: where each snap
    lands, by the module's dynamics (`elastica_auto.analysis.landing`); ``damping``: also
    the damped model's landing for each of these ``c``, from the folds labelled
    ``damping_folds`` (default every fold ending a stable branch). Raises
    :class:`PlanError` naming the argument at fault.
    """
    if not isinstance(problem, ProblemInterface):
        raise PlanError("problem", f"expected a problem from load_problem(), got "
                        f"{type(problem).__name__}")
    if request.landing and (isinstance(parameter, (list, tuple)) or not (
            problem.has_gradient_flow and problem.has_shooting and problem.has_second_variation)):
        raise PlanError("landing", "where a snap lands needs one continued parameter and the "
                        "module's gradient_flow, shooting and second_variation hooks")
    if isinstance(parameter, (list, tuple)):
        return _two_parameter_plan(problem, start, parameter, request, options)
    try:
        problem = problem.with_free(request.free)
    except ProblemError as exc:
        raise PlanError("free", str(exc)) from None
    if not isinstance(parameter, str) or parameter not in problem.parameters:
        raise PlanError("parameter", f"unknown parameter {parameter!r}; {problem.source} "
                        f"declares {', '.join(problem.parameter_names)}")
    if request.map and _starts is None:
        raise PlanError("map", "stability maps are drawn from fold curves: give two parameters "
                        "and LP starts")
    if parameter in problem.solved:
        raise PlanError("parameter", f"{parameter!r} is a free parameter (solved for); "
                        "continue in another one")
    opts = _options(options)
    _check_user_points(request, opts)
    grid = _grid(problem, request.params)
    starts = _starts if _starts is not None else _parse_starts(problem, start)
    _check_branch_count(starts, grid, request.directions)
    specs = _specs(starts, grid, request.directions)
    at_fold, limits = _stops(problem, request.stop)
    _detected(opts, at_fold, request.switch)
    watch = _without_user_values(parse_events(problem, parameter, request.events), parameter,
                                 request.user_values)
    return Plan(problem, parameter, opts, Stops(*request.limits, at_fold, limits),
                request.user_values, specs, watch, request.events,
                varying=[k for k, v in grid.items() if len(v) > 1],
                switch_count=request.switch, switch_depth=request.switch_depth,
                landing=request.landing, damping=request.damping,
                damping_folds=request.damping_folds)


def _without_user_values(watch: tuple[Event, ...], parameter: str,
                         user_values: list[UserValues]) -> tuple[Event, ...]:
    """The requested events less those ``uz`` labels already: an event on the continued
    parameter (``events = ["psi = 0.5"]``) at a ``uz`` value, or at one of its translates
    by ``uz_period`` (to 1e-9 (1 + |v|), `is_user_value`), asks for uz's own point. Kept, it
    would label each crossing twice, a rounding apart (uz solves at the value, the event
    locates its test function's root): dropped, the crossing is one UZ, uz's, as if asked
    for once."""
    if not (watch and user_values):
        return watch
    from ..branches.user_events import UserEvent    # loaded already: an entry asked for it
    return tuple(e for e in watch if not (isinstance(e, UserEvent) and e.name == parameter
                                          and is_user_value(e.value, user_values)))


def _detected(opts: ContinuationOptions, at_fold: int | None, switch: int):
    """A fold stop needs the folds looked for, and ``switch = N`` the branch points."""
    if at_fold is not None and not opts.detect[labels.LP]:
        raise PlanError("stop", f"LP{at_fold} counts folds, which detect.LP = false does not "
                        "look for")
    if switch and not opts.detect[labels.BP]:
        raise PlanError("switch", f"switch = {switch} switches at the branch points found, "
                        "which detect.BP = false does not look for")


def _specs(starts, grid: dict, directions: str) -> list[BranchSpec]:
    """The branches of a plan: the other branch at each stored BP (both ways, at its
    parameters), then for each combination of the ``grid`` values (the first parameter
    varying slowest) each start in order, in each of the ``directions``."""
    specs = []
    for st, _ in starts:  # the other branch at a stored BP: both ways, at its parameters
        if st.kind == "switch":
            if grid:
                raise PlanError("params", "a branch switched at a branch point has that "
                                "point's parameters; give no params")
            specs += [BranchSpec(st, {}, d) for d in (1, -1)]
    keys = list(grid)
    for combo in itertools.product(*(grid[k] for k in keys)):
        for st, given in starts:
            if st.kind == "switch":
                continue
            values = dict(zip(keys, combo))
            twice = sorted(set(given) & set(values))
            if twice:
                raise PlanError("params", f"{', '.join(twice)} given both in the start and "
                                "in params")
            specs += [BranchSpec(st, {**given, **values}, d) for d in DIRECTIONS[directions]]
    return specs


def _check_branch_count(starts, grid: dict, directions: str):
    """Refuse a plan of more than `MAX_BRANCHES` branches, counted as `_specs` would list
    them, before it lists any."""
    switched = sum(st.kind == "switch" for st, _ in starts)
    others = len(starts) - switched
    cells = math.prod(len(v) for v in grid.values())
    count = 2 * switched + cells * others * len(DIRECTIONS[directions])
    if count > MAX_BRANCHES:
        sizes = " x ".join(f"{len(v)} {k}" for k, v in grid.items()) or "1 cell"
        raise PlanError("params", f"{sizes} x {others} start(s) x "
                        f"{len(DIRECTIONS[directions])} direction(s) is {count:,} branches; a "
                        f"plan has at most {MAX_BRANCHES:,}: split the run")


def _check_user_points(request: Request, options: ContinuationOptions):
    """Refuse ``uz`` and ``uz_period`` that put more than `MAX_USER_POINTS` user points
    within a branch's reach: the span of the bounds, or without bounds as far as
    ``max_points`` steps of at most ``ds_max`` go."""
    if request.uz_period is None:
        if len(request.uz) > MAX_USER_POINTS:
            raise PlanError("uz", f"{len(request.uz):,} values; a branch meets at most "
                            f"{MAX_USER_POINTS:,} user points")
        return
    if request.bounds is not None:
        reach = request.bounds[1] - request.bounds[0]
        where, remedy = f"the bounds' span {reach:g}", "narrow the bounds"
    else:
        reach = options.max_points * options.ds_max
        where, remedy = f"max_points x ds_max = {reach:g} (no bounds)", "give bounds"
    count = len(request.uz) * (reach / request.uz_period + 1)
    if count > MAX_USER_POINTS:
        raise PlanError("uz_period", f"{request.uz_period:g} puts {count:.3g} user points "
                        f"within {where}, {len(request.uz)} uz value(s); a branch meets at "
                        f"most {MAX_USER_POINTS:,}: raise uz_period or {remedy}")


def _damping(damping, folds, landing: bool):
    """The checked ``damping`` values (positive, finite) and fold labels (``LP<n>``)."""
    if isinstance(damping, (str, bytes)) or not isinstance(damping, Iterable):
        raise PlanError("damping", f"expected a list of damping values, got {damping!r}")
    damping = tuple(damping)
    if not all(real_number(c) and math.isfinite(c) and c > 0 for c in damping):
        raise PlanError("damping", f"expected positive numbers, got {list(damping)!r}")
    if damping and not landing:
        raise PlanError("damping", "the damped model's landings need landing = true")
    if folds is None:
        return damping, None
    if isinstance(folds, (str, bytes)) or not isinstance(folds, Iterable):
        raise PlanError("damping_folds", f"expected a list of fold labels, got {folds!r}")
    folds = tuple(folds)
    if not all(isinstance(f, str) and re.fullmatch(r"LP[1-9][0-9]*", f) for f in folds):
        raise PlanError("damping_folds", f"expected fold labels such as \"LP3\", got "
                        f"{list(folds)!r}")
    if not damping:
        raise PlanError("damping_folds", "give the damping values too")
    return damping, folds


def _two_parameter_plan(base: Problem, start, parameter, request: Request, options) -> Plan:
    """``parameter = (lam, mu)``: the fold curves (from LP labels) or the branch-point curves
    of the exact family (from BP labels) through the starts, in the (lam, mu) plane; ``lam``
    is solved for, ``mu`` continued (`elastica_auto.branches.codim2`). A BP label that is not
    on the exact family starts a pitchfork curve (`elastica_auto.branches.pitchfork`)."""
    from ..branches import codim2, pitchfork
    if len(parameter) != 2 or not all(isinstance(q, str) for q in parameter) \
            or parameter[0] == parameter[1]:
        raise PlanError("parameter", f"expected one name, or two different names (the fold's "
                        f"parameter, then the continued one), got {parameter!r}")
    lam, mu = parameter
    for q in parameter:
        if q not in base.parameters:
            raise PlanError("parameter", f"unknown parameter {q!r}; {base.source} declares "
                            f"{', '.join(base.parameter_names)}")
    if request.free is not None:
        raise PlanError("free", f"a two-parameter continuation solves for {lam!r}; give no free")
    if request.switch:
        raise PlanError("switch", "no switching on a two-parameter continuation")
    if request.events:
        raise PlanError("events", "no events on a two-parameter continuation (its points are "
                        "folds or branch points all along)")
    items = list(start) if isinstance(start, (list, tuple)) else [start]
    if not items or not all(isinstance(x, StoredLabel) for x in items):
        raise PlanError("start", "a two-parameter continuation starts from LP or BP labels "
                        "(BranchFile(path).label(\"LP1\"))")
    kinds = {labels.kind_of(x.name) for x in items}
    other = [x.name for x in items if labels.kind_of(x.name) not in labels.FOLDS | labels.SWITCHES]
    if other:
        # a UZ or EP of a curve is a point of it, not a fold or branch point to follow
        raise PlanError("start", f"{', '.join(other)}: not an LP or BP label; a two-parameter "
                        "continuation starts from LP labels (fold curves) or BP labels "
                        "(branch-point or pitchfork curves), and any label restarts a "
                        "one-parameter run (give one parameter)")
    if len(kinds) != 1:
        raise PlanError("start", f"expected LP labels (fold curves) or BP labels (branch-point "
                        f"curves), not a mix; got {', '.join(x.name for x in items)}")
    curve = "fold" if kinds <= labels.FOLDS else "bp"
    if curve == "fold":
        free = {_label_free(base, x) for x in items}
        if len(free) != 1:
            raise PlanError("start", "the LP labels were found with different free parameters")
        try:
            base = base.with_free(free.pop())
        except ProblemError as exc:
            raise PlanError("start", str(exc)) from None
    for q in parameter:
        if q in getattr(base, "free", ()):
            raise PlanError("parameter", f"{q!r} is a free parameter of {base.source} (solved "
                            "for along the labels' branches); continue in another one")
    for x in items:
        _start(base, x)
        if x.tangent_parameter != lam:
            what = "fold" if curve == "fold" else "branch point"
            raise PlanError("start", f"{x.name} is a {what}"
                            f" in {x.tangent_parameter!r}, not in {lam!r}")
    ref = None
    if curve == "bp" and not all(_on_exact_family(base, x) for x in items):
        if len(items) != 1:
            raise PlanError("start", "a pitchfork curve (from a BP off the exact family) "
                            "starts from one BP label; give one start per run")
        curve, x = "pitchfork", items[0]
        try:
            ref = pitchfork.reference(base, x.state, x.tangent, lam, _options(options))
            problem = pitchfork.pitchfork_problem(base, lam, ref)
        except (StartError, ProblemError) as exc:
            raise PlanError("start", f"{x.name}: {exc}") from None
    else:
        try:
            problem = (codim2.fold_problem if curve == "fold" else codim2.branch_point_problem)(
                base, lam)
        except ProblemError as exc:
            raise PlanError("parameter", str(exc)) from None
    plan = make_plan(problem, [], mu, dataclasses.replace(request, map=False), options,
                     _starts=[(Start(curve, x.path, x.name, x), {}) for x in items])
    if request.map and (curve != "fold" or not (base.has_shooting and base.has_second_variation)):
        raise PlanError("map", "stability maps need fold curves (LP starts) of a module with "
                        "the shooting and second_variation hooks")
    plan.curve, plan.base, plan.maps, plan.reference = curve, base, request.map, ref
    return plan


#: A BP label is on the module's exact family where its solution is the family's at its
#: parameters to this, relative to the solution's size: the exact family's branch points are
#: located with the family's own solution (the straight rod to rounding), and a branch point of
#: another branch is a finite distance from it.
FAMILY_RTOL = 1e-6


def _on_exact_family(base: Problem, label) -> bool:
    """Whether the BP ``label``'s solution is ``base``'s exact solution at its parameters."""
    s, y = label.state.s, label.state.y
    y0 = base.exact_start(s, label.state.params)
    if y0 is None:
        return False
    scale = 1.0 + float(np.max(np.abs(y)))
    return float(np.max(np.abs(y[: len(y0)] - y0))) <= FAMILY_RTOL * scale


def _label_free(base: Problem, label) -> tuple[str, ...]:
    """The free parameters of the run that found ``label`` (its states ``free:NAME`` among the
    module's square problem's states, before any null vector's)."""
    free = []
    for name in label.states:
        if name.startswith("null:"):
            break
        if name.startswith("free:") and name[5:] in base.parameters:
            free.append(name[5:])
    return tuple(free)


def _finite(key: str, v) -> float:
    if not real_number(v) or not math.isfinite(v):
        raise PlanError(key, f"expected a finite number, got {v!r}")
    return float(v)


def _bounds(bounds) -> tuple[float, float]:
    if bounds is None:
        return -math.inf, math.inf
    if isinstance(bounds, (str, bytes)) or not hasattr(bounds, "__len__") or len(bounds) != 2:
        raise PlanError("bounds", f"expected (lower, upper), got {bounds!r}")
    lower, upper = (_finite("bounds", v) for v in bounds)
    if not lower < upper:
        raise PlanError("bounds", f"need lower < upper, got {lower:g}, {upper:g}")
    return lower, upper


def _uz(uz, uz_period) -> tuple[tuple[float, ...], float | None]:
    if isinstance(uz, (str, bytes)) or not isinstance(uz, Iterable):
        raise PlanError("uz", f"expected a list of values, got {uz!r}")
    values = tuple(_finite("uz", v) for v in uz)
    if uz_period is not None:
        if not values:
            raise PlanError("uz_period", "given without uz")
        if not _finite("uz_period", uz_period) > 0:
            raise PlanError("uz_period", f"must be positive, got {uz_period:g}")
    return values, uz_period and float(uz_period)


#: What a ``stop`` entry may be, for the messages that refuse one.
STOP_FORMS = '"LPn" (such as "LP4"), "NAME > VALUE" or "NAME < VALUE"'


def _stops(problem, stop) -> tuple[int | None, tuple[Limit, ...]]:
    """``stop = ["LP4", "u_max > 100"]``: the fold count at which a branch ends (the
    smallest given), and the limits on ordinates or free parameters. A crossing has no
    "or equal" (``>`` ends the branch where NAME = VALUE on the way up), so ``>=`` is refused
    with the entry to write instead; every refusal names the forms a stop takes."""
    at, limits = None, []
    names = [*problem.ordinate_names, *problem.solved]
    for item in stop:
        if not isinstance(item, str):
            raise PlanError("stop", f"expected {STOP_FORMS}, got {item!r}")
        ops = re.findall(r"[=!]*[<>][<>=]*", item)  # each comparison, with any = or ! on it
        if ops and ops[0] in (">=", "=>", "<=", "=<"):
            op = ops[0].strip("=")
            raise PlanError("stop", f"{item!r}: a stop has no \"or equal\" (the branch ends "
                            f"where NAME = VALUE): write {item.replace(ops[0], op, 1)!r}; "
                            f"expected {STOP_FORMS}")
        if ops and ops[0] in (">", "<"):
            if len(ops) > 1:
                raise PlanError("stop", f"{item!r}: one comparison only; expected {STOP_FORMS}")
            name, op, text = (x.strip() for x in re.split(r"([<>])", item))
            if name not in names:
                # a parameter held fixed does not move, and the continued one ends where
                # `bounds` says (an EP solved exactly there): a stop is not the way to it
                hint = (f"; {name} is a parameter: a branch ends at a value of the continued "
                        "parameter by bounds = [lower, upper]" if name in problem.parameters
                        else "")
                raise PlanError("stop", f"{item!r}: {name!r} is not an ordinate or a free "
                                f"parameter ({', '.join(names) or 'none'}){hint}")
            try:
                value = evaluate(text)
            except ValueError as exc:
                raise PlanError("stop", f"{item!r}: VALUE {exc}") from None
            limits.append(Limit(name, 1 if op == ">" else -1, value))
        # isdigit() alone also accepts "²" and "٣"; only ASCII digits are a count
        elif not ops and labels.kind_of(item) == labels.LP and item[2:].isascii() \
                and item[2:].isdigit() and int(item[2:]) > 0:
            at = min(int(item[2:]), at or math.inf)
        else:
            raise PlanError("stop", f"expected {STOP_FORMS} (NAME an ordinate or free "
                            f"parameter), got {item!r}")
    return at, tuple(limits)


def _options(options) -> ContinuationOptions:
    if isinstance(options, ContinuationOptions):
        return options
    known = {f.name for f in fields(ContinuationOptions)}
    unknown = sorted(set(options or {}) - known)
    if unknown:
        raise PlanError("options", f"unknown option {unknown[0]!r}; expected one of "
                        f"{', '.join(sorted(known))}")
    try:
        return ContinuationOptions(**(options or {}))
    except OptionsError as exc:
        raise PlanError("options", str(exc)) from None


def _grid(problem: Problem, params) -> dict[str, list[float]]:
    grid = {}
    for name, v in (params or {}).items():
        if name not in problem.parameters:
            raise PlanError(f"params.{name}", f"unknown parameter; {problem.source} declares "
                            f"{', '.join(problem.parameter_names)}")
        # a list, tuple or 1-D numpy array (np.linspace) of values, or one value
        values = (list(v) if isinstance(v, (list, tuple))
                  or isinstance(v, np.ndarray) and v.ndim == 1 else [v])
        if not values:
            raise PlanError(f"params.{name}", "empty list")
        grid[name] = [_finite(f"params.{name}", x) for x in values]
    return grid


def _parse_starts(problem: Problem, start) -> list[tuple[Start, dict[str, float]]]:
    """Each start, with the parameter values it was given (a dict start's)."""
    items = list(start) if isinstance(start, (list, tuple)) else [start]
    if not items:
        raise PlanError("start", "empty list")
    return [_start(problem, item) for item in items]


def _start(problem: Problem, item) -> tuple[Start, dict[str, float]]:
    if isinstance(item, Mapping):
        values = {}
        for name, v in item.items():
            if name not in problem.parameters:
                raise PlanError("start", f"unknown parameter {name!r}; {problem.source} "
                                f"declares {', '.join(problem.parameter_names)}")
            values[name] = _finite(f"start.{name}", v)
        return Start("trivial"), values
    kind = "switch" if isinstance(item, Switch) else "label"
    label = item.label if isinstance(item, Switch) else item
    if not isinstance(label, StoredLabel):
        raise PlanError("start", "expected parameter values (a dict), a label "
                        "(BranchFile(path).label(\"UZ1\")) or Switch(label), got "
                        f"{type(item).__name__}")
    if kind == "switch" and labels.kind_of(label.name) not in labels.SWITCHES:
        raise PlanError("start", f"{label.name}: switching branches needs a BP label")
    if label.equation and Path(label.equation).stem != problem.name:
        where = label.path.name if label.path is not None else label.name
        raise PlanError("start", f"{where} was computed with {label.equation!r}, not "
                        f"{problem.source!r}")
    if len(label.state.y) > problem.n \
            and tuple(label.states[: problem.n]) == tuple(problem.states):
        label = _module_states(label, problem.n)
    if problem.n0 < problem.n:   # states it carries (free parameters) by name, not by position
        label = restart.by_name(problem, label)
    if len(label.state.y) != problem.n:
        raise PlanError("start", f"{label.name} has {len(label.state.y)} states, "
                        f"{problem.source} {problem.n}")
    return Start(kind, label.path, label.name, label), {}


def _module_states(label: StoredLabel, n: int) -> StoredLabel:
    """A label of a two-parameter continuation (a fold curve's CP, say) as a solution of the
    module's own problem: its first ``n`` states, at all its parameter values (the solved-for
    one included); no tangent (the stored one is the curve's)."""
    s = label.state
    state = State(s.s, s.y[:n], s.yp[:n], s.params)
    return dataclasses.replace(label, state=state, tangent=None, tangent_parameter=None,
                               states=label.states[:n])

