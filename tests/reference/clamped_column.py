"""A column clamped at both ends: theta(0) = theta0, theta(1) = 0 and x(1) = 0.

A small equation module for elastica-auto (see `elastica_auto.model.problem` for the protocol): the
clamped-guided column of ``guided_column.py`` with its upper end also held on the axis,
x(1) = 0, by a lateral reaction Q, an unknown solved for (``FREE``). First-order state
``[theta, kappa, x, y]``::

    theta' = kappa,  kappa' = -P sin(theta) + Q cos(theta),  x' = -sin(theta),  y' = cos(theta),
    theta(0) = theta0,  theta(1) = 0,  x(0) = 0,  y(0) = 0,  x(1) = 0.

Five conditions for four states: Q is the Lagrange multiplier of the isoperimetric constraint
x(1) = -int_0^1 sin(theta) ds = 0, and the equations are those of the Lagrangian

    L[theta] = int_0^1 ( theta'^2 / 2 + P cos(theta) + Q sin(theta) ) ds.

The stability index is that of its second variation ``int_0^1 (h'^2 - (P cos(theta) + Q
sin(theta)) h^2) ds`` on h(0) = h(1) = 0 restricted to the variations that keep the end on
the axis, ``int_0^1 cos(theta) h ds = 0`` (a constraint of the `SecondVariation`). On the
straight column (Q = 0) the critical loads are 4 pi^2 = 39.478 (symmetric mode 1 - cos 2 pi
s), k^2 = 80.763 with tan(k/2) = k/2, k = 8.9868 (antisymmetric), 16 pi^2 = 157.91, ...; the
index is the number of them below P.
"""

import numpy as np

from elastica_auto import Constraint, Ordinate, Parameter, SecondVariation

STATES = ("theta", "kappa", "x", "y")

PARAMETERS = [
    Parameter("P", 0.0, r"P", "ode", doc="the dead compressive load / (EI / l^2)"),
    Parameter("Q", 0.0, r"Q", "ode", doc="the lateral reaction at s = 1, solved for"),
    Parameter("theta0", 0.0, r"\theta_0", "fixed", doc="rotation of the clamp at s = 0"),
]

FREE = ("Q",)


def rhs(s, y, p):
    theta = y[0]
    return np.vstack((y[1], -p["P"] * np.sin(theta) + p["Q"] * np.cos(theta), -np.sin(theta),
                      np.cos(theta)))


def rhs_jac(s, y, p):
    theta = y[0]
    jac = np.zeros((4, 4, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["P"] * np.cos(theta) - p["Q"] * np.sin(theta)
    jac[2, 0] = -np.cos(theta)
    jac[3, 0] = -np.sin(theta)
    return jac


def bc(ya, yb, p):
    return np.array((ya[0] - p["theta0"], yb[0], ya[2], ya[3], yb[2]))


ORDINATES = [
    Ordinate("y1", r"$y(1)$", lambda s, y, p: y[3, -1], "P",
             "height of the upper end: dL/dP; ordinate for P"),
    Ordinate("m0", r"$m_0$", lambda s, y, p: y[1, 0], "theta0",
             "moment at the clamp theta'(0) = -dL/dtheta0; ordinate for theta0"),
    Ordinate("m1", r"$m_1$", lambda s, y, p: y[1, -1], None, "moment at the upper clamp"),
]


def second_variation(s, y, p):
    """d2L[h] = int_0^1 (h'^2 - (P cos(theta) + Q sin(theta)) h^2) ds with h(0) = h(1) = 0,
    on int_0^1 cos(theta) h ds = 0 (the linearised x(1) = 0)."""
    theta = y[0]
    return SecondVariation(1.0, -p["P"] * np.cos(theta) - p["Q"] * np.sin(theta),
                           fixed0=[0], fixed1=[0], constraints=[Constraint(np.cos(theta))])


def exact_start(s, p):
    """The straight column, exact where theta0 = 0 (any P, Q = 0); None otherwise."""
    if p["theta0"] != 0:
        return None
    return np.vstack((np.zeros((3, len(s))), s))
