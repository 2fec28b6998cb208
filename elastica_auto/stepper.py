"""The pseudo-arclength loop: predictor, corrector, step control, angle guard, events, stops.

One call of :func:`continue_branch` fills one :class:`~elastica_auto.branch.Branch`: from a
start solution, in one direction, until a parameter bound (EP), the point limit (EP), the
n-th fold (``stop = ["LP4"]``), or a corrector failure at ``ds_min`` (MX).

Predictor: the unit tangent at the start (:func:`~elastica_auto.corrector.solve_tangent`),
then the secant through the last two points; the true tangent replaces the secant when a step
is rejected for turning too much (the secant lags a sharply turning curve). Corrector: Keller's arclength system
(:func:`~elastica_auto.corrector.solve_arclength`). A step is rejected, and ds halved, when the
corrector fails or the new secant turns by more than ``max_angle`` from the predictor
direction (which would otherwise let the stepper reverse at a fold and retrace the branch).
After a step that converged on the first mesh and turned by less than half the allowed angle,
ds grows by ``growth`` up to ``ds_max``.

Mesh: each corrector starts on the previous point's mesh, coarsened where its residuals are
far below ``tol`` (:func:`~elastica_auto.corrector.coarsen`). solve_bvp only ever adds nodes;
carrying its meshes forward unpruned lets the mesh balloon as the solution's shape moves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

from .branch import Branch
from .corrector import (State, Tangent, coarsen, inner, secant, solve_arclength,
                        solve_tangent)
from .events import (UserValues, crossings, locate_branch_point, locate_fold,
                     locate_turning_point, locate_value, locate_value_on_step)
from .options import ContinuationOptions
from .stability import direct_index


@dataclass(frozen=True)
class Stops:
    """Where a branch ends: bounds on the continued parameter, and the n-th fold (or None)."""

    lower: float = -math.inf
    upper: float = math.inf
    at_fold: int | None = None


def initial_tangent(branch: Branch, start: State, direction: int, guess: Tangent | None,
                    options: ContinuationOptions) -> Tangent | None:
    """Unit tangent at the start, oriented so the parameter moves in ``direction``.

    With a stored tangent (restart) as ``guess`` the bordering is regular even at a fold; there
    ``direction`` is taken along the stored tangent.
    """
    problem, name = branch.problem, branch.parameter
    t = solve_tangent(problem, start, name, guess, options.tol, options.max_nodes)
    if t is None and guess is not None:
        t = solve_tangent(problem, start, name, None, options.tol, options.max_nodes)
    if t is None:
        return None
    if abs(t.lam) > 1e-6:
        sign = 1.0 if t.lam * direction > 0 else -1.0
    else:
        sign = float(direction)
    return Tangent(t.s, sign * t.y, sign * t.yp, sign * t.lam)


def continue_branch(branch: Branch, start: State, options: ContinuationOptions, stops: Stops,
                    user_values: list[UserValues] = (), start_tangent: Tangent | None = None,
                    progress: Callable[[Branch, float], None] | None = None,
                    singular_start: bool = False, exact_tangent: bool = False) -> Branch:
    """Continue ``start`` in ``branch.parameter`` in ``branch.direction``; fills ``branch``.

    ``singular_start``: the start is a fold or a branch point; no fold or branch point is
    sought in the first step, where the start's own singularity would be found.
    ``exact_tangent``: ``start_tangent`` is the (already oriented) direction to follow, used as
    it is (the other branch at a branch point, where the bordered tangent system is singular).
    Points are appended as they are accepted, so an interrupted call leaves every completed
    point in ``branch``.
    """
    problem, name, opt = branch.problem, branch.parameter, options
    if exact_tangent:
        t = start_tangent
    else:
        t = initial_tangent(branch, start, branch.direction, start_tangent, opt)
    if t is None:
        branch.add(start, type="MX", arclength=0.0, note="singular start")
        branch.end, branch.message = "MX", "no tangent at the start point (singular bordered system)"
        return branch
    base_point = branch.add(start, type="EP", arclength=0.0, tangent=t)
    base, arclength, ds = start, 0.0, abs(opt.ds)
    # secant into base (start: the tangent); folds are sign changes of its parameter component
    t_in = Tangent(t.s, t.y, t.yp, 0.0) if singular_start else t
    if singular_start:
        branch.points[-1].note = ""  # the direct counts may differ at a singular point
    dist_in = abs(opt.ds)
    exact = True        # t is the true tangent at base, not a secant
    mesh = start.s
    cos_max, cos_grow = math.cos(opt.max_angle), math.cos(opt.max_angle / 2)
    history = []

    def end_at_base(kind):
        if base_point.type:
            branch.add(base, type=kind, arclength=arclength, tangent=t)
        else:
            branch.relabel(base_point, kind, base, t)

    while True:
        if len(branch.points) >= opt.max_points:
            end_at_base("EP")
            branch.end, branch.message = "EP", f"reached max_points = {opt.max_points}"
            return branch
        # A corrector that does not converge makes solve_bvp refine up to max_nodes before it
        # gives up; a smaller step is the cheaper cure, so refinement is capped per step.
        res = solve_arclength(problem, base, t, name, ds, opt.tol,
                              min(opt.max_nodes, 3 * len(mesh)), mesh=mesh)
        reason = res.message
        cos_turn = -1.0
        if res.success:
            sec, dist = secant(base, res.state, name)
            cos_turn = inner(sec, t, sec.s)
            if cos_turn < cos_max:
                reason = (f"tangent turned by {math.degrees(math.acos(max(-1.0, cos_turn))):.1f} "
                          f"deg > max_angle")
                if not exact:
                    # The secant into base lags the curve by half the last step's turn, so a
                    # smaller ds cannot cure this: predict along the true tangent instead.
                    true = solve_tangent(problem, base, name, t, opt.tol, opt.max_nodes)
                    if true is not None:
                        t, exact = true, True
                        continue
        if not res.success or cos_turn < cos_max:
            history.append({"ds": ds, "residual": res.residual, "nodes": res.nodes,
                            "message": reason})
            ds /= 2
            if ds < opt.ds_min:
                end_at_base("MX")
                branch.end = "MX"
                branch.message = (f"corrector failed at ds < ds_min = {opt.ds_min:g} after point "
                                  f"{len(branch.points)}: {reason}")
                branch.diagnostics = {"step": len(branch.points), "ds": ds * 2,
                                      "nodes": res.nodes, "history": history[-12:]}
                return branch
            continue
        history.clear()
        new = res.state
        step = _Step(base, new, sec, dist, arclength, ds, name)
        direct_new = direct_index(problem, new)
        found = []
        if t_in.lam * sec.lam < 0:
            # A simple fold changes the index; a turn of the parameter without a change is the
            # branch point of a pitchfork met along its bifurcating branch (or a degenerate fold)
            simple = (direct_new[0] < 0 or base_point.index_direct < 0
                      or direct_new[0] != base_point.index_direct
                      or (singular_start and base is start))
            found.append(_secant_fold(branch, step, t_in, dist_in, opt, simple))
        elif (direct_new[0] >= 0 and base_point.index_direct >= 0
              and direct_new[0] != base_point.index_direct
              and not (singular_start and base is start)):
            # The index changed with no fold seen by the secants: a branch point, or a fold
            # passed within this one step. The parameter then turns back inside the step, so
            # the true tangent at the new point disagrees in sign with the secant: retry with a
            # smaller step, until the secants see the fold.
            true = solve_tangent(problem, new, name, sec, opt.tol, opt.max_nodes)
            if true is not None and true.lam * sec.lam < 0:
                history.append({"ds": ds, "residual": res.residual, "nodes": res.nodes,
                                "message": "a fold was passed within one step"})
                ds /= 2
                if ds >= opt.ds_min:
                    continue
                branch.warnings.append(f"fold inside a step of ds_min near {name} = "
                                       f"{base.params[name]:.6g}; labelled by its test function")
            event = _index_change(branch, step, base_point.index_direct, direct_new[0], opt)
            if event is not None:
                found.append(event)
        if _add_events(branch, step, found, opt, stops, user_values):
            return branch
        arclength += ds
        base_point = branch.add(new, arclength=arclength, ds=ds, niter=res.niter,
                                direct=direct_new)
        if progress is not None:
            progress(branch, res.lam)
        mesh = coarsen(new.s, res.extra["rms_residuals"], opt.tol, opt.ntst + 1)
        if res.niter == 1 and cos_turn > cos_grow:
            ds = min(ds * opt.growth, opt.ds_max)
        base, t, t_in, dist_in, exact = new, sec, sec, dist, False


@dataclass
class _Step:
    """An accepted step from a to b: unit secant, its length, arclength at a, and ds."""

    a: State
    b: State
    secant: Tangent
    dist: float
    arclength: float
    ds: float
    name: str

    def sigma(self, state: State) -> float:
        """Coordinate of a solution along the secant from a (0 at a, dist at b)."""
        d = Tangent(state.s, state.y - self.a(state.s), state.yp - self.a.derivative(state.s),
                    state.params[self.name] - self.a.params[self.name])
        return inner(d, self.secant, state.s)

    def position(self, sigma: float) -> float:
        """Pseudo-arclength of the point at coordinate sigma (for ordering the points)."""
        return self.arclength + self.ds * sigma / self.dist


@dataclass
class _Event:
    sigma: float
    kind: str
    state: State
    tangent: Tangent | None
    residual: float = float("nan")
    note: str = ""


def _secant_fold(branch: Branch, step: _Step, t_in: Tangent, dist_in: float,
                 opt: ContinuationOptions, simple: bool = True) -> _Event:
    """The fold near a, where the parameter components of the secants into and out of a
    differ in sign; an extended solve that fails gives an LP marked as not located.

    With ``simple = False`` (the direct index is the same on both sides) the turning point is
    labelled BP: where a pitchfork's bifurcating branch meets the branch it bifurcates from,
    the parameter turns back without any change of stability, and the fold rule must not
    apply. It is located where the parameter component of the true tangent vanishes; only if
    that fails is the (there singular) extended system tried, with a small mesh budget."""
    problem, name, a = branch.problem, branch.parameter, step.a
    if not simple:
        # the extended system is singular at a pitchfork: find where the parameter turns,
        # after a (along the step) or before it (back along the secant into a)
        reasons = []
        for direction, s0, s1 in ((step.secant, 0.0, step.dist), (t_in, -dist_in, 0.0)):
            state, sigma, lamdot = locate_turning_point(problem, a, direction, name, s0, s1,
                                                        opt.fold_tol, opt.max_nodes)
            if state is not None:
                return _Event(sigma, "BP", state, step.secant, abs(lamdot),
                              note="turning point without index change")
            reasons.append(sigma)
    kind = "LP" if simple else "BP"
    nodes = opt.max_nodes if simple else min(opt.max_nodes, 4 * len(a.s))
    res, offset = locate_fold(problem, a, t_in, step.secant, name, 2 * (dist_in + step.dist),
                              opt.fold_tol, nodes)
    if res.success:
        return _Event(offset, kind, res.state, _null_tangent(res, step.secant), res.residual,
                      note="" if simple else "turning point without index change")
    what = "fold" if simple else "turning point without index change (branch point)"
    why = res.message if simple else "; ".join(reasons + [res.message])
    branch.warnings.append(f"{what} near {name} = {a.params[name]:.6g} not located: {why}")
    return _Event(0.0, kind, a, t_in, note=f"{what} not located: {why}")


def _null_tangent(res, direction: Tangent) -> Tangent:
    """The fold's null vector as a tangent (phi, 0), oriented along ``direction``."""
    phi = res.extra["phi"]
    sign = 1.0 if inner(Tangent(phi.s, phi.y, phi.yp, 0.0), direction, phi.s) >= 0 else -1.0
    return Tangent(phi.s, sign * phi.y, sign * phi.yp, 0.0)


