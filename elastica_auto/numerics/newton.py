"""Newton's method on the collocation equations, bordered by one linear condition, and the
bordered Newton method that locates folds.

The unknowns are the node values Y (n, m) and one free parameter lam; the equations are the
collocation equations and boundary conditions F(Y, lam) = 0 (:mod:`numerics.collocation`)
and one linear condition, the border row

    <c, Y> + d lam = beta,

which is the pseudo-arclength condition ``<x - x_0, t_0> = ds`` (c = quadrature weights times
t_0's state part, d = t_0's parameter part), a hyperplane of a step, or ``lam = value``.

The Jacobian is factorised as a banded matrix (:mod:`numerics.bordered`); once factorised
at one point it serves chord iterations at nearby points and, through a rank-one update, other
border rows. Steps are accepted by the natural monotonicity test (Deuflhard): the next chord
correction must be smaller than the last; if not, the Jacobian is refactorised at the current
iterate, then the step is damped. The iteration has converged when the correction is below
the tolerance, or when the residual itself is zero to working precision (:func:`rounding_floor`:
near a branch point the correction of such an iterate is rounding noise amplified by the
near-singular Jacobian, and would never decrease).
"""

from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np

from . import bordered
from .collocation import Blocks, Discretisation
from ..core.solution import State, Tangent

#: Newton stops when the scaled correction max |dY| / (1 + |Y|), |dlam| / (1 + |lam|) is
#: below this: an order below the discretisation error at the default tol (solve_bvp stops
#: its Newton iteration at a similar level, 1.5 orders below tol in the residual).
NEWTON_TOL = 1e-8
#: The fold locator's tolerance on its last correction. Its Newton matrix is exact up to
#: differences of step 1e-7, so the error left after a correction of 1e-8 is ~1e-15.
FOLD_NEWTON_TOL = 1e-8
MAX_ITER = 12
#: The fold locator starts on the branch next to the fold; a larger correction diverges.
FOLD_MAX_CORRECTION = 0.5
#: Chord iterations continue while at most this many more are predicted (from the last
#: contraction) to reach the tolerance; otherwise the Jacobian is refactorised (about the
#: cost of two or three chord iterations) for quadratic convergence.
CHORD_AHEAD = 4
#: A residual within this many rounding errors of the size of its terms is zero to working
#: precision (:func:`rounding_floor`): the iterate solves the equations as well as floating
#: point can, whatever the next correction says.
ROUNDING_ULPS = 64.0


@dataclass
class Row:
    """The border row ``<c, Y> + d lam = beta``; ``c`` (n, m) includes the quadrature weights."""

    c: np.ndarray
    d: float
    beta: float

    @classmethod
    def hyperplane(cls, disc: Discretisation, origin: State, direction: Tangent, name: str,
                   offset: float) -> "Row":
        """``<x - origin, direction> = offset`` on the mesh of ``disc``."""
        t = direction.on(disc.s)
        c = disc.weights * t.y
        beta = float(np.sum(c * origin(disc.s)) + t.lam * origin.params[name] + offset)
        return cls(c, t.lam, beta)

    @classmethod
    def value(cls, disc: Discretisation, lam: float) -> "Row":
        """``lam = value``: the parameter fixed."""
        return cls(np.zeros((disc.n, disc.m)), 1.0, float(lam))

    def residual(self, Y, lam) -> float:
        return float((self.c * Y).sum() + self.d * lam - self.beta)


