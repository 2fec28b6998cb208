"""Spatial Kirchhoff rod with a rigid lever arm (nondimensional: in-plane bending stiffness 1,
length 1): the 3D extension of ``elastica_lever_arm``, written as its energy (docs/energy.md;
the model and its conventions: docs/kirchhoff.md).

An inextensible, unshearable rod, clamped at s = 0, carries at s = 1 a rigid lever arm with a
dead load F at its end. Its frame (d1, d2, d3) = R (body to space, d3 the tangent) is a
rotation coordinate, its centreline r the quadrature r' = d3::

    E[R] = int_0^1 (1/2) (u - u_hat).K (u - u_hat) ds - F.(r(1) + eps R(1) a_b),   R(0) = R_c,

u = (R^T R')^vee the body (Darboux) curvature, K = diag(1, b2, c), u_hat = (u1, u2, u3). Derived
from it (`load_problem`, `elastica-auto derive`): the states ``y = (r, q, m)``, 10 rows (the
order of the hand-written module this one replaces: the centreline r (3), the frame's
quaternion q (4, R = R(q / |q|)) and the spatial contact moment m = R K (u - u_hat) (3)); the
system ``r' = d3, q' = (1/2) q (x) (0, u), m' = F x d3`` with u = K^-1 R^T m + u_hat; the clamp
q(0) = q_c and the free end's moment balance m(1) = (eps R(1) a_b) x F; their Jacobians; the
second variation in spatial rotations w (A = R K R^T, C = -[m]_x / 2, B = (F.d3) I - sym(F
d3^T), E1 = (F.a) I - sym(F a^T), w(0) = 0) with its parts ``index_in`` (the e_z component) and
``index_out``; where each parameter enters and its distinguished ordinate (named as the paper
and docs/kirchhoff.md name them); the energy E.

Frames and signs (chosen so that the plane z = 0 is the planar module's plane):

* the reference clamp frame is d1 = e_z, d2 = e_x, d3 = e_y (the rod along +y, as theta = 0 in
  the planar module); the clamp is R_c = Rz(theta0) R_ref Rb3(phi0): theta0 turns it about e_z
  as in the planar module, phi0 twists it about its own axis d3. In a planar state R(s) =
  Rz(theta(s)) R_ref: d1 = e_z, d2 = (cos theta, sin theta, 0), d3 = (-sin theta, cos theta,
  0), u = (theta', 0, 0) and m = theta' e_z, so kappa = m.e_z, and in-plane bending is
  bending about d1 (stiffness 1), out-of-plane about d2 (stiffness b2).
* the load F = P (cos beta sin alpha, -cos beta cos alpha, sin beta): the planar module's
  P (sin alpha, -cos alpha) for beta = 0; beta tilts it towards +z.
* the arm, in the tip's body frame, a_b = Rb3(chi) Rb1(-psi) e3 = (-sin psi sin chi,
  sin psi cos chi, cos psi): for chi = 0 the planar module's arm, turned clockwise by psi from
  the tip tangent; chi turns the arm's plane about the tip tangent d3(1).

By hand, what an energy does not say: the straight start ``exact_start``, the isotropic rod's
turn about the load line (``symmetry``, ``symmetric_values``: where it holds, the derived
second variation leaves its zero mode w = e - d3 out of the count), the snap-back targets'
``shooting``, the mirror ``MIRROR``, ``draw``, and the ordinates that are no parameter's:
``z1`` = r(1).e_z (out-of-plane tip displacement), ``twist`` = the total twist int u3 ds,
``m3`` = m(1).d3(1), ``mz1`` = m(1).e_z, ``qnorm`` = max |(|q| - 1)| and ``zero_mode``.
The hand-written module it replaces is tests/reference/kirchhoff_lever_arm.py, the reference
the tests compare this one with.

Imported as a Python module (``import elastica_auto.equations.kirchhoff_lever_arm``) it gives
its derived names too (``rhs``, ``second_variation``, ``PARAMETERS``, ...): the module-level
``__getattr__`` derives them (or reads them from the cache) on first use.
"""

import functools
import math

import numpy as np

from elastica_auto import Mirror, Ordinate
from elastica_auto.core.solution import trapezoid_weights
from elastica_auto.energy import derived_names

