"""Snap-back targets: where a stable branch ends, which stable equilibria remain?

At an LP next to an index-0 segment a stable equilibrium stops existing as the parameter moves
past the fold value, and the structure snaps to another stable equilibrium at the same
parameter values. At a BP next to an index-0 segment the equilibrium goes on existing but
loses its stability; the structure snaps there too if the branches born at the BP are
unstable (a subcritical pitchfork: they exist on the stable side), and follows them if one is
stable (supercritical: no snap). `subcritical` decides it from a few points of each born
branch. The candidates are *all* the equilibria there, as the shooting scan of
`elastica_auto.analysis.equilibria` finds them. Each target records whether a computed branch
of the same file passes through it, and its profile on the branch files' fixed grid (for
drawing the configuration after the snap).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from ..branches.branch import PROFILE_GRID, Branch
from ..core import labels
from ..core.options import ContinuationOptions
from ..core.solution import State
from ..core.values import same_value
from .equilibria import (Equilibrium, beyond_fold, enumerate_equilibria, snap_lps,
                         stable_side)

#: The points of each branch born at a BP that `subcritical` computes (its start included).
BORN_POINTS = 4


#: What `mark_subcritical` says in a BP's note, by its decision. The notes are stored: a
#: branch read back from a file has its decisions from them (`read_subcritical`).
SAID = {True: "subcritical: the branches born here are unstable (a snap)",
        False: "supercritical: a stable branch is born here (no snap)",
        None: "born branches not found (no snap reported)"}


def subcritical(problem, branch, point) -> bool | None:
    """Whether the branch point ``point`` of ``branch`` is subcritical: both branches born
    there (the two orientations of the other direction, `branches.switching`) have index > 0
    at each of their first BORN_POINTS - 1 points past the BP; False if one of those points
    is stable; None if the BP has no second direction or a born branch has no counted point
    (nothing decided: no snap is reported). The born branches are continued with
    ``branch``'s own options and no event located: the index at each point is its direct
    count."""
    from ..branches.stepper import Course, Origin, continue_branch
    from ..branches.switching import switch_direction
    name = branch.parameter
    options = dataclasses.replace(ContinuationOptions(**branch.options), max_points=BORN_POINTS)
    direction = switch_direction(problem, point.state, point.tangent, name, options)
    if direction is None:
        return None
    for d in (1, -1):
        born = Branch.of(problem, name, d, f"switch at {point.name}", options.to_dict(),
                         singular_start=True)
        continue_branch(born, problem, Course(name, options, events=False),
                        Origin(point.state, direction.scaled(d), "switch"))
        counted = [q.index_direct for q in born.points[1:] if q.index_direct >= 0]
        if not counted:
            return None
        if min(counted) == 0:
            return False
    return True


def _stable_side(branch, k: int) -> str | None:
    """'before' or 'after': the side of point ``k`` of ``branch`` with index 0, where the
    other side's index is positive; None if the point bounds no stable segment."""
    return stable_side(branch.points[k - 1].index, branch.points[k + 1].index)


def mark_subcritical(problem, branch) -> None:
    """Decide `subcritical` at each BP of ``branch`` that bounds a stable segment (index 0 on
    one side, positive on the other): set the point's ``subcritical`` and say it in its
    note. A failure of the module there leaves it undecided, with the reason in the note.
    A BP whose solution is that of one decided before, its parameters the same up to whole
    periods of the continued one (the translates of a periodic branch's first period,
    `branches.stepper`), gets the same decision: its born branches are those translated."""
    pts = branch.points
    decided = []    # (scan key, solution values, decision, note) of the BPs decided here
    for k, p in enumerate(pts):
        if p.type not in labels.SWITCHES or k == 0 or k + 1 >= len(pts) or p.tangent is None \
                or _stable_side(branch, k) is None:
            continue
        key = scan_key(problem, branch.parameter, p.params)
        same = next((d for d in decided if d[0] == key and np.array_equal(d[1], p.state.y)),
                    None)
        if same is not None:
            p.subcritical, said = same[2], same[3]
        else:
            try:
                p.subcritical = subcritical(problem, branch, p)
                said = SAID[p.subcritical]
            except (Exception, SystemExit) as exc:  # the module failing on a born branch
                said = f"born branches failed ({type(exc).__name__}: {exc}); no snap reported"
            decided.append((key, p.state.y, p.subcritical, said))
        p.note = "; ".join(filter(None, (p.note, said)))


