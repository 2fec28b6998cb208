"""An independent stability count for the spatial rod (equations/kirchhoff_lever_arm.py): the
Hessian, by finite differences, of the energy of a discretised rod, at a given state.

The rod is N intervals of length h = 1/N between frames R_0 (the clamp), R_1, ..., R_N taken
from the state at s_j = j h. The discrete energy (docs/kirchhoff.md, "Checks") ::

    E_h = sum_j [ h/2 (u_j - u_hat).K (u_j - u_hat) - h F.d3(M_j) ] - F.(eps R_N a_b),
    u_j = log(R_j^T R_(j+1)) / h,   M_j = R_j exp(log(R_j^T R_(j+1)) / 2)  (the midpoint frame),

(midpoint rules for the bending energy and for r(1) = int d3 ds: second order in h) is varied
by R_j -> exp([w_j]_x) R_j, j = 1..N. Nothing of the module's second variation is used: only
its conventions for F, a_b and R(q) (checked against the planar module elsewhere). Every term
couples at most two neighbouring frames, so the Hessian is assembled from 6 x 6 blocks, each by
central differences of that term, for all intervals at once. Its eigenvalues with the lumped
mass (h at inner nodes, h/2 at s = 1) approximate those of the second variation with omega(0) =
0, to O(h^2) (and O(delta^2 / h^2) from the differences, delta = 1e-4: about 1e-4 here).
"""

from __future__ import annotations

import numpy as np


def hat(w):
    """[w]_x for w (..., 3)."""
    z = np.zeros(w.shape[:-1])
    return np.stack((np.stack((z, -w[..., 2], w[..., 1]), -1),
                     np.stack((w[..., 2], z, -w[..., 0]), -1),
                     np.stack((-w[..., 1], w[..., 0], z), -1)), -2)


def expm(w):
    """exp([w]_x) by Rodrigues' formula, (..., 3, 3)."""
    t = np.linalg.norm(w, axis=-1)[..., None, None]
    k = hat(w)
    small = t < 1e-8
    ts = np.where(small, 1.0, t)
    a = np.where(small, 1 - t * t / 6, np.sin(ts) / ts)
    b = np.where(small, 0.5 - t * t / 24, (1 - np.cos(ts)) / (ts * ts))
    return np.eye(3) + a * k + b * (k @ k)


def logm(r):
    """The rotation vector of r (..., 3, 3) (angle below pi), accurate for small angles:
    the angle from atan2(|sin|, cos)."""
    v = 0.5 * np.stack((r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0],
                        r[..., 1, 0] - r[..., 0, 1]), -1)
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (np.trace(r, axis1=-2, axis2=-1) - 1)
    t = np.arctan2(s, c)
    f = np.where(s < 1e-12, 1.0 + s * s / 6, t / np.where(s < 1e-12, 1.0, s))
    return v * f[..., None]


def frames(mod, state, n):
    """The frames R_0..R_n at s_j = j / n, (n + 1, 3, 3)."""
    s = np.linspace(0, 1, n + 1)
    rot = mod.rotation(state(s)[3:7])               # (3, 3, n + 1)
    return rot.transpose(2, 0, 1)


def interval_energy(mod, p, r0, r1, h):
    """The terms of E_h of each interval, from its end frames r0, r1 (m, 3, 3)."""
    rel = logm(np.swapaxes(r0, -1, -2) @ r1)
    du = rel / h - np.array((p["u1"], p["u2"], p["u3"]))
    bend = 0.5 * h * np.einsum("...i,i,...i->...", du, mod.stiffness(p), du)
    d3 = (r0 @ expm(0.5 * rel))[..., :, 2]
    return bend - h * d3 @ mod.load(p)


def arm_energy(mod, p, r):
    return -mod.load(p) @ (p["eps"] * r @ mod.arm_body(p))


