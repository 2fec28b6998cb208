"""Two-parameter continuation: fold curves and branch-point curves (AUTO-07p's ISW = 2).

A fold of the boundary value problem F(y; lam, mu) = 0 (y' = f(s, y; p), g(y(0), y(1); p) = 0)
in its parameter ``lam`` is a solution y at which the linearised problem has a null vector v:

    v' = f_y(s, y; p) v,    g_a v(0) + g_b v(1) = 0,    int_0^1 |v|^2 ds = 1.

`fold_problem` writes these, together with F = 0, as one boundary value problem on the
states (y, v): 2 n states, 2 n boundary conditions, one integral condition (the null vector's
normalisation) and ``lam`` free. Continued in a second parameter ``mu`` by the ordinary
engine, its solutions are folds of the one-parameter problem at every point: a *fold curve*
in the (lam, mu) plane. Where ``mu`` turns along it (a fold of the fold curve), two folds of
the one-parameter family in ``lam`` meet and vanish: a cusp, labelled CP.

`branch_point_problem` does the same for the module's exact family y0(s; p) (its
``exact_start``, the straight rod of the elastica): the branch points of that family are the
parameter values where the linearised problem about y0 has a null vector,

    v' = f_y(s, y0; p) v,    g_a v(0) + g_b v(1) = 0,    int_0^1 |v|^2 ds = 1,

n states, ``lam`` free: the *critical-load curves* of the elastica in (eps, P).

The second derivatives the Jacobians of these systems need (f_yy v, the parameter
derivatives of f_y v) are central differences of the module's first derivatives along v:
by the symmetry of second derivatives, d/dy (f_y v) = d/dt f_y(y + t v) at t = 0, one pair of
calls per Jacobian. Both problems are ordinary `Problem` objects (modules built here), so
everything the engine does (steps, folds, branch points, user points, files) applies.

A module with integral conditions or free parameters of its own is solved as a square problem
on its states, the running integrals and the free parameters (`elastica_auto.model.augmented`):
its fold system is that square problem's, built the same way. The null vector then has
components along the running integrals and the free parameters too (v_mu constant, the
integrals' rows v_w' = phi_y v + phi_mu v_mu, v_w(0) = v_w(1) = 0), and a point of the fold
curve carries the free parameters' values among its parameters. Branch-point curves of such
modules are not built: their exact family would have to be completed the same way.
"""

from __future__ import annotations

import dataclasses
import types
from dataclasses import dataclass

import numpy as np

from ..core import labels
from ..core.errors import PlanError, ProblemError, StartError
from ..model.augmented import Augmented
from ..model.problem import Ordinate, Parameter, Problem
from ..core.solution import State
from .branch import PROFILE_GRID
from .kinds import CONTINUE, Event, Placement

#: The name of the normalisation integral of the null vector (a state ``int:null_norm``).
NORM = "null_norm"


def _step(y, v) -> float:
    """A central-difference step t for derivatives along v at y: t |v| ~ 1e-5 (1 + |y|)."""
    vmax = float(np.abs(v).max()) if v.size else 0.0
    if vmax == 0.0:
        return 1.0
    return 1e-5 * (1.0 + float(np.abs(y).max())) / vmax


def _null_states(base: Problem) -> tuple[str, ...]:
    return tuple(f"null:{name}" for name in base.states)


def _check_base(base, lam: str, what: str):
    if lam not in base.parameters:
        raise PlanError("parameter", f"unknown parameter {lam!r}; {base.source} declares "
                        f"{', '.join(base.parameter_names)}")
    if lam in getattr(base, "free", ()):
        raise PlanError("parameter", f"{lam!r} is a free parameter of {base.source} (solved "
                        f"for); {what} needs a parameter the module holds fixed")


class FoldSystem(Augmented):
    """The square problem of a fold system (`fold_problem`): ``system``, the extended
    module's problem, with ``lam`` solved for; ``folds_of`` is ``base``, the problem whose
    folds its solutions are. Where ``base`` solves for parameters of its own (a module with
    free parameters), a solution's parameter values carry ``lam`` and ``base``'s."""

    def __init__(self, system, lam: str, base):
        super().__init__(system, (lam,))
        self._folds_of = base

    @property
    def folds_of(self):
        return self._folds_of

    def point_params(self, params, y):
        out = super().point_params(params, y)
        base = self._folds_of
        return base.point_params(out, y[: base.n]) if base.solved else out


