"""The gradient flow of an energy module with rotation coordinates: a flow of frames (numpy and
scipy only; docs/energy.md, "The gradient flow of frames").

The energy is discretised on the grid as the scalar coordinates' flow is (the midpoint rule,
`runtime.gradient_flow`), each rotation by its frames at the nodes, R_j = R(q_j / |q_j|):

* on each interval the strain is the exact one of the rotation from R_j to R_(j+1),
  ``U_j = log(R_j^T R_(j+1))^vee / h_j`` (the constant body curvature that turns one frame
  into the other), and the frame at the midpoint is half way along that turn,
  ``Rbar_j = R_j exp(h_j [U_j]_x / 2)``;
* in quaternions, with a = q_j / |q_j|, b = q_(j+1) / |q_(j+1)| and r = conj(a) (x) b =
  (r0, rho) = (cos(phi/2), sin(phi/2) n) for the turn by phi about n:
  ``U_j = (2 / h_j) atan2(|rho|, r0) rho / |rho|`` and ``Rbar_j = R(a + b)`` (a + b is
  a (x) (1 + r), and 1 + r the half turn's quaternion times 2 cos(phi/4)). The turn is the one
  along the great arc of the unit quaternions from a to b (q and -q are the same frame, and
  the field of q chooses: a continuous field of frames has neighbours a small turn apart),
  smooth everywhere but at b = -a;
* ``E_h = sum_j h_j L_eff(zbar_j, (z_(j+1) - z_j)/h_j, Rbar_j, U_j, sbar_j) + B0 + B1 + c``.

For a planar field R_j = Rz(theta_j) R_0 this is ``U_j = ((theta_(j+1) - theta_j) / h_j) e``
and ``Rbar_j = Rz(thetabar_j) R_0`` exactly: the planar energy's midpoint rule, term by term.

The dynamics are those of the frames under spatial turns, ``R_t = [omega]_x R`` with
``omega_j = -(1 / M_j) dE_h/dw_j`` (dE_h/dw_j the derivative along R_j -> exp(e [w]) R_j, M_j
the lumped mass): the steepest descent of E_h in the metric sum_j M_j |omega_j|^2. In the
quaternions (the configuration vector u: the scalar coordinates' free nodal values, then each
rotation's four components at its free nodes) q_t = (0, omega) (x) q / 2; since E_h depends on
q only through q / |q|, its gradient G in q is tangent to the sphere and
``dE_h/dw = Im(G (x) conj(q)) / 2`` at |q| = 1, so ``q_t = -G / (4 M)``: the Euclidean gradient
flow of E_h in q with the mass 4 M (|omega| = 2 |q_t| on the unit sphere). A penalty
``KAPPA sum_j M_j (|q_j|^2 - 1)^2`` (zero on the frames) is added to the potential: its force
``-KAPPA (|q|^2 - 1) q`` is radial, orthogonal to G, so E_h still decreases along the flow
(``dE_h/dt = -G.q_t = -|G|^2 / (4 M) <= 0``), |q| relaxes to 1, and the Jacobian is not singular
along q (E_h alone is flat there). The potential reported (``energy``) is E_h plus the
penalty, the Lyapunov function of the overdamped and the damped model alike; it is E_h where
|q| = 1.

The gradient is exact: the strains and midpoint frames of each interval are differentiated
in its eight quaternion components by the chain rule (`geometry_jacobian`; the tests compare
it with the complex step of `geometry`, written with functions that take complex arguments),
the density's derivatives in the frame entries and strains are the generated module's
formulas. The Jacobian of the force (for the integrator's and Newton's linear solves) is
assembled from each interval's Hessian block, central differences of its exact gradient (all
intervals and inputs in one vectorised evaluation), the end terms' likewise and the
penalty's exactly.
"""

from __future__ import annotations

import numpy as np

