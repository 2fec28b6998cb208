"""Planar Cosserat rod (shearable, extensible) with a rigid lever arm, written as its energy:
the shearable, extensible generalisation of ``elastica_lever_arm`` (docs/soft-robots.md,
"Cosserat rods"; the energy front end: docs/energy.md).

Nondimensional as the elastica: length 1, bending stiffness 1; the shear and extension
stiffnesses GA and EA in units of K / l^2. The rod is clamped at s = 0 (turned by theta0);
theta is the angle of the cross-section's normal to the vertical, so that the frame is
d3 = (-sin theta, cos theta) (the tangent of the unsheared rod, the elastica's tangent) and
d2 = (cos theta, sin theta) (the names of the spatial rod's frame in its plane:
``cosserat_rod`` in a planar state). The centreline r = (x, y) is a coordinate of its own:
the strains are

    u = theta' - u1,   v = R^T r' - (0, v2, v3),   v_2 = d2.r' (shear),  v_3 = d3.r' (stretch),

with the intrinsic curvature u1 and the intrinsic strains (v2, v3) = (0, 1) by default (a
straight, unsheared, unstretched reference). The energy::

    E = int_0^1 ( u^2/2 + GA (d2.r' - v2)^2/2 + EA (d3.r' - v3)^2/2 + g y ) ds
        - F.(r(1) + eps (sin(psi - theta(1)), cos(psi - theta(1)))),
    theta(0) = theta0,  r(0) = 0,

F = P (sin alpha, -cos alpha) the elastica's dead load at the end of its arm (the same P,
eps, psi, alpha, theta0 and conventions: docs/design.md), g the weight per unit length (a
distributed dead load -g e_y, along the elastica's load for alpha = 0).

Derived from it (`load_problem`, `elastica-auto derive`): the states ``[theta, m, x, y, nx,
ny]``, m = u the bending moment and n = dL/dr' = GA (v2 - v2hat) d2 + EA (v3 - v3hat) d3 the
contact force; the balances

    n' = (0, g) = -f,   m' = -(r' x n).e_z,

the clamp and the free end's n(1) = F, m(1) = eps (a x F).e_z; the second variation in
(theta, x, y); where each parameter enters and its distinguished ordinate (P, eps, psi, alpha,
theta0 named as the elastica names them: gamma, beta, m1, mA, m0) and the energy E. As GA and
EA grow, d2.r' -> v2 and d3.r' -> v3 = 1 and the rod becomes the elastica, every quantity at
O(1/GA + 1/EA) (docs/soft-robots.md).

By hand: the straight start (``exact_start``), the mirror x -> -x, and the drawing (the
elastica's).
"""

import math

import numpy as np

from elastica_auto import Mirror
from elastica_auto.energy import derived_names


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s = sp.Symbol("s", real=True)
    (P, eps, psi, alpha, theta0, GA, EA, g, u1, v2, v3) = sp.symbols(
        "P eps psi alpha theta0 GA EA g u1 v2 v3", real=True)
    theta, x, y = (sp.Function(name)(s) for name in ("theta", "x", "y"))
    d2 = sp.Matrix([sp.cos(theta), sp.sin(theta)])
    d3 = sp.Matrix([-sp.sin(theta), sp.cos(theta)])
    dr = sp.Matrix([x.diff(s), y.diff(s)])
    shear, stretch = (d2.T * dr)[0] - v2, (d3.T * dr)[0] - v3
    load = sp.Matrix([P * sp.sin(alpha), -P * sp.cos(alpha)])
    arm_end = sp.Matrix([x, y]) + eps * sp.Matrix([sp.sin(psi - theta), sp.cos(psi - theta)])
    angle = dict(period=2 * sp.pi)
    return Energy(
        density=((theta.diff(s) - u1) ** 2 + GA * shear ** 2 + EA * stretch ** 2) / 2 + g * y,
        end1=-(load.T * arm_end)[0],
        s=s, coordinates=[theta, x, y], momenta={theta: "m", x: "nx", y: "ny"},
        fixed0={theta: theta0, x: 0, y: 0},
        states=("theta", "m", "x", "y", "nx", "ny"),
        parameters={
            P: Param(sp.pi ** 2 / 4, "P", ordinate="gamma",
                     doc="load |F| l^2 / K; negative reverses F"),
            eps: Param(0.25, r"\epsilon", ordinate="beta",
                       doc="lever-arm length / l; negative flips it"),
            psi: Param(0.0, r"\psi", ordinate="m1", **angle,
                       doc="arm angle to the tip's d3, clockwise"),
            alpha: Param(0.0, r"\alpha", ordinate="mA", **angle,
                         doc="load direction from the vertical"),
            theta0: Param(0.0, r"\theta_0", ordinate="m0", period_shift={theta: 2 * sp.pi},
                          doc="rotation of the clamp", **angle),
            GA: Param(1000.0, "GA", doc="shear stiffness l^2 / K"),
            EA: Param(1000.0, "EA", doc="extension stiffness l^2 / K"),
            g: Param(0.0, "g", doc="weight per unit length l^3 / K, along -e_y"),
            u1: Param(0.0, r"\hat u_1", doc="intrinsic curvature"),
            v2: Param(0.0, r"\hat v_2", doc="intrinsic shear"),
            v3: Param(1.0, r"\hat v_3", doc="intrinsic stretch (1: unstretched)"),
        })