def fold_problem(base, lam: str) -> Problem:
    """The fold system of ``base`` in ``lam`` (module docstring): states (y, v), the integral
    condition ``null_norm``, ``lam`` free; the ordinates are ``base``'s, of y. ``base`` is a
    module's problem with one condition per state, or the square problem of one with integral
    conditions or free parameters (`elastica_auto.model.augmented.Augmented`), whose states y
    then include the running integrals and the free parameters."""
    _check_base(base, lam, "a fold curve")
    n = base.n
    module = _module(base, f"Folds of {base.source} in {lam}.", (*base.states, *_null_states(base)),
                     lam, _fold_hooks(base),
                     [_on_y(o, base) for o in base.ordinates.values()], first=n)
    # a base that solves for parameters reads their values from its states: so do the
    # extended system's points (`FoldSystem.point_params`)
    return FoldSystem(Problem(module, base.source), lam, base)


def _fold_hooks(base) -> dict:
    """The hooks of the system (F(y) = 0, F_y v = 0) on the states (y, v): the fold system's
    without its normalisation, shared by fold curves and pitchfork curves."""
    n = base.n

    # (written for few numpy calls: a fold-curve point calls these some 15 times)
    def rhs(s, Y, p):
        y, v = Y[:n], Y[n:]
        return np.concatenate((base.rhs(s, y, p),
                               np.einsum("ijm,jm->im", base.rhs_jac(s, y, p), v)))

    def rhs_jac(s, Y, p):
        y, v = Y[:n], Y[n:]
        t = _step(y, v)
        J = base.rhs_jac(s, y, p)
        out = np.empty((2 * n, 2 * n, Y.shape[1]))
        out[:n, :n] = J
        out[:n, n:] = 0.0
        out[n:, n:] = J
        np.subtract(base.rhs_jac(s, y + t * v, p), base.rhs_jac(s, y - t * v, p),
                    out=out[n:, :n])
        out[n:, :n] *= 0.5 / t
        return out

    def rhs_dp(s, Y, p, name):
        y, v = Y[:n], Y[n:]
        t = _step(y, v)
        return np.concatenate((base.rhs_dp(s, y, p, name),
                               (base.rhs_dp(s, y + t * v, p, name)
                                - base.rhs_dp(s, y - t * v, p, name)) / (2 * t)))

    def bc(Ya, Yb, p):
        ga, gb = base.bc_jac(Ya[:n], Yb[:n], p)
        return np.concatenate((base.bc(Ya[:n], Yb[:n], p), ga @ Ya[n:] + gb @ Yb[n:]))

    def _ends_step(Ya, Yb):
        """The difference step along v at the ends (:func:`_step` of both ends at once)."""
        vmax = max(float(np.abs(Ya[n:]).max()), float(np.abs(Yb[n:]).max()))
        if vmax == 0.0:
            return 1.0
        return 1e-5 * (1.0 + max(float(np.abs(Ya[:n]).max()),
                                 float(np.abs(Yb[:n]).max()))) / vmax

    def bc_jac(Ya, Yb, p):
        ya, yb, va, vb = Ya[:n], Yb[:n], Ya[n:], Yb[n:]
        t = _ends_step(Ya, Yb)
        ga, gb = base.bc_jac(ya, yb, p)
        pa, pb = base.bc_jac(ya + t * va, yb + t * vb, p)
        ma, mb = base.bc_jac(ya - t * va, yb - t * vb, p)
        da, db = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, 2 * n))
        da[:n, :n] = da[n:, n:] = ga
        db[:n, :n] = db[n:, n:] = gb
        da[n:, :n], db[n:, :n] = (pa - ma) / (2 * t), (pb - mb) / (2 * t)
        return da, db

    def bc_dp(Ya, Yb, p, name):
        ya, yb, va, vb = Ya[:n], Yb[:n], Ya[n:], Yb[n:]
        t = _ends_step(Ya, Yb)
        return np.concatenate((base.bc_dp(ya, yb, p, name),
                               (base.bc_dp(ya + t * va, yb + t * vb, p, name)
                                - base.bc_dp(ya - t * va, yb - t * vb, p, name)) / (2 * t)))

    return _hooks(rhs, rhs_jac, rhs_dp, bc, bc_jac, bc_dp)