#: The quaternion's states: turning the clamp by a whole turn (theta0 or phi0 grown by 2 pi)
#: turns q(0), and with it q(s), to -q, the same frame.
QUATERNION = ("q0", "q1", "q2", "q3")

TWO_PI = 2 * math.pi


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param, Rotation, compose, rotation_about
    s = sp.Symbol("s", real=True)
    (P, eps, psi, alpha, theta0, chi, beta, phi0, b2, c, u1, u2, u3) = sp.symbols(
        "P eps psi alpha theta0 chi beta phi0 b2 c u1 u2 u3", real=True)
    R = Rotation("R", quaternion=QUATERNION)
    x, y, z = (sp.Function(name)(s) for name in ("x", "y", "z"))
    bend = R.strain - sp.Matrix([u1, u2, u3])
    load = P * sp.Matrix([sp.cos(beta) * sp.sin(alpha), -sp.cos(beta) * sp.cos(alpha),
                          sp.sin(beta)])
    arm = sp.Matrix([-sp.sin(psi) * sp.sin(chi), sp.sin(psi) * sp.cos(chi), sp.cos(psi)])
    tip = sp.Matrix([x, y, z]) + eps * R.matrix * arm
    half = sp.Rational(1, 2)
    clamp = compose(rotation_about((0, 0, 1), theta0), sp.Matrix([half, -half, -half, -half]),
                    rotation_about((0, 0, 1), phi0))
    angle = dict(period=2 * sp.pi)
    return Energy(
        density=(bend.T * sp.diag(1, b2, c) * bend)[0] / 2,
        end1=-(load.T * tip)[0],
        s=s, coordinates=[R], momenta={R: ("mx", "my", "mz")},
        quadratures={x: R.d3[0], y: R.d3[1], z: R.d3[2]},
        fixed0={R: clamp, x: 0, y: 0, z: 0},
        states=("x", "y", "z", *QUATERNION, "mx", "my", "mz"),
        parts={"index_in": [R[2]], "index_out": [R[0], R[1]]},
        parameters={
            P: Param(sp.pi ** 2 / 4, "P", ordinate="gamma",
                     doc="load |F| l^2 / K1; negative reverses F"),
            eps: Param(0.25, r"\epsilon", ordinate="beps",
                       doc="lever-arm length / l; negative flips it"),
            psi: Param(0.0, r"\psi", ordinate="m1", **angle,
                       doc="arm angle to the tip tangent, clockwise in the arm's plane"),
            alpha: Param(0.0, r"\alpha", ordinate="mA", **angle,
                         doc="load direction from the vertical, in the x-y plane"),
            theta0: Param(0.0, r"\theta_0", ordinate="m0", period_flip=(R,), **angle,
                          doc="rotation of the clamp about e_z (a whole turn is q -> -q)"),
            chi: Param(0.0, r"\chi", ordinate="mchi", **angle,
                       doc="tilt of the arm's plane about the tip tangent"),
            beta: Param(0.0, r"\beta", ordinate="mB", **angle,
                        doc="azimuth of the load out of the x-y plane (towards +z)"),
            phi0: Param(0.0, r"\phi_0", ordinate="mphi", period_flip=(R,), **angle,
                        doc="twist of the clamp about its own axis (a whole turn is q -> -q)"),
            b2: Param(1.0, "b_2", ordinate="Eb2",
                      doc="out-of-plane bending stiffness / in-plane"),
            c: Param(1 / sp.Float(1.3), "c", ordinate="Ec",
                     doc="torsional stiffness / in-plane bending stiffness (1/(1 + nu), "
                         "nu = 0.3)"),
            u1: Param(0.0, r"\hat u_1", doc="intrinsic in-plane curvature"),
            u2: Param(0.0, r"\hat u_2", doc="intrinsic out-of-plane curvature"),
            u3: Param(0.0, r"\hat u_3", doc="intrinsic twist"),
        })


#: Imported as a Python module, the derived names (rhs, second_variation, PARAMETERS, ...)
#: on first use; `load_problem` gives them itself.
__getattr__ = derived_names(__name__)


def _derived(name):
    """A derived function of this module, however it was loaded."""
    return globals()[name] if name in globals() else __getattr__(name)


# ---- quaternions and rotations (vectorised: q (4, m), v (3, m)) ------------------------------

