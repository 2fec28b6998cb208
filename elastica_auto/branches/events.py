"""Special points inside one continuation step, and their exact location.

A step goes from a to b, both solutions with their unit tangents ``t`` (oriented along the
direction of travel) and the sign of the determinant of their bordered Jacobians, on one mesh.

* LP (fold): the parameter component of the tangent changes sign between a and b, and is
  larger than its own accuracy at one of them at least (:func:`parameter_turns`). Located by
  bordered Newton on the minimally augmented system (the corrector's ``fold``), started from
  the solution on the step where that component, interpolated linearly, vanishes.
* BP (branch point): the determinant changes sign (it does not at a fold: AUTO-07p's test for
  boundary value problems). Located as the zero of the determinant, scaled by its value at a,
  on the hyperplanes ``<x - a, secant> = sigma`` by Brent's method; or, where the
  module's symmetry holds at a value of the parameter inside the step on states it moves,
  placed at that value (:func:`place_symmetric_branch_point`).
* A fold pair inside one step leaves both test functions unchanged; :func:`pair_suspected`
  reads it off the cubic that interpolates the parameter along the step (values and slopes at
  both ends): a slope that dips toward zero, or changes sign twice, inside the step.
* UZ (user point) and EP at a parameter bound: the parameter crosses a given value (for
  periodic values, any value + k * period), between two knots (a, the folds, b) where it is
  monotone. Solved at that value from the knots' interpolation, checked to lie between them,
  else by Brent's method on the parameter along the hyperplanes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..numerics.correctors import CorrectorFailure, FoldPoint, Solution
from ..numerics.newton import NEWTON_TOL
from ..core.solution import State, Tangent, difference, inner
from ..model.symmetry import moves


#: The accuracy of a unit tangent's parameter component. The tangent is the kernel of the
#: Jacobian at a point the corrector solved to NEWTON_TOL (its last correction, scaled by
#: 1 + |y|): a point off the branch by delta has a Jacobian whose kernel is off by about
#: |F_yy| delta / sigma_min, of the order of delta where the step is resolved, and the solve
#: adds rounding (eps times the condition number, far less on the shipped runs). So a
#: component within NEWTON_TOL of zero has no sign to speak of: on a branch along which the
#: parameter is constant (the other branch at a symmetric pitchfork) it is rounding, of
#: either sign from point to point (1e-17 on tests/test_detection.py's vertical branch), and
#: on the tail of the Bratu branch, where lam -> 0 like exp(-u(1/2)), it is below 1e-8
#: from lam ~ 1e-9 on. A genuine fold leaves both ends of a step within it only if the step
#: is shorter than 2 NEWTON_TOL / |d t_lam / ds|, the rate at which the component changes
#: along the branch: 4e-8 at the Bratu fold (|d t_lam / ds| = 0.48), below ds_min. With the
#: states scaled by c the rate is divided by c^2: 0.04 for c = 1e3, whose own steps are
#: about 1e3 times longer (tests/test_detection.py).
TURN_NOISE = NEWTON_TOL


def parameter_turns(la: float, lb: float) -> bool:
    """Whether the tangents' parameter components ``la`` at a and ``lb`` at b say that the
    parameter turns between them (a fold): opposite signs, and one of them at least larger
    than their accuracy TURN_NOISE. (Two within it: the parameter is stationary across the
    step to first order, and the signs are rounding.)"""
    return la * lb < 0 and max(abs(la), abs(lb)) > TURN_NOISE


@dataclass(frozen=True)
class UserValues:
    """UZ values of the continued parameter; with ``period`` every ``v + k period`` counts."""

    values: tuple[float, ...]
    period: float | None = None


def is_user_value(lam: float, specs) -> bool:
    """Whether ``lam`` is one of the UZ values of ``specs`` (each with its period), to 1e-9
    (1 + |lam|): a located UZ point, or a copy of one shifted by whole periods."""
    for spec in specs:
        for v in spec.values:
            k = 0 if spec.period is None else round((lam - v) / spec.period)
            if abs(lam - v - k * (spec.period or 0.0)) <= 1e-9 * (1.0 + abs(lam)):
                return True
    return False


def crossings(a: float, b: float, spec: UserValues) -> list[float]:
    """The user values c crossed on the way from a to b: c in (a, b] (or [b, a) going down),
    ordered in the direction of travel."""
    if a == b:
        return []
    lo, hi = min(a, b), max(a, b)
    found = []
    for v in spec.values:
        if spec.period is None:
            cands = [v]
        else:
            T = spec.period
            cands = [v + j * T
                     for j in range(math.ceil((lo - v) / T), math.floor((hi - v) / T) + 1)]
        for c in cands:
            if (a < c <= b) or (b <= c < a):
                found.append(c)
    return sorted(set(found), reverse=bool(b < a))


@dataclass
class Step:
    """An accepted step from a to b: the unit secant, its length, the arclength at a, ds."""

    a: Solution
    b: Solution
    secant: Tangent
    dist: float
    arclength: float
    ds: float
    name: str

    def sigma(self, state: State) -> float:
        """Coordinate of a solution along the secant from a (0 at a, dist at b)."""
        return inner(difference(state, self.a.state, self.name, state.s), self.secant, state.s)

    def position(self, sigma: float) -> float:
        """Pseudo-arclength of the point at coordinate sigma (for ordering the points)."""
        return self.arclength + self.ds * sigma / self.dist


@dataclass
class Located:
    """A point located inside a step: its solution (linearised on its hyperplane), its
    coordinate sigma along the secant, and the test function's value there."""

    solution: Solution
    sigma: float
    value: float

    @property
    def state(self) -> State:
        return self.solution.state