def branch_point_problem(base: Problem, lam: str) -> Problem:
    """The branch-point system of ``base``'s exact family in ``lam`` (module docstring):
    states v, the integral condition ``null_norm``, ``lam`` free; the ordinates are
    ``base``'s, of the exact solution."""
    if base.solved or base.extra_conditions:
        raise PlanError("start", f"{base.source}: branch-point curves of a module with integral "
                        "conditions or free parameters are not built (fold curves are)")
    _check_base(base, lam, "a branch-point curve")

    def y0(s, p):
        y = base.exact_start(np.asarray(s, dtype=float), p)
        if y is None:
            raise ProblemError(f"{base.source} has no exact solution at "
                             f"{', '.join(f'{k}={v:g}' for k, v in p.items())}")
        return y

    def rhs(s, v, p):
        return np.einsum("ijm,jm->im", base.rhs_jac(s, y0(s, p), p), v)

    def rhs_jac(s, v, p):
        return base.rhs_jac(s, y0(s, p), p)

    def along_family(fn, p, name, shape):
        """d fn / d p[name] along the exact family (central differences); NaN for a
        parameter the family does not extend in (the elastica's straight rod and psi)."""
        h = 1e-6 * (1.0 + abs(p[name]))
        up, dn = {**p, name: p[name] + h}, {**p, name: p[name] - h}
        probe = np.array([0.0, 1.0])
        if base.exact_start(probe, up) is None or base.exact_start(probe, dn) is None:
            return np.full(shape, np.nan)
        return (fn(up) - fn(dn)) / (2 * h)

    def rhs_dp(s, v, p, name):
        return along_family(lambda q: rhs(s, v, q), p, name, v.shape)

    def ends(p):
        y = y0(np.array([0.0, 1.0]), p)
        return y[:, 0], y[:, 1]

    def bc(va, vb, p):
        ga, gb = base.bc_jac(*ends(p), p)
        return ga @ va + gb @ vb

    def bc_jac(va, vb, p):
        return base.bc_jac(*ends(p), p)

    def bc_dp(va, vb, p, name):
        return along_family(lambda q: bc(va, vb, q), p, name, va.shape)

    ordinates = [Ordinate(o.name, o.tex, (lambda fn: lambda s, v, p: fn(s, y0(s, p), p))(o.fn),
                          o.parameter, o.doc) for o in base.ordinates.values()]
    module = _module(base, f"Branch points of the exact family of {base.source} in {lam}.",
                     _null_states(base), lam, _hooks(rhs, rhs_jac, rhs_dp, bc, bc_jac, bc_dp),
                     ordinates, first=0)
    return Problem(module, base.source).with_free((lam,))


def _hooks(rhs, rhs_jac, rhs_dp, bc, bc_jac, bc_dp) -> dict:
    """The extended system's functions, by the names of the module hooks they are."""
    return dict(rhs=rhs, rhs_jac=rhs_jac, rhs_dp=rhs_dp, bc=bc, bc_jac=bc_jac, bc_dp=bc_dp)


def _on_y(o: Ordinate, base) -> Ordinate:
    """The ordinate ``o`` of ``base``'s solution y, the first states of the extended system's Y:
    of the module's own states, at parameter values with ``base``'s free ones (if any) read
    from y."""
    if not base.solved:
        n = base.n
        return Ordinate(o.name, o.tex, lambda s, Y, p: o.fn(s, Y[:n], p), o.parameter, o.doc)
    n0, n = base.n0, base.n
    return Ordinate(o.name, o.tex, lambda s, Y, p: o.fn(s, Y[:n0], base.point_params(p, Y[:n])),
                    o.parameter, o.doc)


def _module(base, doc, states, lam, hooks: dict, ordinates, first):
    """A module namespace for `Problem`: the ``hooks`` (``rhs``, ``rhs_jac``, ``rhs_dp``,
    ``bc``, ``bc_jac``, ``bc_dp``: the extended system), the null vector's normalisation
    (states ``first`` on) as the integral condition, ``lam`` free."""

    def integrals(s, Y, p):
        return (np.sum(Y[first:] ** 2, axis=0) - 1.0)[None, :]

    def integrals_jac(s, Y, p):
        out = np.zeros((1, Y.shape[0], Y.shape[1]))
        out[0, first:] = 2 * Y[first:]
        return out

    def integrals_dp(s, Y, p, name):
        return np.zeros((1, Y.shape[1]))

    return types.SimpleNamespace(
        __doc__=doc, STATES=states, PARAMETERS=_extended_parameters(base, states),
        ORDINATES=ordinates, **hooks, INTEGRALS=(NORM,), integrals=integrals,
        integrals_jac=integrals_jac, integrals_dp=integrals_dp, FREE=(lam,))


def _extended_parameters(base, states) -> list[Parameter]:
    """``base``'s parameters, with what a period does to the extended system's ``states``:
    a shift moves the solution's states and leaves the null vector's alone (a direction: the
    shift's derivative is the identity), a flip turns both."""
    out = []
    for q in base.parameters.values():
        flip = [k for k in q.period_flip if k in states]
        flip += [f"null:{k}" for k in q.period_flip if f"null:{k}" in states]
        out.append(dataclasses.replace(
            q, period_shift=tuple((k, v) for k, v in q.period_shift if k in states),
            period_flip=tuple(flip)))
    return out


