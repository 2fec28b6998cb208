"""AUTO-07p's demo ``lin``: a linear eigenvalue problem with an integral condition, rewritten as
an equation module (the same equations and conditions)::

    u1' = u2,   u2' = -(p1 pi)^2 u1,   u1(0) = p2,   u1(1) = 0,   int_0^1 u1^2 ds = p3,

three conditions for two states: p3 is solved for (``FREE``) as p1 is continued. u = 0 with
p3 = 0 solves it for every p1 (at p2 = 0); where p1 = k (k = 1, 2, ...) the solutions
c sin(k pi s) cross that family: branch points at p1 = k exactly, along which p1 stays k
and p3 = c^2 / 2.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter, simpson

STATES = ("u1", "u2")

PARAMETERS = [
    Parameter("p1", 0.0, r"p_1", "ode", doc="the frequency: u1'' = -(p1 pi)^2 u1"),
    Parameter("p2", 0.0, r"p_2", "fixed", doc="u1(0)"),
    Parameter("p3", 0.0, r"p_3", "ode", doc="int u1^2 ds; solved for"),
]

FREE = ("p3",)
INTEGRALS = ("norm",)


def rhs(s, y, p):
    return np.vstack((y[1], -(p["p1"] * np.pi) ** 2 * y[0]))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -(p["p1"] * np.pi) ** 2
    return jac


def bc(ya, yb, p):
    return np.array((ya[0] - p["p2"], yb[0]))


def integrals(s, y, p):
    return (y[0] * y[0] - p["p3"])[None, :]


def integrals_jac(s, y, p):
    jac = np.zeros((1, 2, y.shape[1]))
    jac[0, 0] = 2 * y[0]
    return jac


def exact_start(s, p):
    """u = 0, exact for every p1 at p2 = p3 = 0."""
    return np.zeros((2, len(s))) if p["p2"] == 0 and p["p3"] == 0 else None


def _l2(s, y, p):
    return float(np.sqrt(simpson(s, y[:1], y[1:2], lambda u: u[0] ** 2)
                         + simpson(s, y[1:2], rhs(s, y, p)[1:2], lambda v: v[0] ** 2)))


ORDINATES = [
    Ordinate("du0", r"$u_1'(0)$", lambda s, y, p: y[1, 0], None, "u1' at s = 0"),
    Ordinate("l2", r"$\|u\|_2$", _l2, None,
             "sqrt(int (u1^2 + u2^2) ds): AUTO's L2-NORM, which its A1 bounds"),
]
