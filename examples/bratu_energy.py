"""The Bratu problem (examples/bratu.py) written as its energy (docs/energy.md)::

    E[u] = int_0^1 ( u'^2 / 2 - lam exp(u) ) ds,   u(0) = u(1) = 0.

Derived: the states (u, v = u'), u'' + lam exp(u) = 0, the second variation int (h'^2 - lam
exp(u) h^2) on h(0) = h(1) = 0, lam's distinguished ordinate dE/dlam = -int exp(u) ds and the
energy E. By hand: the start u = 0 at lam = 0 and two more ordinates.
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
