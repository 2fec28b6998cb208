"""AUTO-07p's demo ``nep``: a linear eigenvalue problem with a normalisation, rewritten as an
equation module (the same equations and conditions)::

    u1' = u2,   u2' = -p2 u1,   u3' = -u2^2 / 2 - p2,
    u1(0) = 0,  u1(1) = 0,  u3(0) = p1,  u3(1) = -p1,

four conditions for three states: the eigenvalue p2 is solved for (``FREE``) as p1 is
continued. On u1 = 0 the last equation gives u3 = p1 - p2 s and p2 = 2 p1: the trivial family.
Where p2 = (k pi)^2 the first two equations have the nontrivial solutions u1 = c sin(k pi s),
and the branch of them, along which p2 stays (k pi)^2 and p1 = (k pi)^2 / 2 + c^2 (k pi)^2 / 8
(from 2 p1 = u3(0) - u3(1) = int (u2^2 / 2 + p2) ds), crosses the trivial one: branch points at
p1 = (k pi)^2 / 2.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("u1", "u2", "u3")

PARAMETERS = [
    Parameter("p1", 0.0, r"p_1", "fixed", doc="the end values of u3: u3(0) = p1, u3(1) = -p1"),
    Parameter("p2", 0.0, r"p_2", "ode", doc="the eigenvalue; solved for"),
]

FREE = ("p2",)


def rhs(s, y, p):
    return np.vstack((y[1], -p["p2"] * y[0], -y[1] ** 2 / 2 - p["p2"]))


def rhs_jac(s, y, p):
    jac = np.zeros((3, 3, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["p2"]
    jac[2, 1] = -y[1]
    return jac


def bc(ya, yb, p):
    return np.array((ya[0], yb[0], ya[2] - p["p1"], yb[2] + p["p1"]))


def exact_start(s, p):
    """u = 0, exact at p1 = p2 = 0."""
    return np.zeros((3, len(s))) if p["p1"] == 0 and p["p2"] == 0 else None


ORDINATES = [Ordinate("du0", r"$u_1'(0)$", lambda s, y, p: y[1, 0], None, "u1' at s = 0")]