def _index_change(branch: Branch, step: _Step, index_a: int, index_b: int,
                  opt: ContinuationOptions) -> _Event | None:
    """The branch point between a and b, where the direct index changes and no fold is seen:
    the zero of the Jacobi-field test function along the step. (If its parameter lies beyond
    both ends after all, it is a fold that even a step of ds_min passes: labelled LP.)"""
    problem, name = branch.problem, branch.parameter
    a, b = step.a, step.b
    res, sigma, g = locate_branch_point(problem, a, step.secant, name, step.dist,
                                        opt.fold_tol, opt.max_nodes)
    if res is None:
        branch.warnings.append(f"index changes {index_a} -> {index_b} between {name} = "
                               f"{a.params[name]:.6g} and {b.params[name]:.6g} without a "
                               f"detected fold, and no singular point was located: {sigma}")
        return None
    lam = res.state.params[name]
    la, lb = a.params[name], b.params[name]
    if min(la, lb) <= lam <= max(la, lb):
        return _Event(sigma, "BP", res.state, step.secant, abs(g))
    return _Event(sigma, "LP", res.state, step.secant,
                  note="fold inside a step of ds_min, located by the test function only")


def _add_events(branch: Branch, step: _Step, found: list[_Event], opt: ContinuationOptions,
                stops: Stops, user_values) -> bool:
    """Add the LP/BP events ``found`` in the step and its UZ and bound EP points, in order;
    return True if the branch ends in this step.

    Folds inside the step split it: a value between the parameter at an end and at a fold is
    crossed on each side of the fold, and each crossing is solved from the two solutions that
    bracket it, so it cannot converge to the other side."""
    name = branch.parameter
    inside = sorted((e for e in found if e.kind == "LP" and 0.0 < e.sigma < step.dist),
                    key=lambda e: e.sigma)
    knots = [(0.0, step.a)] + [(e.sigma, e.state) for e in inside] + [(step.dist, step.b)]
    events = list(found)
    bound_hit = None
    for (s0, x), (s1, y) in zip(knots, knots[1:]):
        lx, ly = x.params[name], y.params[name]
        for spec in user_values:
            for c in crossings(lx, ly, spec):
                ev = _value_point(branch, step, x, y, s0, s1, c, "UZ", opt)
                if ev is not None:
                    events.append(ev)
        bound = stops.upper if lx <= stops.upper < ly else \
            stops.lower if ly < stops.lower <= lx else None
        if bound is not None:
            bound_hit = _value_point(branch, step, x, y, s0, s1, bound, "EP", opt)
            if bound_hit is None:
                bound_hit = _Event(s1, "EP", y, step.secant, note="bound not located")
            break
    if bound_hit is not None:
        events = [e for e in events if e.sigma < bound_hit.sigma] + [bound_hit]
    events.sort(key=lambda e: e.sigma)
    nfolds = len(branch.folds)
    for e in events:
        branch.add(e.state, type=e.kind, arclength=step.position(e.sigma), tangent=e.tangent,
                   fold_residual=e.residual, note=e.note)
        if e.kind == "LP":
            nfolds += 1
            if stops.at_fold is not None and nfolds >= stops.at_fold:
                # The fold may lie before the last accepted point: the branch ends at it.
                cut = step.position(e.sigma)
                branch.points[:] = [p for p in branch.points if p.arclength <= cut]
                branch.end, branch.message = "LP", f"stopped at fold {nfolds} (stop = LP{nfolds})"
                return True
        if e.kind == "EP":
            branch.end = "EP"
            branch.message = f"reached {name} = {e.state.params[name]:g}"
            return True
    return False


def _value_point(branch: Branch, step: _Step, x: State, y: State, s0: float, s1: float,
                 value: float, kind: str, opt: ContinuationOptions) -> _Event | None:
    """The solution with the continued parameter equal to ``value`` between the solutions x
    and y (secant coordinates s0 < s1) of one step: solved from their interpolation, checked to
    lie between them, else found by bisection along the arclength hyperplanes."""
    problem, name = branch.problem, branch.parameter
    res, _ = locate_value(problem, x, y, name, value, opt.tol, opt.max_nodes)
    margin = 0.05 * (s1 - s0) + 1e-12
    if res.success:
        sigma = step.sigma(res.state)
        if s0 - margin <= sigma <= s1 + margin:
            return _Event(min(max(sigma, s0), s1), kind, res.state, step.secant)
    res, sigma = locate_value_on_step(problem, step.a, step.secant, name, value, s0, s1,
                                      opt.tol, opt.max_nodes)
    if res is None:
        branch.warnings.append(f"{'user point' if kind == 'UZ' else 'bound'} {name} = "
                               f"{value:.6g} not located: {sigma}")
        return None
    return _Event(sigma, kind, res.state, step.secant)
