"""AUTO-07p's demo ``non``: a Bratu-like problem whose nonlinearity depends on x,

    u'' + p exp(x^3 u) = 0   on x in [0, 1],   u(0) = u(1) = 0,

rewritten as an equation module. AUTO's equations are autonomous, so its demo carries x as a
third state (x' = 1, x(0) = 0); the protocol hands the module s, so here x = s and the state
is ``[u, v]``, v = u'. u = 0 at p = 0 starts the branch, which folds once (at p = 14.07...)
and returns toward p -> 0 with u growing.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter, simpson

STATES = ("u", "v")

PARAMETERS = [Parameter("p", 0.0, r"p", "ode", doc="the parameter of u'' + p exp(x^3 u) = 0")]


def rhs(s, y, p):
    return np.vstack((y[1], -p["p"] * np.exp(s ** 3 * y[0])))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["p"] * s ** 3 * np.exp(s ** 3 * y[0])
    return jac


def rhs_dp(s, y, p, name):
    return np.vstack((np.zeros(y.shape[1]), -np.exp(s ** 3 * y[0])))


def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))


def bc_jac(ya, yb, p):
    return np.array(((1.0, 0.0), (0.0, 0.0))), np.array(((0.0, 0.0), (1.0, 0.0)))


def exact_start(s, p):
    """u = 0, exact at p = 0 only."""
    return np.zeros((2, len(s))) if p["p"] == 0 else None


def _l2(s, y, p):
    """AUTO's L2-NORM of its three states (u, u', x): sqrt(int (u^2 + u'^2 + x^2) dx), with
    int x^2 dx = 1/3."""
    return float(np.sqrt(simpson(s, y[:1], y[1:2], lambda u: u[0] ** 2)
                         + simpson(s, y[1:2], rhs(s, y, p)[1:2], lambda v: v[0] ** 2) + 1 / 3))


ORDINATES = [
    Ordinate("du0", r"$u'(0)$", lambda s, y, p: y[1, 0], None, "slope at x = 0"),
    Ordinate("l2", r"$\|(u, u', x)\|_2$", _l2, None, "AUTO's L2-NORM, which its A1 bounds"),
]
