"""A nonlinear eigenvalue problem with branch points: u'' + p u (1 + u^2) = 0 on x in [0, 1],
u(0) = u(1) = 0.

A small equation module for elastica-auto (see `elastica_auto.model.problem` for the protocol),
fixed at both ends. Its branch points are found from the determinant of the bordered
collocation Jacobian, which needs no stability hook. First-order state ``[u, v]``, v = u'::

    u' = v,  v' = -p u (1 + u^2),  u(0) = 0,  u(1) = 0.

u = 0 solves it for every p (``start = "trivial"``). Its linearisation ``u'' + p u = 0`` has
the solutions ``sin(k pi x)`` exactly at ``p = (k pi)^2``: branch points, where the
nontrivial branches bifurcate. On them the restoring force ``p u (1 + u^2)`` stiffens with
the amplitude, so p decreases as the amplitude grows (subcritical pitchforks).

The equation is the Euler-Lagrange equation of

    E[u] = int_0^1 ( u'^2 / 2 - p (u^2 / 2 + u^4 / 4) ) ds,   u(0) = u(1) = 0,

with the second variation ``int_0^1 (h'^2 - p (1 + 3 u^2) h^2) ds`` on h(0) = h(1) = 0
(``second_variation``). On u = 0 its eigenvalues are (k pi)^2 - p: the index is the number of
(k pi)^2 below p. The branch born at the k-th branch point lies at p < (k pi)^2, where the
trivial branch has index k - 1; by the exchange of stability at a pitchfork its critical
eigenvalue has the opposite sign, so its index is k. The distinguished ordinate of p is
dE/dp = -int (u^2/2 + u^4/4) ds (``dE_dp``).
"""

import numpy as np

from elastica_auto import Ordinate, Parameter, SecondVariation, simpson

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


def _de_dp(s, y, p):
    return 0.0 - simpson(s, y[:1], y[1:2], lambda u: u[0] ** 2 / 2 + u[0] ** 4 / 4)  # not -0


ORDINATES = [
    Ordinate("slope", r"$u'(0)$", _slope, None, "slope at x = 0"),
    Ordinate("amplitude", r"$\max |u|$", _amplitude, None, "largest |u| on the mesh nodes"),
    Ordinate("dE_dp", r"$\partial E/\partial p$", _de_dp, "p",
             "dE/dp = -int (u^2/2 + u^4/4) ds; ordinate for p"),
]


def second_variation(s, y, p):
    """d2E[h] = int_0^1 (h'^2 - p (1 + 3 u^2) h^2) ds with h(0) = h(1) = 0."""
    return SecondVariation(1.0, -p["p"] * (1 + 3 * y[0] ** 2), fixed0=[0], fixed1=[0])


def exact_start(s, p):
    """u = 0, exact for every p."""
    return np.zeros((2, len(s)))
