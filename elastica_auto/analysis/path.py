"""Snap-backs along a path: which folds a straight path in parameter space crosses, and
where the structure can snap to at each (the analysis; ``elastica_auto.snaps_along``, in
`elastica_auto.api`, runs it: `path_starts`, the continuation in ``t``, then `path_snaps`).

A path from the parameter values A to B is the segment p(t) = A + t (B - A), t in [0, 1]
(angles included: a path in psi from 0 to 4 pi turns the arm twice). `path_problem` is the
module's problem in the one parameter ``t`` (``PATH``): the parameters that differ between A
and B follow t, the others keep A's values. `snaps_along` then

1. enumerates every equilibrium at A (the module's ``shooting`` hook, as for snap-back
   targets) and continues each in t over [0, 1], both ways;
2. at each fold where a stable (index 0) stretch ends as t increases, lists every stable
   equilibrium at that fold's parameters (`elastica_auto.analysis.snaps.snap_targets`): where a rod
   moved quasi-statically from A to B along the path snaps to.

Which of several stable equilibria the rod lands on is not decided here (it depends on the
dynamics of the snap). Branches of the path that no equilibrium at A lies on (isolas in t)
are not followed.
"""

from __future__ import annotations

import math
import types
from dataclasses import dataclass, field

import numpy as np

from ..branches.branch import StoredLabel
from ..core.errors import PlanError
from ..core.solution import State
from ..model.problem import Ordinate, Parameter, Problem
from .equilibria import enumerate_equilibria
from .snaps import snap_targets

#: The name of the path parameter.
PATH = "t"


class PathProblem(Problem):
    """The module's problem along a path: its parameter ``t`` moves the parameters
    ``varying`` from ``a`` to ``b``; stored parameter values are the effective ones. Its
    hooks are the module's at the effective values (`path_problem`: the equations, the
    ordinates, the second variation, the shooting scan, the dynamics, the drawing), but
    those `REFUSED` (the problem interface, `elastica_auto.model.interface`)."""

    REFUSED = {
        "mirror": "the module's reflection negates or keeps each parameter, and t moves "
                  "several at once",
        "symmetry": "a branch along the path is continued without a phase condition (the path "
                    "may move the parameters the symmetry needs held)",
        "symmetric_values": "the module's values are those of one of its parameters, not of "
                            "t",
    }

    def refusal(self, hook: str) -> str | None:
        return self.REFUSED.get(hook)

    def __init__(self, module, source, a: dict, b: dict):
        self.a, self.b = dict(a), dict(b)
        self.varying = [k for k in a if a[k] != b[k]]
        super().__init__(module, source)

    def effective(self, p: dict) -> dict:
        """``p`` with the varying parameters at their values at ``p[PATH]``."""
        t = p[PATH]
        return {**p, **{k: self.a[k] + t * (self.b[k] - self.a[k]) for k in self.varying}}

    def point_params(self, params, y):
        return self.effective(params)


def path_problem(base: Problem, a: dict, b: dict) -> PathProblem:
    """``base`` along the segment from the parameter values ``a`` to ``b`` (both complete:
    defaults filled in), in the parameter ``t`` (module docstring)."""
    if PATH in base.parameters:
        raise PlanError("path", f"{base.source} has a parameter named {PATH!r}")
    varying = [k for k in a if a[k] != b[k]]
    if not varying:
        raise PlanError("path", "the two ends of the path are the same point")
    d = {k: b[k] - a[k] for k in varying}

    def eff(p):
        return {**p, **{k: a[k] + p[PATH] * d[k] for k in varying}}

    def along(fn, p, name, *args):
        """d/d(name) of fn: along the path for t, zero for a parameter that t drives."""
        q = eff(p)
        if name == PATH:
            return sum(d[k] * np.asarray(fn(*args, q, k)) for k in varying)
        if name in varying:
            return np.zeros_like(np.asarray(fn(*args, q, varying[0])))
        return fn(*args, q, name)

    def shooting(p):
        return (*base.shooting(eff(p)), base.shooting_reflection(eff(p)))

    def second_variation(s, y, p):
        return base.second_variation(s, y, eff(p))

    def exact_start(s, p):
        return base.exact_start(s, eff(p))

    def gradient_flow(p, nodes):
        return base.gradient_flow(eff(p), nodes)

    def draw(ax, profile, p):
        return base.draw(ax, profile, eff(p))

    parameters = [*base.parameters.values(),
                  Parameter(PATH, 0.0, "t", "free", doc="position on the path, 0 at A, 1 at B")]
    ordinates = [Ordinate(o.name, o.tex, (lambda fn: lambda s, y, p: fn(s, y, eff(p)))(o.fn),
                          o.parameter, o.doc) for o in base.ordinates.values()]
    module = types.SimpleNamespace(
        __doc__=f"{base.source} along a path in {', '.join(varying)}.",
        STATES=base.states, PARAMETERS=parameters, ORDINATES=ordinates,
        rhs=lambda s, y, p: base.rhs(s, y, eff(p)),
        rhs_jac=lambda s, y, p: base.rhs_jac(s, y, eff(p)),
        bc=lambda ya, yb, p: base.bc(ya, yb, eff(p)),
        bc_jac=lambda ya, yb, p: base.bc_jac(ya, yb, eff(p)),
        rhs_dp=lambda s, y, p, name: along(base.rhs_dp, p, name, s, y),
        bc_dp=lambda ya, yb, p, name: along(base.bc_dp, p, name, ya, yb),
        exact_start=exact_start)
    if base.has_shooting:
        module.shooting = shooting
    if base.has_second_variation:
        module.second_variation = second_variation
    if base.has_gradient_flow:
        module.gradient_flow = gradient_flow
    if base.has_draw:
        module.draw, module.DRAW_PROJECTION = draw, base.draw_projection
    return PathProblem(module, base.source, {**a, PATH: 0.0}, {**b, PATH: 1.0})


