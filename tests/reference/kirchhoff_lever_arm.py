"""Spatial Kirchhoff rod with a rigid lever arm (nondimensional: in-plane bending stiffness 1,
length 1): the 3D extension of ``elastica_lever_arm`` (derivation and checks: docs/kirchhoff.md).

An inextensible, unshearable rod, clamped at s = 0, carries at s = 1 a rigid lever arm with a
dead load F at its end. State ``y = (r, q, m)``, 10 rows: the centreline r (3), a quaternion q
(4) of the frame (d1, d2, d3) = R(q) (body to space, d3 the tangent) and the contact moment m
(3, spatial). With the contact force n = F everywhere (no distributed load)::

    r' = d3,   q' = (1/2) q (x) (0, u),   m' = F x d3,
    u = K^-1 R(q)^T m + u_hat,   K = diag(1, b2, c),   u_hat = (u1, u2, u3).

u is the body (Darboux) curvature, R' = R [u]_x. R(q) is the rotation of q / |q| (the
quadratic form over |q|^2), so the frame is orthonormal even if |q| drifts; q' above keeps |q|
constant exactly, the clamp's 4 conditions fix it to 1 and |q| - 1 is stored as a diagnostic.

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
  the tip tangent (its spatial vector eps (sin(psi - theta1), cos(psi - theta1), 0)); chi
  turns the arm's plane about the tip tangent d3(1).
* moment balance of the arm at the tip: m(1) = (eps R(q(1)) a_b) x F (planar: kappa(1) + eps P
  sin(psi + alpha - theta(1)) = 0).

Energy (its Euler-Lagrange equations are the system above; planar: docs/design.md)::

    E[R] = int_0^1 (1/2) (u - u_hat).K (u - u_hat) ds - F.(r(1) + eps R(1) a_b),   R(0) = R_c.

The second variation (``second_variation``) is in spatial rotation perturbations omega(s),
R -> exp([omega]_x) R, with omega(0) = 0 (docs/kirchhoff.md)::

    d2E = int ( omega'.R K R^T omega' - m.(omega x omega') + omega.B omega ) ds
          + omega(1).E1 omega(1),
    B = (F.d3) I - sym(F d3^T),   E1 = (F.a) I - sym(F a^T),   a = eps R(1) a_b,

so A = R K R^T (positive definite: the Legendre condition), C = -[m]_x / 2. At planar states
the e_z component decouples and is the planar module's form (in-plane perturbations); the
other two components are the out-of-plane (lateral-torsional) perturbations.

How the parameters enter (for the fold rule): P, eps, psi, alpha, chi, beta act at the free end
(the load potential), theta0 and phi0 are essential (the clamp), b2, c, u1, u2, u3 are in the
energy density. Distinguished ordinates, dE/dxi (-dE/dxi for the clamp's angles, the reaction):

* psi: ``m1`` = m(1).R(1) e_chi, e_chi = (cos chi, sin chi, 0) the arm's hinge axis in the
  body frame (= m(1).e_z, the planar m1, when chi = 0 in a planar state);
* eps: ``beps`` = -F.R(1) a_b (the planar module's ``beta``, renamed: ``beta`` is the load's
  azimuth here);
* P: ``gamma`` = -(F/P).(r(1) + eps R(1) a_b);  alpha: ``mA`` = (m(1) + r(1) x F).e_z;
* beta: ``mB`` = -(m(1) + r(1) x F).e_alpha, e_alpha = (cos alpha, sin alpha, 0);
* chi: ``mchi`` = -m(1).d3(1);  theta0: ``m0`` = m(0).e_z;  phi0: ``mphi`` = m(0).d3(0);
* b2: ``Eb2`` = int (1/2)(u2 - u_hat2)^2 ds;  c: ``Ec`` = int (1/2)(u3 - u_hat3)^2 ds.

(dE/dalpha: dF/dalpha = e_z x F, so dE/dalpha = -(e_z x F).(r(1) + a) = e_z.((r(1) + a) x F) =
e_z.(m(1) + r(1) x F); dF/dbeta = F x e_alpha likewise; a clamp rotation omega(0) changes E by
-m(0).omega(0).) Others: ``z1`` = r(1).e_z (out-of-plane tip displacement), ``twist`` = the
total twist int u3 ds, ``m3`` = m(1).d3(1), ``mz1`` = m(1).e_z, ``qnorm`` = max |(|q| - 1)|,
and at planar states (where the second variation decouples) ``index_in`` and ``index_out``,
the counts of its e_z block and of its out-of-plane block (their sum is the index; -1 at
non-planar states and where a block has a zero eigenvalue).

``shooting`` (the snap-back targets): equilibria are the roots of the tip condition across F
with m(0) = k1 e1 + k2 e2 across F (m.F is conserved and zero at the tip), |m(0)| bounded
through the Hamiltonian (`moment_bound`; docs/three-d.md, "Snap-back targets in 3D").

``draw`` draws the configuration in space (the module's ``DRAW_PROJECTION`` is ``"3d"``: the
engine gives it 3D axes); on 2D axes it projects it on the x-y plane, like the planar module.
"""

