"""A branch in memory: one row per point, profiles on a fixed grid, labelled solutions."""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core import labels
from ..core.solution import State, Tangent
from ..model.second_variation import as_second_variation
from ..numerics.stability import count

#: Fixed grid on which every point's profile is stored (for configurations and tip traces).
PROFILE_GRID = np.linspace(0.0, 1.0, 101)

#: Label types, AUTO-07p's vocabulary and XT (`elastica_auto.core.labels`, what each means).
LABEL_TYPES = tuple(labels.MEANING)

#: Index columns hold this until the stability post-processor has filled them.
INDEX_UNKNOWN = -1

#: The columns of a branch (``branch.columns``), around its parameters and ordinates. The
#: first seven groups are what ``elastica-auto export`` writes, in its order: branch number,
#: point number (from 1), label type and name ("LP3"; "" on other points), then the
#: parameters, the ordinates and the three stability indices. The rest is bookkeeping:
#: pseudo-arclength, step, Newton iterations, mesh nodes, the located fold's residual, notes,
#: and the index before and after a fold or branch point ("1 -> 0").
LEADING_COLUMNS = ("branch", "pt", "type", "label")
INDEX_COLUMNS = ("index", "index_rule", "index_direct")
EXTRA_COLUMNS = ("arclength", "ds", "niter", "nodes", "fold_residual", "note", "transition")


def export_names(parameters, ordinates) -> list[str]:
    """The columns ``elastica-auto export`` writes, in order."""
    return [*LEADING_COLUMNS, *parameters, *ordinates, *INDEX_COLUMNS]


def column_names(parameters, ordinates) -> list[str]:
    """Every column, in order, of a branch with these parameters and ordinates."""
    return [*export_names(parameters, ordinates), *EXTRA_COLUMNS]


@dataclass
class StoredLabel:
    """A labelled point: its solution (a restart point) and, if stored, its tangent.

    ``path`` and ``equation`` are the branch file's and the module's it was computed with
    (``path`` is None for a label of branches in memory); ``states`` names the rows of
    ``state.y`` (the module's states, then those a two-parameter continuation adds).
    ``options`` are those of the continuation that computed it (`ContinuationOptions`, as a
    dict; empty if not known): its discretisation and tolerance, by which a restart checks
    that the stored solution still solves its equations (`branches.restart.check_stored`)."""

    name: str
    branch: int
    pt: int
    state: State
    tangent: Tangent | None
    tangent_parameter: str | None
    path: Path | None = None
    equation: str = ""
    states: tuple[str, ...] = ()
    options: dict = field(default_factory=dict)


@dataclass
class Point:
    """One point of a branch. ``state``/``tangent`` are kept for labelled points only."""

    params: dict[str, float]
    ordinates: dict[str, float]
    arclength: float
    ds: float
    niter: int
    nodes: int
    type: str
    profile: np.ndarray
    fold_residual: float = float("nan")
    note: str = ""
    state: State | None = None
    tangent: Tangent | None = None
    label: int = 0
    index: int = INDEX_UNKNOWN
    index_rule: int = INDEX_UNKNOWN
    index_direct: int = INDEX_UNKNOWN
    #: At a BP bounding a stable segment: whether the branches born there are unstable (a
    #: snap; `elastica_auto.analysis.snaps.mark_subcritical`), None where not decided.
    subcritical: bool | None = None

    @property
    def name(self) -> str:
        """The label as users write it (``LP3``), or '' for an unlabelled point."""
        return f"{self.type}{self.label}" if self.type else ""