def qmul(a, b):
    """Hamilton product a (x) b of quaternions (4, ...) stored scalar first (written out by
    components: numpy's cross and einsum cost more than the arithmetic at these sizes)."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return np.array((a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                     a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 + a2 * b0 + a3 * b1 - a1 * b3,
                     a0 * b3 + a3 * b0 + a1 * b2 - a2 * b1))


def cross(a, b):
    """a x b for vectors (3, ...), by components."""
    return np.array((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]))


def qaxis(axis, angle):
    """The unit quaternion of the rotation by ``angle`` about the unit vector ``axis``."""
    return np.concatenate(([math.cos(angle / 2)], math.sin(angle / 2) * np.asarray(axis, float)))


def rotation(q):
    """R(q) (3, 3, ...), the rotation of q / |q|: the quadratic form divided by |q|^2, so it is
    orthonormal for any q != 0."""
    w, x, y, z = q
    n2 = w * w + x * x + y * y + z * z
    return np.array(((w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
                     (2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
                     (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z))
                    ) / n2


#: The reference clamp frame: d1 = e_z, d2 = e_x, d3 = e_y (R_REF e1 = e_z, e2 -> e_x,
#: e3 -> e_y): the rotation by -2 pi/3 about (1, 1, 1) / sqrt 3.
Q_REF = np.array((0.5, -0.5, -0.5, -0.5))


def clamp_quaternion(p):
    """q(0) = Rz(theta0) R_REF Rb3(phi0) as a quaternion."""
    return _clamp(float(p["theta0"]), float(p["phi0"]))[0].copy()


@functools.lru_cache(maxsize=64)
def _clamp(theta0, phi0):
    """(q(0), d3(0)) of the clamp, read-only: the boundary conditions and the second variation
    ask for them at every call, with the same two parameters along a branch."""
    q = qmul(qmul(qaxis((0, 0, 1), theta0), Q_REF), qaxis((0, 0, 1), phi0))
    axis = rotation(q)[:, 2]
    q.flags.writeable = axis.flags.writeable = False
    return q, axis


def load(p):
    """F = P (cos beta sin alpha, -cos beta cos alpha, sin beta)."""
    a, b = p["alpha"], p["beta"]
    return p["P"] * np.array((math.cos(b) * math.sin(a), -math.cos(b) * math.cos(a),
                              math.sin(b)))


def arm_body(p):
    """a_b = Rb3(chi) Rb1(-psi) e3, the arm's unit vector in the tip's body frame."""
    ps, ch = p["psi"], p["chi"]
    return np.array((-math.sin(ps) * math.sin(ch), math.sin(ps) * math.cos(ch), math.cos(ps)))


def stiffness(p):
    return np.array((1.0, p["b2"], p["c"]))


def curvature(y, p, rot=None):
    """The body curvature u = K^-1 R^T m + u_hat on the points, (3, m); ``rot``: R(q) if
    already computed."""
    rot = rotation(y[3:7]) if rot is None else rot
    mb = np.einsum("ji...,j...->i...", rot, y[7:10])
    return mb / stiffness(p)[:, None] + np.array((p["u1"], p["u2"], p["u3"]))[:, None]


def tip_arm(yb, p):
    """The arm's spatial vector eps R(q(1)) a_b."""
    return p["eps"] * rotation(yb[3:7]) @ arm_body(p)


# ---- ordinates ---------------------------------------------------------------------------

def _z1(s, y, p):
    return float(y[2, -1])


def _twist(s, y, p):
    return float(trapezoid_weights(s) @ curvature(y, p)[2])


def _m3(s, y, p):
    return float(y[7:10, -1] @ rotation(y[3:7, -1])[:, 2])


def _mz1(s, y, p):
    return float(y[9, -1])


def _zero_mode(s, y, p):
    return 0.0 if zero_mode(s, y, p) is None else 1.0


def _qnorm(s, y, p):
    return float(np.max(np.abs(np.linalg.norm(y[3:7], axis=0) - 1.0)))


def part_counts(s, y, p, shift: float = 0.0) -> dict[str, int]:
    """The index of each of the second variation's parts (``index_in``, the e_z component;
    ``index_out``, the out-of-plane ones) at the state given on the nodes ``s`` less
    ``shift`` times the L2 product, -1 for both at a non-planar state and for a part with a
    zero eigenvalue (the state interpolated by cubic Hermite with the slopes of the ODE, as
    the engine does). Where the engine has not counted them: snap-back targets, mirror
    images, the out-of-plane eigenvalues of tools/three_d.py."""
    from elastica_auto.core.solution import State
    from elastica_auto.numerics.stability import count_form
    rhs, second_variation = _derived("rhs"), _derived("second_variation")
    state = State(s, y, rhs(s, y, p), p)
    return count_form(lambda pts: second_variation(pts, state(pts), p), s, shift=shift).parts


