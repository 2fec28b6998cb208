"""The Bratu (Gelfand) problem, u'' + lam exp(u) = 0 on x in [0, 1], u(0) = u(1) = 0, written as
its energy (docs/energy.md)::

    E[u] = int_0^1 ( u'^2 / 2 - lam exp(u) ) ds,   u(0) = u(1) = 0.

Derived from it: the states ``[u, v]`` (v = u', the momentum), u' = v, v' = -lam exp(u), the
second variation ``int_0^1 (h'^2 - lam exp(u) h^2) ds`` on h(0) = h(1) = 0 (the stability
index: 0 on the lower family, 1 on the upper, changing at the fold), lam's distinguished
ordinate dE/dlam = -int exp(u) ds (lam enters the equation: docs/stability.md, "The fold
rule") and the energy E. By hand: the start u = 0 at lam = 0 (``start = "trivial"``) and two
more ordinates.

Continuing lam upward, the branch of solutions folds at lam_c = 3.51383... and returns toward
lam -> 0 with u(1/2) growing without bound. The solutions are known in closed form,

    u(x) = -2 ln( cosh(z (x - 1/2)) / cosh(z / 2) ),   lam = 2 z^2 / cosh(z / 2)^2,

so u'(0) = 2 z tanh(z / 2), u(1/2) = 2 ln cosh(z / 2), and the fold is where z tanh(z / 2) = 2.
The module written by hand, with every function of the protocol, is tests/reference/bratu.py.
"""

import numpy as np

from elastica_auto import Ordinate, hermite


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s, lam = sp.symbols("s lam", real=True)
    u = sp.Function("u")(s)
    return Energy(density=u.diff(s) ** 2 / 2 - lam * sp.exp(u), s=s, coordinates=[u],
                  momenta=["v"], fixed0={u: 0}, fixed1={u: 0},
                  parameters={lam: Param(0.0, r"\lambda",
                                         doc="the Bratu parameter in u'' + lam exp(u) = 0")})


def exact_start(s, p):
    """u = 0, exact at lam = 0 only; None otherwise."""
    return np.zeros((2, len(s))) if p["lam"] == 0 else None


ORDINATES = [
    Ordinate("du0", r"$u'(0)$", lambda s, y, p: y[1, 0], None, "slope at x = 0"),
    Ordinate("u_half", r"$u(1/2)$",
             lambda s, y, p: float(hermite(s, y[:1], y[1:2], np.array([0.5]))[0, 0]), None,
             "u at the midpoint, its maximum"),
]
