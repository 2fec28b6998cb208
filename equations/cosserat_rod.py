"""Spatial Cosserat rod (shearable, extensible) with a rigid lever arm, written as its energy:
the shearable, extensible generalisation of ``kirchhoff_lever_arm`` (docs/soft-robots.md,
"Cosserat rods"; the energy front end: docs/energy.md, "Rotation coordinates").

Nondimensional as the Kirchhoff rod: length 1, in-plane bending stiffness 1. The frame R =
(d1, d2, d3) (body to space) is a rotation coordinate and, unlike the Kirchhoff rod's, the
centreline r = (x, y, z) is a coordinate of its own, not the quadrature r' = d3; the strains
are the body curvature u = (R^T R')^vee and the body shear-extension v = R^T r'::

    E = int_0^1 ( (1/2) (u - u_hat).K (u - u_hat) + (S/2) |r' - R v_hat|^2 + g y ) ds
        - F.(r(1) + eps R(1) a_b),            R(0) = R_c,  r(0) = 0,

K = diag(1, b2, c), u_hat = (u1, u2, u3), v_hat = (v1, v2, v3) (default (0, 0, 1): straight,
unsheared, unstretched), |r' - R v_hat|^2 = |v - v_hat|^2 (R is orthogonal): the shear and
extension stiffness S the same for the two shears and the extension (a diagonal S = diag(GA,
GA, EA) with EA != GA makes the Legendre map's Hessian in r' the frame-dependent R S R^T, whose
symbolic inverse the energy front end cannot yet keep short: docs/soft-robots.md). g is the
weight per unit length, along -e_y; F, the arm a_b, the clamp R_c and every parameter the
Kirchhoff rod has keep its meaning and conventions (docs/kirchhoff.md).

Derived from it (`load_problem`, `elastica-auto derive`): 13 states ``(r, q, m, n)`` (the
centreline, the frame's quaternion, the spatial contact moment m = R K (u - u_hat) and force
n = S (r' - R v_hat)); the balances

    n' = (0, g, 0) = -f,   m' = -r' x n,   r' = R (n_b / S + v_hat),

the clamp and the free end's n(1) = F, m(1) = eps R(1) a_b x F; their Jacobians; the second
variation in (x, y, z) and the spatial turns of the frame, with the parts ``index_in`` (x, y
and the turn about e_z: in-plane) and ``index_out``; where each parameter enters and its
distinguished ordinate (named as the Kirchhoff rod names them); the energy E. As S grows, r'
-> d3 and the rod becomes the Kirchhoff rod, at O(1/S) (docs/soft-robots.md).

By hand: the straight start, the planar mirror, the isotropic rod's turn about the load line
(``symmetry``, ``symmetric_values``: where it holds, the derived second variation leaves its
zero mode out of the count), the drawing (the Kirchhoff rod's), and the ordinates z1
(out-of-plane tip displacement) and qnorm (the drift of |q| from 1). No ``shooting``
(snap-back targets).
"""

import math

import numpy as np