def new_point(problem, state: State, *, type: str = "", arclength: float, ds: float = 0.0,
              niter: int = 0, tangent: Tangent | None = None,
              fold_residual: float = float("nan"), note: str = "",
              direct: int | None = None, parts: dict | None = None) -> Point:
    """The point of a branch at ``state``: its parameter values (free ones included), its
    ordinates, its profile on PROFILE_GRID and its stability index by direct count
    (``direct`` and the index of each part of the second variation, ``parts``, if the caller
    has them; unknown where a distinguished ordinate is not finite); a labelled point keeps
    its solution and tangent. The ordinates named after the form's parts take their counts."""
    if type and type not in LABEL_TYPES:
        raise ValueError(f"unknown label type {type!r}")
    counted = None
    if type in labels.TURNS and problem.has_second_variation:
        # A located fold or branch point is singular by construction: its count would read
        # the sign of an eigenvalue zero to the location's accuracy, rounding's guess (the
        # BLAS kernel's, or the compiler's); the rows beside it are counted, and `index` is
        # the rule's there.
        direct, parts = INDEX_UNKNOWN, uncounted_parts(problem, state)
    elif direct is None and problem.has_second_variation:
        counted = count(problem, state)
        direct, parts = counted.index, counted.parts
    ordinates = problem.ordinate_values(state.s, state.y, state.params, parts)
    # A distinguished ordinate that is not finite leaves the point neither stable nor
    # unstable (the fold rule reads it). Any other ordinate is a gauge of the module's: NaN
    # there (a ratio 0/0 on a straight rod) says nothing of the state, whose index stands.
    distinguished = {o.name for o in problem.ordinates.values() if o.parameter}
    if not all(math.isfinite(v) for name, v in ordinates.items() if name in distinguished):
        direct = INDEX_UNKNOWN
    elif direct is None:
        direct = INDEX_UNKNOWN  # no second_variation hook
    elif counted is not None and counted.refused:
        # no index here: say why (a zero eigenvalue needs no note)
        note = "; ".join(filter(None, (note, counted.reason)))
    return Point(params=problem.point_params(state.params, state.y), ordinates=ordinates,
                 arclength=float(arclength), ds=float(ds), niter=int(niter),
                 nodes=len(state.s), type=type, profile=state(PROFILE_GRID),
                 fold_residual=float(fold_residual), note=note,
                 state=state if type else None, tangent=tangent if type else None,
                 index_direct=direct)


def uncounted_parts(problem, state: State) -> dict[str, int]:
    """Each part of the second variation (`SecondVariation` ``parts``, read from the form on
    the state's nodes) -1, not counted: what a located fold or branch point has."""
    form = as_second_variation(problem.second_variation(state.s, state.y, state.params),
                               problem.source)
    return dict.fromkeys(form.parts, INDEX_UNKNOWN)


