"""Restarts from stored labels: the stored solution checked, its states matched by name, and
carried to changed parameter values by continuation.

A stored solution becomes a start only once it is checked to solve its problem
(:func:`check_stored`): a label read from a damaged or edited file would otherwise start a
branch that is not one. Its states are those of the run that found it; a restart whose
problem has other free parameters (or the same in another order) gets them by name
(:func:`by_name`).

A restart from a label at new values of some of its parameters needs the solution at those
values. A Newton solve at the new, fixed values fails where a restart is most wanted: its
Jacobian is singular at a fold (LP), a branch point (BP) or a cusp (CP), and nearly so near
one. :func:`move` continues instead, in each changed parameter in turn, from the solution
so far to the parameter's new value, with the other parameters held at their current values:
the engine's own pseudo-arclength loop (`branches.stepper.continue_branch`), bounded by
the current and the new value, so that a branch that gets there ends (EP) exactly at it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .branch import Branch, StoredLabel
from ..numerics.collocation import Discretisation
from ..numerics.correctors import CorrectorFailure, make_corrector
from ..numerics.newton import NEWTON_TOL
from ..core import labels
from ..core.errors import PlanError, StartError
from ..core.options import ContinuationOptions, OptionsError
from ..core.solution import State, Tangent
from .stepper import STATIONARY, Course, Origin, Stops, continue_branch


def _constant(state: State, row: int, label: StoredLabel, name: str) -> float:
    """The value of the state ``row`` of ``state``, which must be constant along s (to the
    rounding of a continuation's solution, relative): a parameter held as a state."""
    values = state.y[row]
    if np.max(np.abs(values - values[0])) > 1e-8 * (1.0 + abs(values[0])):
        raise PlanError("start", f"{label.name}: its state {name!r} is not constant along s, "
                        f"so it is no value of the free parameter {name!r}")
    return float(values[0])


def by_name(problem, label: StoredLabel) -> StoredLabel:
    """``label`` with its solution's rows in the order of ``problem.states``, matched by name.

    A label found with other free parameters than ``problem``'s (their states ``free:NAME``),
    or with the same in another order, holds them in its own order: taken by position, a
    parameter would start at another's value. Each state of ``problem`` is the label's state
    of that name; a free parameter of ``problem`` that the label has no state for (one held
    fixed where it was found) is its stored value, constant along s (its derivative 0), and
    a free parameter of the label that ``problem`` holds fixed keeps its stored value among
    the parameters; a free parameter that the label holds as a state of its own name,
    constant along s (a module that carried it as a state: elastica_pinned's reaction before
    0.2), is that constant. The tangent goes along where the states are the same ones reordered;
    else it is dropped (another problem's tangent). PlanError (``start``) if a state cannot be
    matched: a free parameter without a stored value, or a state of another name."""
    names, have = tuple(problem.states), tuple(label.states)
    if not have or have == names:
        return label
    rows = {name: i for i, name in enumerate(have)}
    state, pick, params = label.state, [], dict(label.state.params)
    for name in names:
        if name in rows:
            pick.append(rows[name])
        elif name.startswith("free:") and name[5:] in problem.parameters:
            value = state.params.get(name[5:])
            if value is None and name[5:] in rows:
                value = _constant(state, rows[name[5:]], label, name[5:])
            if value is None:
                raise PlanError("start", f"{label.name}: no stored value for the free "
                                f"parameter {name[5:]!r} (its states: {', '.join(have)})")
            pick.append(float(value))
            params[name[5:]] = float(value)
        else:
            raise PlanError("start", f"{label.name} has no state {name!r} "
                            f"(its states: {', '.join(have)}; {problem.source}'s: "
                            f"{', '.join(names)})")
    m = len(state.s)

    def rows_of(y, derivative):
        return np.array([y[k] if isinstance(k, int) else
                         np.full(m, 0.0 if derivative else k) for k in pick])

    moved = State(state.s, rows_of(state.y, False), rows_of(state.yp, True), params)
    tangent, t = None, label.tangent
    if t is not None and sorted(have) == sorted(names):
        order = [rows[name] for name in names]
        tangent = Tangent(t.s, t.y[order], t.yp[order], t.lam)
    return dataclasses.replace(label, state=moved, tangent=tangent,
                               tangent_parameter=label.tangent_parameter if tangent else None,
                               states=names)


def check_stored(problem, label: StoredLabel, parameter: str, options: ContinuationOptions,
                 where: str):
    """StartError unless the stored solution of ``label`` solves ``problem``: it must converge
    to itself when it is solved again at its own parameters.

    Newton on the label's own mesh, by the discretisation that computed it (its stored
    options' ``ncol`` and ``corrector``; ``options``'s where not stored), from the solution
    itself, with its parameters fixed; where a tangent is stored, on the hyperplane through
    the solution normal to it instead (its parameter free): at a fold the parameter cannot
    be held fixed. The solution passes if Newton converges and moves it by less than the
    tolerance ``tol`` that computed it (Newton's own scaled measure, max |dy| / (1 + |y|)
    and the same for the parameter): a solution solves its equations to about NEWTON_TOL,
    far below ``tol``; a damaged or edited one is moved by its damage (the report's kappa
    shifted by 0.3: by 0.29). ``parameter`` is the one Newton solves for where no tangent
    is stored."""
    state, tangent = label.state, label.tangent
    own = _own_options(options, label.options)
    why = _not_a_mesh(state)
    if why is None:
        name = (label.tangent_parameter if tangent is not None
                and label.tangent_parameter in problem.parameters else parameter)
        corrector = make_corrector(problem, name, own)
        lam = float(state.params[name])
        normal = tangent if name == label.tangent_parameter else None
        res = corrector.solve_again(state, normal, min(NEWTON_TOL, 1e-3 * own.tol))
        moved = max(float(np.max(np.abs(res.Y - state.y) / (1.0 + np.abs(state.y)))),
                    abs(res.lam - lam) / (1.0 + abs(lam)))
        if not res.converged:
            # where the linearisation is singular whatever the border (a branch point: its
            # kernel has two dimensions) Newton cannot converge from a solution either: the
            # equations' residual there is what tells a solution from one that is not
            why = _residual_too_large(res, own.tol)
        elif not moved < own.tol:
            why = (f"solved again, it moves by {moved:.3g} (its tolerance: {own.tol:g}), "
                   f"{_where_most(res.Y - state.y, state.y, label.states)}")
    if why is not None:
        raise StartError(f"{where}: the stored solution of {label.name} does not solve the "
                         f"problem: {why}")


def _residual_too_large(res, tol: float) -> str | None:
    """Why the residual of the discretised equations at the state Newton started from says it
    is not a solution (``res``: the corrector's `solve_again` that did not converge, with
    that residual: each collocation residual relative to 1 + |y| at its interval's first
    node, each boundary residual relative to 1 + max |y|), or None: at most ``tol`` (a
    solution's are of the order of Newton's tolerance, an edited one's of its edit over the
    mesh's step)."""
    if res.residual <= tol:
        return None
    return (f"Newton from it does not converge ({res.message}), and the residual of its "
            f"equations is {res.residual:.3g} (its tolerance: {tol:g})")


def _own_options(options: ContinuationOptions, stored: dict) -> ContinuationOptions:
    """``options`` with the discretisation and tolerance of the run that computed a label
    (its ``stored`` options), where they are valid ones."""
    keys = ("tol", "ncol", "corrector")
    try:
        return dataclasses.replace(options, **{k: stored[k] for k in keys if k in stored})
    except (OptionsError, TypeError, ValueError):
        return options


def _not_a_mesh(state: State) -> str | None:
    """Why ``state`` is not a solution on a mesh of [0, 1] (None if it is one): its nodes
    must increase from 0 to 1 and its values be finite."""
    s = np.asarray(state.s)
    if s.ndim != 1 or len(s) < 2 or s[0] != 0.0 or s[-1] != 1.0 \
            or not np.all(np.diff(s) > 0):
        return "its mesh is not one of [0, 1]"
    if not (np.all(np.isfinite(state.y)) and np.all(np.isfinite(state.yp))
            and all(math.isfinite(v) for v in state.params.values())):
        return "it holds values that are not finite"
    return None


def _where_most(dy: np.ndarray, y: np.ndarray, names) -> str:
    """"most in STATE": the state that the solve moved most (relative to 1 + |y|)."""
    k = int(np.argmax(np.max(np.abs(dy) / (1.0 + np.abs(y)), axis=1)))
    return f"most in {names[k] if k < len(names) else f'state {k + 1}'}"

def move(problem, origin: Origin, targets: dict[str, float], options: ContinuationOptions, *,
         tangent_parameter: str | None = None, where: str = "") -> State:
    """The solution of ``problem`` at the parameter values ``targets``, continued from
    ``origin``.

    Each parameter of ``targets`` (in their order) is continued from its current value to
    its target, the others held fixed, and the branch that ends exactly at the target gives
    the solution from which the next parameter is continued.

    Parameters
    ----------
    problem
        The problem the start solves (the plan's, free parameters included).
    origin : Origin
        The labelled solution, its stored tangent (or None), and its kind: ``"singular"``
        if it is a fold, branch point or cusp (an LP, BP or CP label), where the first
        continuation does not look for its own singularity in its first step; else
        ``"regular"``.
    targets : dict
        The new values, by parameter (not free ones: those are solved for).
    options : ContinuationOptions
        Step control and accuracy of the continuations (the run's own; ``max_points``, the
        size of the branch to compute, at least its default; from a singular start, no
        mesh coarser than the start's).
    tangent_parameter
        The parameter the stored tangent belongs to: it orients the first continuation if
        that is in the same parameter.
    where : str
        The start, as error messages name it.

    Returns
    -------
    State
        The solution, at exactly the ``targets`` values.

    Raises
    ------
    StartError
        A target not reached: which parameter, its target, and where its continuation
        stopped and why (it turned back at a fold, failed, ...).

    Notes
    -----
    From a start where the parameter is stationary (the label's singular kind, or a tangent
    whose parameter component is at most STATIONARY) the way the parameter moves is not
    decided by the parameter, so both directions are continued; if both reach the target,
    the shorter branch (in arclength) wins, the solution nearest the start, and on a tie
    direction + (along the stored tangent). From any other start only the direction toward
    the target is continued: the other ends at once at the current value, which bounds it.

    A parameter with a period is continued to the translate of its target (by whole periods)
    nearest its current value, at most half a period away: the solution set repeats with the
    period, and a restart at ``psi + 2 pi`` is the label's own solution, which a continuation
    over a whole period, through its folds, need not reach. The solution at the targets
    themselves is then solved for by Newton from the one continued to their translates (its
    translate: the same solution where the parameter enters periodically).
    """
    start, singular = origin.state, origin.kind == "singular"
    options = _move_options(options, start, singular)
    near = {q: _nearest_translate(problem, q, v, start.params[q]) for q, v in targets.items()}
    state, moved = start, []
    for q, value in near.items():
        if value == state.params[q]:
            continue
        first = not moved
        start_here = Origin(state, origin.tangent if first and q == tangent_parameter else None,
                            "singular" if singular and first else "regular", origin.ncol)
        state = _reached(problem, start_here, q, value, targets[q], options, where, moved)
        moved.append((q, value))
    if near == targets:
        return state
    return _from_translate(problem, state, targets, near, options, where)


def _move_options(options: ContinuationOptions, start: State,
                  singular: bool) -> ContinuationOptions:
    """The options of `move`'s continuations: ``max_points`` at least its default, and from
    a singular start, no mesh coarser than the start's."""
    # a short max_points asks for a short branch, not for a start that cannot be reached
    options = dataclasses.replace(
        options, max_points=max(options.max_points, ContinuationOptions.max_points))
    if singular:
        # a fold moves between meshes of tol by as much as a small move from it (1e-7): the
        # moves keep at least the label's mesh (its fold located to fold_tol) by not
        # coarsening below it (a tighter tol would ask Newton for more than the conditioning
        # near a cusp allows)
        options = dataclasses.replace(options, ntst=min(max(options.ntst, len(start.s) - 1),
                                                        options.max_nodes - 1))
    return options


def _from_translate(problem, state: State, targets: dict[str, float], near: dict[str, float],
                    options: ContinuationOptions, where: str) -> State:
    """The solution at ``targets`` from ``state``, the one `move` continued to their
    translates ``near`` (by whole periods): the same solution where the parameters enter
    periodically, so one Newton solve (or none, if ``state`` already solves there)."""
    # whole periods commute with the moves: one solve at the end, from a moved (regular) state
    params = {**state.params, **targets}
    if _solves(problem, state, params):  # Newton would not start at a fold's own translate
        return State(state.s, state.y, problem.rhs(state.s, state.y, params),
                     problem.point_params(params, state.y))
    q = next(iter(targets))
    try:
        return make_corrector(problem, q, options).at_value(state, params, params[q])
    except CorrectorFailure as exc:
        turned = [k for k in targets if near[k] != targets[k]]
        raise StartError(f"{where}: no solution at "
                         f"{', '.join(f'{k} = {targets[k]:.12g}' for k in turned)} by Newton "
                         f"from the one at its translate "
                         f"{', '.join(f'{k} = {near[k]:.12g}' for k in turned)} ({exc})") from None


def _nearest_translate(problem, q: str, value: float, current: float) -> float:
    """``value`` less the whole periods of ``q`` (if it has one) that bring it nearest
    ``current``; ``current`` itself if that is within the rounding of the subtraction (a
    translate of the label by whole periods is not a move by an ulp, to one side of a fold
    or the other by chance)."""
    period = problem.parameters[q].period
    turns = round((value - current) / period) if period else 0
    if turns == 0:
        return value
    near = value - turns * period
    return current if abs(near - current) <= 4 * math.ulp(abs(value) + abs(turns * period)) \
        else near


def _solves(problem, state: State, params: dict) -> bool:
    """``state`` solves the collocation equations at ``params`` as well as at its own
    parameters (to twice their residual, and rounding): it is its own translate by whole
    periods where the parameters enter periodically."""
    disc = Discretisation(problem, state.s)

    def residual(p):
        ev = disc.evaluate(state.y, p)
        return max(float(np.max(np.abs(ev.col))), float(np.max(np.abs(ev.bc))))

    return residual(params) <= 2 * residual(state.params) + 1e-14 * (1 + np.max(np.abs(state.y)))


def _reached(problem, origin: Origin, q: str, value: float, asked: float,
             options: ContinuationOptions, where: str, moved: list) -> State:
    """The solution at ``q = value`` continued from ``origin`` (see :func:`move`); ``asked``
    (the target, of which ``value`` may be a translate) and ``moved`` (the parameters moved
    before) are for the error message."""
    current = origin.state.params[q]
    toward = 1 if value > current else -1
    branches = [_continued(problem, origin, q, value, options, toward)]
    if origin.kind == "singular" or _stationary(branches[0]):
        branches.append(_continued(problem, origin, q, value, options, -toward))
    reached = [b for b in branches if _ends_at(b, q, value)]
    if not reached:
        after = (f" (after moving {', '.join(f'{k} to {v:.12g}' for k, v in moved)})"
                 if moved else "")
        translate = (f" (the translate of {asked:.12g} by whole periods nearest the label's)"
                     if value != asked else "")
        raise StartError(f"{where}: {q} = {value:.12g}{translate} not reached by continuation "
                         f"from {q} = {current:.12g}{after}: "
                         f"{_why(branches, q, value, current)}")
    return min(reached, key=lambda b: (b.points[-1].arclength, -b.direction)).points[-1].state


def _continued(problem, origin: Origin, q: str, value: float, options: ContinuationOptions,
               direction: int) -> Branch:
    """The continuation in ``q`` from ``origin`` in ``direction``, bounded by the current value
    and ``value``. A Ctrl-C during it is raised again (it would read as "not reached")."""
    current = origin.state.params[q]
    branch = Branch.of(problem, q, direction, "restart", options.to_dict())
    continue_branch(branch, problem,
                    Course(q, options, Stops(min(current, value), max(current, value))), origin)
    if branch.interrupted:
        raise KeyboardInterrupt
    return branch


def _ends_at(branch: Branch, q: str, value: float) -> bool:
    """The branch ends with its bound EP at exactly ``q = value`` (an EP where the bound was
    not located, at the step's end, has another value)."""
    last = branch.points[-1]
    return branch.end == labels.EP and last.type == labels.EP and last.params[q] == value


def _stationary(branch: Branch) -> bool:
    """``q`` is stationary at the branch's start (its tangent's ``q`` component is ~0)."""
    t = branch.points[0].tangent
    return t is not None and abs(t.lam) <= STATIONARY


def _why(branches: list[Branch], q: str, value: float, current: float) -> str:
    """Where the branch that came nearest ``q = value`` stopped, and why: it turned back (at
    a fold, or at the start where ``q`` is stationary), or it ended there (MX, max_points)."""
    toward = math.copysign(1.0, value - current)

    def furthest(b):  # the first of the points nearest the target
        return max(range(len(b.points)), key=lambda k: toward * b.points[k].params[q])

    branch, k = max(((b, furthest(b)) for b in branches),
                    key=lambda bk: toward * bk[0].points[bk[1]].params[q])
    p = branch.points[k]
    at = f"{q} = {p.params[q]:.12g}"
    if k < len(branch.points) - 1:
        fold = p.type in labels.FOLDS or (k == 0 and _stationary(branch))
        return f"the branch turns back at {at}" + (" (a fold)" if fold else "")
    return f"the continuation stopped at {at}: {branch.message}"
