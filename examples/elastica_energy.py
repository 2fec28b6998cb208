"""The planar elastica with a lever arm, written as its energy (docs/energy.md).

The rod of `elastica_lever_arm` (docs/design.md, "The elastica with a lever arm"): clamped at
s = 0 (turned by theta0), a rigid arm of length eps welded to the tip at the angle psi
(clockwise from the tip tangent), a dead load F = P (sin alpha, -cos alpha) at the arm's end.
The positions x' = -sin(theta), y' = cos(theta) are passive quadratures, and the load's
potential -F.r_A is an end term at s = 1, linear in x(1), y(1):

    E[theta] = int_0^1 theta'^2 / 2 ds - F.(r(1) + eps (sin(psi - theta(1)), cos(psi - theta(1))))

Everything else is derived: the states (theta, kappa = theta', x, y), the equations and the
free end's natural condition kappa(1) + eps P sin(psi + alpha - theta(1)) = 0, the second
variation, and the distinguished ordinates (named as in the paper): dE/dpsi = m1, dE/deps =
beta, dE/dalpha = mA, dE/dP = gamma and the clamp's reaction -dE/dtheta0 = m0. P and alpha
enter only the end term (``"free"``), theta0 only the essential value (``"fixed"``). By hand:
the straight start, the mirror x -> -x, the drawing and the shooting scan (the shipped
module's).
"""

import math

import numpy as np

from elastica_auto import Mirror
from elastica_auto.equations.elastica_lever_arm import draw, shooting  # noqa: F401  (hooks)


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s = sp.Symbol("s", real=True)
    P, eps, psi, alpha, theta0 = sp.symbols("P eps psi alpha theta0", real=True)
    theta, x, y = (sp.Function(name)(s) for name in ("theta", "x", "y"))
    load = sp.Matrix([P * sp.sin(alpha), -P * sp.cos(alpha)])
    arm_end = sp.Matrix([x, y]) + eps * sp.Matrix([sp.sin(psi - theta), sp.cos(psi - theta)])
    angle = dict(period=2 * sp.pi)
    return Energy(
        density=theta.diff(s) ** 2 / 2,
        end1=-(load.T * arm_end)[0],
        s=s, coordinates=[theta], momenta={theta: "kappa"},
        quadratures={x: -sp.sin(theta), y: sp.cos(theta)},
        fixed0={theta: theta0, x: 0, y: 0},
        parameters={
            P: Param(sp.pi ** 2 / 4, "P", ordinate="gamma",
                     doc="load |F| l^2 / K; negative reverses F"),
            eps: Param(0.25, r"\epsilon", ordinate="beta",
                       doc="lever-arm length / l; negative flips it"),
            psi: Param(0.0, r"\psi", ordinate="m1", **angle,
                       doc="arm angle to the tip tangent, clockwise"),
            alpha: Param(0.0, r"\alpha", ordinate="mA", **angle,
                         doc="load direction from the vertical"),
            theta0: Param(0.0, r"\theta_0", ordinate="m0", period_shift={theta: 2 * sp.pi},
                          doc="rotation of the clamp", **angle),
        })


def exact_start(s, p):
    """The straight rod theta = theta0 along the load line, exact where theta0 = alpha and
    sin(psi) = 0 (mod 2 pi); None otherwise."""
    if (abs(math.remainder(p["theta0"] - p["alpha"], 2 * math.pi)) > 1e-12
            or abs(math.sin(p["psi"])) > 1e-12):
        return None
    t = p["theta0"]
    return np.vstack((np.full_like(s, t), np.zeros_like(s), -s * math.sin(t), s * math.cos(t)))


#: The reflection x -> -x of the plane (as the shipped module's): the moments m1, mA, m0
#: change sign, and so does the shooting unknown theta'(0).
MIRROR = Mirror({"theta": "-theta", "kappa": "-kappa", "x": "-x"}, ("psi", "alpha", "theta0"),
                ("m1", "mA", "m0"), shooting=(-1,))
