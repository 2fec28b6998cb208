"""A heavy column (Greenhill's problem): a rod clamped upright at s = 0, free at s = 1, under
its own weight q (per length, EI / l^3 units), written as its energy in the minimal form::

    E[theta] = int_0^1 ( theta'^2 / 2 + q (1 - s) cos(theta) ) ds,   theta(0) = 0,

the weight of the rod above s acting at s (the reduced energy: its potential is q int y ds,
by parts). The upper end is natural: theta'(1) = 0. The straight column buckles at the
smallest q whose linearised equation h'' + q (1 - s) h = 0, h(0) = 0, h'(1) = 0 has a
solution: with x = 1 - s, h = sqrt(x) J_{-1/3}(2/3 sqrt(q) x^{3/2}), so J_{-1/3}(2/3 sqrt(q))
= 0 and q_c = (3 j / 2)^2 = 7.8373, j = 1.86635 the first zero of J_{-1/3}
(tests/test_energy.py checks the branch point against it).
"""

import numpy as np


def ENERGY():                      # called only when the cache misses
    import sympy as sp
    from elastica_auto.energy import Energy
    s, q = sp.symbols("s q", real=True)
    theta = sp.Function("theta")(s)
    return Energy(density=theta.diff(s)**2 / 2 + q * (1 - s) * sp.cos(theta),
                  s=s, coordinates=[theta], parameters={q: 0.0},
                  fixed0={theta: 0})   # essential at s = 0; every other end natural


def exact_start(s, p):
    """The straight column theta = 0, exact for every q."""
    return np.zeros((2, len(s)))