def read_subcritical(branch) -> None:
    """Set ``subcritical`` at each BP of ``branch``, a branch read back from a file, as
    `mark_subcritical` decided it when the branch was computed: from what it said in the
    point's note (SAID; its parts are joined by "; "), None where it said neither."""
    for p in branch.points:
        if p.type in labels.SWITCHES:
            said = p.note.split("; ")
            p.subcritical = True if SAID[True] in said else False if SAID[False] in said \
                else None


def snap_points(branch) -> list[tuple]:
    """Where ``branch``'s stable segments end with a snap, in order along it: (point, stable
    side 'before'/'after') for its LPs (`snap_lps`) and its BPs marked subcritical
    (`mark_subcritical`) that bound an index-0 segment."""
    pts = branch.points
    out = list(snap_lps(branch)) + [
        (p, _stable_side(branch, k)) for k, p in enumerate(pts)
        if p.type in labels.SWITCHES and p.subcritical and 0 < k < len(pts) - 1]
    where = {id(p): k for k, p in enumerate(pts)}     # (not pts.index: it compares fields)
    return sorted(out, key=lambda pair: where[id(pair[0])])


def k_columns(k) -> dict:
    """A target's shooting value as columns of the snap-back table: ``k``, and for d >= 2
    unknowns ``k`` (the first), ``k_2``, ..., ``k_d``."""
    if np.ndim(k) == 0:
        return {"k": k}
    return {"k": k[0], **{f"k_{j}": v for j, v in enumerate(k[1:], start=2)}}


def _on_branch(tracks: "_Tracks", parameter, period, target: Equilibrium, tol=0.02):
    """Number (1-based) of a branch with the target's fixed parameters that passes through the
    target, or 0: the branch, interpolated at the target's parameter value (modulo the
    period), has the target's ordinates within ``tol`` (relative). Ordinates are physical, so
    they match on every periodic copy of a solution, whose states may differ by 2 pi."""
    value = target.state.params[parameter]
    want = np.array(list(target.ordinates.values()))
    for nb, (name, fixed, lam) in enumerate(tracks.branches(), start=1):
        if name != parameter or not all(same_value(v, target.state.params[q])
                                        for q, v in fixed.items()):
            continue
        if period:
            lam = value + np.remainder(lam - value + period / 2, period) - period / 2
        ords = tracks.ordinates(nb, tuple(target.ordinates))
        for i in np.flatnonzero((lam[:-1] - value) * (lam[1:] - value) <= 0):
            if lam[i + 1] == lam[i] or abs(lam[i + 1] - lam[i]) > (period or np.inf) / 2:
                continue
            w = (value - lam[i]) / (lam[i + 1] - lam[i])
            got = (1 - w) * ords[i] + w * ords[i + 1]
            if np.max(np.abs(got - want)) < tol * (1 + np.max(np.abs(want))):
                return nb
    return 0


class _Tracks:
    """What `_on_branch` compares each target with, made once per table (it was made again
    for every target: every parameter's column of every branch, 0.2 s of `rotating_arm_3d`'s
    60 targets): per branch its parameter, the parameters fixed along it (on a path, others
    move with the path's) with their values, and its parameter's column; its ordinates
    (points, names) when first asked for."""

    def __init__(self, branches):
        self._branches, self._made, self._ordinates = branches, None, {}

    def branches(self) -> list[tuple]:
        if self._made is None:
            self._made = []
            for br in self._branches:
                p0 = br.points[0].params
                fixed = {q: p0[q] for q in p0
                         if q != br.parameter and np.ptp(br.column(q)) == 0}
                self._made.append((br.parameter, fixed, br.column(br.parameter)))
        return self._made

    def ordinates(self, nb: int, names: tuple) -> np.ndarray:
        if (nb, names) not in self._ordinates:
            self._ordinates[nb, names] = np.array(
                [[p.ordinates[o] for o in names] for p in self._branches[nb - 1].points])
        return self._ordinates[nb, names]


def scan_key(problem, parameter: str, params: dict) -> tuple:
    """The key of the enumeration at ``params``: the parameters rounded to 10 digits, the
    continued one modulo its period (periodic copies of a fold have the same equilibria)."""
    period = problem.parameters[parameter].period
    return tuple(sorted((q, round(v if q != parameter or not period
                                  else float(np.remainder(v, period)), 10))
                        for q, v in params.items()))


def own_key(params: dict) -> tuple:
    """The key of the enumeration at exactly ``params`` (to 10 digits)."""
    return tuple(sorted((q, round(v, 10)) for q, v in params.items()))