from elastica_auto import Mirror, Ordinate
from elastica_auto.energy import derived_names
from elastica_auto.equations import kirchhoff_lever_arm as kirchhoff
from elastica_auto.equations.kirchhoff_lever_arm import (
    QUATERNION, arm_body, clamp_axis, clamp_quaternion, load, qmul, rotation)


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param, Rotation, compose, rotation_about
    s = sp.Symbol("s", real=True)
    (P, eps, psi, alpha, theta0, chi, beta, phi0, b2, c, u1, u2, u3, S, g, v1, v2, v3) = (
        sp.symbols("P eps psi alpha theta0 chi beta phi0 b2 c u1 u2 u3 S g v1 v2 v3",
                   real=True))
    R = Rotation("R", quaternion=QUATERNION)
    x, y, z = (sp.Function(name)(s) for name in ("x", "y", "z"))
    bend = R.strain - sp.Matrix([u1, u2, u3])
    gap = sp.Matrix([x.diff(s), y.diff(s), z.diff(s)]) - R.matrix * sp.Matrix([v1, v2, v3])
    load_ = P * sp.Matrix([sp.cos(beta) * sp.sin(alpha), -sp.cos(beta) * sp.cos(alpha),
                           sp.sin(beta)])
    arm = sp.Matrix([-sp.sin(psi) * sp.sin(chi), sp.sin(psi) * sp.cos(chi), sp.cos(psi)])
    tip = sp.Matrix([x, y, z]) + eps * R.matrix * arm
    half = sp.Rational(1, 2)
    clamp = compose(rotation_about((0, 0, 1), theta0), sp.Matrix([half, -half, -half, -half]),
                    rotation_about((0, 0, 1), phi0))
    angle = dict(period=2 * sp.pi)
    return Energy(
        density=((bend.T * sp.diag(1, b2, c) * bend)[0] + S * (gap.T * gap)[0]) / 2 + g * y,
        end1=-(load_.T * tip)[0],
        s=s, coordinates=[x, y, z, R],
        momenta={x: "nx", y: "ny", z: "nz", R: ("mx", "my", "mz")},
        fixed0={R: clamp, x: 0, y: 0, z: 0},
        states=("x", "y", "z", *QUATERNION, "mx", "my", "mz", "nx", "ny", "nz"),
        parts={"index_in": [x, y, R[2]], "index_out": [z, R[0], R[1]]},
        parameters={
            P: Param(sp.pi ** 2 / 4, "P", ordinate="gamma",
                     doc="load |F| l^2 / K1; negative reverses F"),
            eps: Param(0.25, r"\epsilon", ordinate="beps",
                       doc="lever-arm length / l; negative flips it"),
            psi: Param(0.0, r"\psi", ordinate="m1", **angle,
                       doc="arm angle to d3(1), clockwise in the arm's plane"),
            alpha: Param(0.0, r"\alpha", ordinate="mA", **angle,
                         doc="load direction from the vertical, in the x-y plane"),
            theta0: Param(0.0, r"\theta_0", ordinate="m0", period_flip=(R,), **angle,
                          doc="rotation of the clamp about e_z (a whole turn is q -> -q)"),
            chi: Param(0.0, r"\chi", ordinate="mchi", **angle,
                       doc="tilt of the arm's plane about d3(1)"),
            beta: Param(0.0, r"\beta", ordinate="mB", **angle,
                        doc="azimuth of the load out of the x-y plane (towards +z)"),
            phi0: Param(0.0, r"\phi_0", ordinate="mphi", period_flip=(R,), **angle,
                        doc="twist of the clamp about its own axis (a whole turn is q -> -q)"),
            b2: Param(1.0, "b_2", ordinate="Eb2",
                      doc="out-of-plane bending stiffness / in-plane"),
            c: Param(1 / sp.Float(1.3), "c", ordinate="Ec",
                     doc="torsional stiffness / in-plane bending stiffness"),
            u1: Param(0.0, r"\hat u_1", doc="intrinsic in-plane curvature"),
            u2: Param(0.0, r"\hat u_2", doc="intrinsic out-of-plane curvature"),
            u3: Param(0.0, r"\hat u_3", doc="intrinsic twist"),
            S: Param(1000.0, "S", doc="shear and extension stiffness l^2 / K1"),
            g: Param(0.0, "g", doc="weight per unit length l^3 / K1, along -e_y"),
            v1: Param(0.0, r"\hat v_1", doc="intrinsic shear along d1"),
            v2: Param(0.0, r"\hat v_2", doc="intrinsic shear along d2 (in the plane)"),
            v3: Param(1.0, r"\hat v_3", doc="intrinsic stretch (1: unstretched)"),
        })


#: Imported as a Python module, the derived names (rhs, second_variation, PARAMETERS, ...)
#: on first use; `load_problem` gives them itself.
__getattr__ = derived_names(__name__)


def _z1(s, y, p):
    return float(y[2, -1])