import functools
import math

import numpy as np

from elastica_auto.model.problem import (Constraint, Mirror, Ordinate, Parameter,
                                         SecondVariation)
from elastica_auto.core.solution import trapezoid_weights

STATES = ("x", "y", "z", "q0", "q1", "q2", "q3", "mx", "my", "mz")
#: The quaternion's states: turning the clamp by a whole turn (theta0 or phi0 grown by 2 pi)
#: turns q(0), and with it q(s), to -q, the same frame.
QUATERNION = ("q0", "q1", "q2", "q3")

TWO_PI = 2 * math.pi

PARAMETERS = [
    Parameter("P", math.pi ** 2 / 4, r"P", "free", doc="load |F| l^2 / K1; negative reverses F"),
    Parameter("eps", 0.25, r"\epsilon", "free", doc="lever-arm length / l; negative flips it"),
    Parameter("psi", 0.0, r"\psi", "free", period=TWO_PI,
              doc="arm angle to the tip tangent, clockwise in the arm's plane"),
    Parameter("alpha", 0.0, r"\alpha", "free", period=TWO_PI,
              doc="load direction from the vertical, in the x-y plane"),
    Parameter("theta0", 0.0, r"\theta_0", "fixed", period=TWO_PI, period_flip=QUATERNION,
              doc="rotation of the clamp about e_z (a whole turn is q -> -q)"),
    Parameter("chi", 0.0, r"\chi", "free", period=TWO_PI,
              doc="tilt of the arm's plane about the tip tangent"),
    Parameter("beta", 0.0, r"\beta", "free", period=TWO_PI,
              doc="azimuth of the load out of the x-y plane (towards +z)"),
    Parameter("phi0", 0.0, r"\phi_0", "fixed", period=TWO_PI, period_flip=QUATERNION,
              doc="twist of the clamp about its own axis (a whole turn is q -> -q)"),
    Parameter("b2", 1.0, r"b_2", "ode", doc="out-of-plane bending stiffness / in-plane"),
    Parameter("c", 1 / 1.3, r"c", "ode",
              doc="torsional stiffness / in-plane bending stiffness (1/(1 + nu), nu = 0.3)"),
    Parameter("u1", 0.0, r"\hat u_1", "ode", doc="intrinsic in-plane curvature"),
    Parameter("u2", 0.0, r"\hat u_2", "ode", doc="intrinsic out-of-plane curvature"),
    Parameter("u3", 0.0, r"\hat u_3", "ode", doc="intrinsic twist"),
]


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


# ---- the right-hand side and its Jacobian, by constant tensors ----------------------------
#
# R(q) = Q(q) / |q|^2 with Q quadratic in q, and dQ/dq_j = 2 D_j(q) with D_j linear in q (the
# table of ``_dq``); by Euler's relation for a homogeneous quadratic, Q = sum_j q_j D_j. So
# every q-dependent factor of rhs and rhs_jac is a constant tensor T (T[j, a, b, c] =
# dD_j[a, b]/dq_c, and the Hamilton product's L(q), M(u)) times q (x) q, m (x) q or the like:
# one matrix product (W @ X, X with a row per component pair and a column per point) for all
# points. numpy's cost per call, not the arithmetic, dominates at a few hundred points.

