"""AUTO-07p's demo ``kar``: the rotating flow above a disk in a fluid that itself rotates,
rewritten as an equation module (the same equations, parameters and boundary conditions).

With gamma the ratio of the rotations (gamma = 1: the disk turns with the fluid, the flow is
the rigid rotation) and z the axial distance, the similarity equations, truncated to
[0, z_inf] and mapped to s = z / z_inf, are for the state ``u = (u1 .. u5)``::

    u1' = L u2,   u2' = L u3,   u3' = L (-2 gamma u4 + u2^2 - 2 u1 u3 - u4^2),
    u4' = L u5,   u5' = L (2 gamma u2 + 2 u2 u4 - 2 u1 u5),          L = z_inf = 500,

with six boundary conditions for five states: ``u1(0) = u2(0) = 0``, ``u4(0) = 1 - gamma``, the
two conditions of the linearised decay at z_inf (asymptotic boundary conditions, with
``c = sqrt(Finf^4 + 4 gamma^2)``, ``A = sqrt((c + Finf^2) / 2)``, ``B = sqrt((c - Finf^2) / 2)``)

    (Finf + A) u2(1) + u3(1) - gamma u4(1) / A = 0,
    A B^2 u2(1) / gamma + (Finf + A) u4(1) + u5(1) = 0,

and ``u1(1) = Finf``, where ``Finf = -fm`` (``fm`` is AUTO's PAR(2)) is solved for (``FREE``).
u = 0 with Finf = 0 solves them at gamma = 1 (``exact_start``). AUTO continues gamma down from
1 with 40 intervals of 4 Gauss points, looking for folds only; so does the run file
(``kar.toml``).
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("u1", "u2", "u3", "u4", "u5")

PARAMETERS = [
    Parameter("gamma", 1.0, r"\gamma", "ode", doc="the disk's rotation over the fluid's"),
    Parameter("fm", 0.0, r"-F_\infty", "free", doc="minus the axial flow at infinity; solved for"),
    Parameter("z_inf", 500.0, r"z_\infty", "ode", doc="where the interval is truncated"),
]

FREE = ("fm",)


def rhs(s, y, p):
    L, g = p["z_inf"], p["gamma"]
    u1, u2, u3, u4, u5 = y
    return L * np.vstack((u2, u3, -2 * g * u4 + u2 * u2 - 2 * u1 * u3 - u4 * u4, u5,
                          2 * g * u2 + 2 * u2 * u4 - 2 * u1 * u5))


def rhs_jac(s, y, p):
    L, g = p["z_inf"], p["gamma"]
    u1, u2, u3, u4, u5 = y
    jac = np.zeros((5, 5, y.shape[1]))
    jac[0, 1] = L
    jac[1, 2] = L
    jac[2, 0], jac[2, 1], jac[2, 2], jac[2, 3] = -2 * L * u3, 2 * L * u2, -2 * L * u1, \
        L * (-2 * g - 2 * u4)
    jac[3, 4] = L
    jac[4, 0], jac[4, 1], jac[4, 3], jac[4, 4] = -2 * L * u5, L * (2 * g + 2 * u4), \
        2 * L * u2, -2 * L * u1
    return jac


def bc(ya, yb, p):
    g, finf = p["gamma"], -p["fm"]
    # gamma = 0 is singular (A B^2 / gamma; B = 0 there by rounding): the residual is then
    # not finite, which the engine reports (the UZ the demo asks for at gamma = 0 is found by
    # neither program), without numpy's warnings
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.sqrt(finf ** 4 + 4 * g * g)
        a = np.sqrt((c + finf ** 2) / 2)
        b = np.sqrt((c - finf ** 2) / 2)
        return np.array((ya[0], ya[1], ya[3] - 1 + g,
                         (finf + a) * yb[1] + yb[2] - g * yb[3] / a,
                         a * b * b * yb[1] / g + (finf + a) * yb[3] + yb[4],
                         yb[0] - finf))


def exact_start(s, p):
    """u = 0, exact at gamma = 1 with Finf = 0."""
    return np.zeros((5, len(s))) if p["gamma"] == 1 and p["fm"] == 0 else None


ORDINATES = [
    Ordinate("du2_0", r"$u_3(0)$", lambda s, y, p: y[2, 0], None, "u3 at the disk"),
]
