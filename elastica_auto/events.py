"""Detection and exact location of special points between two continuation points.

* LP (fold): the parameter component of the secant changes sign. Located by the extended
  system of :func:`elastica_auto.corrector.solve_fold`; its residual is stored and a failed
  solve is reported as an unlocated LP, never as a located one.
* BP (branch point): the direct stability index changes between two points with no fold near
  them; located as the zero of the Jacobi-field test function along the arclength hyperplanes.
* UZ (user point) and EP at a parameter bound: the parameter crosses a given value (for
  periodic values, any value + k * period). Located by solving the BVP at that value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from .corrector import (Curve, SolveResult, State, Tangent, inner, solve_arclength, solve_fixed,
                        solve_fold, solve_tangent)
from .problem import Problem
from .stability import singularity_test


@dataclass(frozen=True)
class UserValues:
    """UZ values of the continued parameter; with ``period`` every ``v + k period`` counts."""

    values: tuple[float, ...]
    period: float | None = None


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
            cands = [v + j * T for j in range(math.ceil((lo - v) / T), math.floor((hi - v) / T) + 1)]
        for c in cands:
            if (a < c <= b) or (b <= c < a):
                found.append(c)
    return sorted(set(found), reverse=bool(b < a))


def locate_value(problem: Problem, a: State, b: State, name: str, value: float, tol: float,
                 max_nodes: int) -> tuple[SolveResult, float]:
    """Solve the BVP at ``p[name] = value`` between points a and b.

    The initial guess interpolates a and b linearly in the parameter; returns the solve and
    that interpolation weight (0 at a, 1 at b) as the position estimate.
    """
    la, lb = a.params[name], b.params[name]
    w = (value - la) / (lb - la)
    s = b.s
    guess = Curve(s, (1 - w) * a(s) + w * b.y, (1 - w) * a.derivative(s) + w * b.yp)
    return solve_fixed(problem, guess, {**b.params, name: value}, tol, max_nodes), w


def locate_fold(problem: Problem, base: State, t_in: Tangent, t_out: Tangent, name: str,
                max_dist: float, tol: float, max_nodes: int) -> tuple[SolveResult, float]:
    """Locate the fold near ``base``, where the parameter component of the incoming secant
    ``t_in`` and the outgoing ``t_out`` differ in sign.

    The null-vector guess is the mean of the two secants' state components. Returns the solve
    and the fold's signed distance from ``base`` along ``t_out`` (its arclength offset). A
    converged solve that lands farther than ``max_dist`` (the bracket's length) from ``base``
    found some other fold and is reported as a failure.
    """
    s = base.s
    phi = Curve(s, t_in(s) + t_out(s), t_in.derivative(s) + t_out.derivative(s))
    res = solve_fold(problem, base, phi, name, tol, max_nodes)
    if not res.success:
        return res, 0.0
    st = res.state
    d = Tangent(st.s, st.y - base(st.s), st.yp - base.derivative(st.s),
                st.params[name] - base.params[name])
    offset = inner(d, t_out)
    dist = math.sqrt(max(inner(d, d), 0.0))
    if not np.isfinite(dist) or dist > max_dist:
        res.success = False
        res.message = (f"extended system converged {dist:.3g} away from the bracketing point "
                       "(another fold?)")
    return res, offset


def locate_branch_point(problem: Problem, a: State, t_out: Tangent, name: str, dist: float,
                        tol: float, max_nodes: int):
    """Locate a branch point between ``a`` and the next point, at distance ``dist`` along the
    unit secant ``t_out``, as the zero of the Jacobi-field test function
    (:func:`elastica_auto.stability.singularity_test`) on the arclength hyperplanes
    ``<u - u_a, t_out> = sigma``, by Brent's method in sigma.

    Returns ``(solve, sigma, g)`` for the located point, or ``(None, reason, nan)`` if the test
    function does not change sign or a corrector fails.
    """
    solves = {}

    def g(sigma):
        if sigma == 0.0:
            return singularity_test(problem, a)
        res = solve_arclength(problem, a, t_out, name, sigma, tol, max_nodes)
        if not res.success:
            raise RuntimeError(f"corrector failed at sigma = {sigma:.3g}: {res.message}")
        solves[sigma] = res
        return singularity_test(problem, res.state)

    try:
        g0, g1 = g(0.0), g(dist)
        if g0 == 0.0:
            return None, "the step starts at a singular point", float("nan")
        if g0 * g1 > 0:
            return None, "the test function does not change sign", float("nan")
        sigma = brentq(g, 0.0, dist, xtol=1e-13, rtol=4 * np.finfo(float).eps)
        if sigma == 0.0:
            return None, "the step starts at a singular point", float("nan")
        value = g(sigma)
    except RuntimeError as exc:
        return None, str(exc), float("nan")
    return solves[sigma], sigma, value


def locate_value_on_step(problem: Problem, a: State, direction: Tangent, name: str,
                         value: float, s0: float, s1: float, tol: float, max_nodes: int):
    """The solution with ``p[name] = value`` on the arclength hyperplanes
    ``<u - u_a, direction> = sigma``, sigma in [s0, s1], by Brent's method on the parameter's
    value along them, then solved at exactly that value. The robust fallback of a plain solve
    at fixed parameter, which may converge to a solution beyond a nearby fold.

    Returns ``(solve, sigma)``, or ``(None, reason)``.
    """
    def lam(sigma):
        if sigma == 0.0:
            return a.params[name] - value
        res = solve_arclength(problem, a, direction, name, sigma, tol, max_nodes)
        if not res.success:
            raise RuntimeError(f"corrector failed at sigma = {sigma:.3g}: {res.message}")
        solves[sigma] = res
        return res.lam - value

    solves = {}
    try:
        if lam(s0) * lam(s1) > 0:
            return None, f"{name} does not cross {value:.6g} in this step"
        sigma = brentq(lam, s0, s1, xtol=1e-12)
        lam(sigma)
    except RuntimeError as exc:
        return None, str(exc)
    near = solves[sigma].state
    res = solve_fixed(problem, near, {**near.params, name: value}, tol, max_nodes)
    if not res.success:
        return None, res.message
    return res, sigma


def locate_turning_point(problem: Problem, a: State, direction: Tangent, name: str,
                         s0: float, s1: float, tol: float, max_nodes: int):
    """The point where the continued parameter turns back (its tangent component vanishes)
    between the arclength hyperplanes ``<u - u_a, direction> = s0`` and ``s1``, by Brent's
    method on that component of the true tangent (oriented along ``direction``).

    For a turning point where the fold extended system is singular: the branch point of a
    pitchfork met along its bifurcating branch. Returns ``(state, sigma, lamdot)`` or
    ``(None, reason, nan)``."""
    states = {}

    def lamdot(sigma):
        if sigma == 0.0:
            st = a
        else:
            res = solve_arclength(problem, a, direction, name, sigma, tol, max_nodes)
            if not res.success:
                raise RuntimeError(f"corrector failed at sigma = {sigma:.3g}: {res.message}")
            st = res.state
        t = solve_tangent(problem, st, name, direction, tol, max_nodes)
        if t is None:
            raise RuntimeError(f"no tangent at sigma = {sigma:.3g}")
        states[sigma] = st
        return t.lam

    try:
        f0, f1 = lamdot(s0), lamdot(s1)
        if f0 * f1 > 0:
            return None, "the parameter does not turn in this interval", float("nan")
        sigma = brentq(lamdot, s0, s1, xtol=1e-12)
        value = lamdot(sigma)
    except RuntimeError as exc:
        return None, str(exc), float("nan")
    return states[sigma], sigma, value
