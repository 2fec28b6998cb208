"""A cantilever with a load inside it: the elastica clamped at s = 0, free at s = 1, under a
dead tip load P along -y (it compresses the straight rod) and a dead lateral load F along +x
at mid-span, written from its energy alone (docs/energy.md, a load inside the rod).

The energy in the rod's own arclength sigma in [0, 1] (theta the tangent's angle from the y
axis, x' = -sin(theta), y' = cos(theta)) is ::

    E[theta] = int_0^1 theta'^2 / 2 d sigma + P y(1) - F x(1/2),    theta(0) = 0.

The load at sigma = 1/2 makes theta'' jump there (theta'' = -P sin(theta) + F cos(theta) on the
lower half, -P sin(theta) on the upper), which a density or rate written with a step in s
cannot give the collocation (a jump inside a mesh interval; such a module is refused). The
two halves are therefore two coordinates on s in [0, 1], the upper one run backwards, so that
the point where they meet is s = 1 for both:

    a(s) = theta(s / 2),        a(s) + b(s) = theta(1 - s / 2).

Continuity at mid-span is the essential end value b(1) = 0; the clamp is a(0) = 0; the tip is
s = 0 of the upper half, where b is natural (no moment). With d/d sigma = 2 d/ds on the lower
half and -2 d/ds on the upper, each half's bending energy int theta'^2 / 2 d sigma over a
length 1/2 is int_0^1 (2 q')^2 / 2 ds / 2 = int_0^1 q'^2 ds, so

    L = a'^2 + (a' + b')^2,

strictly convex in (a', b') (its Hessian [[4, 2], [2, 2]]). The positions are quadratures of
each half, X1' = -sin(a) / 2, Y1' = cos(a) / 2 (mid-span: x(1/2) = X1(1)), X2' = -sin(a + b) / 2,
Y2' = cos(a + b) / 2 (the tip: x(1) = X1(1) + X2(1)), and the loads are the end term
P (Y1(1) + Y2(1)) - F X1(1). The distinguished ordinate of F is dE/dF = -x(1/2), the
mid-span's deflection against the load.
"""

import numpy as np


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s, P, F = sp.symbols("s P F", real=True)
    a, b, X1, X2, Y1, Y2 = (sp.Function(n)(s) for n in ("a", "b", "X1", "X2", "Y1", "Y2"))
    half = sp.Rational(1, 2)
    return Energy(density=a.diff(s) ** 2 + (a.diff(s) + b.diff(s)) ** 2,
                  end1=P * (Y1 + Y2) - F * X1,
                  s=s, coordinates=[a, b],
                  quadratures={X1: -half * sp.sin(a), X2: -half * sp.sin(a + b),
                               Y1: half * sp.cos(a), Y2: half * sp.cos(a + b)},
                  fixed0={a: 0, X1: 0, X2: 0, Y1: 0, Y2: 0}, fixed1={b: 0},
                  parameters={P: Param(3.0, doc="the tip load, along -y"),
                              F: Param(0.0, doc="the lateral load at mid-span, along +x")})


def exact_start(s, p):
    """The straight rod, exact where there is no lateral load: a = b = 0, each half's height
    s / 2."""
    if p["F"] != 0:
        return None
    y = np.zeros((8, len(s)))
    y[6] = y[7] = s / 2
    return y