#: The ordinates that are no parameter's (the distinguished ones, E and the parts' indices
#: are derived).
ORDINATES = [
    Ordinate("z1", r"$z(1)$", _z1, None, "out-of-plane tip displacement r(1).e_z"),
    Ordinate("twist", r"$\int u_3\,ds$", _twist, None, "total twist (trapezoidal rule)"),
    Ordinate("m3", r"$m(1)\cdot d_3(1)$", _m3, None, "twisting moment at the tip"),
    Ordinate("mz1", r"$m(1)\cdot e_z$", _mz1, None, "tip moment about e_z"),
    Ordinate("qnorm", r"$\max||q| - 1|$", _qnorm, None, "diagnostic: drift of |q| from 1"),
    Ordinate("zero_mode", r"zero modes", _zero_mode, None,
             "1 where the symmetry's zero mode (rotation about the load line, omega = e - "
             "d3) is left out of the index, else 0"),
]

#: The planar mirror x -> -x (docs/kirchhoff.md, "Mirror images"): r -> M r, m -> -M m with
#: M = diag(-1, 1, 1), and q -> -(e_x (x) q (x) e_y) = (-q3, q2, q1, -q0), the sign that
#: keeps the clamp's quaternion the mirrored clamp's. psi, alpha, theta0, chi, phi0, u1, u3
#: change sign, and so do their distinguished ordinates (dE/dxi) and mz1, twist and m3 (the
#: energy E does not). Of
#: the shooting unknowns (`shooting`), k1 = m(0).e1 changes sign (e1 = e_z in the plane) and
#: k2 = m(0).e2 does not (e2 -> -M e2 as m -> -M m).
MIRROR = Mirror({"x": "-x", "q0": "-q3", "q1": "q2", "q2": "q1", "q3": "-q0", "my": "-my",
                 "mz": "-mz"},
                ("psi", "alpha", "theta0", "chi", "phi0", "u1", "u3"),
                ("m1", "mA", "m0", "mchi", "mphi", "dE_du1", "dE_du3", "mz1", "twist", "m3"),
                shooting=(-1, 1))


def exact_start(s, p):
    """The straight rod along the load line, exact when F x d3(0) = 0 (theta0 = alpha and
    beta = 0, or theta0 = alpha + pi and beta = pi, ...), the arm along the tip tangent
    (sin psi = 0) and no intrinsic bending (u1 = u2 = 0), or unloaded (P = 0, any alpha, beta,
    psi) without intrinsic bending: r = s d3(0), m = 0, and q(s) =
    q_c (x) (cos(u3 s / 2), 0, 0, sin(u3 s / 2)) (the intrinsic twist turns the frame about the
    straight axis). None otherwise; the tests to 1e-12 as in the planar module."""
    qc = clamp_quaternion(p)
    d3 = rotation(qc)[:, 2]
    f = load(p)
    loaded = p["P"] != 0       # unloaded, the arm exerts no moment whatever its direction
    if (loaded and (np.linalg.norm(np.cross(f, d3)) > 1e-12 * abs(p["P"])
                    or abs(math.sin(p["psi"])) > 1e-12)) or p["u1"] != 0 or p["u2"] != 0:
        return None
    s = np.asarray(s, dtype=float)
    half = 0.5 * p["u3"] * s
    twist = np.vstack((np.cos(half), np.zeros_like(s), np.zeros_like(s), np.sin(half)))
    return np.vstack((np.outer(d3, s), qmul(qc[:, None], twist), np.zeros((3, len(s)))))


# ---- the isotropic rod's rotation about the load line (docs/kirchhoff.md, "Symmetry") ------

#: b2 - 1, u1, u2, |F x d3(0)| / |F| and the arm's |sin psi| (when eps != 0) within this of
#: zero: the rotation about the clamp axis maps solutions to solutions.
SYMMETRIC = 1e-12


def clamp_axis(p):
    """e = d3(0), the clamp's axis (spatial)."""
    return _clamp(float(p["theta0"]), float(p["phi0"]))[1].copy()


