"""A clamped-guided column, theta(0) = theta0, theta(1) = 0, the ends free to move sideways,
written as its energy (docs/energy.md).

An inextensible elastic column of unit length and stiffness, clamped at s = 0 and held at s = 1
by a guide that keeps the tangent vertical but lets the end slide sideways, under a dead
compressive load P at s = 1 (its potential P y(1), linear in the position y(1))::

    E[theta] = int_0^1 theta'^2 / 2 ds + P y(1),   x' = -sin(theta), y' = cos(theta),
    theta(0) = theta0, theta(1) = 0, x(0) = y(0) = 0.

Derived from it: the states ``[theta, kappa, x, y]``, theta' = kappa, kappa' = -P sin(theta),
the second variation ``int_0^1 (h'^2 - P cos(theta) h^2) ds`` on h(0) = h(1) = 0 (the
stability index), P's distinguished ordinate dE/dP = y(1) (P enters the end term only:
``"free"``) and the clamp's reaction m0 = theta'(0) = -dE/dtheta0 (an essential end value;
docs/stability.md). On the straight column (theta0 = 0, theta = 0) the eigenvalues are
(n pi)^2 - P: the critical loads are (n pi)^2 and the index is the number of them below P.
By hand: the straight start and the slide of the guided end. The module written by hand is
tests/reference/guided_column.py.
"""

import numpy as np

from elastica_auto import Ordinate


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s, P, theta0 = sp.symbols("s P theta0", real=True)
    theta, x, y = (sp.Function(name)(s) for name in ("theta", "x", "y"))
    return Energy(density=theta.diff(s) ** 2 / 2, end1=P * y, s=s, coordinates=[theta],
                  momenta=["kappa"], quadratures={x: -sp.sin(theta), y: sp.cos(theta)},
                  fixed0={theta: theta0, x: 0, y: 0}, fixed1={theta: 0},
                  parameters={P: Param(0.0, "P", ordinate="y1",
                                       doc="the dead compressive load / (EI / l^2)"),
                              theta0: Param(0.0, r"\theta_0", ordinate="m0",
                                            doc="rotation of the clamp at s = 0")})


def exact_start(s, p):
    """The straight column, exact where theta0 = 0 (any P); None otherwise."""
    if p["theta0"] != 0:
        return None
    return np.vstack((np.zeros((3, len(s))), s))


ORDINATES = [
    Ordinate("x1", r"$x(1)$", lambda s, y, p: y[2, -1], None, "sideways slide of the guided end"),
]
