"""Two interacting modes: a secondary bifurcation on a switched branch, in closed form.

    u'' + lam u - u (u^2 + a v^2) = 0,
    v'' + (lam - d) v - v (v^2 + a u^2) = 0,      u' = v' = 0 at s = 0 and s = 1,

the Euler-Lagrange equations of E = int ( (u'^2 + v'^2) / 2 - F(u, v) ) ds with
F = lam u^2 / 2 + (lam - d) v^2 / 2 - (u^4 + v^4) / 4 - a u^2 v^2 / 2. With ``a = 1/2`` and
``d = 1`` (the defaults) and lam below pi^2 (where the first non-constant mode cos(pi s)
would bifurcate), every branch is constant in s:

- u = v = 0, with branch points at lam = 0 (the u-mode) and lam = d = 1 (the v-mode);
- the pure modes u^2 = lam, v = 0 and u = 0, v^2 = lam - d;
- the mixed mode u^2 = (lam - a (lam - d)) / (1 - a^2), v^2 = (lam - d - a lam) / (1 - a^2),
  born from the pure u-mode at its secondary branch point lam = d / (1 - a) = 2, where the
  v-direction's coefficient lam - d - a u^2 vanishes.

The mixed mode is reached by switching twice (``switch_depth = 2``). First-order state
``[u, u', v, v']``.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("u", "du", "v", "dv")

PARAMETERS = [
    Parameter("lam", 0.0, r"\lambda", "ode", doc="the load on both modes"),
    Parameter("a", 0.5, r"a", "ode", doc="the modes' coupling"),
    Parameter("d", 1.0, r"d", "ode", doc="the v-mode's detuning"),
]


def rhs(s, y, p):
    u, du, v, dv = y
    a, lam = p["a"], p["lam"]
    return np.vstack((du, -lam * u + u * (u * u + a * v * v),
                      dv, -(lam - p["d"]) * v + v * (v * v + a * u * u)))


def rhs_jac(s, y, p):
    u, _, v, _ = y
    a, lam = p["a"], p["lam"]
    jac = np.zeros((4, 4, y.shape[1]))
    jac[0, 1] = jac[2, 3] = 1.0
    jac[1, 0] = -lam + 3 * u * u + a * v * v
    jac[1, 2] = jac[3, 0] = 2 * a * u * v
    jac[3, 2] = -(lam - p["d"]) + 3 * v * v + a * u * u
    return jac


def bc(ya, yb, p):
    return np.array((ya[1], ya[3], yb[1], yb[3]))


def exact_start(s, p):
    """u = v = 0, at every lam."""
    return np.zeros((4, len(s)))


ORDINATES = [
    Ordinate("u0", r"$u(0)$", lambda s, y, p: y[0, 0], "lam", "the u-mode's amplitude"),
    Ordinate("v0", r"$v(0)$", lambda s, y, p: y[2, 0], "lam", "the v-mode's amplitude"),
]
