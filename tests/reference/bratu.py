"""The Bratu (Gelfand) problem: u'' + lam exp(u) = 0 on x in [0, 1], u(0) = u(1) = 0.

A small non-elastica equation module for elastica-auto (see `elastica_auto.model.problem` for the
protocol). First-order state ``[u, v]`` with v = u'::

    u' = v,  v' = -lam exp(u),  u(0) = 0,  u(1) = 0.

u = 0 solves it at lam = 0 (``start = "trivial"``). Continuing lam upward, the branch of
solutions folds at lam_c = 3.51383... and returns toward lam -> 0 with u(1/2) growing without
bound. The solutions are known in closed form,

    u(x) = -2 ln( cosh(z (x - 1/2)) / cosh(z / 2) ),   lam = 2 z^2 / cosh(z / 2)^2,

so u'(0) = 2 z tanh(z / 2), u(1/2) = 2 ln cosh(z / 2), and the fold is where z tanh(z / 2) = 2.

The equation is the Euler-Lagrange equation of the energy

    E[u] = int_0^1 ( u'^2 / 2 - lam exp(u) ) ds,   u(0) = u(1) = 0,

whose second variation ``int_0^1 (h'^2 - lam exp(u) h^2) ds`` on h(0) = h(1) = 0 gives the
stability index (``second_variation``): 0 on the lower family, 1 on the upper, changing at the
fold. The distinguished ordinate of lam, which the fold rule reads, is dE/dlam = -int exp(u) ds
(``dE_dlam``; lam enters the equation: docs/stability.md, "The fold rule").
"""

import numpy as np
from elastica_auto import Ordinate, Parameter, SecondVariation, hermite, simpson

STATES = ("u", "v")

PARAMETERS = [
    Parameter("lam", 0.0, r"\lambda", "ode", doc="the Bratu parameter in u'' + lam exp(u) = 0"),
]


def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0])))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["lam"] * np.exp(y[0])
    return jac


def rhs_dp(s, y, p, name):
    out = np.zeros_like(y)
    if name == "lam":
        out[1] = -np.exp(y[0])
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


def _du0(s, y, p):
    return y[1, 0]


def _u_half(s, y, p):
    # u' = v is part of the state, so cubic Hermite interpolation is 4th-order accurate.
    return float(hermite(s, y[:1], y[1:2], np.array([0.5]))[0, 0])


def _de_dlam(s, y, p):
    return -simpson(s, y[:1], y[1:2], lambda u: np.exp(u[0]))


ORDINATES = [
    Ordinate("du0", r"$u'(0)$", _du0, None, "slope at x = 0"),
    Ordinate("u_half", r"$u(1/2)$", _u_half, None, "u at the midpoint, its maximum"),
    Ordinate("dE_dlam", r"$\partial E/\partial\lambda$", _de_dlam, "lam",
             "dE/dlam = -int exp(u) ds; ordinate for lam"),
]


def second_variation(s, y, p):
    """d2E[h] = int_0^1 (h'^2 - lam exp(u) h^2) ds with h(0) = h(1) = 0."""
    return SecondVariation(1.0, -p["lam"] * np.exp(y[0]), fixed0=[0], fixed1=[0])


def exact_start(s, p):
    """u = 0, exact at lam = 0 only; None otherwise."""
    if p["lam"] != 0:
        return None
    return np.zeros((2, len(s)))
