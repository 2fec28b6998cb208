"""AUTO-07p's demo ``pvl``: the Bratu problem u'' + lam exp(u) = 0, u(0) = u(1) = 0, with
AUTO's solution measures as output (its PVLS routine, here ``ORDINATES``): the L2 norm of u,
the least value of v = u', v(0) (AUTO's boundary value ``BV0``) and v at the first mesh
point (the same value).
"""

import numpy as np

from elastica_auto import Ordinate, Parameter, simpson

STATES = ("u", "v")

PARAMETERS = [Parameter("lam", 0.0, r"\lambda", "ode", doc="the Bratu parameter")]


def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0])))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["lam"] * np.exp(y[0])
    return jac


def rhs_dp(s, y, p, name):
    return np.vstack((np.zeros(y.shape[1]), -np.exp(y[0])))


def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))


def bc_jac(ya, yb, p):
    return np.array(((1.0, 0.0), (0.0, 0.0))), np.array(((0.0, 0.0), (1.0, 0.0)))


def exact_start(s, p):
    """u = 0, exact at lam = 0 only."""
    return np.zeros((2, len(s))) if p["lam"] == 0 else None


def _norm(s, y, p):
    return float(np.sqrt(simpson(s, y[:1], y[1:2], lambda u: u[0] ** 2)))


ORDINATES = [
    Ordinate("nrm", r"$\|u\|_2$", _norm, None, "the L2 norm of u (AUTO's NRM)"),
    Ordinate("vmin", r"$\min v$", lambda s, y, p: float(np.min(y[1])), None,
             "the least u' on the mesh (AUTO's MIN)"),
    Ordinate("v0", r"$v(0)$", lambda s, y, p: y[1, 0], None, "u'(0) (AUTO's BV0)"),
]
