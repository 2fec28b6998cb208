"""An independent solver for the elastica with a lever arm, by shooting (no elastica_auto code).

The reduced problem (docs/design.md, "The elastica with a lever arm") is the initial value problem

    theta'' = -P sin(theta - alpha),  theta(0) = theta0,  theta'(0) = k0,

whose solutions are equilibria when the free-end residual

    r(k0, psi) = kappa(1) + eps P sin(psi + alpha - theta(1))

vanishes. The Jacobi field u = d theta / d k0 solves u'' = -P cos(theta - alpha) u, u(0) = 0,
u'(0) = 1, so dr/dk0 = u'(1) - eps P cos(psi + alpha - theta(1)) u(1). A fold in psi is a root of
(r, dr/dk0) in (k0, psi). Everything is integrated by scipy's DOP853 at rtol = atol = 1e-12.
"""

from __future__ import annotations

import math

from scipy.integrate import solve_ivp
from scipy.optimize import brentq, root

RTOL = ATOL = 1e-12


def integrate(P, alpha, theta0, k0, rtol=RTOL, atol=ATOL):
    """(theta(1), kappa(1), u(1), u'(1)) for the IVP and its Jacobi field."""
    def f(s, z):
        th, k, u, up = z
        return [k, -P * math.sin(th - alpha), up, -P * math.cos(th - alpha) * u]

    sol = solve_ivp(f, (0.0, 1.0), [theta0, k0, 0.0, 1.0], method="DOP853", rtol=rtol, atol=atol)
    assert sol.success, sol.message
    return sol.y[:, -1]


def profile(P, alpha, y0, s):
    """The full state [theta, kappa, x, y] on the points s from y(0) = y0
    (theta' = kappa, kappa' = -P sin(theta - alpha), x' = -sin theta, y' = cos theta)."""
    def f(_, z):
        th, k = z[0], z[1]
        return [k, -P * math.sin(th - alpha), -math.sin(th), math.cos(th)]

    sol = solve_ivp(f, (0.0, 1.0), list(y0), method="DOP853", rtol=RTOL, atol=ATOL, t_eval=s)
    assert sol.success, sol.message
    return sol.y


def residual(k0, psi, P, eps, alpha=0.0, theta0=0.0, **kw):
    """(r, dr/dk0) at (k0, psi)."""
    th1, k1, u1, up1 = integrate(P, alpha, theta0, k0, **kw)
    a = psi + alpha - th1
    return k1 + eps * P * math.sin(a), up1 - eps * P * math.cos(a) * u1


def fold(P, eps, k0, psi, alpha=0.0, theta0=0.0, **kw):
    """The fold (k0, psi) nearest the guess, and kappa(1) there. Checks convergence."""
    sol = root(lambda z: residual(z[0], z[1], P, eps, alpha, theta0, **kw), [k0, psi],
               method="hybr", options={"xtol": 1e-12})
    r, dr = residual(sol.x[0], sol.x[1], P, eps, alpha, theta0, **kw)
    # |r| and |dr| are O(1)-scaled; 1e-10 is far above the integration error (~1e-13).
    assert abs(r) < 1e-10 and abs(dr) < 1e-10 * (1 + abs(eps * P)), (sol.message, r, dr)
    th1, k1, _, _ = integrate(P, alpha, theta0, sol.x[0], **kw)
    return float(sol.x[0]), float(sol.x[1]), float(k1)


def solve_at(psi, P, eps, k0, alpha=0.0, theta0=0.0):
    """The equilibrium k0 at fixed psi by Newton's method on r (exact derivative dr/dk0)."""
    for _ in range(50):
        r, dr = residual(k0, psi, P, eps, alpha, theta0)
        step = r / dr
        k0 -= step
        if abs(step) < 1e-13 * (1 + abs(k0)):
            return k0
    raise AssertionError(f"Newton did not converge at psi = {psi}")


def roots_beside_fold(psi, P, eps, k0_fold, width, alpha=0.0, theta0=0.0):
    """The two equilibria at fixed psi on either side of a fold at k0_fold: roots of r(., psi)
    in [k0_fold - width, k0_fold] and [k0_fold, k0_fold + width], by bracketing."""
    def r(k):
        return residual(k, psi, P, eps, alpha, theta0)[0]

    lo, mid, hi = k0_fold - width, k0_fold, k0_fold + width
    rlo, rmid, rhi = r(lo), r(mid), r(hi)
    assert rlo * rmid < 0 and rmid * rhi < 0, "no sign change on one side of the fold"
    return (brentq(r, lo, mid, xtol=1e-14, rtol=1e-14),
            brentq(r, mid, hi, xtol=1e-14, rtol=1e-14))