class Linearization:
    """The bordered Jacobian ``[[F_y, F_lam], [c, d]]`` at (Y, lam) on the mesh of ``disc``,
    evaluated and factorised, with the border row of ``row``."""

    def __init__(self, disc: Discretisation, name: str, params: dict, Y, lam: float, row: Row,
                 split, interior=None):
        self.disc, self.name, self.row, self.split = disc, name, row, split
        self.Y, self.lam = Y, float(lam)
        self.params = {**params, name: self.lam}
        # Gauss collocation's stage values: given, or solved for Y (see numerics.gauss)
        self.ev = disc.evaluate(Y, self.params, interior)
        self.blocks = disc.blocks(self.ev, self.params, (name,))
        self.fact = bordered.factor(self.blocks, (name,), [(row.c, [row.d])], split)

    @property
    def sign(self) -> int:
        """sign det of the bordered matrix: the branch-point test function. It keeps its sign
        through folds and changes it at simple branch points; for two border rows c with
        ``<c, t> > 0`` (t the tangent) it is the same."""
        return self.fact.sign

    def state(self) -> State:
        return State(self.disc.s, self.Y, self.ev.f,
                     self.disc.problem.point_params(self.params, self.Y))

    def tangent(self) -> Tangent:
        """The unit tangent: the kernel of ``[F_y, F_lam]``, ``<row, t> > 0``."""
        u_y, u_p = self.fact.null_direction()
        return unit(self.disc, self.blocks, u_y, float(u_p[0]), self.name)

    def solve(self, row: Row, col, bc, g):
        """The Newton correction for residuals (col, bc, g) with border row ``row``."""
        if row is self.row or (row.c is self.row.c and row.d == self.row.d):
            dY, dp = self.fact.solve(col, bc, [g])
        else:
            dY, dp = with_border(self.fact, self.blocks, self.name, self.split, row.c, row.d,
                                  col, bc, g)
        return dY, float(dp[0])

    def correct(self, row: Row, ev, g):
        """The Newton correction ``(dY, dlam, dK)`` for the residuals of the evaluation
        ``ev`` and ``g``: the interior residuals condensed into the node rows with this
        linearisation's local factors, and the interior correction recovered from dY (dK
        None without interior unknowns)."""
        dY, dlam = self.solve(row, self.blocks.condense(ev), ev.bc, g)
        return dY, dlam, self.blocks.interior(ev, dY, dlam, self.name)


def with_border(fact, blocks, name, split, c, d: float, col, bc, g):
    """The solution of ``fact``'s system with its border row exchanged for ``(c, d)``: by
    the Sherman-Morrison update, or where that would lose its digits
    (`bordered.IllConditionedUpdate`), by a factorisation of the system with that row."""
    try:
        return fact.solve_with_border(c, [d], col, bc, [g])
    except bordered.IllConditionedUpdate:
        return bordered.factor(blocks, (name,), [(c, [d])], split).solve(col, bc, [g])


def unit(disc: Discretisation, blocks: Blocks, v, v_lam: float, name: str) -> Tangent:
    """A solution (v, v_lam) of the linearised equations as a unit Tangent (its node slopes
    from the linearised right-hand side)."""
    scale = np.sqrt(float((disc.weights * (v * v).sum(axis=0)).sum()) + v_lam * v_lam)
    v, v_lam = v / scale, v_lam / scale
    return Tangent(disc.s, v, blocks.slopes(v, v_lam, name), v_lam)


def scaled_norm(dY, dlam, Y, lam) -> float:
    return max(float((np.abs(dY) / (1 + np.abs(Y))).max()), abs(dlam) / (1 + abs(lam)))


def rounding_floor(ev, row: Row, Y, lam) -> tuple[float, float]:
    """The sizes below which the residuals at (Y, lam) are zero to working precision:
    ROUNDING_ULPS rounding errors of the size of the terms they are computed from, 1 + max |Y|
    + max |f| for the collocation and boundary rows, the row's terms for the border row.

    Near a singular point (a branch point, a symmetry's family) the Newton correction of an
    iterate whose residuals are below them is their rounding noise amplified by the inverse of
    the Jacobian's smallest singular value, and need not decrease: the iterate is a solution
    to working precision (its backward error is rounding), and the ill-conditioning of the
    problem, not the iteration, limits its forward error. At a regular point this changes
    nothing: the correction of such an iterate is far below the tolerance."""
    ulp = ROUNDING_ULPS * np.finfo(float).eps
    border = abs(row.beta) + float(np.abs(row.c * Y).sum()) + abs(row.d * lam)
    return (ulp * (1.0 + float(np.abs(Y).max()) + float(np.abs(ev.f).max())),
            ulp * (1.0 + border))