def copy_key(problem, parameter: str, params: dict) -> tuple:
    """`own_key` of ``params`` with ``parameter`` taken modulo its period where a period
    leaves the states as they are (no ``period_shift`` or ``period_flip``): the enumerations
    at such copies are the same, states included (a clamp turned by 2 pi is not such a
    copy: its quaternion changes sign)."""
    q = problem.parameters[parameter]
    if q.period and not q.period_shift and not q.period_flip:
        params = {**params, parameter: float(np.remainder(params[parameter], q.period))}
    return own_key(params)


def mirror_key(problem, parameter: str, params: dict) -> tuple | None:
    """`copy_key` of the mirror image of ``params`` (the module's ``MIRROR``, where it says
    how the shooting unknowns turn), or None."""
    mirror = problem.mirror
    if mirror is None or not mirror[2].shooting:
        return None
    return copy_key(problem, parameter, problem.mirrored(np.zeros((problem.n, 0)), params)[1])


def mirrored_scan(problem, parameter: str, params: dict,
                  copies: dict) -> list[Equilibrium] | None:
    """The equilibria at ``params`` as the mirror images of those enumerated at the image of
    ``params`` or at a copy of it (``copies``: `copy_key` -> `enumerate_equilibria` there),
    in the order `enumerate_equilibria` gives them; None if that enumeration is not there,
    or if an image's initial values are not those of its shooting unknowns turned by the
    declared signs (then the scan is computed). Each image: the state turned, the ordinates
    negated as declared, the same index (`elastica_auto.branches.mirror`)."""
    key = mirror_key(problem, parameter, params)
    there = copies.get(key) if key is not None else None
    if there is None:
        return None
    _, _, mirror = problem.mirror
    signs = np.array(mirror.shooting)
    _, _, initial, _ = problem.shooting(params)
    out = []
    for eq in there:
        k = signs * np.atleast_1d(eq.k)
        y, _ = problem.mirrored(eq.state.y, {})
        yp, _ = problem.mirrored(eq.state.yp, {})
        y0 = np.asarray(initial(k if len(k) == 1 else k[:, None]), dtype=float)[:, 0]
        if np.max(np.abs(y0 - y[:, 0])) > 1e-12 * (1.0 + np.max(np.abs(y[:, 0]))):
            return None
        ordinates = problem.mirrored_ordinates(eq.ordinates)
        out.append(Equilibrium(float(k[0]) if np.ndim(eq.k) == 0 else tuple(map(float, k)),
                               State(eq.state.s, y, yp, params), eq.index, ordinates))
    return sorted(out, key=lambda eq: eq.k)


def scans(problem, branch) -> dict[tuple, dict]:
    """The enumerations `snap_targets` needs for ``branch``: key (`scan_key`) -> the
    parameters to enumerate at (those of the first fold with that key), one per key."""
    if not (problem.has_shooting and problem.has_second_variation):
        return {}
    out = {}
    for p, _ in snap_points(branch):
        out.setdefault(scan_key(problem, branch.parameter, p.params), dict(p.params))
    return out