def is_symmetric(p) -> bool:
    """Whether the rotation about the clamp axis (the frames counter-rotated about d3) maps
    solutions to solutions: b2 = 1, u1 = u2 = 0, the load along the axis (or none) and the
    arm along the tip tangent (or of length 0)."""
    if not (abs(p["b2"] - 1.0) <= SYMMETRIC and abs(p["u1"]) <= SYMMETRIC
            and abs(p["u2"]) <= SYMMETRIC
            and (p["eps"] == 0 or abs(math.sin(p["psi"])) <= SYMMETRIC)):
        return False
    (f1, f2, f3), (e1, e2, e3) = load(p).tolist(), clamp_axis(p).tolist()
    return math.hypot(f2 * e3 - f3 * e2, f3 * e1 - f1 * e3, f1 * e2 - f2 * e1) <= (
        SYMMETRIC * abs(p["P"]))


def symmetric_values(name, lo, hi, p):
    """The values of ``name`` in [lo, hi] where :func:`is_symmetric` holds, the other
    parameters at ``p``: for the arm angle psi, its multiples of pi (the arm along the tip
    tangent, sin psi = 0) where the rest is symmetric and the arm has a length; none for the
    other parameters (the engine searches for their branch points)."""
    if name != "psi" or p["eps"] == 0 or not is_symmetric({**p, "psi": 0.0}):
        return []
    return [k * math.pi for k in range(math.ceil(lo / math.pi), math.floor(hi / math.pi) + 1)]


def symmetry(s, y, p):
    """The rotation T_theta about the clamp axis e = d3(0) through the clamp, with the frames
    counter-rotated about their own d3: r -> Q r, m -> Q m, q -> q_Q (x) q (x) q_3(-theta)
    (Q = Rot(e, theta); R -> Q R Rb3(-theta) keeps the clamp, the isotropic bending energy,
    the load along e and the arm along d3). Generator g = (e x r, (e^ (x) q - q (x) e3^) / 2,
    e x m) (e^ the pure quaternion); unfolding b = grad J of J = m.(d3 - e), conserved
    (m.d3 for b2 = 1, u1 = u2 = 0; m.e for F along e) and zero at both ends (d3(0) = e;
    m(1) = eps d3(1) x F): the unfolded solutions have mu = 0 (docs/kirchhoff.md). None where
    the parameters break the symmetry."""
    from elastica_auto.model.symmetry import Symmetry
    if not is_symmetric(p):
        return None
    e = clamp_axis(p)
    r, q, m = y[0:3], y[3:7], y[7:10]
    zero = np.zeros_like(q[:1])
    e_hat = np.vstack((zero, np.outer(e, np.ones(q.shape[1]))))
    e3_hat = np.vstack((zero, zero, zero, zero + 1.0))
    g = np.vstack((np.cross(e, r, axis=0), 0.5 * (qmul(e_hat, q) - qmul(q, e3_hat)),
                   np.cross(e, m, axis=0)))
    w, x, yq, z = q
    n2 = w * w + x * x + yq * yq + z * z
    d3 = rotation(q)[:, 2]
    grad_q = (2 * (m[0] * np.array((yq, z, w, x)) + m[1] * np.array((-x, -w, z, yq))
                   + m[2] * np.array((w, -x, -yq, z))) - 2 * np.sum(m * d3, axis=0) * q) / n2
    b = np.vstack((np.zeros_like(r), grad_q, d3 - e[:, None]))
    return Symmetry(g, b)


def zero_mode(s, y, p):
    """The symmetry's zero mode of the second variation, the rotation field omega = e - d3(s)
    (spatial; omega(0) = 0), L2-normalised on the points ``s``, or None where the parameters
    break the symmetry or the state is fixed by it (omega = 0: the straight rod)."""
    return _zero_mode_of(s, rotation(y[3:7])[:, 2], p) if is_symmetric(p) else None


def _zero_mode_of(s, d3, p):
    """:func:`zero_mode` of a symmetric state from its tangents d3 (3, m)."""
    omega = _clamp(float(p["theta0"]), float(p["phi0"]))[1][:, None] - d3
    size = math.sqrt(float(trapezoid_weights(s) @ np.sum(omega * omega, axis=0)))
    return omega / size if size > ZERO_MODE else None