class _Corrections:
    """`newton`'s correction at an iterate (Y, K, lam): the residuals F of the discretisation
    and g of the border row there, and (dY, dlam, dK) = J^-1 (F, g) by the factorisation
    ``lin`` (at the iterate, or elsewhere: a chord step), with its size, the largest scaled
    correction (inf if a residual is not finite: a failed step). Keeps the last residuals
    for `at_rounding`."""

    def __init__(self, disc: Discretisation, name: str, params: dict, row: Row,
                 interior: bool):
        self.disc, self.name, self.params, self.row = disc, name, params, row
        self.interior = interior    # the discretisation has stage values K
        self.last = None            # the last (evaluation, border residual)
        self.floor = None           # rounding_floor, once a correction is above the tolerance

    def __call__(self, lin, Y, K, lam):
        p = {**self.params, self.name: lam}
        with np.errstate(over="ignore", invalid="ignore"):  # non-finite: a failed step
            ev = self.disc.evaluate(Y, p, K)
        g = self.row.residual(Y, lam)
        if not (np.isfinite(ev.col).all() and np.isfinite(ev.bc).all() and np.isfinite(g)
                and (K is None or np.isfinite(ev.stage).all())):
            return None, None, None, np.inf
        self.last = ev, g
        dY, dlam, dK = lin.correct(self.row, ev, g)
        size = scaled_norm(dY, dlam, Y, lam)
        if dK is not None:
            size = max(size, float((np.abs(dK) / (1 + np.abs(K))).max()))
        return dY, dlam, dK, size

    def at_rounding(self, Y, lam) -> bool:
        """The last residuals are zero to working precision (`rounding_floor`)."""
        ev, g = self.last
        if self.floor is None:  # once per solve: the size of the terms changes little
            self.floor = rounding_floor(ev, self.row, Y, lam)
        return (np.abs(ev.col).max() <= self.floor[0] and np.abs(ev.bc).max() <= self.floor[0]
                and (not self.interior or np.abs(ev.stage).max() <= self.floor[0])
                and abs(g) <= self.floor[1])


def _finite_blocks(blocks) -> bool:
    """Every entry of the Jacobian ``blocks`` (`collocation.Blocks`) is finite: the
    collocation and boundary rows' derivatives in the states and the parameters."""
    arrays = [blocks.d0, blocks.d1, blocks.ga, blocks.gb, *blocks.dcol.values(),
              *blocks.dbc.values()]
    return all(np.isfinite(a).all() for a in arrays)


@dataclass
class NewtonResult:
    converged: bool
    Y: np.ndarray
    lam: float
    niter: int
    message: str = ""
    contraction: float = 0.0   # the first iteration's |correction 2| / |correction 1|
    correction: float = float("nan")    # the size of the last correction
    interior: np.ndarray | None = None  # Gauss collocation's stage values at Y