@dataclass
class Snap:
    """A fold on the path where a stable stretch ends as t increases, and the stable
    equilibria there (each a row of `elastica_auto.analysis.snaps.snap_targets`: its ordinates,
    index, whether a computed branch passes through it)."""

    t: float
    params: dict[str, float]
    ordinates: dict[str, float]
    targets: list[dict] = field(default_factory=list)


def path_starts(base: Problem, a: dict, b: dict) -> tuple[PathProblem, list[StoredLabel]]:
    """The path from ``a`` to ``b`` (parameter values; the others at the module's defaults)
    as a problem in ``t`` (`path_problem`), and every equilibrium at ``a`` as a start of it
    (a label ``EQ1``, ``EQ2``, ... at ``t = 0``): what the continuation in ``t`` starts from."""
    if not (base.has_shooting and base.has_second_variation):
        raise PlanError("path", f"{base.source} has no shooting or second_variation hook: "
                        "its equilibria at the start cannot be enumerated")
    for end in (a, b):
        unknown = sorted(set(end) - set(base.parameters))
        if unknown:
            raise PlanError("path", f"unknown parameter {unknown[0]!r}; {base.source} "
                            f"declares {', '.join(base.parameter_names)}")
    a = {**base.defaults(), **a}
    b = {**a, **b}
    problem = path_problem(base, a, b)
    at_a = enumerate_equilibria(base, a)
    if not at_a:
        raise PlanError("path", "no equilibrium found at the start of the path")
    starts = [StoredLabel(f"EQ{k}", 0, 0, _on(eq.state), None, None, None,
                          base.source, tuple(base.states)) for k, eq in enumerate(at_a, 1)]
    return problem, starts


def path_snaps(problem: PathProblem, branches) -> list[Snap]:
    """The snaps on the path of ``problem`` that ``branches`` (continued in ``t`` from
    `path_starts`) cross, in order of t: each fold where a stable stretch ends as t
    increases, with its stable equilibria (`snap_targets`), each fold and target once."""
    rows = snap_targets(problem, branches)
    snaps: dict[tuple, Snap] = {}
    for row in rows:
        br = branches[row["branch"] - 1]
        lp = next(p for p in br.points if p.name == row["lp"])
        k = br.points.index(lp)
        t = br.column(PATH)
        # the stable side lies below the fold in t: moving up the path reaches the fold
        side = t[k - 1] if row["stable_side"] == "before" else t[k + 1]
        if not side < t[k]:
            continue
        key = (round(t[k], 9), *(round(v, 6) for v in lp.ordinates.values()))
        snap = snaps.setdefault(key, Snap(float(t[k]), dict(lp.params), dict(lp.ordinates)))
        if not any(_same_row(row, other) for other in snap.targets):
            snap.targets.append(row)
    return sorted(snaps.values(), key=lambda s: s.t)


def _on(state) -> State:
    """An equilibrium at A as a state of the path problem (t = 0)."""
    return State(state.s, state.y, state.yp, {**state.params, PATH: 0.0})


def _same_row(r1: dict, r2: dict) -> bool:
    keys = [k for k in r1 if k.startswith("target_")]
    return all(math.isclose(r1[k], r2[k], rel_tol=1e-6, abs_tol=1e-6) for k in keys)
