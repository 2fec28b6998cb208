"""A column in space, written from its energy alone (docs/energy.md, "Tutorial: a rod in
space"): an inextensible, unshearable rod of length 1, clamped at s = 0 along e_z, free at
s = 1 under a dead compressive load P along -e_z, bending stiffnesses 1 and b2 about its two
principal axes, torsional stiffness c::

    E[R] = int_0^1 (u1^2 + b2 u2^2 + c u3^2) / 2 ds + P z(1),   r' = d3,   R(0) = I,

u = (R^T R')^vee the body curvature, the frame R a rotation coordinate (its quaternion and
spatial moment are derived states), the centreline r = (x, y, z) quadratures. Nothing else is
written but the straight start. Continued in P from the straight column, it buckles where a
clamped-free column of stiffness B does, P = B ((2 n - 1) pi / 2)^2 for B = 1 and B = b2: the
branch points, each raising the index by one (tests/test_energy_rod.py).
"""

import numpy as np


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param, Rotation
    s, P, b2, c = sp.symbols("s P b2 c", real=True)
    R = Rotation("R")
    x, y, z = (sp.Function(name)(s) for name in ("x", "y", "z"))
    u1, u2, u3 = R.strain
    return Energy(density=(u1 ** 2 + b2 * u2 ** 2 + c * u3 ** 2) / 2, end1=P * z,
                  s=s, coordinates=[R], quadratures={x: R.d3[0], y: R.d3[1], z: R.d3[2]},
                  fixed0={R: (1, 0, 0, 0), x: 0, y: 0, z: 0},
                  parameters={P: Param(0.0, doc="the dead compressive load at the tip"),
                              b2: Param(2.0, "b_2", doc="the second bending stiffness"),
                              c: Param(0.8, doc="the torsional stiffness")})


def exact_start(s, p):
    """The straight column along e_z (any load): R = I, no moment."""
    out = np.zeros((10, len(s)))
    out[0] = 1.0                                     # q = (1, 0, 0, 0)
    out[9] = s                                       # z = s
    return out