def _qnorm(s, y, p):
    return float(np.max(np.abs(np.linalg.norm(y[3:7], axis=0) - 1.0)))


#: The ordinates that are no parameter's (the distinguished ones, E and the parts' indices
#: are derived).
ORDINATES = [
    Ordinate("z1", r"$z(1)$", _z1, None, "out-of-plane tip displacement r(1).e_z"),
    Ordinate("qnorm", r"$\max||q| - 1|$", _qnorm, None, "diagnostic: drift of |q| from 1"),
]

#: The planar mirror x -> -x, as the Kirchhoff rod's (docs/kirchhoff.md, "Mirror images"): r ->
#: M r, the force n -> M n, the moment m -> -M m (M = diag(-1, 1, 1)), q -> (-q3, q2, q1, -q0),
#: that is R -> M R N with N = diag(1, -1, 1) in the body, so u_hat -> -N u_hat (u1, u3 change
#: sign) and v_hat -> N v_hat (v2 changes sign).
MIRROR = Mirror({"x": "-x", "q0": "-q3", "q1": "q2", "q2": "q1", "q3": "-q0", "my": "-my",
                 "mz": "-mz", "nx": "-nx"},
                ("psi", "alpha", "theta0", "chi", "phi0", "u1", "u3", "v2"),
                ("m1", "mA", "m0", "mchi", "mphi", "dE_du1", "dE_du3", "dE_dv2"))


def exact_start(s, p):
    """The straight rod along the load line: exact when the load and the weight lie along
    d3(0) (F x d3(0) = 0; g = 0 or d3(0) = +-e_y), the arm along d3(1) (sin psi = 0) or no
    load, and no intrinsic bending or shear (u1 = u2 = v1 = v2 = 0). Then n(s) = F - g (1 - s)
    e_y is along d3(0), the stretch v(s) = v3 + n.d3 / S, m = 0, r = d3(0) int_0^s v, and q(s)
    = q_c (x) (cos(u3 s / 2), 0, 0, sin(u3 s / 2)) (the intrinsic twist turns the frame about
    the straight axis). None otherwise, and for S = 0 (the generated code divides by S)."""
    qc = clamp_quaternion(p)
    d3 = rotation(qc)[:, 2]
    f = load(p)
    if (np.linalg.norm(np.cross(f, d3)) > 1e-12 * max(1.0, abs(p["P"]))
            or abs(p["g"]) * math.hypot(d3[0], d3[2]) > 1e-12
            or abs(p["eps"] * p["P"] * math.sin(p["psi"])) > 1e-12
            or p["u1"] != 0 or p["u2"] != 0 or p["v1"] != 0 or p["v2"] != 0
            or p["S"] == 0):
        return None
    s = np.asarray(s, dtype=float)
    n3 = f @ d3 - p["g"] * (1 - s) * d3[1]
    along = p["v3"] * s + ((f @ d3) * s - p["g"] * d3[1] * (s - s * s / 2)) / p["S"]
    half = 0.5 * p["u3"] * s
    twist = np.vstack((np.cos(half), np.zeros_like(s), np.zeros_like(s), np.sin(half)))
    return np.vstack((np.outer(d3, along), qmul(qc[:, None], twist), np.zeros((3, len(s))),
                      np.outer(d3, n3)))


# ---- the isotropic rod's turn about the load line (as the Kirchhoff rod's: docs/kirchhoff.md,
# "Symmetry") ---------------------------------------------------------------------------------

def is_symmetric(p) -> bool:
    """Whether the rotation about the clamp axis e = d3(0), the frames counter-rotated about
    their own d3, maps solutions to solutions: the Kirchhoff rod's conditions (b2 = 1, u1 = u2
    = 0, the load along e, the arm along the tip's d3 or of length 0), no intrinsic shear (v1
    = v2 = 0: v_hat along e3, which the counter-rotation keeps) and the weight along e (g = 0
    or e = +-e_y)."""
    if not kirchhoff.is_symmetric(p) or p["v1"] != 0 or p["v2"] != 0:
        return False
    e = clamp_axis(p)
    return p["g"] == 0 or math.hypot(e[0], e[2]) <= kirchhoff.SYMMETRIC


