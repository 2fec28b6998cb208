"""AUTO-07p's demo ``int``: the Bratu equation with a periodicity-like boundary condition and an
integral condition,

    u'' + lam exp(u) = 0,   u(0) - u(1) = p2,   int_0^1 u ds = p3,

two conditions for the two states of u'' (AUTO's NBC = 1, NINT = 1), with lam continued and
p2 = p3 = 0 held. The protocol asks for at least one boundary condition per state
(`elastica_auto.model.problem`), so the integral is carried as a third state here,
w' = u - p3 with w(0) = w(1) = 0: the same solutions u, and the same condition on them.
u = 0 at lam = 0 starts the branch, which folds once (lam = 11.92...).
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("u", "v", "w")

PARAMETERS = [
    Parameter("lam", 0.0, r"\lambda", "ode", doc="the Bratu parameter"),
    Parameter("p2", 0.0, r"p_2", "fixed", doc="u(0) - u(1)"),
    Parameter("p3", 0.0, r"p_3", "ode", doc="the mean of u"),
]


def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0]), y[0] - p["p3"]))


def rhs_jac(s, y, p):
    jac = np.zeros((3, 3, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["lam"] * np.exp(y[0])
    jac[2, 0] = 1.0
    return jac


def bc(ya, yb, p):
    return np.array((ya[0] - yb[0] - p["p2"], ya[2], yb[2]))


def bc_jac(ya, yb, p):
    da = np.zeros((3, 3))
    db = np.zeros((3, 3))
    da[0, 0], db[0, 0] = 1.0, -1.0
    da[1, 2] = 1.0
    db[2, 2] = 1.0
    return da, db


def exact_start(s, p):
    """u = 0, exact at lam = p2 = p3 = 0."""
    return np.zeros((3, len(s))) if p["lam"] == p["p2"] == p["p3"] == 0 else None


ORDINATES = [Ordinate("u0", r"$u(0)$", lambda s, y, p: y[0, 0], None, "u at s = 0")]
