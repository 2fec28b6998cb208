"""The correctors behind the stepper, each implementing the corrector interface
(:class:`~elastica_auto.numerics.corrector.Corrector`): solves at fixed parameters,
pseudo-arclength steps, solves on a hyperplane, fold location, each returning a
:class:`Solution`, and the linearisations the test functions, the kernel at a branch point
and the error estimates are read from.

``corrector = "collocation"`` (the default, :class:`Collocation`): Newton's method on the
collocation equations assembled directly (:mod:`elastica_auto.numerics.newton`), one banded LU per
step reused for chord iterations, the mesh kept between steps while solve_bvp's error
estimate stays under ``tol`` and regridded by equidistribution when it does not
(:func:`~elastica_auto.numerics.collocation.equidistributed_mesh`); folds by bordered Newton on the
minimally augmented system, on a mesh that resolves the solution and its null vector to
``fold_tol``.

With ``ncol = 2..7`` (:class:`Gauss`): the same Newton iteration, steps, meshes and folds on
Gauss collocation's discretisation (:mod:`elastica_auto.numerics.gauss`).

``corrector = "solve_bvp"`` (:class:`SolveBVP`): the cubic discretisation solved by
`scipy.integrate.solve_bvp` (:mod:`elastica_auto.numerics.bvp`), starts, steps and folds (by its
extended system) alike: an independent check of the first, sharing none of its solves.

Either way a :class:`Solution` carries the factorised bordered Jacobian at the point, on the
point's mesh (``lin``: read by the corrector only), from which the corrector reads the unit
tangent (the fold test function is its parameter component) and the sign of the determinant
(the branch-point test function). Each corrector makes its linearisations by a
:class:`Linearizer` of its own discretisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from . import bordered
from .collocation import Discretisation, equidistributed_mesh
from .gauss import GaussDiscretisation
from .newton import NEWTON_TOL, Linearization, Row, fold_newton, kernel, newton, unit
from ..core.errors import NumericalFailure
from ..core.options import NCOL_AUTO, ContinuationOptions
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


def _mesh(s, rms, target: float, min_intervals: int, max_intervals: int, order: int):
    """`equidistributed_mesh` from the error estimate ``rms`` on ``s``; CorrectorFailure,
    marked as the module's values (an infinite residual, which the stepper reports so),
    where an estimate is not finite. The estimates of a tangent or a kernel read the
    module's Jacobian (``rhs_jac``, or the differences of ``rhs``) between the nodes: a
    Jacobian that is NaN there, with finite values at the nodes, left a NaN count of
    intervals and the branch ended with an internal error."""
    if not np.all(np.isfinite(rms)):
        raise CorrectorFailure("the error estimate is not finite (the equations or their "
                               "Jacobian are not finite between the nodes)", math.inf)
    return equidistributed_mesh(s, rms, target, min_intervals, max_intervals, order)


@dataclass
class Solution:
    """A solution on its mesh with its linearisation: ``lin`` is the bordered Jacobian at the
    point with the border row of the condition that defined it (factorised; the corrector's
    own, read by nothing outside ``numerics/``), ``tangent`` the unit tangent oriented along
    that row, ``rms`` the error estimate per interval."""

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


class Linearizer:
    """The linearisations a corrector answers with, on the meshes of one discretisation,
    ``discretisation(problem, s)`` (the cubic Lobatto IIIA scheme, which is solve_bvp's own,
    or Gauss collocation). Every :class:`Solution` carries one: the
    bordered Jacobian ``[[F_y, F_lam], [c, d]]`` of the discrete equations at the point,
    factorised (:class:`~elastica_auto.numerics.newton.Linearization`), from which the tangent,
    the determinant's sign and log, the kernel at a branch point and the error estimates are
    read. Each corrector owns one (composition, not inheritance: the solve_bvp corrector
    shares none of the collocation corrector's Newton iteration, meshes or steps)."""

    def __init__(self, problem, parameter: str, discretisation):
        self.problem, self.parameter = problem, parameter
        self._discretisation = discretisation
        self._seen = _boundary_pattern(problem)
        #: the boundary rows by the end they involve (`bordered.split_rows`)
        self.split = bordered.split_rows(*self._seen)
        self._discs: dict[bytes, Discretisation] = {}

    def disc(self, s) -> Discretisation:
        """The discretisation on the mesh ``s`` (a few kept: the same meshes recur)."""
        key = np.asarray(s, dtype=float).tobytes()
        d = self._discs.get(key)
        if d is None:
            if len(self._discs) > 8:
                self._discs.clear()
            d = self._discs[key] = self._discretisation(self.problem, s)
        return d

    def linearization(self, disc, params, Y, lam, row, interior=None) -> Linearization:
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
        lin = self.linearization(disc, params, Y, lam, row, interior)
        rms = disc.rms_residuals(Y, lin.ev.f, lin.params, lin.ev)
        if not np.all(np.isfinite(rms)):
            # the equations not finite between the nodes (an energy module's Legendre inverse
            # that did not converge there): no error estimate, and no solution to step from
            raise CorrectorFailure("the error estimate is not finite (the equations are not "
                                   "finite between the nodes)", math.inf)
        return Solution(lin.state(), lin.tangent(), lin, rms, niter)

    def linearize(self, state: State, along: Tangent | None) -> Solution:
        """``state`` (a solution on its mesh) linearised with the border row along ``along``,
        ``(weights t_y, t_lam)`` on the mesh, or the row ``lam = value`` where None; the
        tangent oriented along that row."""
        disc = self.disc(state.s)
        lam = state.params[self.parameter]
        row = Row.value(disc, lam) if along is None else _tangent_row(disc, along)
        return self.solution(disc, state.params, state.y, lam, row)

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

    def error_estimate(self, state: State) -> np.ndarray:
        """The error estimate per interval of ``state`` on its own mesh (the one ``tol``
        bounds; from its node slopes ``state.yp``)."""
        return self.disc(state.s).rms_residuals(state.y, state.yp, state.params)

    def determinant(self, sol: Solution, along: Tangent, s) -> tuple[int, float]:
        """(sign, log|det|) of the bordered Jacobian at ``sol`` on the mesh ``s`` with the
        border row along ``along``: ``sol``'s own factorisation where it is that one, else
        ``sol`` interpolated onto ``s`` and factorised there. On one mesh and one row, a test
        function that varies smoothly along a step (its sign: the branch-point test)."""
        lin = sol.lin
        t = along.on(s)
        if not (np.array_equal(lin.disc.s, s) and lin.row.d == t.lam
                and np.array_equal(lin.row.c, lin.disc.weights * t.y)):
            disc = self.disc(s)
            lin = Linearization(disc, self.parameter, sol.state.params, sol.state(s), sol.lam,
                                Row(disc.weights * t.y, t.lam, 0.0), self.split)
        return lin.sign, lin.fact.logdet

    def kernel(self, sol: Solution) -> tuple[Tangent, float]:
        """At a branch point (``sol``'s bordered Jacobian singular): the unit kernel direction
        of ``[F_y, F_lam]`` orthogonal to the border row (the other branch's), and its residual
        in the linearised equations relative to the size of their terms
        (:func:`kernel_residual`: rounding at a branch point, 1e-2 or more where the matrix is
        regular and the "kernel" is a solve's answer to a random right-hand side)."""
        lin = sol.lin
        v, v_lam = kernel(lin)
        direction = unit(lin.disc, lin.blocks, v, v_lam, self.parameter)
        if not np.isfinite(direction.lam):
            return direction, np.inf
        return direction, kernel_residual(lin.blocks, direction.y, direction.lam,
                                          self.parameter)

    def left_kernel(self, sol: Solution) -> np.ndarray:
        """The left kernel's collocation multipliers at the branch point ``sol``
        (:meth:`Corrector.left_kernel`): one solve with the transposed factorisation and a
        fixed pseudo-random right-hand side, whose component along the left kernel is
        amplified by 1 / sigma_min (inverse iteration's first step, as :meth:`kernel` does
        for the right one). At a pitchfork the left kernel of the bordered matrix is
        (psi, 0): psi^T [F_y, F_lam] = 0, psi^T F_lam vanishing by the symmetry."""
        lin = sol.lin
        rng = np.random.default_rng(20261206)
        w_col, _, _ = lin.fact.solve_transpose(rng.standard_normal((lin.disc.n, lin.disc.m)),
                                               rng.standard_normal(lin.fact.st.k))
        return w_col

    def kernel_error(self, sol: Solution) -> np.ndarray:
        """The error estimate per interval of the kernel direction at the branch point
        ``sol`` (the solution of the linearised equations the other branch leaves along):
        what, with ``sol.rms``, a located branch point must have resolved."""
        lin = sol.lin
        v, v_lam = kernel(lin)
        return lin.disc.linear_rms_residuals(sol.state.y, sol.state.params, v, v_lam,
                                             self.parameter)

    def solve_again(self, state: State, normal: Tangent | None, tol: float) -> Resolved:
        """Newton on the discrete equations from the solution ``state`` on its own mesh (no
        regrid), its parameter fixed, or on the hyperplane through it normal to ``normal``
        (the parameter free): whether ``state`` solves the equations this discretisation
        computed it by. ``tol``: Newton's (scaled correction)."""
        disc = self.disc(state.s)
        name = self.parameter
        lam = float(state.params[name])
        row = (Row.value(disc, lam) if normal is None
               else Row.hyperplane(disc, state, normal, name, 0.0))
        res = newton(disc, name, state.params, state.y, lam, row, None, self.split, tol=tol)
        if res.converged:
            return Resolved(True, res.Y, res.lam, "")
        # the equations' residual at state: each collocation residual relative to 1 + |y| at
        # its interval's first node, each boundary residual relative to 1 + max |y|
        ev = disc.evaluate(state.y, state.params)
        scale = 1.0 + np.abs(state.y)
        worst = max(float(np.max(np.abs(ev.col) / scale[:, :-1])),
                    float(np.max(np.abs(ev.bc)) / (1.0 + float(np.max(np.abs(state.y))))))
        return Resolved(False, res.Y, res.lam, res.message, worst)


@dataclass
class Resolved:
    """The outcome of :meth:`Linearizer.solve_again`: where Newton converged (``Y``, ``lam``),
    or the last iterate, Newton's message and ``residual``, the largest relative residual of
    the discrete equations at the state it started from (NaN where it converged)."""

    converged: bool
    Y: np.ndarray
    lam: float
    message: str
    residual: float = float("nan")


def kernel_residual(blocks, v, v_lam: float, name: str) -> float:
    """The residual of ``(v, v_lam)`` in the linearised equations ``F_y v + F_lam v_lam = 0``
    of ``blocks``, relative to the size of their terms (the largest row of
    ``|F_y| |v| + |F_lam| |v_lam|``); 0 for a zero vector of a zero Jacobian."""
    col, bc = blocks.times(v)
    col = col + blocks.dcol[name] * v_lam
    bc = bc + blocks.dbc[name] * v_lam
    a = np.abs(v)
    size_col = (np.einsum("iab,bi->ai", np.abs(blocks.d0), a[:, :-1])
                + np.einsum("iab,bi->ai", np.abs(blocks.d1), a[:, 1:])
                + np.abs(blocks.dcol[name]) * abs(v_lam))
    size_bc = (np.abs(blocks.ga) @ a[:, 0] + np.abs(blocks.gb) @ a[:, -1]
               + np.abs(blocks.dbc[name]) * abs(v_lam))
    size = max(float(np.max(size_col)), float(np.max(size_bc)))
    residual = max(float(np.max(np.abs(col))), float(np.max(np.abs(bc))))
    return residual / size if size > 0 else (0.0 if residual == 0 else np.inf)


class _Linearized:
    """The operations of the corrector interface that only read linearisations
    (:class:`~elastica_auto.numerics.corrector.Corrector`), forwarded to the corrector's own
    :class:`Linearizer` ``self._linearizer``."""

    _linearizer: Linearizer

    def linearize(self, state: State, along: Tangent | None) -> Solution:
        return self._linearizer.linearize(state, along)

    def relinearize(self, a: Solution, s) -> Solution:
        return self._linearizer.relinearize(a, s)

    def error_estimate(self, state: State) -> np.ndarray:
        return self._linearizer.error_estimate(state)

    def determinant(self, sol: Solution, along: Tangent, s) -> tuple[int, float]:
        return self._linearizer.determinant(sol, along, s)

    def kernel(self, sol: Solution) -> tuple[Tangent, float]:
        return self._linearizer.kernel(sol)

    def kernel_error(self, sol: Solution) -> np.ndarray:
        return self._linearizer.kernel_error(sol)

    def left_kernel(self, sol: Solution) -> np.ndarray:
        return self._linearizer.left_kernel(sol)

    def solve_again(self, state: State, normal: Tangent | None, tol: float) -> Resolved:
        return self._linearizer.solve_again(state, normal, tol)


class Collocation(_Linearized):
    """The collocation corrector for continuing ``problem`` in ``parameter``, on solve_bvp's
    cubic scheme (:mod:`elastica_auto.numerics.collocation`, ``ncol = 0``): Newton's method
    over the discretisation interface (``evaluate``, ``blocks``, ``stages``, the error
    estimates), which :class:`Gauss` shares with its own discretisation."""

    name = "collocation"

    def __init__(self, problem, parameter: str, options: ContinuationOptions):
        if options.ncol not in (0, NCOL_AUTO) and type(self) is Collocation:
            # never the cubic scheme unasked
            raise ValueError(f"ncol = {options.ncol} is Gauss collocation: make it with "
                             "make_corrector (or Gauss), not Collocation")
        self.problem, self.parameter, self.options = problem, parameter, options
        self._linearizer = Linearizer(problem, parameter, self.discretisation)

    def discretisation(self, problem, s):
        """The discrete equations on the mesh ``s``."""
        return Discretisation(problem, s)

    def _solve(self, s, params, guess: State, lam: float, make_row, lin=None,
               tol=None, regrid=True, row_of=None) -> Solution:
        """Newton from ``guess`` on mesh ``s`` with the condition ``make_row(disc)``; then, if
        ``regrid``, regrid and solve again until the error estimate is under ``tol``. The
        solution is linearised with the border row ``row_of(disc)`` (default: the
        condition's)."""
        tol = self.options.tol if tol is None else tol
        disc = self._linearizer.disc(s)
        Y = guess(disc.s)
        niter = 0
        for _ in range(MESH_ROUNDS):
            row = make_row(disc)
            res = self._newton(disc, params, Y, lam, row, lin)
            niter += res.niter
            sol = self._linearizer.solution(disc, params, res.Y, res.lam,
                                row if row_of is None else row_of(disc), niter, res.interior)
            sol.extra["contraction"] = res.contraction
            worst = float(sol.rms.max())
            if not regrid or worst <= tol:
                return sol
            disc = self._linearizer.disc(self.regrid(disc.s, sol.rms))
            Y, lam, lin = sol.state(disc.s), res.lam, None
        raise CorrectorFailure(f"error estimate {worst:.2e} > tol after {MESH_ROUNDS} meshes")

    def _newton(self, disc, params, Y, lam, row, lin):
        # Newton stops three orders below the discretisation tolerance (NEWTON_TOL at the
        # default tol = 1e-5), so that a tighter tol also gives a tighter solution.
        res = newton(disc, self.parameter, params, Y, lam, row, lin, self._linearizer.split,
                     tol=min(NEWTON_TOL, 1e-3 * self.options.tol))
        if not res.converged:
            raise CorrectorFailure(res.message, res.correction)
        return res

    def regrid(self, s, rms, tol=None):
        opt = self.options
        return _mesh(s, rms, REGRID_TARGET * (opt.tol if tol is None else tol),
                     opt.ntst, opt.max_nodes - 1, self._linearizer.disc(s).order)

    def fold_mesh(self, s, rms):
        """The mesh, equidistributed from the error estimate ``rms`` on ``s``, on which a fold
        or a branch point is solved again with its kernel: aimed at FOLD_TARGET of
        ``fold_tol`` (it serves no further step, and a located point needs its solution and
        kernel within fold_tol only)."""
        opt = self.options
        return _mesh(s, rms, FOLD_TARGET * opt.fold_tol, opt.ntst,
                     opt.max_nodes - 1, self._linearizer.disc(s).order)

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
    def at_value(self, guess: State, params: dict, value: float,
                 near: Solution | None = None) -> State:
        """The solution with the continued parameter at ``value`` on the guess's mesh, from
        ``guess``; ``near``: a solution nearby whose factorisation starts the chord
        iterations."""
        disc = self._linearizer.disc(guess.s)
        row = Row.value(disc, value)
        res = self._newton(disc, params, guess.y, value, row,
                           None if near is None else near.lin)
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
        disc = self._linearizer.disc(near.mesh)
        Y, lam, t = near.state.y, near.lam, near.tangent
        params = near.state.params
        for _ in range(MESH_ROUNDS):
            res = fold_newton(disc, name, params, Y, lam, t, self._linearizer.split)
            if not res.converged:
                raise CorrectorFailure(f"fold not located: {res.message}")
            p = {**params, name: res.lam}
            ev = disc.evaluate(res.Y, p)
            rms = np.maximum(disc.rms_residuals(res.Y, ev.f, p, ev),
                             disc.linear_rms_residuals(res.Y, p, res.phi.y))
            state = State(disc.s, res.Y, ev.f, self.problem.point_params(p, res.Y))
            if rms.max() <= opt.fold_tol:
                return FoldPoint(state, res.phi, float(rms.max()))
            disc = self._linearizer.disc(self.fold_mesh(disc.s, rms))
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


class SolveBVP(_Linearized):
    """The solve_bvp corrector: starts, value solves, steps and folds by
    `scipy.integrate.solve_bvp` (:mod:`elastica_auto.numerics.bvp`), meshes by solve_bvp's own
    refinement (and :func:`~elastica_auto.numerics.bvp.coarsen` between steps). It shares no
    solve with the collocation corrector, so that the two check each other. Its
    linearisation (tangents, the determinant's sign, the kernel at a branch point) is that of
    solve_bvp's own discrete equations, the cubic Lobatto IIIA scheme of
    :mod:`~elastica_auto.numerics.collocation`, on solve_bvp's mesh, by a
    :class:`Linearizer` of its own: solve_bvp computes a Jacobian but gives none back, and the
    stepper needs one at every point."""

    name = "solve_bvp"

    def __init__(self, problem, parameter: str, options: ContinuationOptions):
        self.problem, self.parameter, self.options = problem, parameter, options
        self._linearizer = Linearizer(problem, parameter, Discretisation)

    def _bvp_solution(self, res, row_of) -> Solution:
        if not res.success:
            raise CorrectorFailure(res.message)
        st = res.state
        disc = self._linearizer.disc(st.s)
        return self._linearizer.solution(disc, st.params, st.y, st.params[self.parameter],
                                 row_of(disc), res.niter)

    def point(self, guess: State) -> Solution:
        """The solution at the guess's parameters by solve_bvp from the guess (its mesh
        refined by solve_bvp to ``tol``), linearised with the row ``lam = value``."""
        from .bvp import solve_fixed
        opt = self.options
        lam = guess.params[self.parameter]
        res = solve_fixed(self.problem, guess, guess.params, opt.tol, opt.max_nodes)
        return self._bvp_solution(res, lambda disc: Row.value(disc, lam))

    def at_value(self, guess: State, params: dict, value: float,
                 near: Solution | None = None) -> State:
        """The solution at ``value`` by solve_bvp from ``guess`` (``near`` unused: solve_bvp
        makes its own Jacobians)."""
        from .bvp import solve_fixed
        res = solve_fixed(self.problem, guess, {**params, self.parameter: value},
                          self.options.tol, self.options.max_nodes)
        if not res.success:
            raise CorrectorFailure(res.message)
        return res.state

    def step(self, a: Solution, ds: float, curvature: Tangent | None = None) -> Solution:
        """Keller's pseudo-arclength step ``<x - a, t_a> = ds`` by solve_bvp, predicted at
        ``a + ds t_a`` (``+ ds^2 / 2 curvature``) as the collocation corrector's."""
        return self.on_plane(a, a.tangent, ds, curvature=curvature)

    def on_plane(self, a: Solution, direction: Tangent, sigma: float, s=None,
                 regrid: bool = True, curvature: Tangent | None = None) -> Solution:
        """The solution on the hyperplane ``<x - a, direction> = sigma`` by solve_bvp, started
        on the mesh ``s`` (default a's); ``regrid`` unused: solve_bvp refines the mesh it is
        given whenever its residual asks for it."""
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
        """a's mesh, with every other node dropped where the residual is far below ``tol``
        (solve_bvp itself only ever adds nodes). Where a's residual exceeds ``tol`` on some
        interval, which a point solve_bvp computed never does (it refines until every
        interval's is below), a is a start from a label that another discretisation computed
        (Gauss collocation's few intervals across a boundary layer, or a looser ``tol``): the
        step gets the mesh equidistributed from that residual to REGRID_TARGET tol, as the
        collocation corrector's regrid. From a's own mesh, solve_bvp, held to three times its
        nodes in a step (`on_plane`), could not resolve the layer and the branch ended MX at
        its first step ("the maximum number of mesh nodes is exceeded")."""
        from .bvp import coarsen
        opt = self.options
        if float(a.rms.max()) > opt.tol:
            return _mesh(a.mesh, a.rms, REGRID_TARGET * opt.tol, opt.ntst,
                         opt.max_nodes - 1, Discretisation.order)
        return coarsen(a.mesh, a.rms, opt.tol, opt.ntst + 1)

    def fold_mesh(self, s, rms):
        """The mesh a branch point is solved again on: equidistributed from the residual
        ``rms`` on ``s`` for FOLD_TARGET of ``fold_tol`` (solve_bvp refines it further where
        its own residual asks for it)."""
        opt = self.options
        return _mesh(s, rms, FOLD_TARGET * opt.fold_tol, opt.ntst,
                     opt.max_nodes - 1, Discretisation.order)

    def fold(self, near: Solution) -> FoldPoint:
        """The fold near ``near`` by solve_bvp on the fold's extended system (the BVP, its null
        vector and its normalisation, the parameter free), to ``fold_tol``."""
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


class Gauss(Collocation):
    """The Gauss collocation corrector: ``corrector = "collocation"`` with ``ncol = 2..7``
    points per interval (AUTO-07p's NCOL; :mod:`elastica_auto.numerics.gauss`, its stage
    equations condensed per interval into the same blocks as the cubic scheme's). Its
    discretisation is its own; the Newton iteration, the steps, the regridding and the folds
    are the collocation corrector's, which reaches the discrete equations only through the
    discretisation interface."""

    name = "gauss"

    def discretisation(self, problem, s):
        return GaussDiscretisation(problem, s, self.options.ncol)


#: The correctors a run file or the API names (``corrector = ...``, core.options.CORRECTORS).
CORRECTORS = {c.name: c for c in (Collocation, SolveBVP)}


def make_corrector(problem, parameter: str, options: ContinuationOptions):
    """The corrector ``options.corrector`` names, for continuing ``problem`` in ``parameter``
    (:class:`~elastica_auto.numerics.corrector.Corrector`): the collocation corrector with
    ``ncol`` Gauss points is :class:`Gauss`. With ``ncol = "auto"``, not yet chosen for a
    branch (`choose_ncol`), it is the cubic scheme: a start solved from a module's guess,
    and the solves of a run outside its branches."""
    if options.corrector == Collocation.name and options.ncol not in (0, NCOL_AUTO):
        return Gauss(problem, parameter, options)
    return CORRECTORS[options.corrector](problem, parameter, options)


#: Gauss collocation's points per interval where ``ncol = "auto"`` chooses it (AUTO-07p's
#: usual NCOL; at 3 and 5 the measured costs are within 10% of 4's: docs/numerics.md).
AUTO_GAUSS = 4
#: ``ncol = "auto"`` chooses Gauss collocation where the cubic scheme's mesh at a branch's
#: start would have more than GAUSS_PAYS times the nodes of Gauss collocation's. A Gauss
#: step costs about 1.7x a cubic one per node on the planar elastica and more with more
#: states (the condensation inverts an n k x n k block per interval), and each point has a
#: fixed cost besides: measured, Gauss took 1.08x the cubic scheme's time at 2.7x fewer
#: nodes (the elastica), 1.6x at 4.9x fewer (the spatial rod) and 0.55x at 13x fewer (a
#: boundary layer, AUTO's kar) (docs/numerics.md, `benchmarks/schemes.py`).
GAUSS_PAYS = 8


def choose_ncol(problem, parameter: str, options: ContinuationOptions, state: State,
                stored: int | None = None) -> int:
    """The discretisation ``ncol`` of a branch of ``problem`` in ``parameter`` started at
    ``state``: ``options.ncol`` where it is a number (the user's choice always wins), the
    cubic scheme (0) for the solve_bvp corrector and for a problem with a stability index
    (`may_turn_to_gauss`); under ``"auto"``, ``stored`` where the
    start is a stored label computed with that ``ncol`` (a restart keeps its scheme), else
    the cheaper at ``tol`` by the start's own error estimates.

    The estimate: the mesh each scheme would equidistribute to ``tol`` from its error
    estimate on the start's mesh (`Collocation.regrid`, the mesh a step from the start would
    get; the cubic residual scales like h^3, Gauss's error like h^(k+1)). Gauss
    collocation at AUTO_GAUSS points is chosen where the cubic mesh has more than
    GAUSS_PAYS times its nodes. The cubic count is looked at first: at most GAUSS_PAYS
    times the fewest nodes a mesh has (``ntst + 1``, where Gauss sits on smooth problems),
    Gauss cannot pay and its estimate (which solves its stage equations on the start's
    mesh) is not made. Both are functions of the start alone: the same start gives the same
    choice on every machine, whatever the load."""
    if options.ncol != NCOL_AUTO:
        return int(options.ncol)
    if options.corrector != Collocation.name or not may_turn_to_gauss(problem):
        return 0
    if stored is not None:
        return int(stored)
    return AUTO_GAUSS if gauss_pays(problem, parameter, options, state) else 0


def may_turn_to_gauss(problem) -> bool:
    """Whether ``ncol = "auto"`` may choose Gauss collocation for ``problem`` at all: not
    where its points get a direct count of the stability index (a ``second_variation``
    hook). The count is made on the solution's own mesh (`elastica_auto.numerics.stability`),
    and the meshes on which Gauss resolves the solution with few nodes do not resolve the
    eigenfunctions it counts: on the shipped run `higher_loads` (the elastica at P up to
    about 9 pi^2/4), Gauss at the fewest intervals, which its estimate asked for where the
    cubic mesh had 409-649 nodes, changed the direct index at 4 points and the labels of
    two branches. Such problems stay on the cubic scheme unless the user sets ``ncol``."""
    return not getattr(problem, "has_second_variation", False)


def gauss_pays(problem, parameter: str, options: ContinuationOptions, state: State) -> bool:
    """Whether Gauss collocation at AUTO_GAUSS points is the cheaper discretisation at
    ``options.tol`` for the solution ``state`` (`choose_ncol`): the cubic scheme's mesh
    equidistributed to tol from its error estimate on ``state``'s mesh has more than
    GAUSS_PAYS times the nodes of Gauss collocation's (the second looked at only where the
    first exceeds GAUSS_PAYS (ntst + 1))."""
    cubic = Collocation(problem, parameter, replace(options, ncol=0))
    nodes = len(cubic.regrid(state.s, cubic.error_estimate(state)))
    if nodes <= GAUSS_PAYS * (options.ntst + 1):
        return False
    gauss = Gauss(problem, parameter, replace(options, ncol=AUTO_GAUSS))
    return nodes > GAUSS_PAYS * len(gauss.regrid(state.s, gauss.error_estimate(state)))