def _normalised(s, v):
    """v scaled so that int_0^1 |v|^2 ds = 1 (trapezoidal rule on the mesh)."""
    norm2 = np.trapezoid(np.sum(v ** 2, axis=0), s)
    if not norm2 > 0:
        raise StartError("the null vector at the start is zero")
    return v / np.sqrt(norm2)


def fold_start(problem, state: State, null) -> State:
    """The fold system's state at a fold ``state`` of the module's problem, with null vector
    ``null`` (n, m) on ``state.s`` (approximate: solve from it)."""
    y = np.vstack((state.y, _normalised(state.s, null)))
    return State.from_values(problem, state.s, problem.complete(state.s, y, state.params),
                             state.params)


def branch_point_start(problem, state: State, null) -> State:
    """The branch-point system's state at a branch point ``state`` of the exact family, with
    null vector ``null`` (n, m) on ``state.s`` (approximate: solve from it)."""
    v = _normalised(state.s, null)
    return State.from_values(problem, state.s, problem.complete(state.s, v, state.params),
                             state.params)


def family_slope(base: Problem, state: State, lam: str) -> np.ndarray:
    """d y0 / d lam of the exact family on ``state.s`` (central differences)."""
    p, h = state.params, 1e-6 * (1.0 + abs(state.params[lam]))
    return (base.exact_start(state.s, {**p, lam: p[lam] + h})
            - base.exact_start(state.s, {**p, lam: p[lam] - h})) / (2 * h)


#: A fold of a fold curve (where the continued parameter turns) is a cusp where the solved-for
#: parameter lam is stationary too. Then lam moves like the cube of the distance h along the
#: curve; at the other folds of a fold curve it moves like h itself. The test compares lam's
#: change over the step to each neighbouring point with the part of it that lam's slope at
#: the fold accounts for, rho = |t_lam| h / |Delta lam|: about 1 where lam moves through the
#: fold (0.99 to 1.31 at the folds of runs/fold_curves_arm.toml and fold_curves_load.toml),
#: about 0 at a cusp (4e-11 to 9e-6 at theirs: t_lam there is the fold's location error),
#: and 1/2 where the slope's part and the cubic's are equal. A ratio of two changes of lam
#: over one step: the same for any units of the states or of the parameters (issue 45 item 5;
#: it replaces a bound on t_lam relative to the whole tangent, which scaling the states
#: changes: tests/test_fold_curve_labels.py).
CUSP_RATIO = 0.5
#: A fold of a fold curve is on the module's exact family (the straight rod) where its
#: solution is the family's at its parameters to FAMILY_RATIO of the distance the curve moves
#: in the step to its nearer neighbouring point: the curve passes through the family there to
#: the accuracy of its points (2e-13 to 3e-13 at those of runs/fold_curves_arm.toml, against
#: steps of 2e-3 to 0.13: ratios of 2e-12 to 8e-11). A ratio of two distances between
#: solutions, in the same norm: the same for any units of the states.
FAMILY_RATIO = 1e-6


@dataclass(frozen=True)
class _Near:
    """What the tests read of a point of the fold curve: its parameter values (the solved-for
    ones included), its arclength and its profile on PROFILE_GRID, as its branch stores
    them (`elastica_auto.branches.branch.new_point`)."""

    params: dict
    arclength: float
    profile: np.ndarray

    @classmethod
    def of(cls, problem, state: State, arclength: float) -> _Near:
        return cls(problem.point_params(state.params, state.y), float(arclength),
                   state(PROFILE_GRID))


def _is_cusp(p: _Near, near, lam: str, t_lam: float) -> bool:
    """CUSP_RATIO's test at the fold ``p`` of a fold curve, on each neighbouring point."""
    rho = []
    for q in near:
        change = abs(q.params[lam] - p.params[lam])
        rho.append(abs(t_lam) * abs(q.arclength - p.arclength) / change if change > 0
                   else np.inf)
    return bool(rho) and max(rho) < CUSP_RATIO


def _on_family(p: _Near, near, own, n: int) -> bool:
    """FAMILY_RATIO's test at the fold ``p`` of a fold curve: its solution's distance from
    the exact family (max norm, on the stored profile grid) against the distance to its
    nearer neighbouring point."""
    y0 = own.exact_start(PROFILE_GRID, p.params)
    if y0 is None or not near:
        return False
    y = p.profile[:n]
    step = min(float(np.max(np.abs(q.profile[:n] - y))) for q in near)
    return float(np.max(np.abs(y - y0))) <= FAMILY_RATIO * step


