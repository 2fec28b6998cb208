"""A concentric-tube robot of two pre-curved tubes in the torsional model, written as its
energy (docs/energy.md; the model, its snap-free bound and the runs: docs/soft-robots.md,
"Concentric-tube robots").

Two elastic tubes, one inside the other, each pre-curved with the constant curvature kappa_i
(in a plane that turns with the tube) along the same curved length L, with bending
stiffnesses EI_i and torsional stiffnesses GJ_i. Each tube reaches the curved section
through a straight transmission of length Lt from its actuator, where it is turned: tube 1's
base is held at 0, tube 2's turned by beta, the actuated base rotation. psi_i(s) is the
rotation of tube i about the common axis at the fraction s of the curved section (arclength
L s). The torsional model: the tubes share one curvature u, the bending couple of the pair,
and each twists freely under its own torque; u minimises the bending energy
sum_i EI_i |u - kappa_i e(psi_i)|^2 / 2 (e(psi) the unit vector at angle psi in the cross
section), so u = sum_i EI_i kappa_i e(psi_i) / (EI1 + EI2) and the bending energy per length is

    EI1 EI2 / (2 (EI1 + EI2)) |kappa1 e(psi1) - kappa2 e(psi2)|^2
        = EI1 EI2 / (2 (EI1 + EI2)) (kappa1^2 + kappa2^2 - 2 kappa1 kappa2 cos(psi2 - psi1)).

The transmissions are straight: a tube's twist is uniform there, and its energy is that of a
torsion spring GJ_i / Lt between the actuator and the curved section's start. With arclength
L s::

    E[psi1, psi2] = int_0^1 ( (GJ1 psi1'^2 + GJ2 psi2'^2) / (2 L)
                              + L EI1 EI2 / (2 (EI1 + EI2)) |kappa1 e(psi1) - kappa2 e(psi2)|^2 ) ds
                    + (GJ1 psi1(0)^2 + GJ2 (psi2(0) - beta)^2) / (2 Lt),

every end natural (the tip is free: no torque at s = 1). Derived from it: the states
``[psi1, psi2, T1, T2]``, T_i = GJ_i psi_i' / L the torque carried by tube i; the natural
conditions T1(0) = GJ1 psi1(0) / Lt, T2(0) = GJ2 (psi2(0) - beta) / Lt (the torque is the same
along the straight transmission) and T1(1) = T2(1) = 0; the second variation; beta enters only
the end term (``"free"``), with the ordinate ``torque`` = dE/dbeta = -T2(0), the torque the
actuator applies to hold tube 2 at beta.

The relative rotation alpha = psi2 - psi1 carries the physics: (GJ1 psi1 + GJ2 psi2) is
linear in s with zero slope (the total torque vanishes at the free tip), and alpha obeys
alpha'' = lambda^2 sin(alpha) on the curved section, with the design parameter

    lambda = L sqrt(c),   c = EI1 EI2 kappa1 kappa2 / (EI1 + EI2) (1 / GJ1 + 1 / GJ2).

Turned through beta = pi (the tubes' curvatures opposed), the tip lags the base; the robot
is snap-free for every beta while lambda < arctan(1 / (sqrt(c) Lt)), and beyond it a fold
pair encloses beta = pi: the tip snaps (the derivation: docs/soft-robots.md).

By hand: the straight start (each tube unturned, or tube 2 at beta = k pi), the extra
ordinates ``tip`` (the relative rotation at the tip, alpha(1)), ``base`` (alpha(0)) and
``lam`` (lambda, a function of the parameters, to plot a fold curve against), and the
drawing of the robot's backbone in space (``backbone``, ``draw``).

Defaults: tubes of one material and section (EI1 = EI2 = 1; GJ = EI / (1 + nu) for a thin
tube, nu = 0.3), kappa1 = kappa2 = 1, L = Lt = 1: lambda = sqrt(1.3) = 1.1402 past the bound
arctan(1 / sqrt(1.3)) = 0.7200, so the default robot snaps. Units are the user's: any
consistent lengths and stiffnesses.
"""

