"""The Bratu problem with a prescribed mean and a free boundary level:

    u'' + lam exp(u) = 0,   u(0) = u(1) = c,   int_0^1 u dx = M,

with the level c solved for (``FREE``: two boundary conditions and an integral condition on
two states need one free parameter). Continued in lam at fixed M, the branch folds; the fold
moves with M, so the module has a fold curve in (lam, M).

Closed form. u - c solves the Bratu problem with zero ends at Lam = lam exp(c):

    u - c = -2 ln( cosh(z (x - 1/2)) / cosh(z / 2) ),   Lam = 2 z^2 / cosh(z / 2)^2,

whose mean is m(z) = int_0^1 (u - c) dx, so M = m(z) + c and

    lam exp(M) = Lam(z) exp(m(z)) =: G(z).

At fixed M the branch is z -> lam = G(z) exp(-M): it folds where G is largest, at z*, and the
fold curve is lam = G(z*) exp(-M) with c = M - m(z*) (the same solution shifted). First-order
state ``[u, v]``, v = u'.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("u", "v")

PARAMETERS = [
    Parameter("lam", 0.0, r"\lambda", "ode", doc="the Bratu parameter"),
    Parameter("M", 0.0, r"M", "ode", doc="the prescribed mean of u"),
    Parameter("c", 0.0, r"c", "fixed", doc="the level of u at both ends, solved for"),
]

INTEGRALS = ("mean",)
FREE = ("c",)


def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0])))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["lam"] * np.exp(y[0])
    return jac


def rhs_dp(s, y, p, name):
    out = np.zeros(y.shape)
    if name == "lam":
        out[1] = -np.exp(y[0])
    return out


def bc(ya, yb, p):
    return np.array((ya[0] - p["c"], yb[0] - p["c"]))


def bc_jac(ya, yb, p):
    return np.array([[1.0, 0.0], [0.0, 0.0]]), np.array([[0.0, 0.0], [1.0, 0.0]])


def bc_dp(ya, yb, p, name):
    return np.array((-1.0, -1.0)) if name == "c" else np.zeros(2)


def integrals(s, y, p):
    """The integrand of int_0^1 (u - M) dx = 0."""
    return (y[0] - p["M"])[None, :]


def integrals_jac(s, y, p):
    jac = np.zeros((1, 2, y.shape[1]))
    jac[0, 0] = 1.0
    return jac


def integrals_dp(s, y, p, name):
    return np.full((1, y.shape[1]), -1.0 if name == "M" else 0.0)


def exact_start(s, p):
    """u = M, lam = 0 (c = M: the free parameter's value comes from solving)."""
    return np.vstack((np.full(len(s), p["M"]), np.zeros(len(s)))) if p["lam"] == 0 else None


ORDINATES = [
    Ordinate("du0", r"$u'(0)$", lambda s, y, p: y[1, 0], "lam", "slope at x = 0"),
]
