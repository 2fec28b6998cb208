"""AUTO-07p's demo ``spb``: a singularly perturbed boundary value problem,

    eps u'' = rl ( u (u^2 - 1) u' + u ),   u(0) = 3/2,   u(1) = gamma,

rewritten as an equation module (state ``[u, v]``, v = u'). At rl = 0 the solution is the
straight line ``u = 3/2 + (gamma - 3/2) s`` (``exact_start``); the demo continues rl from 0 to
1 (a homotopy), then eps from 0.1 down to 1e-5, where the solution has layers of width ~eps,
then gamma from the solution at eps = 1e-3 down to -2.2.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("u", "v")

PARAMETERS = [
    Parameter("gamma", 1.2, r"\gamma", "free", doc="u(1)"),
    Parameter("eps", 0.1, r"\varepsilon", "ode", doc="the small parameter"),
    Parameter("rl", 0.0, r"r", "ode", doc="the homotopy from u'' = 0"),
]


def rhs(s, y, p):
    u, v = y
    return np.vstack((v, p["rl"] * (u * (u * u - 1) * v + u) / p["eps"]))


def rhs_jac(s, y, p):
    u, v = y
    c = p["rl"] / p["eps"]
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = c * ((3 * u * u - 1) * v + 1)
    jac[1, 1] = c * u * (u * u - 1)
    return jac


def bc(ya, yb, p):
    return np.array((ya[0] - 1.5, yb[0] - p["gamma"]))


def bc_jac(ya, yb, p):
    return np.array(((1.0, 0.0), (0.0, 0.0))), np.array(((0.0, 0.0), (1.0, 0.0)))


def exact_start(s, p):
    """The straight line from 3/2 to gamma, exact at rl = 0."""
    if p["rl"] != 0:
        return None
    slope = p["gamma"] - 1.5
    return np.vstack((1.5 + slope * s, np.full(len(s), slope)))


ORDINATES = [Ordinate("v0", r"$u'(0)$", lambda s, y, p: y[1, 0], None, "u' at s = 0")]