import math

import numpy as np

from elastica_auto import Ordinate
from elastica_auto.energy import derived_names


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s = sp.Symbol("s", real=True)
    beta, kappa1, kappa2, EI1, EI2, GJ1, GJ2, L, Lt = sp.symbols(
        "beta kappa1 kappa2 EI1 EI2 GJ1 GJ2 L Lt", real=True)
    psi1, psi2 = sp.Function("psi1")(s), sp.Function("psi2")(s)
    twist = (GJ1 * psi1.diff(s) ** 2 + GJ2 * psi2.diff(s) ** 2) / (2 * L)
    bend = L * EI1 * EI2 / (2 * (EI1 + EI2)) * (
        kappa1 ** 2 + kappa2 ** 2 - 2 * kappa1 * kappa2 * sp.cos(psi2 - psi1))
    return Energy(
        density=twist + bend,
        end0=(GJ1 * psi1 ** 2 + GJ2 * (psi2 - beta) ** 2) / (2 * Lt),
        s=s, coordinates=[psi1, psi2], momenta=["T1", "T2"],
        parameters={
            beta: Param(0.0, r"\beta", period=2 * sp.pi, period_shift={psi2: 2 * sp.pi},
                        ordinate="torque",
                        doc="actuated base rotation of tube 2 (tube 1's base held at 0)"),
            kappa1: Param(1.0, r"\kappa_1", doc="pre-curvature of tube 1"),
            kappa2: Param(1.0, r"\kappa_2", doc="pre-curvature of tube 2"),
            EI1: Param(1.0, r"EI_1", doc="bending stiffness of tube 1"),
            EI2: Param(1.0, r"EI_2", doc="bending stiffness of tube 2"),
            GJ1: Param(1 / sp.Rational(13, 10), r"GJ_1", doc="torsional stiffness of tube 1"),
            GJ2: Param(1 / sp.Rational(13, 10), r"GJ_2", doc="torsional stiffness of tube 2"),
            L: Param(1.0, "L", doc="curved length (both tubes curved over it)"),
            Lt: Param(1.0, r"L_t", doc="straight transmission length (> 0)"),
        })


#: Imported as a Python module, the derived names on first use (`load_problem` gives them).
__getattr__ = derived_names(__name__)


def stiffness_product(p) -> float:
    """c = EI1 EI2 kappa1 kappa2 / (EI1 + EI2) (1/GJ1 + 1/GJ2): alpha'' = c sin(alpha) in
    arclength, alpha = psi2 - psi1 the relative rotation."""
    return (p["EI1"] * p["EI2"] * p["kappa1"] * p["kappa2"] / (p["EI1"] + p["EI2"])
            * (1 / p["GJ1"] + 1 / p["GJ2"]))


def design_parameter(p) -> float:
    """lambda = L sqrt(c) (NaN where c < 0: curvatures of opposite signs are the same tubes
    with one turned by pi)."""
    c = stiffness_product(p)
    return p["L"] * math.sqrt(c) if c >= 0 else math.nan


def snap_free_bound(p) -> float:
    """The largest snap-free lambda at the transmission length Lt of ``p``: arctan(1 / (sqrt(c)
    Lt)), where the relative rotation alpha = pi (tubes opposed) at beta = pi loses its
    stability (sqrt(c) Lt tan(lambda) = 1; docs/soft-robots.md). pi/2 as Lt -> 0."""
    return math.atan2(1.0, math.sqrt(stiffness_product(p)) * p["Lt"])


