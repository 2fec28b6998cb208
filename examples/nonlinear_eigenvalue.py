"""A nonlinear eigenvalue problem with branch points: u'' + p u (1 + u^2) = 0 on x in [0, 1],
u(0) = u(1) = 0.

A small equation module for elastica-auto (see `elastica_auto.problem` for the protocol),
fixed at both ends and without a ``second_variation`` hook: its branch points are found from
the determinant of the bordered collocation Jacobian alone. First-order state ``[u, v]``,
v = u'::

    u' = v,  v' = -p u (1 + u^2),  u(0) = 0,  u(1) = 0.

u = 0 solves it for every p (``start = "trivial"``). Its linearisation ``u'' + p u = 0`` has
the solutions ``sin(k pi x)`` exactly at ``p = (k pi)^2``: branch points, where the
nontrivial branches bifurcate. On them the restoring force ``p u (1 + u^2)`` stiffens with
the amplitude, so p decreases as the amplitude grows (subcritical pitchforks).
"""

import numpy as np

from elastica_auto.problem import Ordinate, Parameter

STATES = ("u", "v")

PARAMETERS = [
    Parameter("p", 0.0, r"p", "ode", doc="the eigenvalue parameter in u'' + p u (1 + u^2) = 0"),
]


def rhs(s, y, p):
    u = y[0]
    return np.vstack((y[1], -p["p"] * u * (1 + u * u)))


def rhs_jac(s, y, p):
    u = y[0]
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["p"] * (1 + 3 * u * u)
    return jac


def rhs_dp(s, y, p, name):
    out = np.zeros_like(y)
    if name == "p":
        u = y[0]
        out[1] = -u * (1 + u * u)
    return out


def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))


def bc_jac(ya, yb, p):
    da = np.zeros((2, 2))
    db = np.zeros((2, 2))
    da[0, 0] = 1.0
    db[1, 0] = 1.0
    return da, db


def bc_dp(ya, yb, p, name):
    return np.zeros(2)


def _slope(s, y, p):
    return y[1, 0]


def _amplitude(s, y, p):
    return float(np.max(np.abs(y[0])))


ORDINATES = [
    Ordinate("slope", r"$u'(0)$", _slope, "p", "slope at x = 0; ordinate for p"),
    Ordinate("amplitude", r"$\max |u|$", _amplitude, None, "largest |u| on the mesh nodes"),
]


def exact_start(s, p):
    """u = 0, exact for every p."""
    return np.zeros((2, len(s)))
