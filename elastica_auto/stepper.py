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

import numpy as np

from .branch import Branch
from .corrector import (State, Tangent, coarsen, inner, secant, solve_arclength,
                        solve_tangent)
from .events import UserValues, crossings, locate_branch_point, locate_fold, locate_value
from .stability import direct_index
from .options import ContinuationOptions


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
                    singular_start: bool = False) -> Branch:
    """Continue ``start`` in ``branch.parameter`` in ``branch.direction``; fills ``branch``.

    ``singular_start``: the start is a branch point and ``start_tangent`` the (already
    oriented) direction of the branch to follow; it is used as it is, and no fold or branch
    point is sought in the first step, where the start's own singularity would be found.
    Points are appended as they are accepted, so an interrupted call leaves every completed
    point in ``branch``.
    """
    problem, name, opt = branch.problem, branch.parameter, options
    if singular_start:
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
    dist_in = abs(opt.ds)
    exact = True        # t is the true tangent at base, not a secant
    mesh = start.s
    cos_max, cos_grow = math.cos(opt.max_angle), math.cos(opt.max_angle / 2)
    history = []
    # A change of the direct index between two points with no fold near either is a branch
    # point; it is located one step later, once a fold just after the second point is ruled out.
    pending = None

    def end_at_base(kind):
        if base_point.type:
            branch.add(base, type=kind, arclength=arclength, tangent=t)
        else:
            branch.relabel(base_point, kind, base, t)

    while True:
        if len(branch.points) >= opt.max_points:
            if pending is not None:
                _branch_point(branch, *pending, opt)
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
                if pending is not None:
                    _branch_point(branch, *pending, opt)
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
        direct_new = direct_index(problem, new)
        fold_here = t_in.lam * sec.lam < 0
        if pending is not None and not fold_here:
            _branch_point(branch, *pending, opt)
        pending = None
        if (not fold_here and direct_new[0] >= 0 and not (singular_start and base is start)
                and direct_new[0] != base_point.index_direct):
            pending = (base, new, sec, dist, arclength, base_point.index_direct, direct_new[0])
        stop = _events(branch, base, new, t_in, sec, dist_in, dist, arclength, ds, opt, stops,
                       user_values)
        if stop:
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


def _branch_point(branch: Branch, a: State, b: State, t_out: Tangent, dist: float,
                  arclength: float, index_a: int, index_b: int, opt: ContinuationOptions):
    """Locate and add the branch point between a and b, where the direct index changes with no
    fold: the zero of the Jacobi-field test function along the arclength hyperplanes from a."""
    res, sigma, g = locate_branch_point(branch.problem, a, t_out, branch.parameter, dist,
                                        opt.fold_tol, opt.max_nodes)
    name = branch.parameter
    if res is None:
        branch.warnings.append(f"index changes {index_a} -> {index_b} between {name} = "
                               f"{a.params[name]:.6g} and {b.params[name]:.6g} without a fold, "
                               f"but no branch point was located: {sigma}")
        return
    branch.add(res.state, type="BP", arclength=arclength + sigma, tangent=t_out,
               fold_residual=abs(g))


def _events(branch: Branch, a: State, b: State, t_in: Tangent, t_out: Tangent, dist_in: float,
            dist: float, arclength: float, ds: float, opt: ContinuationOptions, stops: Stops,
            user_values) -> bool:
    """Add the LP, UZ and bound EP points between accepted points a and b (in order of
    arclength); return True if the branch ends here. ``t_in`` and ``dist_in`` are the unit
    secant into a and its length, ``t_out`` and ``dist`` those from a to b."""
    problem, name = branch.problem, branch.parameter
    la, lb = a.params[name], b.params[name]
    found = []
    if t_in.lam * t_out.lam < 0:
        res, offset = locate_fold(problem, a, t_in, t_out, name, 2 * (dist_in + dist),
                                  opt.fold_tol, opt.max_nodes)
        if res.success:
            phi = res.extra["phi"]
            sign = 1.0 if inner(Tangent(phi.s, phi.y, phi.yp, 0.0), t_out, phi.s) >= 0 else -1.0
            null = Tangent(phi.s, sign * phi.y, sign * phi.yp, 0.0)
            found.append((offset, "LP", res.state, res.residual, "", null))
        else:
            found.append((0.0, "LP", a, float("nan"), f"fold not located: {res.message}", t_in))
            branch.warnings.append(f"fold near {name} = {la:.6g} not located: {res.message}")
    for spec in user_values:
        for c in crossings(la, lb, spec):
            res, w = locate_value(problem, a, b, name, c, opt.tol, opt.max_nodes)
            if res.success:
                found.append((w * ds, "UZ", res.state, float("nan"), "", t_out))
            else:
                branch.warnings.append(f"user point {name} = {c:.6g} not located: {res.message}")
    bound = stops.upper if lb > stops.upper else stops.lower if lb < stops.lower else None
    if bound is not None:
        res, w = locate_value(problem, a, b, name, bound, opt.tol, opt.max_nodes)
        end_state = res.state if res.success else b
        found = [f for f in found if f[0] < w * ds]
        found.append((w * ds, "EP", end_state, float("nan"), "" if res.success else
                      f"bound not located: {res.message}", t_out))
    found.sort(key=lambda f: f[0])
    nfolds = len(branch.folds)
    for offset, kind, state, residual, note, tangent in found:
        branch.add(state, type=kind, arclength=arclength + offset, tangent=tangent,
                   fold_residual=residual, note=note)
        if kind == "LP":
            nfolds += 1
            if stops.at_fold is not None and nfolds >= stops.at_fold:
                # The fold may lie just before the last accepted point: the branch ends at it.
                cut = arclength + offset
                branch.points[:] = [p for p in branch.points if p.arclength <= cut]
                branch.end, branch.message = "LP", f"stopped at fold {nfolds} (stop = LP{nfolds})"
                return True
        if kind == "EP":
            branch.end, branch.message = "EP", f"reached {name} = {bound:g}"
            return True
    return False
