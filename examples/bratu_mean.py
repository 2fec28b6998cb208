"""The Bratu problem with a prescribed mean: u'' + lam exp(u) = 0, u(0) = u(1) = 0 and

    int_0^1 u dx = M,

an integral condition (AUTO-07p's NINT) with lam solved for (``FREE``), continued in M. In
lam the Bratu branch folds at lam_c = 3.5138; in M it does not: the mean grows along the
whole family u = -2 ln(cosh(z (x - 1/2)) / cosh(z / 2)), lam = 2 z^2 / cosh^2(z / 2), so the
continuation in M passes lam_c without a fold and lam rises, then falls. First-order state
``[u, v]``, v = u'.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("u", "v")

PARAMETERS = [
    Parameter("lam", 0.0, r"\lambda", "ode", doc="the Bratu parameter, solved for"),
    Parameter("M", 0.0, r"M", "ode", doc="the prescribed mean of u"),
]

INTEGRALS = ("mean",)
FREE = ("lam",)


def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0])))


def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))


def integrals(s, y, p):
    """The integrand of int_0^1 (u - M) dx = 0."""
    return (y[0] - p["M"])[None, :]


def integrals_jac(s, y, p):
    jac = np.zeros((1, 2, y.shape[1]))
    jac[0, 0] = 1.0
    return jac


def exact_start(s, p):
    """u = 0, lam = 0: exact at M = 0 only."""
    return np.zeros((2, len(s))) if p["M"] == 0 else None


ORDINATES = [
    Ordinate("du0", r"$u'(0)$", lambda s, y, p: y[1, 0], "M", "slope at x = 0"),
]
