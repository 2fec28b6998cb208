"""A clamped-guided column: theta(0) = theta0, theta(1) = 0, the ends free to move sideways.

A small equation module for elastica-auto (see `elastica_auto.model.problem` for the protocol): an
inextensible elastic column of unit length and stiffness, clamped at s = 0 and held at s = 1
by a guide that keeps the tangent vertical but lets the end slide sideways, under a dead
compressive load P at s = 1. First-order state ``[theta, kappa, x, y]``::

    theta' = kappa,  kappa' = -P sin(theta),  x' = -sin(theta),  y' = cos(theta),
    theta(0) = theta0,  theta(1) = 0,  x(0) = 0,  y(0) = 0.

These are the Euler-Lagrange equations of the energy (the load's potential is P y(1))

    E[theta] = int_0^1 ( theta'^2 / 2 + P cos(theta) ) ds,

whose second variation ``int_0^1 (h'^2 - P cos(theta) h^2) ds`` on h(0) = h(1) = 0 gives the
stability index. On the straight column (theta0 = 0, theta = 0) its eigenvalues are
(n pi)^2 - P: the critical loads are (n pi)^2 and the index is the number of them below P.
Distinguished ordinates: dE/dP = y(1) for P (it enters the equation) and m0 = theta'(0) =
-dE/dtheta0 for the clamp's rotation theta0 (an essential end value; docs/stability.md).
"""

import numpy as np

from elastica_auto import Ordinate, Parameter, SecondVariation

STATES = ("theta", "kappa", "x", "y")

PARAMETERS = [
    Parameter("P", 0.0, r"P", "ode", doc="the dead compressive load / (EI / l^2)"),
    Parameter("theta0", 0.0, r"\theta_0", "fixed", doc="rotation of the clamp at s = 0"),
]


def rhs(s, y, p):
    theta = y[0]
    return np.vstack((y[1], -p["P"] * np.sin(theta), -np.sin(theta), np.cos(theta)))


def rhs_jac(s, y, p):
    theta = y[0]
    jac = np.zeros((4, 4, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["P"] * np.cos(theta)
    jac[2, 0] = -np.cos(theta)
    jac[3, 0] = -np.sin(theta)
    return jac


def bc(ya, yb, p):
    return np.array((ya[0] - p["theta0"], yb[0], ya[2], ya[3]))


ORDINATES = [
    Ordinate("y1", r"$y(1)$", lambda s, y, p: y[3, -1], "P",
             "height of the guided end: dE/dP; ordinate for P"),
    Ordinate("m0", r"$m_0$", lambda s, y, p: y[1, 0], "theta0",
             "moment at the clamp theta'(0) = -dE/dtheta0; ordinate for theta0"),
    Ordinate("x1", r"$x(1)$", lambda s, y, p: y[2, -1], None, "sideways slide of the guided end"),
]


def second_variation(s, y, p):
    """d2E[h] = int_0^1 (h'^2 - P cos(theta) h^2) ds with h(0) = h(1) = 0."""
    return SecondVariation(1.0, -p["P"] * np.cos(y[0]), fixed0=[0], fixed1=[0])


def exact_start(s, p):
    """The straight column, exact where theta0 = 0 (any P); None otherwise."""
    if p["theta0"] != 0:
        return None
    return np.vstack((np.zeros((3, len(s))), s))
