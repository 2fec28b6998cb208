"""A column clamped at both ends, theta(0) = theta0, theta(1) = 0 and x(1) = 0, written as its
energy (docs/energy.md)::

    E[theta] = int_0^1 theta'^2 / 2 ds + P y(1),   x' = -sin(theta), y' = cos(theta),
    theta(0) = theta0, theta(1) = 0, x(0) = y(0) = 0, x(1) = 0,

the dead compressive load P on the upper end (its potential P y(1), linear in the position
y(1)), the end held on the axis by the isoperimetric constraint x(1) = 0, whose multiplier Q is
the lateral reaction, solved for (``FREE``): the Lagrangian is E - Q x(1) = int (theta'^2 / 2
+ P cos(theta) + Q sin(theta)) ds. Derived: the states ``[theta, kappa, x, y]``, theta' =
kappa, kappa' = -P sin(theta) + Q cos(theta), the five end conditions, the second variation
``int_0^1 (h'^2 - (P cos(theta) + Q sin(theta)) h^2) ds`` on h(0) = h(1) = 0 restricted to the
variations that keep the end on the axis (int cos(theta) h ds = 0), P's ordinate dE/dP =
y(1) and the clamp's reaction -dE/dtheta0 = kappa(0). On the straight column (Q = 0) the
critical loads are 4 pi^2 = 39.478 (symmetric mode 1 - cos 2 pi s), k^2 = 80.763 with
tan(k/2) = k/2, k = 8.9868 (antisymmetric), 16 pi^2 = 157.91, ...; the index is the number of
them below P. The module written by hand is tests/reference/clamped_column.py.
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
                  multipliers={x: -Q},        # E - Q x(1): Q the lateral reaction
                  parameters={P: Param(0.0, "P", ordinate="y1",
                                       doc="the dead compressive load / (EI / l^2)"),
                              Q: Param(0.0, "Q", doc="the lateral reaction holding x(1) = 0, "
                                                     "solved for"),
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