def symmetric_values(name, lo, hi, p):
    """The values of ``name`` in [lo, hi] where :func:`is_symmetric` holds, the others at
    ``p``: the multiples of pi of the arm angle psi (the arm along d3(1)) where the rest is
    symmetric and the arm has a length; none for the other parameters."""
    if name != "psi" or p["eps"] == 0 or not is_symmetric({**p, "psi": 0.0}):
        return []
    return [k * math.pi for k in range(math.ceil(lo / math.pi), math.floor(hi / math.pi) + 1)]


def symmetry(s, y, p):
    """The rotation T_theta about e = d3(0) through the clamp, the frames counter-rotated
    about their own d3: r -> Q r, m -> Q m, n -> Q n, q -> q_Q (x) q (x) q_3(-theta)
    (Q = Rot(e, theta)). It keeps the clamp, the energy (K = diag(1, 1, c), S |v - e3|^2 are
    invariant under turns about e3 in the body), the load and the weight along e and the arm
    along d3. Generator g = (e x r, (e^ (x) q - q (x) e3^) / 2, e x m, e x n) (e^ the pure
    quaternion); unfolding b = grad J of

        J = m.d3 - (m + r x n).e,

    conserved for every state: (m.d3)' = -(r' x n).d3 + m_b.(u x e3) = 0 with r' = n / S + d3
    and u = K^-1 m_b, b2 = 1; (m + r x n)' = r x n' = g r x e_y, whose e-component vanishes for
    e = +-e_y. J is zero at both ends (d3(0) = e, r(0) = 0; m(1) = eps d3(1) x F, F along e):
    the unfolded solutions have mu = 0. None where the parameters break the symmetry."""
    from elastica_auto.model.symmetry import Symmetry
    if not is_symmetric(p):
        return None
    e = clamp_axis(p)
    r, q, m, n = y[0:3], y[3:7], y[7:10], y[10:13]
    zero = np.zeros_like(q[:1])
    e_hat = np.vstack((zero, np.outer(e, np.ones(q.shape[1]))))
    e3_hat = np.vstack((zero, zero, zero, zero + 1.0))
    g = np.vstack((np.cross(e, r, axis=0), 0.5 * (qmul(e_hat, q) - qmul(q, e3_hat)),
                   np.cross(e, m, axis=0), np.cross(e, n, axis=0)))
    w, x, yq, z = q
    n2 = w * w + x * x + yq * yq + z * z
    d3 = rotation(q)[:, 2]
    # d(m.d3)/dq, d3 = R(q / |q|) e3 (the Kirchhoff rod's formula)
    grad_q = (2 * (m[0] * np.array((yq, z, w, x)) + m[1] * np.array((-x, -w, z, yq))
                   + m[2] * np.array((w, -x, -yq, z))) - 2 * np.sum(m * d3, axis=0) * q) / n2
    ee = np.outer(e, np.ones(q.shape[1]))
    b = np.vstack((np.cross(ee, n, axis=0), grad_q, d3 - e[:, None],
                   np.cross(r, ee, axis=0)))
    return Symmetry(g, b)


#: The engine gives ``draw`` 3D axes (matplotlib's mplot3d).
DRAW_PROJECTION = "3d"


def tip_arm(yb, p):
    """The arm's spatial vector eps R(q(1)) a_b."""
    return p["eps"] * rotation(yb[3:7]) @ arm_body(p)


def draw(ax, profile, p):
    """The Kirchhoff rod's drawing (clamp, centreline, its shadow, arm, load) of this rod's
    profile: its first ten rows are the Kirchhoff rod's states."""
    import elastica_auto.equations.kirchhoff_lever_arm as rod
    rod.draw(ax, profile[:10], p)