@dataclass
class Placed:
    """A point placed inside a step without a search: its state, coordinate sigma along the
    secant and the test function's value there."""

    state: State
    sigma: float
    value: float


def along(corr, step: Step, fn, lo: float = 0.0, hi: float | None = None, s=None,
          ends: tuple[float, float] | None = None, xtol: float = 1e-12) -> Located:
    """Where the test function ``fn(solution)`` changes sign along the step: the solution on
    the hyperplane ``<x - a, secant> = sigma`` found by Brent's method in sigma in
    [lo, hi] (default the whole step), on the mesh ``s`` (default b's), to ``xtol`` of the
    step. ``ends``: fn at lo and hi where known (None where not). The one locator of every
    event but folds.
    CorrectorFailure if fn has one sign at both ends."""
    s = step.b.mesh if s is None else s
    hi = step.dist if hi is None else hi
    found = {}

    def f(sigma):
        sol = corr.on_plane(step.a, step.secant, sigma, s, regrid=False)
        found[sigma] = sol
        return fn(sol)

    f0, f1 = ends or (None, None)
    f0 = f(lo) if f0 is None else f0
    f1 = f(hi) if f1 is None else f1
    if f0 * f1 > 0:
        raise CorrectorFailure("no sign change along the step")
    sigma = brent(f, lo, hi, f0, f1, xtol * step.dist)
    value = f(sigma) if sigma not in found else fn(found[sigma])
    return Located(found[sigma], sigma, value)


