"""Bratu's problem coupled to a mode that can buckle out of it, a symmetry-breaking pitchfork:

    u'' + lam exp(u) + a w^2 = 0,    w'' + (lam exp(u) + mu) w = 0,    u = w = 0 at x = 0, 1.

w -> -w is a symmetry. Its fixed solutions (w = 0) are Bratu's closed-form family

    u = -2 ln( cosh(z (x - 1/2)) / cosh(z / 2) ),    lam = 2 z^2 / cosh(z / 2)^2,

and along it the w-equation is the eigenvalue problem -w'' - lam exp(u) w = mu w: the family
has a branch point (w's mode grows out of it, both signs alike: a pitchfork) wherever mu is an
eigenvalue of -d^2/dx^2 - lam exp(u(x; lam)) with Dirichlet ends. The first one, mu =
Lambda_1(lam), is the curve a pitchfork curve from the first BP follows in (lam, mu)
(`tests/test_pitchfork.py` computes Lambda_1 by finite differences on the closed form).

The module declares no ``exact_start`` on purpose: its branch points are then off any exact
family, as a branch point of a computed branch is (the tendon robot's planar lift), and a
two-parameter run from one follows it as a pitchfork curve. It starts from ``guess``, the
solution u = w = 0 at lam = 0, solved for at the start's values. First-order state
``[u, u', w, w']``.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("u", "du", "w", "dw")

PARAMETERS = [
    Parameter("lam", 0.0, r"\lambda", "ode", doc="the Bratu parameter"),
    Parameter("mu", 5.0, r"\mu", "ode", doc="the shift of w's equation (its eigenvalue)"),
    Parameter("a", 1.0, r"a", "ode", doc="w's feedback on u (makes the pitchfork generic)"),
]


def rhs(s, y, p):
    e = p["lam"] * np.exp(y[0])
    return np.vstack((y[1], -e - p["a"] * y[2] ** 2, y[3], -(e + p["mu"]) * y[2]))


def rhs_jac(s, y, p):
    e = p["lam"] * np.exp(y[0])
    jac = np.zeros((4, 4, y.shape[1]))
    jac[0, 1] = jac[2, 3] = 1.0
    jac[1, 0] = -e
    jac[1, 2] = -2 * p["a"] * y[2]
    jac[3, 0] = -e * y[2]
    jac[3, 2] = -(e + p["mu"])
    return jac


def rhs_dp(s, y, p, name):
    out = np.zeros(y.shape)
    if name == "lam":
        out[1] = -np.exp(y[0])
        out[3] = -np.exp(y[0]) * y[2]
    elif name == "mu":
        out[3] = -y[2]
    elif name == "a":
        out[1] = -y[2] ** 2
    return out


def bc(ya, yb, p):
    return np.array((ya[0], yb[0], ya[2], yb[2]))


def bc_jac(ya, yb, p):
    ga, gb = np.zeros((4, 4)), np.zeros((4, 4))
    ga[0, 0] = gb[1, 0] = ga[2, 2] = gb[3, 2] = 1.0
    return ga, gb


def bc_dp(ya, yb, p, name):
    return np.zeros(4)


def guess(s, p):
    """u = w = 0 (the solution at lam = 0), solved from at the start's values."""
    return np.zeros((4, len(s)))


ORDINATES = [
    Ordinate("du0", r"$u'(0)$", lambda s, y, p: y[1, 0], "lam", "slope of u at x = 0"),
    Ordinate("dw0", r"$w'(0)$", lambda s, y, p: y[3, 0], "lam", "slope of w at x = 0"),
]
