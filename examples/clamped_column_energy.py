"""The column clamped at both ends (examples/clamped_column.py) written as its energy::

    E[theta] = int_0^1 theta'^2 / 2 ds + P y(1),   x' = -sin(theta), y' = cos(theta),
    theta(0) = theta0, theta(1) = 0, x(0) = y(0) = 0, x(1) = 0,

the dead load P on the upper end (its potential P y(1), linear in the position y(1)), the end
held on the axis by the isoperimetric constraint x(1) = 0, whose multiplier Q (E + Q x(1)) is
solved for. Q is minus the lateral reaction of examples/clamped_column.py (there the
Lagrangian has + Q sin(theta), here Q x' = -Q sin(theta)). Derived: the states (theta,
kappa, x, y), the equations, the constrained second variation (int cos(theta) h ds = 0),
P's ordinate dE/dP = y(1) and the clamp's reaction -dE/dtheta0 = kappa(0).
"""

import numpy as np

from elastica_auto import Ordinate


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s, P, Q, theta0 = sp.symbols("s P Q theta0", real=True)
    theta, x, y = (sp.Function(name)(s) for name in ("theta", "x", "y"))
    return Energy(density=theta.diff(s) ** 2 / 2, end1=P * y, s=s, coordinates=[theta],
                  momenta=["kappa"], quadratures={x: -sp.sin(theta), y: sp.cos(theta)},
                  fixed0={theta: theta0, x: 0, y: 0}, fixed1={theta: 0, x: 0},
                  multipliers={x: Q},
                  parameters={P: Param(0.0, "P", ordinate="y1",
                                       doc="the dead compressive load / (EI / l^2)"),
                              Q: Param(0.0, "Q", doc="the multiplier of x(1) = 0, solved for"),
                              theta0: Param(0.0, r"\theta_0", ordinate="m0",
                                            doc="rotation of the clamp at s = 0")})


def exact_start(s, p):
    """The straight column, exact where theta0 = 0 (any P, Q = 0); None otherwise."""
    if p["theta0"] != 0:
        return None
    return np.vstack((np.zeros((3, len(s))), s))


ORDINATES = [
    Ordinate("m1", r"$m_1$", lambda s, y, p: y[1, -1], None, "moment at the upper clamp"),
]