#: The zero mode is removed from the count where its L2 size exceeds this.
ZERO_MODE = 1e-6


# ---- shooting (the snap-back targets) -------------------------------------------------------

def load_frame(p):
    """Two unit vectors (e1, e2) across the load F: e1 the part of e_z across F (e_z itself
    when F lies in the x-y plane), e2 = F/|F| x e1. For P = 0, F's direction at P = 1."""
    f = load({**p, "P": 1.0 if p["P"] >= 0 else -1.0})
    f = f / np.linalg.norm(f)
    e1 = np.array((0.0, 0.0, 1.0)) - f[2] * f
    if np.linalg.norm(e1) < 1e-8:                  # F along e_z
        e1 = np.array((1.0, 0.0, 0.0)) - f[0] * f
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(f, e1)


def moment_bound(p):
    """A bound on |m(0)| at every equilibrium, from the Hamiltonian H = (1/2) m_b.K^-1 m_b +
    m_b.u_hat + F.d3 (conserved): at s = 1, |m| = |a x F| <= |eps P|, so H <= M^2/(2 k_min) +
    M |u_hat| + |P| with M = |eps P|; at s = 0, H >= x^2/(2 k_max) - x |u_hat| - |P| with
    x = |m(0)|; hence x <= k_max |u_hat| + sqrt((k_max |u_hat|)^2 + 2 k_max (H_1 + |P|))
    (sqrt((eps P)^2 + 4 |P|) for the planar rod's K = 1, u_hat = 0)."""
    k = stiffness(p)
    kmin, kmax = float(np.min(k)), float(np.max(k))
    uh = math.sqrt(p["u1"] ** 2 + p["u2"] ** 2 + p["u3"] ** 2)
    big_m, big_p = abs(p["eps"] * p["P"]), abs(p["P"])
    h1 = big_m ** 2 / (2 * kmin) + big_m * uh + big_p
    return kmax * uh + math.sqrt((kmax * uh) ** 2 + 2 * kmax * (h1 + big_p))


def shooting(p):
    """Equilibria are the roots k in R^2 of the tip's moment balance with m(0) = k1 e1 +
    k2 e2 (`load_frame`: m(0).F = 0, because m.F is conserved and m(1).F = (a x F).F = 0):
    ``residual`` = ((m(1) - a x F).e1, (m(1) - a x F).e2), whose component along F vanishes
    with m(0).F. In the plane (F in the x-y plane) k1 = m(0).e_z, the planar module's
    theta'(0), and planar states are k2 = 0. |k| <= `moment_bound` (the Hamiltonian), so the
    box is [-bound, bound]^2 (docs/three-d.md, "Snap-back targets in 3D"). At parameters
    that keep the plane z = 0 (`keeps_plane`) its reflection z -> -z maps equilibria to
    equilibria and (k1, k2) to (k1, -k2) (m(0) -> -S m(0) with S = diag(1, 1, -1), e1 = e_z
    and e2 in the plane): the fifth item, (1, -1), halves the scan."""
    e1, e2 = load_frame(p)
    qc = clamp_quaternion(p)
    f = load(p)
    arm = p["eps"] * arm_body(p)
    bound = moment_bound(p)

    def initial(k):
        k = np.asarray(k, dtype=float).reshape(2, -1)
        m = np.outer(e1, k[0]) + np.outer(e2, k[1])
        return np.vstack((np.zeros((3, k.shape[1])), np.repeat(qc[:, None], k.shape[1], 1), m))

    def residual(ya, yb):
        a = np.einsum("ij...,j->i...", rotation(yb[3:7]), arm)
        gap = yb[7:10] - np.cross(a, f, axis=0)
        return np.vstack((e1 @ gap, e2 @ gap))

    return ((-bound, -bound), (bound, bound), initial, residual,
            (1, -1) if keeps_plane(p) else None)


def keeps_plane(p) -> bool:
    """The reflection z -> -z maps the problem at ``p`` to itself: the load, the arm and the
    clamp's frame in or across the plane (beta, chi, phi0 multiples of pi) and no intrinsic
    out-of-plane bending or twist (u2 = u3 = 0; the in-plane u1 is kept)."""
    return (all(abs(math.sin(p[k])) <= SYMMETRIC for k in ("beta", "chi", "phi0"))
            and p["u2"] == 0 and p["u3"] == 0)


