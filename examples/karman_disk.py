"""Von Karman's rotating-disk flow with wall suction: a boundary layer with a free parameter.

A user module for elastica-auto (see `elastica_auto.model.problem` for the protocol). An infinite
disk rotates with angular velocity Omega in a viscous fluid at rest; with z the axial distance
in units of sqrt(nu / Omega), the similarity solution ``(u, v, w) = (r Omega F(z), r Omega
G(z), sqrt(nu Omega) H(z))`` satisfies (von Karman 1921; Cochran 1934)

    2 F + H' = 0,   F'' = F^2 - G^2 + H F',   G'' = 2 F G + H G',
    F(0) = 0,  G(0) = 1,  H(0) = -a,  F(inf) = 0,  G(inf) = 0,

with ``a`` the uniform suction through a porous disk (a = 0: the impermeable disk). The axial
inflow from infinity, ``H(inf) = -inflow``, is not prescribed: it is the free parameter this
module solves for (``FREE``), 0.884474 at a = 0, the values known there being
``F'(0) = 0.510233``, ``G'(0) = -0.615922`` (Cochran; Rogers and Lance 1960). With suction
the layer thins like 1/a and ``inflow -> a``, ``G'(0) -> -a``, ``F'(0) -> 1 / (2 a)``.

The semi-infinite interval is truncated to [0, z_inf] (the solution decays like
``exp(-inflow z)``: at z_inf = 20 the truncation changes the values above by ~1e-8) and
mapped to s = z / z_inf in [0, 1]. First-order state ``[F, F', G, G', H]`` (primes d/dz)::

    dF/ds = L F',  dF'/ds = L (F^2 - G^2 + H F'),  dG/ds = L G',
    dG'/ds = L (2 F G + H G'),  dH/ds = -2 L F,     L = z_inf,

six boundary conditions for five states: F(0), G(0) - 1, H(0) + a, F(1), G(1),
H(1) + inflow.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("F", "dF", "G", "dG", "H")

PARAMETERS = [
    Parameter("a", 0.0, r"a", "fixed", doc="suction through the disk: H(0) = -a"),
    Parameter("inflow", 0.884, r"-H(\infty)", "free",
              doc="axial inflow from infinity, H(z_inf) = -inflow; solved for"),
    Parameter("z_inf", 20.0, r"z_\infty", "ode", doc="where the interval is truncated"),
]

FREE = ("inflow",)


def rhs(s, y, p):
    L = p["z_inf"]
    F, dF, G, dG, H = y
    return L * np.vstack((dF, F * F - G * G + H * dF, dG, 2 * F * G + H * dG, -2 * F))


def rhs_jac(s, y, p):
    L = p["z_inf"]
    F, dF, G, dG, H = y
    jac = np.zeros((5, 5, y.shape[1]))
    jac[0, 1] = L
    jac[1, 0], jac[1, 1], jac[1, 2], jac[1, 4] = L * 2 * F, L * H, -L * 2 * G, L * dF
    jac[2, 3] = L
    jac[3, 0], jac[3, 2], jac[3, 3], jac[3, 4] = L * 2 * G, L * 2 * F, L * H, L * dG
    jac[4, 0] = -2 * L
    return jac


def rhs_dp(s, y, p, name):
    if name == "z_inf":
        return rhs(s, y, p) / p["z_inf"]
    return np.zeros_like(y)


def bc(ya, yb, p):
    return np.array((ya[0], ya[2] - 1.0, ya[4] + p["a"], yb[0], yb[2], yb[4] + p["inflow"]))


def bc_jac(ya, yb, p):
    da = np.zeros((6, 5))
    db = np.zeros((6, 5))
    da[0, 0] = da[1, 2] = da[2, 4] = 1.0
    db[3, 0] = db[4, 2] = db[5, 4] = 1.0
    return da, db


def bc_dp(ya, yb, p, name):
    out = np.zeros(6)
    if name == "a":
        out[2] = 1.0
    elif name == "inflow":
        out[5] = 1.0
    return out


def guess(s, p):
    """A rough profile with about the right slopes and inflow at a = 0."""
    z = p["z_inf"] * np.asarray(s, dtype=float)
    c, k, g = 0.51, 1.074, 0.616
    e = np.exp(-k * z)
    F = c * z * e
    dF = c * (1 - k * z) * e
    G = np.exp(-g * z)
    H = -p["a"] - 2 * c / k ** 2 * (1 - e * (1 + k * z))
    return np.vstack((F, dF, G, -g * G, H))


ORDINATES = [
    Ordinate("dF0", r"$F'(0)$", lambda s, y, p: y[1, 0], None, "radial wall shear F'(0)"),
    Ordinate("dG0", r"$G'(0)$", lambda s, y, p: y[3, 0], None, "azimuthal wall shear G'(0)"),
]