def brent(f, x0, x1, f0, f1, xtol, maxiter=200):
    """A root of f in [x0, x1] with f0 f1 < 0 by Brent's method (Brent, Algorithms for
    Minimization without Derivatives, 1973, ch. 4): inverse quadratic interpolation or
    secant steps on the latest iterates while they stay inside the bracket and each is
    less than half the step before the last, else bisection (at a multiple root, where
    interpolation creeps, about every fourth step). A step is at least ``xtol / 2``, so
    that the bracket collapses once the root is that close. Returns the end of the last
    bracket (of width at most ``xtol``) where |f| is smaller, an abscissa f was evaluated
    at. (Against the Illinois method it used before: 4.6 against 6.1 corrector solves per
    branch point on a refined mesh, 6.5 against 8.4 on b's.)"""
    a, b, fa, fb = x0, x1, f0, f1
    c, fc = a, fa
    d = e = b - a
    for _ in range(maxiter):
        if (fb > 0) == (fc > 0):                 # keep the root between b and c
            c, fc = a, fa
            d = e = b - a
        if abs(fc) < abs(fb):                    # b the best estimate
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        tol = 2.0 * 2.2e-16 * abs(b) + 0.5 * xtol
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            return b
        if abs(e) >= tol and abs(fa) > abs(fb):
            s = fb / fa
            if a == c:                           # secant
                p, q = 2.0 * m * s, 1.0 - s
            else:                                # inverse quadratic interpolation
                q, r = fa / fc, fb / fc
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0))
                q = (q - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0:
                q = -q
            else:
                p = -p
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e, d = d, p / q
            else:
                d = e = m
        else:
            d = e = m
        a, fa = b, fb
        b += d if abs(d) > tol else math.copysign(tol, m)
        fb = f(b)
    return b


def locate_fold(corr, step: Step, before: State | None = None) -> FoldPoint:
    """The fold between a and b, where the tangents' parameter components differ in sign.

    Bordered Newton (the corrector's ``fold``) from the solution on the step where that
    component, interpolated linearly, vanishes; if that converges off the step or to the fold
    ``before`` (the branch's previous one: a pair closer than the interpolation can tell),
    from where it vanishes exactly, found by Brent's method along the step. Raises
    CorrectorFailure if neither lands in the step."""
    la, lb = step.a.tangent.lam, step.b.tangent.lam
    reason = ""
    for start in ("estimate", "root"):
        if start == "estimate":
            near = corr.on_plane(step.a, step.secant, step.dist * la / (la - lb), step.b.mesh,
                                 regrid=False)
        else:
            near = _slope_root(corr, step)
        try:
            fold = corr.fold(near)
        except CorrectorFailure as exc:
            reason = str(exc)
            continue
        where = step.sigma(fold.state)
        d = difference(fold.state, step.a.state, step.name, fold.state.s)
        off = math.sqrt(max(inner(d, d, fold.state.s) - where * where, 0.0))
        if not (-0.01 * step.dist <= where <= 1.01 * step.dist) or off > step.dist:
            reason = (f"the fold system converged off the step (at sigma = {where:.3g} of "
                      f"{step.dist:.3g}, {off:.3g} beside it)")
        elif before is not None and _same(fold.state, before, step.name):
            reason = "the fold system converged to the fold before"
        else:
            return fold
    raise CorrectorFailure(reason)


def _same(x: State, y: State, name: str) -> bool:
    """The same solution (a fold found twice), to the accuracy folds are located to."""
    lam = x.params[name]
    if abs(y.params[name] - lam) > 1e-9 * (1 + abs(lam)):
        return False
    s = x.s
    return bool(np.max(np.abs(x.y - y(s))) <= 1e-6 * (1 + np.max(np.abs(x.y))))


def _slope_root(corr, step: Step) -> Solution:
    """The solution on the step where the tangent's parameter component vanishes (to 1e-6
    of the step)."""
    return along(corr, step, lambda sol: sol.tangent.lam,
                 ends=(step.a.tangent.lam, step.b.tangent.lam), xtol=1e-6).solution


def _det_on(corr, sol: Solution, row_direction: Tangent, s) -> tuple[int, float]:
    """(sign, log|det|) of the bordered Jacobian at ``sol`` on mesh ``s`` with the border row
    of ``row_direction`` (the corrector's linearisation): a test function that varies
    smoothly along a step on one mesh."""
    return corr.determinant(sol, row_direction, s)


#: The half-widths, as fractions of the step, of the brackets in which the branch point is
#: looked for on a refined mesh around its root on the mesh before (then in the whole step):
#: the roots move between the meshes by up to 1e-4 of the step on the shipped 3D runs (the
#: hyperplanes' coordinate of the discrete solution changes with its mesh), and the root
#: finder's iterations from a narrow bracket are fewer.
NEAR = (1e-3, 0.02)
#: The accuracy, as a fraction of the step, of a branch point's root: on the mesh it is
#: reported on (BP_XTOL: closer than the parameter's rounding at the symmetric points, where
#: the index counted at the branch point itself is then refused as it should be, the zero
#: eigenvalue at rounding level), and on a mesh it is only the start of a refined one's
#: search from (COARSE_XTOL: that mesh is made from the error estimate there, which a shift
#: of 1e-8 of the step does not change).
BP_XTOL = 1e-12
COARSE_XTOL = 1e-8


def locate_branch_point(corr, step: Step) -> Located:
    """The branch point between a and b, where the determinant changes sign: the root of
    ``det(sigma) / |det(0)|`` along the hyperplanes, on b's mesh and then, until the solution
    and the kernel (the other branch's direction) are resolved to ``fold_tol``, on
    equidistributed ones, bracketed within NEAR of the root on the mesh before; to BP_XTOL of
    the step, on b's mesh first to COARSE_XTOL (b's mesh is seldom the last). ``value``: the
    scaled determinant there.

    The sign change must be seen on two meshes: a change of sign that an under-resolved mesh
    makes (a discrete eigenvalue that crosses zero on one mesh only) is not a branch point.
    Where the root was found again on an equidistributed mesh, between two points solved
    there (b's mesh did not resolve the kernel to ``fold_tol``, as at every branch point of
    the shipped 3D runs), that is the second mesh; else a and b are solved again on the last
    mesh with every interval halved. CorrectorFailure where the change does not survive."""
    s, brackets, xtol = step.b.mesh, [(0.0, step.dist)], COARSE_XTOL
    for _ in range(4):
        bp, solved_here = _branch_point_on(corr, step, s, brackets, xtol)
        sol = bp.solution
        rms = np.maximum(sol.rms, corr.kernel_error(sol))
        brackets = [(max(bp.sigma - w * step.dist, 0.0), min(bp.sigma + w * step.dist,
                                                               step.dist))
                    for w in NEAR] + [(0.0, step.dist)]
        if rms.max() <= corr.options.fold_tol:
            if xtol > BP_XTOL:
                bp, solved_here = _branch_point_on(corr, step, s, brackets, BP_XTOL)
            if s is step.b.mesh or not solved_here:
                check_on_finer_mesh(corr, step, bp.solution.mesh)
            return bp
        # the solution's own mesh: solve_bvp's corrector refines the one it is given
        s, xtol = corr.fold_mesh(sol.mesh, rms), BP_XTOL
    raise CorrectorFailure(f"branch point: error estimate {rms.max():.2e} > fold_tol after "
                           "4 meshes")


def place_symmetric_branch_point(corr, problem, step: Step) -> Placed | None:
    """The branch point in the step where the module's symmetry holds: the one value of
    the parameter inside the step that its ``symmetric_values`` gives, solved there on b's
    mesh (:func:`locate_value`), where the group moves that state (its generator, then in
    the kernel of the linearisation, is not zero). Exact on every mesh: the discretised
    problem keeps the symmetry. None where the module gives no such value, or more than
    one, or the solve fails, or the group fixes the state there: the determinant's root is
    then searched for (:func:`locate_branch_point`). ``value`` 0: the determinant vanishes
    there."""
    if not getattr(problem, "has_symmetric_values", False):
        return None
    a, b, name = step.a.state, step.b.state, step.name
    lo, hi = sorted((a.params[name], b.params[name]))
    inside = [v for v in problem.symmetric_values(name, lo, hi, b.params) if lo < v < hi]
    if len(inside) != 1:
        return None
    try:
        state, sigma = locate_value(corr, step, a, b, 0.0, step.dist, inside[0])
    except CorrectorFailure:
        return None
    return Placed(state, sigma, 0.0) if moves(problem, state) else None


def check_on_finer_mesh(corr, step: Step, s):
    """CorrectorFailure unless the determinant has opposite signs at a and b solved again on
    the mesh ``s`` with its intervals halved (with as many halved as ``max_nodes`` allows),
    or vanishes at one end: |det| there at most BP_XTOL times |det| at the other.

    A step can land on the branch point itself (a branch whose arclength is its parameter's,
    stepped in exact fractions towards a branch point at a round value: AUTO-07p's `lin` at
    p1 = 1 and 4 with Gauss collocation), and the next step starts there. The determinant at
    that end is then zero to rounding and its sign is the rounding's, on either mesh (which
    end, and whether the step that lands or the one that leaves sees the change, depends on
    the BLAS kernel's rounding). Near a simple root the determinant is about linear along the
    step, so the ratio of its sizes at the two ends is the root's distance from the smaller
    end in units of the step: below the location's own tolerance, that end is the branch
    point on both meshes."""
    room = max(corr.options.max_nodes - len(s), 0)
    widest = np.argsort(np.diff(s))[::-1][:room]
    fine = np.sort(np.concatenate([s, (s[widest] + s[widest + 1]) / 2]))
    (sign_a, log_a), (sign_b, log_b) = [
        _det_on(corr, corr.on_plane(step.a, step.secant, sigma, fine, regrid=False),
                step.secant, fine) for sigma in (0.0, step.dist)]
    vanishes = sign_a == 0 or sign_b == 0 or abs(log_b - log_a) >= -math.log(BP_XTOL)
    if sign_a * sign_b >= 0 and not vanishes:
        raise CorrectorFailure("the determinant's change of sign does not survive a finer "
                               f"mesh ({len(fine)} nodes)")


def _branch_point_on(corr, step: Step, s, brackets, xtol: float) -> tuple[Located, bool]:
    """The root of the scaled determinant on mesh ``s``, in the first of the ``brackets``
    ((lo, hi) pairs) where it changes sign, to ``xtol`` of the step; and whether both ends
    of that bracket were solved on ``s`` (a, at sigma = 0, is only interpolated onto it)."""
    sec, a, b = step.secant, step.a, step.b
    known = {}

    def det(sigma):
        if sigma not in known:
            if sigma == 0.0:
                sol = a
            elif sigma == step.dist and s is b.mesh:
                sol = b     # on the hyperplane <x - a, secant> = dist by the secant's making
            else:
                sol = corr.on_plane(a, sec, sigma, s, regrid=False)
            known[sigma] = _det_on(corr, sol, sec, s)
        return known[sigma]

    for lo, hi in brackets:
        (sign0, ref), (sign1, log1) = det(lo), det(hi)
        if sign0 * sign1 < 0:
            break
    else:
        raise CorrectorFailure("the determinant does not change sign along the secant")

    def tau(sol):
        sign, logdet = _det_on(corr, sol, sec, s)
        # sign 0: a pivot exactly zero, the branch point itself (exp(-inf - ref) would be 0
        # too, but not where ref is -inf as well)
        return sign * math.exp(min(logdet - ref, 700.0)) if sign else 0.0

    root = along(corr, step, tau, lo, hi, s,
                 ends=(float(sign0), sign1 * math.exp(min(log1 - ref, 700.0))), xtol=xtol)
    return root, lo > 0.0 or np.array_equal(a.mesh, s)


def locate_index_change(corr, step: Step, index_of, index_a: int,
                        xtol: float = 1e-10) -> Located:
    """Where the stability index ``index_of(state)`` leaves ``index_a`` along the step, by
    bisection on the hyperplanes ``<x - a, secant> = sigma`` (the index is a step function:
    -1 where it is not counted, at the zero eigenvalue itself, is left out), to ``xtol`` of the
    step; ``value`` is the index just past it. For a branch point of even multiplicity,
    where the determinant keeps its sign and only the index says that eigenvalues crossed
    zero. CorrectorFailure where the index at b is ``index_a``."""
    s = step.b.mesh
    lo, hi, past = 0.0, step.dist, index_of(step.b.state)
    if past == index_a:
        raise CorrectorFailure("the index does not change along the step")
    best = step.b
    while hi - lo > xtol * step.dist:
        mid = 0.5 * (lo + hi)
        sol = corr.on_plane(step.a, step.secant, mid, s, regrid=False)
        k = index_of(sol.state)
        if k == index_a:
            lo = mid
        elif k >= 0:
            hi, past, best = mid, k, sol
        else:       # on the zero eigenvalue itself
            return Located(sol, mid, float(past))
    return Located(best, hi, float(past))


def pair_suspected(step: Step, dip: float = 0.5) -> float | None:
    """Where inside the step a fold pair may hide, as a fraction of the step, or None.

    The parameter along the step is modelled by the cubic with its values and slopes (the
    tangents' parameter components, per unit arclength) at a and b; its slope is then the
    quadratic ``q(u) = l_a + beta u + gamma u^2`` on u in [0, 1]. Suspected: q changes sign
    inside (two folds the end tests cannot see), or dips below ``dip`` times the smaller end
    slope (a near-cusp, where a pair can be narrower than the model). Never where both end
    slopes are within TURN_NOISE: their signs are rounding, and so would a dip be."""
    la, lb = step.a.tangent.lam, step.b.tangent.lam
    if la == 0.0 or la * lb <= 0 or max(abs(la), abs(lb)) <= TURN_NOISE:
        return None
    mean = (step.b.lam - step.a.lam) / step.dist
    gamma = 3.0 * (la + lb - 2.0 * mean)
    beta = lb - la - gamma
    sign = math.copysign(1.0, la)
    if sign * gamma <= 0:
        return None         # q is concave in the direction of travel: no interior minimum
    u = -beta / (2 * gamma)
    if not 0.0 < u < 1.0:
        return None
    q_min = la + beta * u + gamma * u * u
    if sign * q_min <= dip * min(abs(la), abs(lb)):
        return u
    return None


def locate_value(corr, step: Step, x: State, y: State, s0: float, s1: float,
                 value: float) -> tuple[State, float]:
    """The solution with the continued parameter equal to ``value`` between the knots x and y
    (secant coordinates s0 < s1): solved at that value from their interpolation (chord
    iterations with b's Jacobian), checked to lie between them, else found by Brent's
    method on the parameter along the hyperplanes. Raises CorrectorFailure if neither
    works."""
    name = step.name
    lx, ly = x.params[name], y.params[name]
    w = (value - lx) / (ly - lx)
    s = step.b.mesh
    guess = State(s, (1 - w) * x(s) + w * y(s), (1 - w) * x.derivative(s) + w * y.derivative(s),
                  {**y.params, name: value})
    margin = 0.05 * (s1 - s0) + 1e-12
    try:
        state = corr.at_value(guess, y.params, value, near=step.b)
        sigma = step.sigma(state)
        if s0 - margin <= sigma <= s1 + margin:
            return state, min(max(sigma, s0), s1)
    except CorrectorFailure:
        pass

    def lam(sol):
        return sol.lam - value

    ends = (step.a.lam - value if s0 == 0.0 else None,
            step.b.lam - value if s1 == step.dist else None)
    try:
        at = along(corr, step, lam, s0, s1, s, ends=ends)
    except CorrectorFailure:
        raise CorrectorFailure(f"{name} does not cross {value:.6g} in this step") from None
    sol = at.solution
    return corr.at_value(sol.state, y.params, value, near=sol), at.sigma


def locate_limit(corr, problem, step: Step, limit) -> Located:
    """Where a limit on an ordinate or a free parameter (``stop = ["u_max > 5"]``) is
    reached inside the step, its excess passing zero."""
    return along(corr, step, lambda sol: limit.excess(problem, sol.state),
                 ends=(limit.excess(problem, step.a.state), limit.excess(problem, step.b.state)))


def tangent_between(step: Step, sigma: float) -> Tangent:
    """The unit tangent at coordinate sigma of the step, interpolated between a's and b's
    (for labelled points that are not located by a linearisation of their own)."""
    u = min(max(sigma / step.dist, 0.0), 1.0)
    s = step.b.mesh
    ta, tb = step.a.tangent.on(s), step.b.tangent
    t = Tangent(s, (1 - u) * ta.y + u * tb.y, (1 - u) * ta.yp + u * tb.yp,
                (1 - u) * ta.lam + u * tb.lam)
    return t.scaled(1.0 / max(float(np.sqrt(inner(t, t))), 1e-300))