def _dq(q):
    """D_j(q) = (1/2) dQ/dq_j, (4, 3, 3, ...): each linear in q."""
    w, x, y, z = q
    return np.array((((w, -z, y), (z, w, -x), (-y, x, w)),        # d/dw
                     ((x, y, z), (y, -x, -w), (z, w, -x)),        # d/dx
                     ((-y, x, w), (x, y, z), (-w, z, -y)),        # d/dy
                     ((-z, -w, x), (w, -z, y), (x, y, z))))       # d/dz, each (3, 3, ...)


def _left(q):
    """L(q)[:, 1:], (4, 3, ...): q (x) (0, v) = L(q)[:, 1:] v."""
    q0, q1, q2, q3 = q
    return np.array(((-q1, -q2, -q3), (q0, -q3, q2), (q3, q0, -q1), (-q2, q1, q0)))


def _right(u):
    """M((0, u)), (4, 4, ...): q (x) (0, u) = M((0, u)) q."""
    u1, u2, u3 = u
    zero = 0.0 * u1
    return np.array(((zero, -u1, -u2, -u3), (u1, zero, u3, -u2), (u2, -u3, zero, u1),
                     (u3, u2, -u1, zero)))


def _cross_matrix(v):
    """[v]_x, (3, 3, ...): [v]_x w = v x w."""
    zero = np.zeros_like(v[0])
    return np.array(((zero, -v[2], v[1]), (v[2], zero, -v[0]), (-v[1], v[0], zero)))


_T = _dq(np.eye(4))                                  # T[j, a, b, c] = dD_j[a, b] / dq_c
_HL = 0.5 * _left(np.eye(4))                         # L(q)[:, 1:] / 2 = _HL[:, :, c] q_c
#: _W_QUAD @ (q (x) q) = Q, rows (a, b), columns (j, c).
_W_QUAD = _T.transpose(1, 2, 0, 3).reshape(9, 16)
#: _W_GRAD @ (m (x) q) = (D_j^T m)_i, rows (i, j), columns (l, c): T[j, l, i, c].
_W_GRAD = _T.transpose(2, 0, 1, 3).reshape(12, 12)
#: _W_COL3 @ q = D_j e3, rows (a, j).
_W_COL3 = _T[:, :, 2, :].transpose(1, 0, 2).reshape(12, 4)
#: _W_QDOT @ (u (x) q) = L(q)[:, 1:] u / 2, columns (k, c); for X (3, n) the same product
#: with X (x) q (rows (k, c), columns (j, m)) is L(q)[:, 1:] X / 2.
_W_QDOT = _HL.reshape(4, 12)
#: _W_RIGHT @ u = M((0, u)) / 2, rows (r, s).
_W_RIGHT = 0.5 * _right(np.eye(3)).reshape(16, 3)
#: _W_HALF_CROSS @ m = -[m]_x / 2, rows (i, j).
_W_HALF_CROSS = -0.5 * _cross_matrix(np.eye(3)).reshape(9, 3)


def _frame(y):
    """(q, q (x) q (16, m), |q|^2, R (9, m): rows (a, b)) at the points."""
    q = y[3:7]
    npts = q.shape[1]
    n2 = np.einsum("ij,ij->j", q, q)
    qq = (q[:, None, :] * q[None, :, :]).reshape(16, npts)
    rot = _times(_W_QUAD, qq)
    rot /= n2
    return q, qq, n2, rot


def _body_moment(rot, m):
    """R^T m (3, m) from R's rows (a, b) (9, m)."""
    return (rot.reshape(3, 3, -1) * m[:, None, :]).sum(axis=0)


