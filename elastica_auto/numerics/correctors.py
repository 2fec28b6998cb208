"""The two correctors behind the stepper: solves at fixed parameters, pseudo-arclength steps,
solves on a hyperplane, and fold location, each returning a :class:`Solution`.

``corrector = "collocation"`` (the default, :class:`Collocation`): Newton's method on the
collocation equations assembled directly (:mod:`elastica_auto.numerics.newton`), one banded LU per
step reused for chord iterations, the mesh kept between steps while solve_bvp's error
estimate stays under ``tol`` and regridded by equidistribution when it does not
(:func:`~elastica_auto.numerics.collocation.equidistributed_mesh`); folds by bordered Newton on the
minimally augmented system, on a mesh that resolves the solution and its null vector to
``fold_tol``.

``corrector = "solve_bvp"`` (:class:`SolveBVP`): the same discretisation solved by
`scipy.integrate.solve_bvp` (:mod:`elastica_auto.numerics.bvp`), folds by its extended system: an
independent check of the first.

Either way a :class:`Solution` carries the factorised bordered Jacobian at the point, on the
point's mesh, from which the stepper reads the unit tangent (the fold test function is its
parameter component) and the sign of the determinant (the branch-point test function).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import bordered
from .collocation import Discretisation, equidistributed_mesh
from .gauss import GaussDiscretisation
from .newton import NEWTON_TOL, Linearization, Row, fold_newton, newton
from ..core.errors import NumericalFailure
from ..core.options import ContinuationOptions
from ..core.solution import State, Tangent, inner

#: A regridded mesh aims at this fraction of the tolerance, so that it serves many steps;
#: the next step gets one when a point's error estimate exceeds REFINE_ABOVE tol.
REGRID_TARGET, REFINE_ABOVE = 0.125, 0.4
#: The mesh is coarsened for the next step when the error is this far below the tolerance
#: and the equidistributed mesh has at most COARSEN_SIZE of the nodes.
COARSEN_BELOW, COARSEN_SIZE = 1 / 64, 0.7
#: A step uses the hyperplane normal to the border row of its start's factorisation (the
#: previous tangent) while that is within acos(STALE_NORMAL) of the tangent; else the
#: tangent's own hyperplane, through a rank-one update.
STALE_NORMAL = 0.5
#: A fold's or branch point's mesh aims at this fraction of fold_tol (it serves no further
#: step; `fold_mesh`).
FOLD_TARGET = 0.5
#: Regrid-and-resolve rounds before a solve is given up.
MESH_ROUNDS = 4


def _tangent_row(disc, t: Tangent) -> Row:
    """A border row along the direction t on the mesh of ``disc``."""
    t = t.on(disc.s)
    return Row(disc.weights * t.y, t.lam, 0.0)


class CorrectorFailure(NumericalFailure):
    """A solve that did not converge; the message says why, ``residual`` is the size of the
    last Newton correction (NaN where there was none)."""

    def __init__(self, message: str, residual: float = float("nan")):
        super().__init__(message)
        self.residual = residual


@dataclass
class Solution:
    """A solution on its mesh with its linearisation: ``lin`` is the bordered Jacobian at the
    point with the border row of the condition that defined it (factorised), ``tangent`` the
    unit tangent oriented along that row, ``rms`` the error estimate per interval."""

    state: State
    tangent: Tangent
    lin: Linearization
    rms: np.ndarray
    niter: int = 0
    extra: dict = field(default_factory=dict)

    @property
    def lam(self) -> float:
        return self.lin.lam

    @property
    def sign(self) -> int:
        return self.lin.sign

    @property
    def mesh(self) -> np.ndarray:
        return self.state.s


def _boundary_pattern(problem):
    """Where the module's boundary Jacobian (dg/dy_0, dg/dy_1) is nonzero, at a few generic
    states and the default parameters: which boundary rows involve which end.

    The states are a Weyl sequence (fractional parts of multiples of the golden ratio,
    spread over [-2, 2]): as generic as random ones for finding structural zeros, without
    importing numpy.random (15 ms of a short run's start-up, more with its platform probe)."""
    p = problem.defaults()
    n = problem.n
    ga = np.zeros((n, n), dtype=bool)
    gb = np.zeros((n, n), dtype=bool)
    weyl = 4.0 * ((np.arange(1, 6 * n + 1) * 0.6180339887498949) % 1.0) - 2.0
    for ya, yb in weyl.reshape(3, 2, n):
        da, db = problem.bc_jac(ya.copy(), yb.copy(), p)
        ga |= np.asarray(da) != 0
        gb |= np.asarray(db) != 0
    return ga, gb


class Collocation:
    """The collocation corrector for continuing ``problem`` in ``parameter``: Gauss
    collocation at ``options.ncol`` points per interval (:mod:`elastica_auto.numerics.gauss`), or
    with ``ncol = 0`` solve_bvp's cubic scheme (:mod:`elastica_auto.numerics.collocation`)."""

    name = "collocation"
    #: whether ``options.ncol`` chooses the discretisation (else always the cubic scheme)
    uses_ncol = True

    def __init__(self, problem, parameter: str, options: ContinuationOptions):
        self.problem, self.parameter, self.options = problem, parameter, options
        self.ncol = options.ncol if self.uses_ncol else 0
        self._seen = _boundary_pattern(problem)
        self.split = bordered.split_rows(*self._seen)
        self._discs: dict[bytes, Discretisation] = {}

    # -- meshes ---------------------------------------------------------------------------------
    def disc(self, s) -> Discretisation:
        key = np.asarray(s, dtype=float).tobytes()
        d = self._discs.get(key)
        if d is None:
            if len(self._discs) > 8:
                self._discs.clear()
            d = self._discs[key] = (GaussDiscretisation(self.problem, s, self.ncol)
                                    if self.ncol else Discretisation(self.problem, s))
        return d

    def _linearize(self, disc, params, Y, lam, row, interior=None) -> Linearization:
        lin = Linearization(disc, self.parameter, params, Y, lam, row, self.split, interior)
        st, blocks = lin.fact.st, lin.blocks
        if blocks.gb[st.left].any() or blocks.ga[st.right].any():
            # a boundary row classified as one-sided involves the other end here (the module's
            # Jacobian had structural zeros at the probes): it couples both ends from now on
            self._seen = (self._seen[0] | (blocks.ga != 0), self._seen[1] | (blocks.gb != 0))
            self.split = bordered.split_rows(*self._seen)
            lin = Linearization(disc, self.parameter, params, Y, lam, row, self.split,
                                interior)
        return lin

    def solution(self, disc, params, Y, lam, row, niter=0, interior=None) -> Solution:
        """Linearise at a converged (Y, lam) with border ``row``; tangent and error estimate.
        ``interior``: the discretisation's interior unknowns there (Gauss collocation's
        stage values; solved for Y if not given)."""
        lin = self._linearize(disc, params, Y, lam, row, interior)
        rms = disc.rms_residuals(Y, lin.ev.f, lin.params, lin.ev)
        if not np.all(np.isfinite(rms)):
            # the equations not finite between the nodes (an energy module's Legendre inverse
            # that did not converge there): no error estimate, and no solution to step from
            raise CorrectorFailure("the error estimate is not finite (the equations are not "
                                   "finite between the nodes)")
        return Solution(lin.state(), lin.tangent(), lin, rms, niter)

    def relinearize(self, a: Solution, s) -> Solution:
        """``a`` interpolated onto the mesh ``s`` and linearised there with its own tangent as
        border row (for comparing test functions with a point on that mesh)."""
        disc = self.disc(s)
        t = a.tangent.on(disc.s)
        row = Row(disc.weights * t.y, t.lam, 0.0)
        out = self.solution(disc, a.state.params, a.state(disc.s), a.lam, row)
        out.tangent = t
        out.extra = dict(a.extra)
        return out

    def _solve(self, s, params, guess: State, lam: float, make_row, lin=None,
               tol=None, regrid=True, row_of=None) -> Solution:
        """Newton from ``guess`` on mesh ``s`` with the condition ``make_row(disc)``; then, if
        ``regrid``, regrid and solve again until the error estimate is under ``tol``. The
        solution is linearised with the border row ``row_of(disc)`` (default: the
        condition's)."""
        tol = self.options.tol if tol is None else tol
        disc = self.disc(s)
        Y = guess(disc.s)
        niter = 0
        for _ in range(MESH_ROUNDS):
            row = make_row(disc)
            res = self._newton(disc, params, Y, lam, row, lin)
            niter += res.niter
            sol = self.solution(disc, params, res.Y, res.lam,
                                row if row_of is None else row_of(disc), niter, res.interior)
            sol.extra["contraction"] = res.contraction
            worst = float(sol.rms.max())
            if not regrid or worst <= tol:
                return sol
            disc = self.disc(self.regrid(disc.s, sol.rms))
            Y, lam, lin = sol.state(disc.s), res.lam, None
        raise CorrectorFailure(f"error estimate {worst:.2e} > tol after {MESH_ROUNDS} meshes")

    def _newton(self, disc, params, Y, lam, row, lin):
        # Newton stops three orders below the discretisation tolerance (NEWTON_TOL at the
        # default tol = 1e-5), so that a tighter tol also gives a tighter solution.
        res = newton(disc, self.parameter, params, Y, lam, row, lin, self.split,
                     tol=min(NEWTON_TOL, 1e-3 * self.options.tol))
        if not res.converged:
            raise CorrectorFailure(res.message, res.correction)
        return res

    def regrid(self, s, rms, tol=None):
        opt = self.options
        return equidistributed_mesh(s, rms, REGRID_TARGET * (opt.tol if tol is None else tol),
                                    opt.ntst, opt.max_nodes - 1, self.disc(s).order)

    def fold_mesh(self, s, rms):
        """The mesh, equidistributed from the error estimate ``rms`` on ``s``, on which a fold
        or a branch point is solved again with its kernel: aimed at FOLD_TARGET of
        ``fold_tol`` (it serves no further step, and a located point needs its solution and
        kernel within fold_tol only)."""
        opt = self.options
        return equidistributed_mesh(s, rms, FOLD_TARGET * opt.fold_tol, opt.ntst,
                                    opt.max_nodes - 1, self.disc(s).order)

    def next_mesh(self, a: Solution):
        """The mesh for the step from ``a``: its own while its error estimate stays between
        COARSEN_BELOW tol and REFINE_ABOVE tol, else an equidistributed one (a coarser one
        only if it saves nodes)."""
        opt = self.options
        worst = float(a.rms.max())
        if worst > REFINE_ABOVE * opt.tol:
            return self.regrid(a.mesh, a.rms)
        if worst > COARSEN_BELOW * opt.tol or len(a.mesh) - 1 <= opt.ntst:
            return a.mesh
        new = self.regrid(a.mesh, a.rms)
        return new if len(new) <= COARSEN_SIZE * len(a.mesh) else a.mesh

    # -- the solves the stepper asks for --------------------------------------------------------
    def at_value(self, guess: State, params: dict, value: float, lin=None) -> State:
        """The solution with the continued parameter at ``value`` on the guess's mesh, from
        ``guess``; ``lin``: a factorisation nearby to start the chord iterations with."""
        disc = self.disc(guess.s)
        row = Row.value(disc, value)
        res = self._newton(disc, params, guess.y, value, row, lin)
        p = {**params, self.parameter: value}
        return State(disc.s, res.Y, self.problem.rhs(disc.s, res.Y, p),
                     self.problem.point_params(p, res.Y))

    def point(self, guess: State) -> Solution:
        """The solution at the guess's parameters, from the guess, on a mesh that meets
        ``tol``."""
        lam = guess.params[self.parameter]
        sol = self._solve(guess.s, guess.params, guess, lam, lambda disc: Row.value(disc, lam))
        # the row fixes the parameter at lam, which the bordered solve gives back to its
        # rounding (-4e-31 for 0 with one BLAS kernel, 0.0 or -0.0 with another): lam itself,
        # so that a start's value is the one asked for, whatever the kernel (a UZ value or a
        # bound at the start is then met the same way)
        sol.state.params = {**sol.state.params, self.parameter: lam}
        sol.lin.lam, sol.lin.params = lam, {**sol.lin.params, self.parameter: lam}
        return sol

    def step(self, a: Solution, ds: float, curvature: Tangent | None = None) -> Solution:
        """Keller's pseudo-arclength step ``<x - a, t_a> = ds`` on a's mesh (a's factorised
        Jacobian serves for the chord iterations), predicted at ``a + ds t_a`` or, given the
        curve's ``curvature`` (the derivative of its unit tangent in arclength), at
        ``a + ds t_a + ds^2 / 2 curvature``."""
        name, t = self.parameter, a.tangent
        row = a.lin.row
        cos = float((row.c * t.y).sum() + row.d * t.lam)
        if cos < STALE_NORMAL or a.extra.get("singular"):
            return self.on_plane(a, t, ds, curvature=curvature)
        # the hyperplane normal to the border row a was factorised with (the tangent one point
        # back) through the predictor: a plain solve with a's factors, no rank-one update
        s = a.mesh
        if curvature is not None:
            k = curvature.on(s)
            t = Tangent(s, t.y + ds / 2 * k.y, t.yp + ds / 2 * k.yp, t.lam + ds / 2 * k.lam)
        pred = State(s, a.state.y + ds * t.y, a.state.yp + ds * t.yp,
                     {**a.state.params, name: a.lam + ds * t.lam})
        beta = float((row.c * pred.y).sum() + row.d * pred.params[name])
        sol = self._solve(s, a.state.params, pred, pred.params[name],
                          lambda disc: (Row(row.c, row.d, beta) if disc.s is s else
                                        Row.hyperplane(disc, pred, a.tangent, name, 0.0)),
                          lin=a.lin, row_of=lambda disc: _tangent_row(disc, a.tangent))
        return sol

    def on_plane(self, a: Solution, direction: Tangent, sigma: float, s=None,
                 regrid: bool = True, curvature: Tangent | None = None) -> Solution:
        """The solution on the hyperplane ``<x - a, direction> = sigma``, predicted at
        ``a + sigma direction`` (``+ sigma^2 / 2 curvature``)."""
        name = self.parameter
        s = a.mesh if s is None else s
        same = len(s) == len(a.mesh) and np.array_equal(s, a.mesh)
        t = direction.on(s)
        if curvature is not None:
            k = curvature.on(s)
            t = Tangent(s, t.y + sigma / 2 * k.y, t.yp + sigma / 2 * k.yp,
                        t.lam + sigma / 2 * k.lam)
        pred = State(s, a.state(s) + sigma * t.y, a.state.derivative(s) + sigma * t.yp,
                     {**a.state.params, name: a.lam + sigma * t.lam})
        return self._solve(s, a.state.params, pred, a.lam + sigma * t.lam,
                           lambda disc: Row.hyperplane(disc, a.state, direction, name, sigma),
                           lin=a.lin if same and not a.extra.get("singular") else None,
                           regrid=regrid)

    def fold(self, near: Solution) -> "FoldPoint":
        """The fold near ``near`` (a solution on the branch close to it, whose tangent
        approximates the null vector), on a mesh that resolves the solution and its null
        vector to ``fold_tol``."""
        opt, name = self.options, self.parameter
        disc = self.disc(near.mesh)
        Y, lam, t = near.state.y, near.lam, near.tangent
        params = near.state.params
        for _ in range(MESH_ROUNDS):
            res = fold_newton(disc, name, params, Y, lam, t, self.split)
            if not res.converged:
                raise CorrectorFailure(f"fold not located: {res.message}")
            p = {**params, name: res.lam}
            ev = disc.evaluate(res.Y, p)
            rms = np.maximum(disc.rms_residuals(res.Y, ev.f, p, ev),
                             disc.linear_rms_residuals(res.Y, p, res.phi.y))
            state = State(disc.s, res.Y, ev.f, self.problem.point_params(p, res.Y))
            if rms.max() <= opt.fold_tol:
                return FoldPoint(state, res.phi, float(rms.max()))
            disc = self.disc(self.fold_mesh(disc.s, rms))
            Y, lam, t = state(disc.s), res.lam, res.phi
        raise CorrectorFailure(f"fold: error estimate {rms.max():.2e} > fold_tol after "
                               f"{MESH_ROUNDS} meshes")


@dataclass
class FoldPoint:
    """A located fold: its solution, null vector (unit, parameter part 0) and residual (the
    largest error estimate of the solution and null vector)."""

    state: State
    phi: Tangent
    residual: float


class SolveBVP(Collocation):
    """The solve_bvp corrector: steps, value solves and folds by `scipy.integrate.solve_bvp`;
    tangents and test functions by the same linearisation as the collocation corrector, on
    solve_bvp's mesh."""

    name = "solve_bvp"
    uses_ncol = False

    def _bvp_solution(self, res, row_of) -> Solution:
        if not res.success:
            raise CorrectorFailure(res.message)
        st = res.state
        disc = self.disc(st.s)
        return self.solution(disc, st.params, st.y, st.params[self.parameter], row_of(disc),
                             res.niter)

    def at_value(self, guess: State, params: dict, value: float, lin=None) -> State:
        from .bvp import solve_fixed
        res = solve_fixed(self.problem, guess, {**params, self.parameter: value},
                          self.options.tol, self.options.max_nodes)
        if not res.success:
            raise CorrectorFailure(res.message)
        return res.state

    def step(self, a: Solution, ds: float, curvature: Tangent | None = None) -> Solution:
        """Keller's pseudo-arclength step ``<x - a, t_a> = ds`` by solve_bvp, predicted as the
        collocation corrector's (the inherited step would run the collocation Newton, and
        the cross-check of the two correctors would not be one)."""
        return self.on_plane(a, a.tangent, ds, curvature=curvature)

    def on_plane(self, a: Solution, direction: Tangent, sigma: float, s=None,
                 regrid: bool = True, curvature: Tangent | None = None) -> Solution:
        from .bvp import solve_arclength
        opt = self.options
        mesh = a.mesh if s is None else s
        predictor = None
        if curvature is not None:
            t, k = direction.on(mesh), curvature.on(mesh)
            predictor = Tangent(mesh, t.y + sigma / 2 * k.y, t.yp + sigma / 2 * k.yp,
                                t.lam + sigma / 2 * k.lam)
        # solve_bvp answers a failing Newton by refining; a smaller step is the cheaper cure
        res = solve_arclength(self.problem, a.state, direction, self.parameter, sigma, opt.tol,
                              min(opt.max_nodes, 3 * len(mesh)), mesh=mesh, predictor=predictor)
        return self._bvp_solution(res, lambda disc: Row.hyperplane(
            disc, a.state, direction, self.parameter, sigma))

    def next_mesh(self, a: Solution):
        from .bvp import coarsen
        return coarsen(a.mesh, a.rms, self.options.tol, self.options.ntst + 1)

    def fold(self, near: Solution) -> FoldPoint:
        from .bvp import solve_fold
        opt = self.options
        res = solve_fold(self.problem, near.state, near.tangent, self.parameter, opt.fold_tol,
                         opt.max_nodes)
        if not res.success:
            raise CorrectorFailure(f"fold not located: {res.message}")
        phi = res.extra["phi"]
        scale = np.sqrt(inner(phi, phi))
        return FoldPoint(res.state, Tangent(phi.s, phi.y / scale, phi.yp / scale, 0.0),
                         res.residual)


CORRECTORS = {c.name: c for c in (Collocation, SolveBVP)}


def make_corrector(problem, parameter: str, options: ContinuationOptions):
    return CORRECTORS[options.corrector](problem, parameter, options)