#: Imported as a Python module, the derived names (rhs, second_variation, PARAMETERS, ...)
#: on first use; `load_problem` gives them itself.
__getattr__ = derived_names(__name__)


#: The reflection x -> -x: theta -> -theta (d2 -> its mirror image with the sign of d2.e_x
#: kept: d2 -> -M d2, so the shear v2 changes sign), x -> -x, m -> -m, nx -> -nx; psi,
#: alpha, theta0, u1 and v2 change sign, and so do the moments m1, mA, m0 and the ordinates
#: of u1 and v2.
MIRROR = Mirror({"theta": "-theta", "m": "-m", "x": "-x", "nx": "-nx"},
                ("psi", "alpha", "theta0", "u1", "v2"),
                ("m1", "mA", "m0", "dE_du1", "dE_dv2"))


def exact_start(s, p):
    """The straight rod along the load line: theta = theta0, exact when the load and the
    weight lie along d3(0) (theta0 = alpha mod pi with P != 0 or P = 0; sin theta0 = 0 or
    g = 0), the arm along d3 (sin psi = 0 or eps P = 0), no intrinsic curvature or shear (u1 =
    v2 = 0). Then n(s) = F - g (1 - s) e_y is along d3, n.d3 = EA (v - v3) gives the stretch
    v = v3 + n.d3 / EA, m = 0, and r = d3 int_0^s v. None otherwise, and where a
    stiffness is zero (the generated code divides by GA and EA)."""
    t = p["theta0"]
    d3 = np.array((-math.sin(t), math.cos(t)))
    f = p["P"] * np.array((math.sin(p["alpha"]), -math.cos(p["alpha"])))
    if (abs(f[0] * d3[1] - f[1] * d3[0]) > 1e-12 * max(1.0, abs(p["P"]))
            or abs(p["g"] * d3[0]) > 1e-12 or abs(p["eps"] * p["P"] * math.sin(p["psi"])) > 1e-12
            or p["u1"] != 0 or p["v2"] != 0
            or p["EA"] == 0 or p["GA"] == 0):
        return None
    s = np.asarray(s, dtype=float)
    n3 = f @ d3 - p["g"] * (1 - s) * d3[1]                 # n.d3 along the rod
    # r.d3 = int_0^s (v3 + n3 / EA) ds, with int_0^s (1 - t) dt = s - s^2 / 2
    along = p["v3"] * s + ((f @ d3) * s - p["g"] * d3[1] * (s - s * s / 2)) / p["EA"]
    n = np.outer(d3, n3)
    return np.vstack((np.full_like(s, t), np.zeros_like(s), d3[0] * along, d3[1] * along,
                      n[0], n[1]))


def arm_end(profile, p):
    """The end of the lever arm of a profile ``[theta, m, x, y, ...]``."""
    theta1, x1, y1 = profile[0, -1], profile[2, -1], profile[3, -1]
    return np.array((x1 + p["eps"] * np.sin(p["psi"] - theta1),
                     y1 + p["eps"] * np.cos(p["psi"] - theta1)))


def draw(ax, profile, p):
    """The elastica's drawing (clamp, centreline, arm, load arrow): it reads the rows theta,
    x, y (0, 2, 3), which this rod's profile has in the same places."""
    import elastica_auto.equations.elastica_lever_arm as planar
    planar.draw(ax, profile, p)