class FoldCurvePoint(Event):
    """The codimension-two points of a fold curve (a walk whose problem is a fold system:
    its ``folds_of`` is set), among its folds (LP, where the continued parameter turns and
    two folds of the one-parameter family meet):

    - CP, a cusp, where the solved-for parameter ``lam`` is stationary as well: over the
      step to each neighbouring point, ``lam``'s slope at the fold accounts for less than
      CUSP_RATIO of its change;
    - BP, where the fold's solution is the module's exact solution (its ``exact_start``,
      the straight rod) at those parameters, to FAMILY_RATIO of the distance to the nearer
      neighbouring point: the fold curve meets the exact family's branch-point curve (a
      critical load).

    The other folds stay LP: there the two folds that meet face opposite ways (the
    one-parameter branches reconnect, or an isola appears), and ``lam`` moves through. Every
    fold of the curve is noted with ``lam``'s slope in its unit tangent.

    A placed kind, the last of ``PLACEMENT``: its test reads the fold's neighbouring points
    on the branch (the points the step places on each side of it, a user point or a bound
    between it and the step's end among them), which are known once every other placed kind
    has placed its points and the end; and the turn's label LP is what the placed kinds
    before it read (the monotone pieces between the step's folds, the fold stop's count).
    A fold it labels otherwise stays a fold of the branch for the walk
    (`elastica_auto.branches.kinds.branch_folds`: the next fold's locator, the fold stop,
    a period's translates)."""

    label, action = labels.CP, CONTINUE

    def place(self, walk, placement: Placement) -> None:
        """Label the folds among the step's points that stay (before the end found, and the
        end itself), each against its neighbours there: the nearest point on each side at
        another arclength among the step's, else the branch's last point before the step,
        or b, the step's end, where the branch goes on past the step."""
        base = walk.problem.folds_of
        if base is None:
            return
        step, end = placement.step, placement.end
        kept = [e for e in placement.points
                if end is None or placement.ender.keeps(walk, placement, e)]
        order = sorted(kept + ([end] if end is not None else []), key=lambda e: e.sigma)
        if not any(e.kind in labels.FOLDS for e in order):
            return
        problem = walk.problem
        row = problem.n - 1                      # the solved-for parameter is the last state
        own, lam = base.module_problem, problem.solved[0]
        here = [step.position(e.sigma) for e in order]
        for i, e in enumerate(order):
            if e.kind not in labels.FOLDS or e.tangent is None:
                continue
            p = _Near.of(problem, e.state, here[i])
            near = [self._before(walk, order, here, i),
                    self._after(walk, placement, order, here, i)]
            near = [q for q in near if q is not None]
            t = e.tangent
            states = np.trapezoid(np.sum(t.y[:row] ** 2, axis=0), t.s)
            slope = abs(t.y[row, 0]) / np.sqrt(states + t.y[row, 0] ** 2 + t.lam ** 2)
            note = f"d{lam}/ds = {slope:.1e} of the tangent"
            walk.refolded[id(e.state)] = (e.state, not e.note)
            if _is_cusp(p, near, lam, t.y[row, 0]):
                e.kind = labels.CP
            if _on_family(p, near, own, own.n):
                e.kind = labels.BP
                note += "; on the exact family: the fold curve meets its branch-point curve"
            e.note = "; ".join(filter(None, (e.note, note)))

    @staticmethod
    def _before(walk, order, here, i) -> _Near | None:
        """The nearest point before ``order[i]`` at another arclength: one of the step's,
        else the branch's (its last point, a's, or one before it)."""
        for j in range(i - 1, -1, -1):
            if here[j] != here[i]:
                return _Near.of(walk.problem, order[j].state, here[j])
        q = next((q for q in reversed(walk.branch.points) if q.arclength != here[i]), None)
        return None if q is None else _Near(q.params, q.arclength, q.profile)

    @staticmethod
    def _after(walk, placement: Placement, order, here, i) -> _Near | None:
        """The nearest point after ``order[i]`` at another arclength: one of the step's, else
        b, the step's end, where the branch does not end in the step (the walk adds b after
        the step's points, at its arclength plus ds)."""
        for j in range(i + 1, len(order)):
            if here[j] != here[i]:
                return _Near.of(walk.problem, order[j].state, here[j])
        if placement.end is not None:
            return None
        step = placement.step
        return _Near.of(walk.problem, step.b.state, step.arclength + step.ds)