def snap_targets(problem, branches, warnings: list | None = None,
                 landing: bool = False, cache: dict | None = None,
                 mapper: Callable | None = None, mirror: bool = True,
                 failures: list | None = None) -> list[dict]:
    """Rows: for every LP, and every subcritical BP, bounding a stable segment
    (`snap_points`), every stable equilibrium at its parameter values (excluding the point's
    own solution), with the branch that passes through it.

    With ``landing`` (and the module's ``gradient_flow`` hook), the row of the equilibrium
    the rod's overdamped dynamics reach from the fold (`elastica_auto.analysis.landing`) has
    ``landed = 1`` and the energy released and transit time; the other rows ``landed = 0``
    and NaN. A fold whose dynamics fail, or end at none of them, has ``landed = 0`` on
    every row, and ``warnings`` (a list) gets a line saying why (a failure is also added to
    ``failures``, if given). The landings are tasks (`landing.landing_task`), computed by
    ``mapper`` as `landing.damping_sweep`'s are (default here, one after the other).

    ``cache``: enumerations computed already (elsewhere: on a cluster's workers, as the
    branches came in), key (`scan_key`) -> (parameters, `enumerate_equilibria` there); one
    is used where its parameters are those of the first fold with its key (of a periodic
    parameter, another copy's differ by a period, and so may its equilibria's states), and
    the others are computed here: the rows are the same whoever computed them.

    ``mirror``: the enumeration at the mirror image of parameters enumerated already, or of
    a copy of them by a period that leaves the states as they are (`copy_key`), is made from
    that one (`mirrored_scan`) rather than computed (the run's option ``mirror``)."""
    if not (problem.has_shooting and problem.has_second_variation):
        return []
    from .landing import landing_task, one_by_one
    warnings = warnings if warnings is not None else []
    landing = landing and problem.has_gradient_flow
    given, cache, exact, copies = cache or {}, {}, {}, {}
    folds, tasks, where = [], [], {}
    for nb, br in enumerate(branches, start=1):
        name = br.parameter
        for p, side in snap_points(br):
            params = dict(p.params)
            key = scan_key(problem, name, params)
            own = own_key(params)
            if key not in cache:
                there = given.get(key)
                cache[key] = exact[own] = copies[copy_key(problem, name, params)] = (
                    there[1] if there is not None and there[0] == params
                    else mirror and mirrored_scan(problem, name, params, copies)
                    or enumerate_equilibria(problem, params))
            at = None
            if landing and p.type in labels.SWITCHES:
                warnings.append(f"{p.name}: no landing from a branch point (the dynamics "
                                "start from folds)")
            elif landing:
                beyond = beyond_fold(br, p, side)
                # periodic copies of a fold land alike: the same parameters (mod the period)
                # and the same initial values y(0), hence the same solution
                at = (key, beyond, tuple(np.round(p.state.y[:, 0], 8)))
                if at not in where:
                    # the dynamics' end is compared with equilibria at the fold's own
                    # parameters: a periodic copy of the cached ones (a parameter moved by
                    # its period) may differ from them by a period in the states (theta0)
                    if own not in exact:
                        exact[own] = enumerate_equilibria(problem, params)
                    where[at] = (len(tasks), p.name, own)
                    tasks.append((problem, p.state, p.tangent, exact[own], name, beyond, None))
            folds.append((nb, br, p, side, params, key, own, at))
    ends = (mapper or one_by_one)(landing_task, tasks, lambda i, result: None)
    landings = {}
    for at, (i, lp, own) in where.items():
        landings[at] = _landed(ends[i], lp, warnings, failures)
        if landings[at] is not None and landings[at].target is not None:
            # the same equilibrium in the cached list: by its ordinates, which are physical
            # and so the same on every periodic copy
            hit = exact[own][landings[at].target].ordinates
            landings[at].target = int(np.argmin(
                [max(abs(eq.ordinates[o] - v) for o, v in hit.items())
                 for eq in cache[at[0]]]))
    rows, rescans, tracks = [], {}, _Tracks(branches)
    for nb, br, p, side, params, key, exact_key, at in folds:
        name = br.parameter
        period = problem.parameters[name].period
        reached = landings.get(at)
        k_fold = p.state.y[:, 0]

        def own(eq):
            """The point's own (at a fold vanishing, numerically a near-double) root."""
            return np.max(np.abs(eq.state.y[:, 0] - k_fold)) < 1e-3 * (1 + np.max(np.abs(k_fold)))

        there = cache[key]
        if p.type in labels.SWITCHES and not any(own(eq) for eq in there):
            # a branch point's solution is a root of the scan at its parameters; the cached
            # scan of a periodic copy may give it other states (a clamp turned by 2 pi has
            # the opposite quaternion), so that the states above do not find it: scan here
            if exact_key not in rescans:
                rescans[exact_key] = enumerate_equilibria(problem, params)
            there = rescans[exact_key]
        for j, eq in enumerate(there):
            if eq.index != 0:
                continue
            shifted = State(eq.state.s, eq.state.y, eq.state.yp, params)
            if own(eq):
                continue
            target = Equilibrium(eq.k, shifted, eq.index, eq.ordinates)
            row = {"lp": p.name, "branch": nb, "parameter": name,
                   "value": params[name], "stable_side": side, **k_columns(eq.k),
                   "index": eq.index, **{f"target_{o}": v
                                         for o, v in eq.ordinates.items()},
                   "on_branch": _on_branch(tracks, name, period, target)}
            if landing:
                here = reached is not None and reached.target == j
                row.update(landed=int(here),
                           energy_released=reached.energy_released if here else np.nan,
                           transit_time=reached.transit_time if here else np.nan)
            rows.append({**row, "profile": eq.state(PROFILE_GRID)})
    return rows


def _landed(end, lp: str, warnings: list, failures: list | None = None):
    """A fold's landing (`landing.landing_task`'s result), or None with a line in
    ``warnings`` (and the failure in ``failures``, if given): a failure of the module's
    dynamics costs the fold its landing, not the run its snap-back table."""
    if isinstance(end, dict):
        warnings.append(f"{lp}: the dynamics from the fold failed: {end['message']}")
        if failures is not None:
            failures.append({**end, "message": warnings[-1]})
        return None
    if end.target is None:
        warnings.append(f"{lp}: the dynamics from the fold ended at no enumerated "
                        f"stable equilibrium (the nearest is {end.distance:.3g} away)")
    return end