ORDINATES = [
    Ordinate("tip", r"$\psi_2(1)-\psi_1(1)$", lambda s, y, p: float(y[1, -1] - y[0, -1]), None,
             "relative rotation of the tubes at the tip"),
    Ordinate("base", r"$\psi_2(0)-\psi_1(0)$", lambda s, y, p: float(y[1, 0] - y[0, 0]), None,
             "relative rotation of the tubes where the curved section starts"),
    Ordinate("lam", r"$\lambda$", lambda s, y, p: design_parameter(p), None,
             "design parameter lambda = L sqrt(c)"),
]


def exact_start(s, p):
    """The tubes unturned along their length, psi1 = 0 and psi2 = beta, exact where sin(beta)
    = 0 (to 1e-12: the curvatures aligned or opposed, no torque anywhere); None otherwise."""
    if abs(math.sin(p["beta"])) > 1e-12:
        return None
    zero = np.zeros_like(s)
    return np.vstack((zero, np.full_like(s, p["beta"]), zero, zero))


#: Configurations are drawn in space (docs/equation-modules.md, ``DRAW_PROJECTION``).
DRAW_PROJECTION = "3d"
#: Colours of the drawing: the transmission, the curved section, the tip.
TRANSMISSION_COLOR, BACKBONE_COLOR, TIP_COLOR = "0.55", "black", "#e66101"


def backbone(profile, p):
    """The backbone's centreline (3, m) on the profile grid, from the base of the curved
    section at the origin along e_z (the transmission lies on the negative z axis).

    The rotations psi_i are measured from a frame R(s) that does not twist (its curvature has
    no component along the tangent d3), and tube i's pre-curvature is kappa_i e(psi_i) in its
    cross-section, so the shared curvature in that frame is u = (sum_i EI_i kappa_i (cos psi_i,
    sin psi_i) / K, 0): R' = R [u]_x, r' = R e_z per unit length (d3' = -u_x d2 + u_y d1).
    Integrated on the grid by rotations through the midpoint curvature (R_(j+1) = R_j
    exp(L h [u_mid]_x), Rodrigues' formula) and the trapezoidal rule for r: second order."""
    psi1, psi2 = profile[0], profile[1]
    K = p["EI1"] + p["EI2"]
    u = np.array([p["EI1"] * p["kappa1"] * np.cos(psi1) + p["EI2"] * p["kappa2"] * np.cos(psi2),
                  p["EI1"] * p["kappa1"] * np.sin(psi1) + p["EI2"] * p["kappa2"] * np.sin(psi2),
                  np.zeros_like(psi1)]) / K
    m = profile.shape[1]
    step = p["L"] / (m - 1)
    R, r = np.eye(3), np.zeros((3, m))
    for j in range(m - 1):
        w = 0.5 * (u[:, j] + u[:, j + 1]) * step
        angle = np.linalg.norm(w)
        W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        if angle > 0:
            W = (np.sin(angle) / angle * W
                 + (1 - np.cos(angle)) / angle ** 2 * W @ W)
        R_next = R @ (np.eye(3) + W)
        r[:, j + 1] = r[:, j] + 0.5 * step * (R[:, 2] + R_next[:, 2])
        R = R_next
    return r


def draw(ax, profile, p):
    """The robot in space: the straight transmission (grey, from z = -Lt), the curved section's
    backbone and its tip. On 2D axes, the projection on the x-y plane (seen along the
    transmission)."""
    r = backbone(profile, p)
    if getattr(ax, "name", "") == "3d":
        ax.plot((0, 0), (0, 0), (-p["Lt"], 0), color=TRANSMISSION_COLOR, lw=1.2,
                gid="transmission")
        ax.plot(*r, color=BACKBONE_COLOR, lw=1.4, gid="backbone")
        ax.plot(*r[:, -1:], "o", ms=2.5, color=TIP_COLOR)
    else:
        ax.plot(r[0], r[1], color=BACKBONE_COLOR, lw=1.4, gid="backbone")
        ax.plot(r[0, -1], r[1, -1], "o", ms=2.5, color=TIP_COLOR)
