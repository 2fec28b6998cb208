"""A tendon-driven continuum robot: the spatial Cosserat backbone of ``cosserat_rod`` with
four tendons routed parallel to it, written as its energy (docs/soft-robots.md,
"Tendon-driven robots"; the energy front end: docs/energy.md, "A density not quadratic in the
strains"; tendons routed helically: ``tendon_helical``, which shares this module's hooks).

Nondimensional: length 1, bending stiffness about d1 equal to 1. The backbone is clamped at
the origin with the identity frame (d3(0) = e_z, d1(0) = e_x, d2(0) = e_y), its tip free. The
frame R = (d1, d2, d3) is a rotation coordinate, the centreline r = (x, y, z) a coordinate;
the strains are u = (R^T R')^vee and v = R^T r'. Tendon i runs at the fixed body offset

    d_i = delta (cos a_i, sin a_i, 0),   a_i = (i - 1) pi / 2,   i = 1..4,

along the path r + R d_i, from the base to the tip where it is tied; its unit length in the
body is t_i = v + u x d_i (the derivative of R^T (r + R d_i)). Held at the fixed tension tau_i
by an actuator at the base, tendon i stores the potential tau_i |t_i| per unit length (the
work the actuator does when the tendon lengthens by dl is -tau_i dl), so

    E = int_0^1 ( u.K u / 2 + (v - e3).Kse (v - e3) / 2 + sum_i tau_i |v + u x d_i| + g y ) ds
        + P y(1),

K = diag(1, b2, c), Kse = S diag(1, 1, se) (shear stiffness S, extension stiffness S se), g
the weight per unit length along -e_y and P a dead weight at the tip along -e_y. The density
is not quadratic in the strains: the front end inverts the Legendre map by Newton's method at
each point.

Derived from it (`load_problem`): 13 states ``(r, q, m, n)`` with the total contact moment m
and force n, the backbone's and the tendons' together,

    n = R ( Kse (v - e3) + sum_i tau_i t_i / |t_i| ),
    m = R ( K u + sum_i tau_i d_i x t_i / |t_i| ),

balanced by n' = (0, g, 0) and m' = -r' x n (the energy is invariant under translations and
rotations of the whole robot); the clamp; the free tip's natural conditions
n(1) = (0, -P, 0), m(1) = 0. In the backbone's own force n - sum_i tau_i R t_i / |t_i| these
say that each tendon's termination pulls the tip back along the tendon with the force tau_i
and the moment (R d_i) x (-tau_i R t_i / |t_i|) about the centreline (docs/soft-robots.md).

By hand: the straight start (balanced tensions, no weight), the ordinates x1, y1, z1 (the tip)
and bend (the angle between d3(1) and e_z), the drawing; ``tendon_helical`` uses them too,
its turns k read as 0 where the parameters have none.
"""

import math

import numpy as np

from elastica_auto.energy import derived_names
from elastica_auto.equations.kirchhoff_lever_arm import QUATERNION, rotation

from elastica_auto import Ordinate

#: Tendons' angles a_i about d3 in the section, from d1 towards d2.
ANGLES = tuple(i * math.pi / 2 for i in range(4))


def ENERGY():
    return energy()


def energy(helical: bool = False):
    """The robot's energy (the module docstring); ``helical``: with the turns ``k`` of the
    tendons about the backbone (``tendon_helical``: offsets d_i(s) turning with angle
    a_i + 2 pi k s, and t_i = v + u x d_i + d_i'). Without, the offsets' angles are exact
    multiples of pi / 2 and the derived code keeps their exact zeros."""
    import sympy as sp

    from elastica_auto.energy import Energy, Param, Rotation
    s = sp.Symbol("s", real=True)
    taus = sp.symbols("tau1:5", real=True)
    delta, b2, c, S, se, k, g, P = sp.symbols("delta b2 c S se k g P", real=True)
    R = Rotation("R", quaternion=QUATERNION)
    x, y, z = (sp.Function(name)(s) for name in ("x", "y", "z"))
    u = R.strain
    v = R.matrix.T * sp.Matrix([x.diff(s), y.diff(s), z.diff(s)])
    tendons = 0
    for i, tau in enumerate(taus):
        angle = i * sp.pi / 2 + (2 * sp.pi * k * s if helical else 0)   # ANGLES[i] (+ turns)
        d = delta * sp.Matrix([sp.cos(angle), sp.sin(angle), 0])
        t = v + u.cross(d) + (d.diff(s) if helical else sp.zeros(3, 1))
        tendons += tau * sp.sqrt((t.T * t)[0])
    gap = v - sp.Matrix([0, 0, 1])
    elastic = (u.T * sp.diag(1, b2, c) * u)[0] + S * (gap.T * sp.diag(1, 1, se) * gap)[0]
    density = elastic / 2 + tendons + g * y
    tension = {tau: Param(0.0, rf"\tau_{i + 1}",
                          doc=f"tension of tendon {i + 1} (at angle {i * 90} deg) l^2 / K1")
               for i, tau in enumerate(taus)}
    turns = {k: Param(0.0, "k", doc="tendons' turns about the backbone per length l "
                                    "(0: parallel)")} if helical else {}
    return Energy(
        density=density, end1=P * y,
        s=s, coordinates=[x, y, z, R],
        momenta={x: "nx", y: "ny", z: "nz", R: ("mx", "my", "mz")},
        fixed0={R: (1, 0, 0, 0), x: 0, y: 0, z: 0},
        states=("x", "y", "z", *QUATERNION, "mx", "my", "mz", "nx", "ny", "nz"),
        parts={"index_in": [y, z, R[0]], "index_out": [x, R[1], R[2]]},
        parameters={
            **tension,
            delta: Param(0.05, r"\delta", doc="tendons' offset from the centreline / l"),
            b2: Param(1.0, "b_2", doc="bending stiffness about d2 / about d1"),
            c: Param(1 / sp.Float(1.3), "c", doc="torsional stiffness / bending stiffness"),
            S: Param(1000.0, "S", doc="shear stiffness l^2 / K1"),
            se: Param(1.0, "s_e", doc="extension stiffness / shear stiffness"),
            **turns,
            g: Param(0.0, "g", doc="weight per unit length l^3 / K1, along -e_y"),
            P: Param(0.0, "P", doc="dead weight at the tip l^2 / K1, along -e_y"),
        })