#: The stiffness of the penalty that holds |q| at 1 (its relaxation rate is 2 KAPPA).
KAPPA = 10.0
#: The complex step (exact derivatives to rounding for any step this small).
COMPLEX_STEP = 1e-30
#: The central differences' step for the force's Jacobian (relative to 1 + |u|).
DIFFERENCE_STEP = 1e-6
#: Below this t = |rho|^2 / r0^2, atan(sqrt t) / sqrt t by its series (error below 1e-16).
SERIES = 1e-4


def hamilton(a, b):
    """a (x) b, quaternions (4, ...) scalar first (any dtype: complex for the complex step)."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return np.array((a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                     a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 + a2 * b0 + a3 * b1 - a1 * b3,
                     a0 * b3 + a3 * b0 + a1 * b2 - a2 * b1))


def rotation(q):
    """R(q / |q|), (3, 3, ...): the quadratic form over |q|^2 (complex-step safe: no
    conjugates, no absolute values)."""
    w, x, y, z = q
    n2 = w * w + x * x + y * y + z * z
    return np.array(((w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
                     (2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
                     (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z))
                    ) / n2


def _unit(q):
    return q / np.sqrt(np.sum(q * q, axis=0))


def _turn(rho, r0):
    """f = theta / |rho| with theta = atan2(|rho|, r0), the half angle of the turn r = (r0,
    rho), so that the turn's rotation vector is 2 f rho; with fs = (df/d|rho|) / |rho| and
    fr = df/dr0 (each (...)), complex-step safe: atan(|rho| / r0) where r0 >= |rho| (a turn
    by at most a quarter turn; its series in t = |rho|^2 / r0^2 below SERIES), pi / 2 -
    atan(r0 / |rho|) otherwise (well conditioned there, |rho| >= 1 / sqrt 2; beyond a half
    turn, the one the quaternions' great arc makes; singular only at b = -a, rho = 0)."""
    sigma2 = np.sum(rho * rho, axis=0)
    with np.errstate(all="ignore"):
        near = (np.real(r0) > 0) & (np.real(r0 * r0) >= np.real(sigma2))
        r0n = np.where(near, r0, 1.0)
        t = sigma2 / (r0n * r0n)
        small = near & (np.real(t) < SERIES)
        tt = np.where(small, 1.0, t)
        root = np.sqrt(tt)
        g = np.where(small, 1 - t / 3 + t * t / 5 - t ** 3 / 7, np.arctan(root) / root)
        dg = np.where(small, -1 / 3 + 2 * t / 5 - 3 * t * t / 7, (1 / (1 + tt) - g) / (2 * tt))
        sigma = np.sqrt(np.where(near, 1.0, sigma2))
        far = (np.pi / 2 - np.arctan(r0 / sigma)) / sigma
        both = sigma2 + r0 * r0
        f = np.where(near, g / r0n, far)
        fs = np.where(near, 2 * dg / r0n ** 3, (r0 / both - far) / (sigma * sigma))
        fr = -1 / both                  # -(g + 2 t g') / r0^2 = -1 / ((1 + t) r0^2) in both
    return f, fs, fr


def geometry(qa, qb, h):
    """The strains U (3, ...) and midpoint frames Rbar (3, 3, ...) of the intervals from the
    quaternions qa (4, ...) to qb (4, ...) of lengths h: the module docstring's formulas
    (complex-step safe)."""
    a, b = _unit(qa), _unit(qb)
    r = hamilton(np.array((a[0], -a[1], -a[2], -a[3])), b)
    f, _, _ = _turn(r[1:], r[0])
    return 2 * f * r[1:] / h, rotation(a + b)


def _left(a):
    """L(a) (4, 4, ...): a (x) b = L(a) b."""
    a0, a1, a2, a3 = a
    return np.array(((a0, -a1, -a2, -a3), (a1, a0, -a3, a2), (a2, a3, a0, -a1),
                     (a3, -a2, a1, a0)))


def _right(b):
    """R(b) (4, 4, ...): a (x) b = R(b) a."""
    b0, b1, b2, b3 = b
    return np.array(((b0, -b1, -b2, -b3), (b1, b0, b3, -b2), (b2, -b3, b0, b1),
                     (b3, b2, -b1, b0)))


def geometry_jacobian(qa, qb, h):
    """U (3, m), Rbar (3, 3, m) and their derivatives in the eight components (qa, qb):
    dU (3, 8, m) and dRbar (3, 3, 8, m), by the chain rule through a = qa / |qa|,
    b = qb / |qb|, r = conj(a) (x) b and a + b (real arithmetic; the tests compare it with
    the complex step of `geometry`)."""
    from .runtime import frame_derivatives
    na, nb = np.sqrt(np.sum(qa * qa, axis=0)), np.sqrt(np.sum(qb * qb, axis=0))
    a, b = qa / na, qb / nb
    eye = np.eye(4)[:, :, None]
    da = (eye - a[:, None] * a[None]) / na                      # da/dqa (4, 4, m)
    db = (eye - b[:, None] * b[None]) / nb
    conj = np.array((1.0, -1.0, -1.0, -1.0))
    r = np.einsum("ijm,jm->im", _right(b), conj[:, None] * a)
    dr = np.concatenate((np.einsum("ijm,j,jkm->ikm", _right(b), conj, da),
                         np.einsum("ijm,jkm->ikm", _left(conj[:, None] * a), db)), axis=1)
    r0, rho = r[0], r[1:]
    f, fs, fr = _turn(rho, r0)
    U = 2 * f * rho / h
    # dU/drho = (2 / h) (f I + fs rho rho^T), dU/dr0 = (2 / h) fr rho
    dU_drho = 2 * (f * np.eye(3)[:, :, None] + fs * rho[:, None] * rho[None]) / h
    dU_dr0 = 2 * fr * rho / h
    dU = np.einsum("cdm,dkm->ckm", dU_drho, dr[1:]) + dU_dr0[:, None] * dr[0][None]
    qbar = a + b
    Rbar = rotation(qbar)
    dR_dq = frame_derivatives(qbar, Rbar)
    dR = np.concatenate((np.einsum("jabm,jkm->abkm", dR_dq, da),
                         np.einsum("jabm,jkm->abkm", dR_dq, db)), axis=2)
    return U, Rbar, dU, dR


def rotation_jacobian(q):
    """R(q / |q|) (3, 3) and dR/dq (3, 3, 4) of one quaternion q (4,), by the complex step."""
    z = q.astype(complex)
    out = np.empty((3, 3, 4))
    for i in range(4):
        z[i] += 1j * COMPLEX_STEP
        out[:, :, i] = rotation(z).imag / COMPLEX_STEP
        z[i] -= 1j * COMPLEX_STEP
    return rotation(q), out


def frame_flow(p, nodes, density, ends, essential, k, nrot, flow, zrows, qrows):
    """The energy at ``p`` discretised on ``nodes`` and the overdamped dynamics of its frames,
    as an `elastica_auto.analysis.landing.Flow` (the module docstring).

    ``density(s, z, v, R, U, p)``: L_eff (m,) at the midpoints and its derivatives in z, v
    (k, m), in the frames' entries (nrot, 3, 3, m) and in the strains (nrot, 3, m);
    ``ends(za, Ra, zb, Rb, p)``: (B, dB/dz (k,), dB/dR (nrot, 3, 3)) at each end;
    ``essential(p)``: the scalar coordinates' essential values at s = 0 and 1 ({i: value}),
    the energy's constant, and the clamps' quaternions at s = 0 and 1 ({j: (4,)}); ``zrows``,
    ``qrows``: the rows of the scalar coordinates and of each rotation's quaternion in the
    states; ``flow``: the class `elastica_auto.Flow`."""
    from scipy.sparse import coo_matrix

    from ..core.solution import trapezoid_weights
    nodes = np.asarray(nodes, dtype=float)
    fixed0, fixed1, constant, clamps0, clamps1 = essential(p)
    npts = len(nodes)
    h = np.diff(nodes)
    sm = 0.5 * (nodes[:-1] + nodes[1:])
    weights = trapezoid_weights(nodes)
    ncomp = k + 4 * nrot
    keep = np.ones((ncomp, npts), dtype=bool)
    full = np.zeros((ncomp, npts))
    for i, value in fixed0.items():
        keep[i, 0], full[i, 0] = False, value
    for i, value in fixed1.items():
        keep[i, -1], full[i, -1] = False, value
    for j, qc in clamps0.items():
        keep[k + 4 * j:k + 4 * j + 4, 0] = False
        full[k + 4 * j:k + 4 * j + 4, 0] = qc
    for j in clamps1:
        keep[k + 4 * j:k + 4 * j + 4, -1] = False
    free = np.flatnonzero(keep.ravel())
    mass = np.concatenate((np.tile(weights, k), 4 * np.tile(weights, 4 * nrot)))[free]
    rows = [*zrows, *(r for rows4 in qrows for r in rows4)]
    held = [~keep[k + 4 * j] for j in range(nrot)]        # each rotation's clamped nodes
    quaternion = [slice(k + 4 * j, k + 4 * j + 4) for j in range(nrot)]
    # an interval's inputs (and local gradient): z at its left and right node, then each
    # rotation's q at the left node, then at the right; ``where`` their rows (component,
    # side) in the configuration
    where = ([(c, 0) for c in range(k)] + [(c, 1) for c in range(k)]
             + [(k + 4 * j + c, 0) for j in range(nrot) for c in range(4)]
             + [(k + 4 * j + c, 1) for j in range(nrot) for c in range(4)])
    nloc = len(where)

    def configuration(u):
        x = full.copy().ravel()
        x[free] = u
        x = x.reshape(ncomp, npts)
        for j, qc in clamps1.items():
            # the clamp's frame at s = 1, as the quaternion on the side of its neighbour's
            # (q and -q are the same frame; the field is continuous)
            x[quaternion[j], -1] = qc if qc @ x[quaternion[j], -2] >= 0 else -qc
        return x

    def local_inputs(x):
        """(nloc, intervals): each interval's inputs."""
        return np.array([x[c, :-1] if side == 0 else x[c, 1:] for c, side in where])

    def intervals(w, hh, ss, gradient):
        """sum h L on intervals with inputs w (nloc, m), and, with ``gradient``, its
        derivatives in them (nloc, m)."""
        zl, zr = w[:k], w[k:2 * k]
        zm, vm = 0.5 * (zl + zr), (zr - zl) / hh
        m = w.shape[1]
        U, R, jac = np.empty((nrot, 3, m)), np.empty((nrot, 3, 3, m)), []
        for j in range(nrot):
            qa = w[2 * k + 4 * j:2 * k + 4 * j + 4]
            qb = w[2 * k + 4 * nrot + 4 * j:2 * k + 4 * nrot + 4 * j + 4]
            if gradient:
                U[j], R[j], dU, dR = geometry_jacobian(qa, qb, hh)
                jac.append((dU, dR))
            else:
                U[j], R[j] = geometry(qa, qb, hh)
        L, Lz, Lv, LR, LU = density(ss, zm, vm, R, U, p)
        if not gradient:
            return hh * L, None
        g = np.empty((nloc, m))
        g[:k] = 0.5 * hh * Lz - Lv
        g[k:2 * k] = 0.5 * hh * Lz + Lv
        for j, (dU, dR) in enumerate(jac):
            gq = hh * (np.einsum("cm,cim->im", LU[j], dU)
                       + np.einsum("abm,abim->im", LR[j], dR))
            g[2 * k + 4 * j:2 * k + 4 * j + 4] = gq[:4]
            g[2 * k + 4 * nrot + 4 * j:2 * k + 4 * nrot + 4 * j + 4] = gq[4:]
        return hh * L, g

    def end_terms(x, gradient):
        """B0 + B1 at the configuration x and, with ``gradient``, their derivatives in z and q
        at each end, (ncomp,) twice."""
        za, zb = x[:k, 0], x[:k, -1]
        if not gradient:
            (b0, _, _), (b1, _, _) = ends(
                za, np.array([rotation(x[quaternion[j], 0]) for j in range(nrot)]),
                zb, np.array([rotation(x[quaternion[j], -1]) for j in range(nrot)]), p)
            return b0 + b1, None
        frames = [[rotation_jacobian(x[quaternion[j], side]) for j in range(nrot)]
                  for side in (0, -1)]
        (b0, b0z, b0r), (b1, b1z, b1r) = ends(
            za, np.array([f for f, _ in frames[0]]).reshape(nrot, 3, 3),
            zb, np.array([f for f, _ in frames[1]]).reshape(nrot, 3, 3), p)
        out = []
        for bz, br, fr in ((b0z, b0r, frames[0]), (b1z, b1r, frames[1])):
            g = np.empty(ncomp)
            g[:k] = bz
            for j in range(nrot):
                g[quaternion[j]] = np.einsum("ab,abi->i", br[j], fr[j][1])
            out.append(g)
        return b0 + b1, out

    def penalty(x):
        """KAPPA sum_j M_j (|q_j|^2 - 1)^2 over the free nodes, its gradient (ncomp, npts)
        and each node's Hessian (nrot, 4, 4, npts)."""
        value, g = 0.0, np.zeros((ncomp, npts))
        hess = np.zeros((nrot, 4, 4, npts))
        for j in range(nrot):
            q = x[quaternion[j]]
            c = KAPPA * np.where(held[j], 0.0, weights)
            n2 = np.sum(q * q, axis=0) - 1
            value += float(np.sum(c * n2 ** 2))
            g[quaternion[j]] = 4 * c * n2 * q
            hess[j] = 4 * c * (n2 * np.eye(4)[:, :, None] + 2 * q[:, None] * q[None])
        return value, g, hess

    def energy(u):
        x = configuration(u)
        hl, _ = intervals(local_inputs(x), h, sm, False)
        b, _ = end_terms(x, False)
        return float(np.sum(hl) + b + constant) + penalty(x)[0]

    def gradient_of(x):
        w = local_inputs(x)
        _, gl = intervals(w, h, sm, True)
        g = penalty(x)[1]
        for a, (c, side) in enumerate(where):
            if side == 0:
                g[c, :-1] += gl[a]
            else:
                g[c, 1:] += gl[a]
        _, (g0, g1) = end_terms(x, True)
        g[:, 0] += g0
        g[:, -1] += g1
        return g

    def force(u):
        return -gradient_of(configuration(u)).ravel()[free] / mass

    def jacobian(u):
        """d force / du = -M^-1 times the Hessian of the potential: each interval's (nloc,
        nloc) block by central differences of its exact gradient (all intervals and inputs
        in one evaluation), the ends' by differences of theirs, the penalty's exactly."""
        x = configuration(u)
        w = local_inputs(x)
        m = w.shape[1]
        step = DIFFERENCE_STEP * (1 + np.abs(w))                       # (nloc, m)
        batch = np.repeat(w[:, None, :], 2 * nloc, axis=1)             # (nloc, 2 nloc, m)
        for a in range(nloc):
            batch[a, a] += step[a]
            batch[a, nloc + a] -= step[a]
        _, gb = intervals(batch.reshape(nloc, -1), np.tile(h, 2 * nloc),
                          np.tile(sm, 2 * nloc), True)
        gb = gb.reshape(nloc, 2 * nloc, m)
        block = (gb[:, :nloc] - gb[:, nloc:]) / (2 * step[None])      # (row a, column b, m)
        index = np.array([c * npts + side for c, side in where])       # + interval number
        interval = np.arange(m)
        hr = (index[:, None, None] + interval).repeat(nloc, axis=1)
        hc = (index[None, :, None] + interval).repeat(nloc, axis=0)
        rows_h, cols_h, vals = [hr.ravel()], [hc.ravel()], [block.ravel()]
        # the end terms: differences of their exact gradients in each end's values
        for side in (0, -1):
            at = side % npts
            for c in range(ncomp):
                d = DIFFERENCE_STEP * (1 + abs(x[c, at]))
                xp, xm = x.copy(), x.copy()
                xp[c, at] += d
                xm[c, at] -= d
                gp, gm = end_terms(xp, True)[1], end_terms(xm, True)[1]
                col = (gp[0 if side == 0 else 1] - gm[0 if side == 0 else 1]) / (2 * d)
                rows_h.append(np.arange(ncomp) * npts + at)
                cols_h.append(np.full(ncomp, c * npts + at))
                vals.append(col)
        hess = penalty(x)[2]
        for j in range(nrot):
            base = (k + 4 * j) * npts
            r4 = base + np.arange(4)[:, None, None] * npts + np.arange(npts)
            c4 = base + np.arange(4)[None, :, None] * npts + np.arange(npts)
            rows_h.append(np.broadcast_to(r4, (4, 4, npts)).ravel())
            cols_h.append(np.broadcast_to(c4, (4, 4, npts)).ravel())
            vals.append(hess[j].ravel())
        size = ncomp * npts
        full_h = coo_matrix((np.concatenate(vals), (np.concatenate(rows_h),
                                                    np.concatenate(cols_h))),
                            shape=(size, size)).tocsr()
        from scipy.sparse import diags
        return (-diags(1.0 / mass) @ full_h[free][:, free]).tocsc()

    def to_u(y):
        return np.asarray(y)[rows].ravel()[free]

    def parts(u, du):
        """Full configurations of u and of a displacement du (zero where held)."""
        d = np.zeros(ncomp * npts)
        d[free] = du
        return configuration(u), d.reshape(ncomp, npts)

    def size(u, du):
        """The largest change of a scalar coordinate, or angle a frame turns by, per unit of
        the displacement du at u: |omega| = 2 |dq - (dq.q) q / |q|^2| / |q|."""
        x, d = parts(u, du)
        out = float(np.max(np.abs(d[:k]))) if k else 0.0
        for j in range(nrot):
            q, dq = x[k + 4 * j:k + 4 * j + 4], d[k + 4 * j:k + 4 * j + 4]
            n2 = np.sum(q * q, axis=0)
            across = dq - np.sum(dq * q, axis=0) / n2 * q
            out = max(out, float(np.max(2 * np.sqrt(np.sum(across * across, axis=0) / n2))))
        return out

    def distance(u, v):
        """The largest difference of a scalar coordinate, or angle between two frames at a
        node, of the configurations u and v (the quaternions' signs do not matter)."""
        x, y = configuration(u), configuration(v)
        out = float(np.max(np.abs(x[:k] - y[:k]))) if k else 0.0
        for j in range(nrot):
            a, b = _unit(x[k + 4 * j:k + 4 * j + 4]), _unit(y[k + 4 * j:k + 4 * j + 4])
            b = b * np.where(np.sum(a * b, axis=0) >= 0, 1.0, -1.0)
            angle = 4 * np.arctan2(np.sqrt(np.sum((a - b) ** 2, axis=0)),
                                   np.sqrt(np.sum((a + b) ** 2, axis=0)))
            out = max(out, float(np.max(angle)))
        return out

    return flow(nodes, to_u, mass, energy, force, jacobian, size=size, distance=distance)