@dataclass
class Branch:
    """The points of one continuation in one direction, in order of pseudo-arclength: a plain
    record (it pickles), named after its problem's parameters and ordinates."""

    parameter: str
    direction: int
    start: str
    options: dict
    equation: str = ""
    parameter_names: tuple[str, ...] = ()
    ordinate_names: tuple[str, ...] = ()
    state_names: tuple[str, ...] = ()
    singular_start: bool = False
    points: list[Point] = field(default_factory=list)
    end: str = ""
    message: str = ""
    diagnostics: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0
    interrupted: bool = False
    number: int = 0
    worker: str = "local"
    cell: str = ""
    #: Points at UZ values not asked for, kept out of ``points`` for the branch's mirror image
    #: (`elastica_auto.branches.mirror.set_aside`); not saved.
    mirror_points: list[Point] = field(default_factory=list)

    @property
    def internal_error(self) -> bool:
        """Whether the branch ended on an internal error of the engine (a bug, not a hard
        problem: `elastica_auto.core.errors.failure_kind`)."""
        return self.diagnostics.get("kind") == "engine"

    @classmethod
    def of(cls, problem, parameter: str, direction: int, start: str, options: dict,
           **fields) -> "Branch":
        """An empty branch of ``problem``."""
        return cls(parameter, direction, start, options, problem.source,
                   tuple(problem.parameter_names), tuple(problem.ordinate_names),
                   tuple(problem.states), **fields)

    def insert(self, point: Point) -> Point:
        """Put ``point`` at its place in arclength order."""
        if not self.points or point.arclength >= self.points[-1].arclength:
            self.points.append(point)
        else:
            keys = [p.arclength for p in self.points]
            self.points.insert(bisect.bisect_right(keys, point.arclength), point)
        return point

    def relabel(self, point: Point, type: str, state: State, tangent: Tangent | None):
        """Give an existing point a label (e.g. the last point becomes EP or MX)."""
        point.type, point.state, point.tangent = type, state, tangent

    def transition(self, point: Point) -> str:
        """``"1 -> 0"``: the index before and after a labelled point, in the direction of
        travel ('' where unknown)."""
        for k, p in enumerate(self.points):
            if p is point:
                return self._transition(k)
        raise ValueError("the point is not on this branch")

    def _transition(self, k: int) -> str:
        """`transition` of the k-th point (found by position: ``points.index`` compares
        every field of the points before it, a branch's labels made saving it quadratic)."""
        if k + 1 >= len(self.points):
            return ""
        before, after = self.points[k].index, self.points[k + 1].index
        return f"{before} -> {after}" if before >= 0 and after >= 0 else ""

    def label(self, name: str) -> StoredLabel:
        """The solution labelled ``name`` on this branch, to restart from (as a label read
        from a branch file)."""
        for pt, p in enumerate(self.points, 1):
            if p.type and p.name == name:
                return StoredLabel(name, self.number, pt, p.state, p.tangent, self.parameter,
                                   None, self.equation, self.state_names, dict(self.options))
        names = sorted((p.name for p in self.points if p.type), key=labels.label_order)
        raise KeyError(f"no label {name!r} on this branch; labels: "
                       f"{labels.compact(names) or 'none'}")

    @property
    def disagreements(self) -> list[Point]:
        """Points where the fold rule and the direct count disagree."""
        return [p for p in self.points if "index disagreement" in p.note]

    @property
    def folds(self) -> list[Point]:
        return [p for p in self.points if p.type in labels.FOLDS]

    @property
    def closed(self) -> bool:
        """Whether the branch is a closed loop: its last point is its first point's solution
        (the continuation ends there when it comes back to its start)."""
        pts = self.points
        return (len(pts) > 2 and pts[-1].params == pts[0].params
                and np.array_equal(pts[-1].profile, pts[0].profile))

    @property
    def labelled(self) -> list[Point]:
        return [p for p in self.points if p.type]

    @property
    def columns(self) -> dict[str, np.ndarray]:
        """Every column (:func:`column_names`) as an array, one row per point:
        ``branch.columns["psi"]``, ``branch.columns["index"]``."""
        return {name: self.column(name) for name in
                column_names(self.parameter_names, self.ordinate_names)}

    def column(self, name: str) -> np.ndarray:
        """One of :attr:`columns`, computed alone."""
        pts = self.points
        if name in self.parameter_names:
            return np.array([p.params[name] for p in pts], dtype=float)
        if name in self.ordinate_names:
            return np.array([p.ordinates[name] for p in pts], dtype=float)
        if name == "branch":
            return np.full(len(pts), self.number)
        if name == "pt":
            return np.arange(1, len(pts) + 1)
        if name in ("type", "label", "note", "transition"):
            values = ([p.name for p in pts] if name == "label" else
                      [self._transition(k) if p.type in labels.TURNS else ""
                       for k, p in enumerate(pts)]
                      if name == "transition" else [getattr(p, name) for p in pts])
            return np.array(values, dtype=object)
        if name in (*INDEX_COLUMNS, *EXTRA_COLUMNS):
            return np.array([getattr(p, name) for p in pts])
        names = column_names(self.parameter_names, self.ordinate_names)
        raise KeyError(f"no column {name!r}; columns: {', '.join(names)}")