#: Imported as a Python module, the derived names (rhs, second_variation, PARAMETERS, ...)
#: on first use; `load_problem` gives them itself.
__getattr__ = derived_names(__name__)


def _tip(k):
    return lambda s, y, p: float(y[k, -1])


def _bend(s, y, p):
    d3 = rotation(y[3:7, -1])[:, 2]
    return float(math.atan2(math.hypot(d3[0], d3[1]), d3[2]))


#: The ordinates that are no parameter's (the tendons' lengths dE_dtau_i, E and the parts'
#: indices are derived).
ORDINATES = [
    Ordinate("x1", r"$x(1)$", _tip(0), None, "tip position r(1).e_x"),
    Ordinate("y1", r"$y(1)$", _tip(1), None, "tip position r(1).e_y"),
    Ordinate("z1", r"$z(1)$", _tip(2), None, "tip position r(1).e_z"),
    Ordinate("bend", r"$\angle(d_3(1), e_z)$", _bend, None,
             "angle between the tip's tangent and the base's, in [0, pi]"),
]


def exact_start(s, p):
    """The straight backbone along e_z: exact when the tendons' pulls balance about the
    centreline (sum_i tau_i d_i = 0), nothing weighs (g = P = 0) and the tendons are
    parallel (k = 0) or slack. Then u = 0, t_i = v = v3 e3 with S se (v3 - 1) + sum_i tau_i
    = 0 (n = 0), and m = sum_i tau_i d_i x e3 = 0. None otherwise (taut helical tendons
    twist the backbone: docs/soft-robots.md), and where the tendons would have no length
    (v3 <= 0)."""
    arm = sum(t * np.array((math.cos(a), math.sin(a)))
              for t, a in zip((p["tau1"], p["tau2"], p["tau3"], p["tau4"]), ANGLES))
    total = p["tau1"] + p["tau2"] + p["tau3"] + p["tau4"]
    axial = p["S"] * p["se"]
    if (p["delta"] * np.linalg.norm(arm) > 1e-12 * max(1.0, total) or p["g"] != 0
            or p["P"] != 0 or axial == 0 or 1 - total / axial <= 0
            or (p.get("k", 0.0) != 0 and total != 0)):
        return None
    s = np.asarray(s, dtype=float)
    out = np.zeros((13, len(s)))
    out[2] = (1 - total / axial) * s
    out[3] = 1.0
    return out


#: The engine gives ``draw`` 3D axes (matplotlib's mplot3d).
DRAW_PROJECTION = "3d"


def draw(ax, profile, p):
    """The backbone, its tendons (each at r + R d_i(s), drawn thin) and the base. The profile
    carries no s: the helical offsets are placed at the centreline's arc-length fraction
    (exact where the backbone is not stretched; the stretch is of order tau / S)."""
    r = profile[0:3]
    ax.plot(r[0], r[1], r[2], lw=2, color="k")
    frames = np.array([rotation(q) for q in profile[3:7].T])
    arc = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(r, axis=1), axis=0))))
    s = arc / arc[-1] if arc[-1] > 0 else arc
    for i, a in enumerate(ANGLES):
        tau = p[f"tau{i + 1}"]
        w = a + 2 * math.pi * p.get("k", 0.0) * s
        d = p["delta"] * np.vstack((np.cos(w), np.sin(w), np.zeros_like(w)))
        path = r + np.einsum("mij,jm->im", frames, d)
        ax.plot(path[0], path[1], path[2], lw=1.5 if tau > 0 else 0.5,
                color="C3" if tau > 0 else "0.6")
    ax.scatter([0], [0], [0], color="k", marker="s")