def newton(disc: Discretisation, name: str, params: dict, Y, lam: float, row: Row,
           lin: Linearization | None, split, tol: float = NEWTON_TOL) -> NewtonResult:
    """Solve F(Y, lam) = 0 with the border row ``row`` from (Y, lam).

    ``lin``: a factorisation to start the chord iterations with (at a nearby point, with any
    border row), or None to factorise at the start. Non-finite residuals count as a failed
    step (damped, then failure). Interior unknowns of the discretisation (Gauss
    collocation's stage values) are iterated with the node values, started from the
    interpolant of Y (``disc.stages``)."""
    Y = np.array(Y, dtype=float)
    lam = float(lam)
    K = disc.stages(Y, {**params, name: lam})
    correction = _Corrections(disc, name, params, row, K is not None)

    def moved(K, dK, alpha):
        return None if K is None else K - alpha * dK

    fresh = lin is None
    if fresh:
        lin = Linearization(disc, name, params, Y, lam, row, split, K)
    dY, dlam, dK, size = correction(lin, Y, K, lam)
    if not np.isfinite(size):
        # the residuals not finite (``last`` unset: the module's values, marked by an
        # infinite correction, which the stepper reports so); or finite, with a Jacobian that
        # is not (the module's derivatives, or its values at the states and parameters next
        # to the guess that the engine's differences read: a rhs that is NaN beyond a
        # parameter value, with the guess just below it), the module's too; or both finite
        # with a correction that is not (NaN): the Jacobian there is singular, and the module
        # not to blame
        if correction.last is None:
            return NewtonResult(False, Y, lam, 0, "non-finite residual at the initial guess",
                                correction=math.inf)
        if not _finite_blocks(lin.blocks):
            return NewtonResult(False, Y, lam, 0, "non-finite Jacobian at the initial guess",
                                correction=math.inf)
        return NewtonResult(False, Y, lam, 0, "non-finite Newton correction at the initial "
                            "guess (a singular Jacobian)", correction=math.nan)
    first = None
    for it in range(1, MAX_ITER + 1):
        if size <= tol:
            return NewtonResult(True, Y - dY, lam - dlam, it, contraction=first or 0.0,
                                interior=moved(K, dK, 1.0))
        if correction.at_rounding(Y, lam):     # the correction is amplified rounding
            return NewtonResult(True, Y, lam, it, contraction=first or 0.0, interior=K)
        alpha = 1.0
        while True:
            Y1, lam1, K1 = Y - alpha * dY, lam - alpha * dlam, moved(K, dK, alpha)
            dY1, dlam1, dK1, size1 = correction(lin, Y1, K1, lam1)
            if size1 <= (1 - alpha / 4) * size:
                break
            if not fresh:  # the Jacobian is stale: refactorise here first, then damp
                lin = Linearization(disc, name, params, Y, lam, row, split, K)
                fresh = True
                dY, dlam, dK, size = correction(lin, Y, K, lam)
                alpha = 1.0
                continue
            alpha /= 2
            if alpha < 1 / 16:
                return NewtonResult(False, Y, lam, it,
                                    f"no decrease of the Newton correction ({size:.2e})",
                                    correction=size)
        theta = size1 / size
        if first is None:
            first = theta
        Y, lam, K = Y1, lam1, K1
        ahead = np.log(tol / size1) / np.log(theta) if 0 < theta < 1 and size1 > tol else 0
        if ahead > CHORD_AHEAD:
            lin = Linearization(disc, name, params, Y, lam, row, split, K)
            fresh = True
            dY, dlam, dK, size = correction(lin, Y, K, lam)
        else:
            dY, dlam, dK, size, fresh = dY1, dlam1, dK1, size1, False
    return NewtonResult(False, Y, lam, MAX_ITER,
                        f"no convergence in {MAX_ITER} iterations (correction {size:.2e})",
                        correction=size)


@dataclass
class FoldResult:
    converged: bool
    Y: np.ndarray
    lam: float
    phi: Tangent | None          # the null vector (unit, lam part 0)
    niter: int
    message: str = ""


def null_vector(disc, blocks, name, c, split):
    """(v, g, w_col, w_bc, fact) of the bordered system ``[[F_y, F_lam], [c, 0]]``: ``F_y v +
    F_lam g = 0``, ``<c, v> = 1``; w the multipliers of its transpose with the same
    right-hand side; ``fact`` its factorisation. ``g`` vanishes exactly where F_y is singular
    with null vector v (a fold when F_lam is not in the range of F_y)."""
    fact = bordered.factor(blocks, (name,), [(c, [0.0])], split)
    v, g = fact.null_direction()
    w_col, w_bc, _ = fact.solve_transpose(np.zeros((disc.n, disc.m)), [1.0])
    return v, float(g[0]), w_col, w_bc, fact


def fold_gradient(disc, name, p, Y, blocks, v, w_col, w_bc) -> tuple[np.ndarray, float]:
    """The gradient ``(g_Y (n, m), g_lam)`` of the test function g of :func:`null_vector`
    (its border b and row c held fixed) at the point Y, ``p`` of ``blocks``, from its null
    vector v and multipliers w: differentiating ``[[F_y, b], [c, 0]] (v, g) = (0, 1)``,
    ``dg = -w^T (dF_y) v``, so ``g_Y = -(d/dY (F_y v))^T w`` and ``g_lam = -w^T (dF_y/dlam) v
    = -w^T (dF_lam/dY) v`` (mixed derivatives commute): both from one linearisation at
    ``Y + eps v``, a one-sided difference whose O(eps) error only slows Newton's (then
    linear, rate ~eps) convergence; F and g themselves are exact."""
    eps = 1e-7 * (1 + float(np.max(np.abs(Y)))) / max(float(np.max(np.abs(v))), 1e-300)
    plus = disc.blocks(disc.evaluate(Y + eps * v, p), p, (name,))
    g_y = -(plus.transpose_times(w_col, w_bc) - blocks.transpose_times(w_col, w_bc)) / eps
    g_lam = -(float(np.sum(w_col * (plus.dcol[name] - blocks.dcol[name])))
              + float(w_bc @ (plus.dbc[name] - blocks.dbc[name]))) / eps
    return g_y, g_lam