def _curvature(mb, p):
    """u = K^-1 R^T m + u_hat from the body moment R^T m (3, m)."""
    k, u_hat = _constitutive(float(p["b2"]), float(p["c"]), float(p["u1"]), float(p["u2"]),
                             float(p["u3"]))
    u = mb / k
    u += u_hat
    return u


@functools.lru_cache(maxsize=64)
def _constitutive(b2, c, u1, u2, u3):
    """(K as a column (3, 1), u_hat as a column), read-only: asked for at every call."""
    out = (stiffness({"b2": b2, "c": c})[:, None], np.array((u1, u2, u3))[:, None])
    for a in out:
        a.flags.writeable = False
    return out


def rhs(s, y, p):
    """r' = d3, q' = (1/2) L(q)[:, 1:] u, m' = F x d3."""
    q, _, _, rot = _frame(y)
    d3 = rot[2::3]
    u = _curvature(_body_moment(rot, y[7:10]), p)
    out = np.empty((10, q.shape[1]), dtype=rot.dtype)
    out[0:3] = d3
    out[3:7] = _times(_W_QDOT, (u[:, None, :] * q[None, :, :]).reshape(12, -1))
    np.matmul(_load_cross(p), d3, out=out[7:10])
    return out


#: OpenBLAS runs a product of more than 65536 x 4 multiply-adds on several threads: at these
#: sizes that costs several times as much CPU (far more while the machine is busy).
_SINGLE_THREAD = 65536 * 4


