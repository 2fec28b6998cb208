"""A column on an elastic (Winkler) foundation, written from its energy alone (the tutorial
of docs/energy.md).

A shearable (Timoshenko) column of unit length, bending stiffness 1 and shear stiffness G,
pinned at both ends, on a foundation of stiffness k, under the axial load P. Its coordinates
are the deflection w and the rotation phi of the cross-sections, with the energy ::

    E[w, phi] = int_0^1 ( phi'^2 / 2 + G (w' - phi)^2 / 2 + k w^2 / 2 - P w'^2 / 2 ) ds,
    w(0) = w(1) = 0 (pinned; phi free: no moment at the ends).

It is first order in (w, phi), and strictly convex in (w', phi') while P < G. The straight
column w = phi = 0 buckles where the mode w = sin(n pi s), phi = b cos(n pi s) solves the
linearised equations: with c = n pi,

    P_n = k / c^2 + G c^2 / (c^2 + G),

the Euler-Bernoulli column's (n pi)^2 + k / (n pi)^2 as G grows. A stiff foundation buckles
it in a higher mode first (k = 400, G = 100: P_2 = 38.43 < P_1 = 49.51 < P_3 = 51.54).
"""

import numpy as np


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s, P, k, G = sp.symbols("s P k G", real=True)
    w, phi = sp.Function("w")(s), sp.Function("phi")(s)
    density = (phi.diff(s) ** 2 / 2 + G * (w.diff(s) - phi) ** 2 / 2 + k * w ** 2 / 2
               - P * w.diff(s) ** 2 / 2)
    return Energy(density=density, s=s, coordinates=[w, phi], momenta=["Q", "M"],
                  fixed0={w: 0}, fixed1={w: 0},
                  parameters={P: Param(0.0, doc="the axial load"),
                              k: Param(400.0, doc="the foundation's stiffness"),
                              G: Param(100.0, doc="the shear stiffness")})


def exact_start(s, p):
    """The straight column, exact for every load."""
    return np.zeros((4, len(s)))