def fold_newton(disc: Discretisation, name: str, params: dict, Y, lam: float, t: Tangent,
                split, tol: float = FOLD_NEWTON_TOL, max_iter: int = 15) -> FoldResult:
    """Locate a fold by Newton's method on the minimally augmented system (Govaerts)

        F(Y, lam) = 0,    g(Y, lam) = 0,

    with g from ``[[F_y, F_lam], [c, 0]] (v, g) = (0, 1)`` (:func:`null_vector`): ``c`` = the
    weighted state part of ``t`` (an approximate null vector), fixed. The Newton matrix
    ``[[F_y, F_lam], [g_y, g_lam]]`` is that bordered matrix with the gradient of g as its
    last row (:func:`fold_gradient`), so it is solved with the same factorisation, its last
    row exchanged (Sherman-Morrison, `Factorization.solve_with_border`, or a factorisation of
    its own where that update would lose its digits: :func:`with_border`). The gradient holds
    the border column F_lam fixed: its variation adds ``-w^T (dF_lam) g`` to dg, a term that
    vanishes with g at the fold, so that Newton's convergence stays quadratic (the
    iterations on the shipped runs are those of a border frozen at the start)."""
    Y = np.array(Y, dtype=float)
    lam = float(lam)
    p = {**params, name: lam}
    ev = disc.evaluate(Y, p)
    blocks = disc.blocks(ev, p, (name,))
    c = disc.weights * t.on(disc.s).y
    for it in range(1, max_iter + 1):
        v, g, w_col, w_bc, fact = null_vector(disc, blocks, name, c, split)
        g_y, g_lam = fold_gradient(disc, name, p, Y, blocks, v, w_col, w_bc)
        dY, dlam = with_border(fact, blocks, name, split, g_y, g_lam, ev.col, ev.bc, g)
        dlam = float(dlam[0])
        size = scaled_norm(dY, dlam, Y, lam)
        if not size < FOLD_MAX_CORRECTION:  # started near the fold: this diverges (or is NaN)
            return FoldResult(False, Y, lam, None, it,
                              f"Newton correction {size:.2g} (diverging)")
        Y, lam = Y - dY, lam - dlam
        p = {**params, name: lam}
        ev = disc.evaluate(Y, p)
        blocks = disc.blocks(ev, p, (name,))
        if size <= tol:
            # the null vector of the last iterate, within the last correction of this one's
            return FoldResult(True, Y, lam, unit(disc, blocks, v, 0.0, name), it)
    return FoldResult(False, Y, lam, None, max_iter,
                      f"no convergence in {max_iter} iterations")


def kernel(lin: Linearization) -> tuple[np.ndarray, float]:
    """The kernel of a singular bordered matrix, by one solve with a fixed pseudo-random
    right-hand side: its component along the kernel is amplified by 1 / sigma_min. At a
    branch point located to ~1e-12 this is the direction of the other branch that is
    orthogonal to the border row (the first branch's tangent). Returns (v (n, m), v_lam)."""
    disc, fact = lin.disc, lin.fact
    rng = np.random.default_rng(20261201)
    diag = fact.lu[fact.st.kl + fact.st.ku]
    zero = diag == 0.0
    # a pivot exactly zero (a branch point met exactly, as on a trivial branch whose entries
    # are few distinct numbers) would make the solve inf: a pivot at rounding level amplifies
    # the kernel component as intended
    diag[zero] = np.finfo(float).eps * np.max(np.abs(diag))
    try:
        v, v_lam = fact.solve(rng.standard_normal((disc.n, disc.m - 1)),
                              rng.standard_normal(disc.n), [rng.standard_normal()])
    finally:
        diag[zero] = 0.0
    return v, float(v_lam[0])