def hessian(mod, state, n, delta=1e-4, interval=None, end=None):
    """The Hessian of E_h in (w_1, ..., w_n) (3n x 3n) at the frames of ``state``;
    ``interval(p, r0, r1, h)`` and ``end(p, r)`` the terms of another energy discretised
    alike (default the rod's `interval_energy` and `arm_energy`), ``mod`` giving
    ``rotation(q)`` and the quaternion's rows 3:7 of the state."""
    p = state.params
    rot = frames(mod, state, n)
    h = 1.0 / n
    r0, r1 = rot[:-1], rot[1:]
    eye = np.eye(6)
    interval = interval or (lambda p, a, b, h: interval_energy(mod, p, a, b, h))
    end = end or (lambda p, r: arm_energy(mod, p, r))

    def term(x):                                    # x (6,): (w_j, w_(j+1)) for every j
        return interval(p, expm(x[:3]) @ r0, expm(x[3:]) @ r1, h)

    blocks = np.zeros((n, 6, 6))
    for a in range(6):
        for b in range(a, 6):
            ea, eb = delta * eye[a], delta * eye[b]
            d2 = (term(ea + eb) - term(ea - eb) - term(eb - ea) + term(-ea - eb)) / (4 * delta ** 2)
            blocks[:, a, b] = blocks[:, b, a] = d2
    big = np.zeros((3 * (n + 1), 3 * (n + 1)))
    for j in range(n):
        big[3 * j:3 * j + 6, 3 * j:3 * j + 6] += blocks[j]
    arm = np.zeros((3, 3))
    for a in range(3):
        for b in range(a, 3):
            ea, eb = delta * np.eye(3)[a], delta * np.eye(3)[b]
            d2 = sum(sa * sb * end(p, expm(sa * ea + sb * eb) @ rot[-1])
                     for sa in (1, -1) for sb in (1, -1)) / (4 * delta ** 2)
            arm[a, b] = arm[b, a] = d2
    big[-3:, -3:] += arm
    return big[3:, 3:]                               # w_0 = 0: the clamp


def chain_hessian(interval, pair, delta):
    """The Hessian of sum_j interval(pair)_j, a chain of interval terms, in its nodes'
    unknowns: column j of ``pair`` (2k rows) holds node j's k unknowns then node j+1's,
    ``interval`` maps such an array to each interval's energy (n,). By central differences,
    each pair of one interval's unknowns perturbed at once in every interval; assembled
    over the nodes: ((n + 1) k) square, node 0 first."""
    width, n = pair.shape
    k = width // 2
    block = np.zeros((n, width, width))
    for i in range(width):
        for j in range(i, width):
            total = 0.0
            for si in (1, -1):
                for sj in (1, -1):
                    z = pair.copy()
                    z[i] += si * delta
                    z[j] += sj * delta
                    total = total + si * sj * interval(z)
            block[:, i, j] = block[:, j, i] = total / (4 * delta ** 2)
    big = np.zeros((k * (n + 1), k * (n + 1)))
    for j in range(n):
        big[k * j:k * j + width, k * j:k * j + width] += block[j]
    return big


def eigenvalues(mod, state, n):
    """The eigenvalues of the discrete second variation with the lumped mass, ascending."""
    mass = np.full(3 * n, 1.0 / n)
    mass[-3:] *= 0.5
    w = 1 / np.sqrt(mass)
    return np.linalg.eigvalsh(w[:, None] * hessian(mod, state, n) * w[None, :])


def discrete_count(mod, state, n=200):
    """(number of negative eigenvalues at n intervals, the smallest |eigenvalue|, its error
    estimate): the error of the lowest eigenvalues from those at n/2 (second order: the error
    at n is about a third of the difference)."""
    fine, coarse = eigenvalues(mod, state, n), eigenvalues(mod, state, n // 2)
    low = min(8, len(coarse))
    err = np.abs(fine[:low] - coarse[:low]) / 3
    i = int(np.argmin(np.abs(fine[:low])))
    return int(np.sum(fine < 0)), float(abs(fine[i])), float(np.max(err[:low]))