# ---- drawing -------------------------------------------------------------------------------

#: The engine gives ``draw`` 3D axes (matplotlib's mplot3d).
DRAW_PROJECTION = "3d"

#: Colour of the centreline's shadow on the plane z = 0 (its in-plane projection).
SHADOW_COLOR = "0.7"


def draw(ax, profile, p):
    """The configuration in space on 3D axes: the clamp (a square plate across d3(0), hatched
    by its frame's d1, d2), the centreline, its shadow on the plane z = 0 where it leaves the
    plane, the lever arm, and the load F as an arrow ending at the arm's end, of fixed length.
    On 2D axes, the projection on the x-y plane (the planar module's view)."""
    if getattr(ax, "name", "") != "3d":
        _draw_plane(ax, profile, p)
        return
    import elastica_auto.equations.elastica_lever_arm as planar
    r = profile[0:3]
    frame = rotation(profile[3:7, 0])
    half = planar.CLAMP_HALF_WIDTH
    corners = np.array([frame[:, 0] * a + frame[:, 1] * b
                        for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1), (-1, -1))]).T * half
    ax.plot(*corners, color=planar.CLAMP_COLOR, lw=planar.LINE_WIDTH * 0.7, gid="clamp")
    for v in np.linspace(-half, half, 5):
        a = v * frame[:, 1]
        b = a - 0.09 * frame[:, 2]
        ax.plot(*np.column_stack((a, b)), color="0.35", lw=0.6)
    if np.max(np.abs(r[2])) > 1e-3:
        ax.plot(r[0], r[1], 0 * r[2], color=SHADOW_COLOR, lw=planar.LINE_WIDTH * 0.6,
                ls="--", gid="shadow")
    ax.plot(*r, color=planar.ROD_COLOR, lw=planar.LINE_WIDTH, gid="rod")
    tip = r[:, -1]
    end = tip + tip_arm(profile[:, -1], p)
    ax.plot(*np.column_stack((tip, end)), color=planar.ARM_COLOR, lw=planar.LINE_WIDTH * 0.7,
            gid="lever arm")
    ax.plot(*end[:, None], "o", ms=planar.LINE_WIDTH * 1.8, color=planar.ARM_COLOR)
    f = load(p)
    if np.linalg.norm(f) > 1e-12:
        arrow = planar.ARROW_LENGTH * f / np.linalg.norm(f)
        tail = end - arrow
        ax.quiver(*tail, *arrow, color=planar.LOAD_COLOR, lw=planar.LINE_WIDTH * 0.75,
                  arrow_length_ratio=0.3, gid="load")
        ax.plot(*tail[:, None], alpha=0)    # the arrow's tail inside the data limits


def _draw_plane(ax, profile, p):
    """The configuration projected on the x-y plane (the planar module's view): clamp,
    centreline, lever arm and the load's in-plane part."""
    import elastica_auto.equations.elastica_lever_arm as planar
    x, y = profile[0], profile[1]
    t0 = p["theta0"]
    tangent = np.array((-math.sin(t0), math.cos(t0)))
    normal = np.array((math.cos(t0), math.sin(t0)))
    half = planar.CLAMP_HALF_WIDTH
    wall = np.outer(normal, (-half, half))
    ax.plot(wall[0], wall[1], color=planar.CLAMP_COLOR, lw=planar.LINE_WIDTH * 0.9, zorder=3)
    for v in np.linspace(-half, half, 5):
        a = v * normal
        b = a - 0.09 * tangent - 0.07 * normal
        ax.plot((a[0], b[0]), (a[1], b[1]), color="0.35", lw=0.6, zorder=3)
    ax.plot(x, y, color=planar.ROD_COLOR, lw=planar.LINE_WIDTH, zorder=4, gid="rod")
    tip = profile[0:3, -1]
    end = tip + tip_arm(profile[:, -1], p)
    ax.plot((tip[0], end[0]), (tip[1], end[1]), color=planar.ARM_COLOR,
            lw=planar.LINE_WIDTH * 0.7, zorder=4, gid="lever arm")
    ax.plot(*end[:2], "o", ms=planar.LINE_WIDTH * 1.8, color=planar.ARM_COLOR, zorder=5)
    f = load(p)[:2]
    if np.hypot(*f) > 1e-12:
        planar.draw_force(ax, end[:2], f, "load")