def _times(w, x):
    """w @ x for a constant w (r, c) and x (c, n), in blocks of columns that BLAS multiplies
    on one thread (_SINGLE_THREAD)."""
    step = max(1, _SINGLE_THREAD // w.size)
    if x.shape[1] <= step:
        return w @ x
    return np.concatenate([w @ x[:, i:i + step] for i in range(0, x.shape[1], step)], axis=1)


def tip_arm(yb, p):
    """The arm's spatial vector eps R(q(1)) a_b."""
    return p["eps"] * _rotation_at(yb[3:7]) @ arm_body(p)


def _rotation_at(q):
    """R(q) (3, 3) at one quaternion (4,) (``rotation``'s Q(q) / |q|^2 by the tensor)."""
    return (_W_QUAD @ np.outer(q, q).reshape(16)).reshape(3, 3) / (q @ q)


def bc(ya, yb, p):
    return np.concatenate((ya[0:3], ya[3:7] - _clamp(float(p["theta0"]), float(p["phi0"]))[0],
                           yb[7:10] - cross(tip_arm(yb, p), load(p))))



# ---- Jacobians (the derivatives of rhs and bc; derivation in docs/kirchhoff.md) -----------

def rhs_jac(s, y, p):
    """df/dy, (10, 10, m), of ``rhs``: with dR_j = dR/dq_j = 2 (D_j - q_j R) / |q|^2,
    dd3/dq_j = dR_j e3; du/dq_j = K^-1 dR_j^T m = 2 K^-1 (D_j^T m - q_j R^T m) / |q|^2,
    du/dm = K^-1 R^T;
    q' = (1/2) q (x) (0, u) = (1/2) M((0, u)) q = (1/2) L(q) (0, u), so
    dq'/dq = (1/2) M((0, u)) + (1/2) L(q)[:, 1:] du/dq and dq'/dm = (1/2) L(q)[:, 1:] du/dm;
    m' = F x d3: dm'/dq_j = F x dd3/dq_j. L and M are the left and right multiplication
    matrices of the Hamilton product (each factor by the constant tensors above)."""
    q, _, n2, rot = _frame(y)
    m = y[7:10]
    npts = q.shape[1]
    kinv = 1 / stiffness(p)
    scale = 2 / n2
    d3 = rot[2::3]
    mb = _body_moment(rot, m)
    u = _curvature(mb, p)
    du_dq = _times(_W_GRAD, (m[:, None, :] * q[None, :, :]).reshape(12, npts)).reshape(3, 4, npts)
    du_dq -= mb[:, None, :] * q[None, :, :]
    du_dq *= kinv[:, None, None] * scale                                  # (3, 4, m)
    dd3 = (_W_COL3 @ q).reshape(3, 4, npts)
    dd3 -= d3[:, None, :] * q[None, :, :]
    dd3 *= scale                                                          # (3, 4, m)
    jac = np.zeros((10, 10, npts))
    jac[0:3, 3:7] = dd3
    jac[3:7, 3:7] = (_W_RIGHT @ u).reshape(4, 4, npts)
    jac[3:7, 3:7] += _times(_W_QDOT, (du_dq[:, None] * q[None, :, None]).reshape(
        12, 4 * npts)).reshape(4, 4, npts)
    du_dm = rot.reshape(3, 3, npts).transpose(1, 0, 2) * kinv[:, None, None]   # K^-1 R^T
    jac[3:7, 7:10] = _times(_W_QDOT, (du_dm[:, None] * q[None, :, None]).reshape(
        12, 3 * npts)).reshape(4, 3, npts)
    jac[7:10, 3:7] = (_load_cross(p) @ dd3.reshape(3, 4 * npts)).reshape(3, 4, npts)
    return jac


def bc_jac(ya, yb, p):
    """(dbc/dya, dbc/dyb) of ``bc``: the clamp's 7 rows are the identity on (r, q)(0); the
    tip's m(1) - (eps R(q(1)) a_b) x F = m(1) + [F]_x eps R(q(1)) a_b has d/dm = I and
    d/dq_j = [F]_x eps dR/dq_j a_b."""
    q = yb[3:7]
    n2 = q @ q
    # dR/dq_j a_b = 2 (D_j - q_j R) a_b / |q|^2, rows j
    darm = (_T @ q) @ arm_body(p) - np.outer(q, _rotation_at(q) @ arm_body(p))
    darm *= 2 * p["eps"] / n2
    da = np.zeros((10, 10))
    db = np.zeros((10, 10))
    da[0:7, 0:7] = _EYE7
    db[7:10, 7:10] = _EYE7[:3, :3]
    db[7:10, 3:7] = _load_cross(p) @ darm.T
    return da, db


_EYE7 = np.eye(7)


def _load_cross(p):
    """[F]_x (3, 3), read-only (cached per P, alpha, beta: asked for at every call)."""
    return _load_cross_of(float(p["P"]), float(p["alpha"]), float(p["beta"]))


@functools.lru_cache(maxsize=64)
def _load_cross_of(P, alpha, beta):
    out = _cross_matrix(load({"P": P, "alpha": alpha, "beta": beta}))
    out.flags.writeable = False
    return out


# ---- ordinates ---------------------------------------------------------------------------

def _m1(s, y, p):
    ch = p["chi"]
    return float(y[7:10, -1] @ rotation(y[3:7, -1]) @ np.array((math.cos(ch), math.sin(ch), 0)))


def _beps(s, y, p):
    return float(-load(p) @ rotation(y[3:7, -1]) @ arm_body(p))


def _gamma(s, y, p):
    f = load(p)
    f_hat = f / p["P"] if p["P"] != 0 else load({**p, "P": 1.0})
    return float(-f_hat @ (y[0:3, -1] + tip_arm(y[:, -1], p)))


def _moment_about_origin(y, p):
    return y[7:10, -1] + np.cross(y[0:3, -1], load(p))


def _m_alpha(s, y, p):
    return float(_moment_about_origin(y, p)[2])


def _m_beta(s, y, p):
    a = p["alpha"]
    return float(-_moment_about_origin(y, p) @ np.array((math.cos(a), math.sin(a), 0.0)))


def _m_chi(s, y, p):
    return float(-y[7:10, -1] @ rotation(y[3:7, -1])[:, 2])


def _m0(s, y, p):
    return float(y[9, 0])


def _m_phi(s, y, p):
    return float(y[7:10, 0] @ rotation(y[3:7, 0])[:, 2])


def _energy_part(i):
    def fn(s, y, p):
        d = curvature(y, p)[i] - (p["u1"], p["u2"], p["u3"])[i]
        return float(trapezoid_weights(s) @ (0.5 * d * d))
    return fn


def _z1(s, y, p):
    return float(y[2, -1])


def _twist(s, y, p):
    return float(trapezoid_weights(s) @ curvature(y, p)[2])


def _m3(s, y, p):
    return -_m_chi(s, y, p)


def _mz1(s, y, p):
    return float(y[9, -1])


def _zero_mode(s, y, p):
    return 0.0 if zero_mode(s, y, p) is None else 1.0


def _qnorm(s, y, p):
    return float(np.max(np.abs(np.linalg.norm(y[3:7], axis=0) - 1.0)))


#: The second variation's parts (`SecondVariation` ``parts``): at a planar state the form
#: decouples into its e_z component (rotations in the plane) and its (e_x, e_y) components
#: (rotations out of it). The engine counts each part at every point of a branch, and the
#: ordinates of the same names take those counts.
PARTS = {"index_in": [2], "index_out": [0, 1]}


def part_counts(s, y, p, shift: float = 0.0) -> dict[str, int]:
    """The index of each of the second variation's parts (PARTS) at the state given on the
    nodes ``s`` less ``shift`` times the L2 product, -1 for both at a non-planar state and
    for a part with a zero eigenvalue (the state interpolated by cubic Hermite with the
    slopes of the ODE, as the engine does). Where the engine has not counted them: snap-back
    targets, mirror images."""
    from elastica_auto.core.solution import State
    from elastica_auto.numerics.stability import count_form
    state = State(s, y, rhs(s, y, p), p)
    return count_form(lambda pts: second_variation(pts, state(pts), p), s, shift=shift).parts


def _part_count(name):
    def fn(s, y, p):
        s, y = np.ascontiguousarray(s, dtype=float), np.ascontiguousarray(y, dtype=float)
        return _part_counts_of(s.tobytes(), y.tobytes(), len(y), tuple(sorted(p.items())))[name]
    return fn


@functools.lru_cache(maxsize=4)
def _part_counts_of(s_bytes, y_bytes, n, items):
    """:func:`part_counts` of the state given by value: index_in and index_out are asked for
    one after the other and share one count (the cache is safe across threads computing side
    by side)."""
    return part_counts(np.frombuffer(s_bytes).copy(),
                       np.frombuffer(y_bytes).reshape(n, -1).copy(), dict(items))


ORDINATES = [
    Ordinate("m1", r"$m(1)\cdot R(1)e_\chi$", _m1, "psi",
             "dE/dpsi; m(1).e_z (the planar m1) for chi = 0 in a planar state"),
    Ordinate("beps", r"$\beta$", _beps, "eps",
             "-F.R(1)a_b = dE/deps: the planar module's beta"),
    Ordinate("mA", r"$(m + r\times F)\cdot e_z$", _m_alpha, "alpha",
             "dE/dalpha = (m(1) + r(1) x F).e_z = m(0).e_z"),
    Ordinate("gamma", r"$\gamma$", _gamma, "P",
             "dE/dP = -(F/P).(r(1) + eps R(1) a_b)"),
    Ordinate("m0", r"$m(0)\cdot e_z$", _m0, "theta0", "clamp moment m(0).e_z = -dE/dtheta0"),
    Ordinate("mchi", r"$-m(1)\cdot d_3(1)$", _m_chi, "chi", "dE/dchi = -m(1).d3(1)"),
    Ordinate("mB", r"$-(m + r\times F)\cdot e_\alpha$", _m_beta, "beta",
             "dE/dbeta = -(m(1) + r(1) x F).(cos alpha, sin alpha, 0)"),
    Ordinate("mphi", r"$m(0)\cdot d_3(0)$", _m_phi, "phi0",
             "clamp twisting moment m(0).d3(0) = -dE/dphi0"),
    Ordinate("Eb2", r"$\int (u_2 - \hat u_2)^2/2$", _energy_part(1), "b2",
             "dE/db2 (trapezoidal rule)"),
    Ordinate("Ec", r"$\int (u_3 - \hat u_3)^2/2$", _energy_part(2), "c",
             "dE/dc (trapezoidal rule)"),
    Ordinate("z1", r"$z(1)$", _z1, None, "out-of-plane tip displacement r(1).e_z"),
    Ordinate("twist", r"$\int u_3\,ds$", _twist, None, "total twist (trapezoidal rule)"),
    Ordinate("m3", r"$m(1)\cdot d_3(1)$", _m3, None, "twisting moment at the tip"),
    Ordinate("mz1", r"$m(1)\cdot e_z$", _mz1, None, "tip moment about e_z"),
    Ordinate("qnorm", r"$\max||q| - 1|$", _qnorm, None, "diagnostic: drift of |q| from 1"),
    Ordinate("zero_mode", r"zero modes", _zero_mode, None,
             "1 where the symmetry's zero mode (rotation about the load line, omega = e - "
             "d3) is left out of the index, else 0"),
    Ordinate("index_in", r"index in plane", _part_count("index_in"), None,
             "index of the in-plane (e_z) block at a planar state; -1 elsewhere or at a zero "
             "eigenvalue"),
    Ordinate("index_out", r"index out of plane", _part_count("index_out"), None,
             "index of the out-of-plane block at a planar state; -1 elsewhere or at a zero "
             "eigenvalue"),
]

#: The planar mirror x -> -x (docs/kirchhoff.md, "Mirror images"): r -> M r, m -> -M m with
#: M = diag(-1, 1, 1), and q -> -(e_x (x) q (x) e_y) = (-q3, q2, q1, -q0), the sign that
#: keeps the clamp's quaternion the mirrored clamp's. psi, alpha, theta0, chi, phi0, u1, u3
#: change sign, and so do their distinguished ordinates (dE/dxi) and mz1, twist and m3. Of
#: the shooting unknowns (`shooting`), k1 = m(0).e1 changes sign (e1 = e_z in the plane) and
#: k2 = m(0).e2 does not (e2 -> -M e2 as m -> -M m).
MIRROR = Mirror({"x": "-x", "q0": "-q3", "q1": "q2", "q2": "q1", "q3": "-q0", "my": "-my",
                 "mz": "-mz"},
                ("psi", "alpha", "theta0", "chi", "phi0", "u1", "u3"),
                ("m1", "mA", "m0", "mchi", "mphi", "mz1", "twist", "m3"), shooting=(-1, 1))


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


def second_variation(s, y, p):
    """The second variation in spatial rotation perturbations omega (docs/kirchhoff.md):
    A = R K R^T, C = -[m]_x / 2, B = (F.d3) I - sym(F d3^T), E1 = (F.a) I - sym(F a^T) with
    a = eps R(1) a_b, omega(0) = 0 (the clamp), natural at s = 1; its parts PARTS (in and
    out of the plane, decoupled at a planar state)."""
    # A and B to the last bit as they were (R by ``rotation``): a count at a located branch
    # point, whose pivot is at the zero threshold, turns on their rounding
    rot = rotation(y[3:7])                                    # (3, 3, m)
    a = np.einsum("ik...,k,jk...->ij...", rot, stiffness(p), rot)
    f = load(p)
    d3 = rot[:, 2]
    fd = np.einsum("i,j...->ij...", f, d3)
    b = (f @ d3) * _EYE7[:3, :3, None] - 0.5 * (fd + fd.transpose(1, 0, 2))
    c = (_W_HALF_CROSS @ y[7:10]).reshape(3, 3, -1)                      # -[m]_x / 2 exactly
    arm = (p["eps"] * rot[:, :, -1]) @ arm_body(p)
    fa = np.outer(f, arm)
    e1 = (f @ arm) * np.eye(3) - 0.5 * (fa + fa.T)
    mode = _zero_mode_of(s, d3, p) if is_symmetric(p) else None
    return SecondVariation(a, b, c, E1=e1, fixed0=[0, 1, 2],
                           constraints=() if mode is None else [Constraint(mode, kernel=True)],
                           parts=PARTS)



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

