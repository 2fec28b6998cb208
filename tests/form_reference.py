"""Independent reference counts for the index of a vector quadratic form (numpy/scipy only).

For h(s) in R^k on [0, 1]::

    Q[h] = int_0^1 (h'.A h' + 2 h'.C h + h.B h) ds + h(0).E0 h(0) + h(1).E1 h(1)

with A(s) symmetric positive definite, C(s) any, B(s), E0, E1 symmetric; essential conditions
G0 h(0) = 0, G1 h(1) = 0 (the other directions natural) and optional integral constraints
``int g.h ds + d0.h(0) + d1.h(1) = 0``. The index is the number of negative eigenvalues of Q on
the admissible space (L2 inner product).

End terms (the natural conditions). With W = A h' + C h, the first variation is
``dQ[h; eta] / 2 = int (eta'.W + eta.(C^T h' + B h)) ds + eta(0).E0 h(0) + eta(1).E1 h(1)``;
integrating ``int eta'.W = [eta.W]_0^1 - int eta.W'`` gives the Euler-Lagrange (Jacobi) system
``W' = C^T h' + B h`` and the boundary terms ``eta(1).(W(1) + E1 h(1)) - eta(0).(W(0) - E0 h(0))``.
So the natural conditions are ``N0^T (W(0) - E0 h(0)) = 0`` and ``N1^T (W(1) + E1 h(1)) = 0``,
N_end an orthonormal basis of null(G_end): the signs at the two ends differ.

* :func:`conjugate_count` -- the Morse index theorem (forms without integral constraints).
  k Jacobi fields (U, W), U' = A^-1 (W - C U), W' = C^T U' + B U, start on the Lagrangian plane
  of the s = 0 conditions: columns (U, W) = (N0, E0 N0) (natural directions, satisfying the
  condition above) and (0, R0) (R0 a basis of the fixed directions, orthogonal to null(G0)).
  U^T W is constant along the flow (d/ds (U^T W - W^T U) = 0 by the symmetry of A, B) and
  [[N0^T E0 N0, 0], [0, 0]] at s = 0, so symmetric. A focal point is an s in (0, 1) where U(s)
  is singular; the Legendre condition A > 0 makes each crossing positive, so at a simple one
  det U changes sign. For a Jacobi field h = U c the interior Euler-Lagrange terms vanish and
  ``Q[h] = c^T U(1)^T W(1) c - c^T U(0)^T W(0) c + c^T U(0)^T E0 U(0) c + c^T U(1)^T E1 U(1) c``;
  the s = 0 terms cancel (U(0)^T W(0) = U(0)^T E0 U(0) = N0^T E0 N0 block), and with
  x = U(1) c, ``Q = x^T M1 x``, ``M1 = W(1) U(1)^-1 + E1`` (symmetric). Hence::

      index = #{focal points in (0, 1)} + n_-(N1^T M1 N1).

  RK4 on a uniform grid (the linear step matrices built vectorised over all steps), the
  frame re-orthonormalised by a right multiplication (QR) every few steps; the sign changes
  of det U are compared within one frame, so the multiplier does not matter.
* :func:`dense_count` -- Legendre-Galerkin: per component the end functions 1 - s, s and the
  bubbles (L_j - L_{j-2})(2s - 1) (zero at both ends; derivative (2j - 1) L_{j-1} times 2),
  Gauss-Legendre quadrature, stiffness of Q and L2 mass; all linear conditions (G0, G1, the
  integral constraints) by a null-space basis Z, and the inertia of the pencil
  (Z^T K Z, Z^T M Z) (the basis is made L2-orthonormal and Z orthonormal, so Z^T M Z = I and
  the eigenvalues are those of Z^T K Z). Spectral accuracy for smooth coefficients.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from numpy.polynomial import legendre
from scipy.linalg import cholesky, null_space, orth, qr, solve_triangular

Coefficient = Callable[[np.ndarray], np.ndarray]     # s (m,) -> (m, k, k)


@dataclass
class Form:
    """A form given by callables (s -> (m, k, k)), end matrices and conditions.

    ``G0``, ``G1``: (r, k) arrays (r = 0 for a natural end); ``constraints``: a list of
    ``(g, d0, d1)`` with g a callable s -> (m, k) and d0, d1 in R^k."""

    k: int
    A: Coefficient
    B: Coefficient
    C: Coefficient | None = None
    E0: np.ndarray | None = None
    E1: np.ndarray | None = None
    G0: np.ndarray | None = None
    G1: np.ndarray | None = None
    constraints: list = field(default_factory=list)

    def coefficients(self, s):
        """A, B, C at the points s, each (m, k, k)."""
        s = np.asarray(s, dtype=float)
        a, b = self.A(s), self.B(s)
        c = self.C(s) if self.C is not None else np.zeros_like(a)
        return a, b, c

    def ends(self):
        """E0, E1 as (k, k), G0, G1 as (r, k)."""
        k = self.k

        def mat(e):
            return np.zeros((k, k)) if e is None else np.asarray(e, dtype=float).reshape(k, k)

        def gmat(g):
            return np.zeros((0, k)) if g is None else np.asarray(g, dtype=float).reshape(-1, k)

        return mat(self.E0), mat(self.E1), gmat(self.G0), gmat(self.G1)


def fixed_rows(components, k):
    """G for holding the listed components fixed: rows of the identity."""
    return np.eye(k)[list(components)].reshape(-1, k)


def _null_and_range(g, k):
    """Orthonormal bases of null(G) and of its orthogonal complement (row space of G)."""
    if g.shape[0] == 0:
        return np.eye(k), np.zeros((k, 0))
    return null_space(g), orth(g.T)


@dataclass
class ConjugateResult:
    index: int
    focal: int             # sign changes of det U in (0, 1)
    end: int               # n_-(N1^T M1 N1)
    cond_u1: float         # condition number of U(1): large means s = 1 is nearly focal
    asymmetry: float       # |M1 - M1^T| / |M1|, a check of the integration


def conjugate_count(form: Form, steps: int = 2000, every: int = 10) -> ConjugateResult:
    """Index by the Morse index theorem (module docstring); no integral constraints."""
    if form.constraints:
        raise ValueError("conjugate points do not apply to integral constraints")
    k = form.k
    e0, e1, g0, g1 = form.ends()
    n0, r0 = _null_and_range(g0, k)
    n1, _ = _null_and_range(g1, k)
    # Y = [U; W] (2k, k) obeys Y' = F Y, F = [[-A^-1 C, A^-1], [B - C^T A^-1 C, C^T A^-1]]
    s = np.linspace(0.0, 1.0, 2 * steps + 1)           # nodes and midpoints
    a, b, c = form.coefficients(s)
    ainv = np.linalg.inv(a)
    ct_ainv = np.swapaxes(c, 1, 2) @ ainv
    f = np.empty((len(s), 2 * k, 2 * k))
    f[:, :k, :k] = -ainv @ c
    f[:, :k, k:] = ainv
    f[:, k:, :k] = b - ct_ainv @ c
    f[:, k:, k:] = ct_ainv
    # RK4 for a linear system: Y_{n+1} = P_n Y_n, P_n built for all steps at once
    h = 1.0 / steps
    eye = np.eye(2 * k)
    f0, fm, f1 = f[0:-1:2], f[1::2], f[2::2]
    k1 = f0
    k2 = fm @ (eye + h / 2 * k1)
    k3 = fm @ (eye + h / 2 * k2)
    k4 = f1 @ (eye + h * k3)
    prop = eye + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    y = np.zeros((2 * k, k))
    nf = n0.shape[1]
    y[:k, :nf] = n0
    y[k:, :nf] = e0 @ n0
    y[k:, nf:] = r0
    focal = 0
    d_prev = None              # det U at s = 0 is zero when some direction is fixed: skip it
    for j in range(steps):
        y = prop[j] @ y
        d = np.linalg.det(y[:k])
        if d_prev is not None and (d > 0) != (d_prev > 0):
            focal += 1
        if (j + 1) % every == 0 and j + 1 < steps:
            q, r = qr(y, mode="economic")
            y = q                 # the same right multiplier on U and W
            d = np.linalg.det(y[:k])
        d_prev = d
    u1, w1 = y[:k], y[k:]
    cond = float(np.linalg.cond(u1))
    m1 = w1 @ np.linalg.inv(u1) + e1
    asym = float(np.linalg.norm(m1 - m1.T) / max(np.linalg.norm(m1), 1e-300))
    m1 = 0.5 * (m1 + m1.T)
    end = int(np.count_nonzero(np.linalg.eigvalsh(n1.T @ m1 @ n1) < 0)) if n1.size else 0
    return ConjugateResult(focal + end, focal, end, cond, asym)


class LegendreBasis:
    """Per-component basis on [0, 1]: 1 - s, s and ``size`` bubbles, at ``nodes`` Gauss
    points, orthonormalised in L2; values ``phi`` and derivatives ``dphi`` (n, q), end values
    ``at0``, ``at1`` (n,)."""

    def __init__(self, size: int = 44, nodes: int = 128):
        x, w = legendre.leggauss(nodes)
        self.s, self.w = (x + 1) / 2, w / 2
        lv = np.empty((size + 2, nodes))
        lv[0], lv[1] = 1.0, x
        for n in range(1, size + 1):
            lv[n + 1] = ((2 * n + 1) * x * lv[n] - n * lv[n - 1]) / (n + 1)
        n = size + 2
        phi, dphi = np.empty((n, nodes)), np.empty((n, nodes))
        phi[0], dphi[0] = 1 - self.s, -1.0
        phi[1], dphi[1] = self.s, 1.0
        for j in range(2, n):
            scale = 1.0 / np.sqrt(2 * (2 * j - 1))      # keeps the Gram matrix well scaled
            phi[j] = scale * (lv[j] - lv[j - 2])
            dphi[j] = scale * 2 * (2 * j - 1) * lv[j - 1]    # d/ds = 2 d/dx
        at0, at1 = np.zeros(n), np.zeros(n)
        at0[0] = at1[1] = 1.0
        # made L2-orthonormal (M = R^T R, functions R^-T phi), so that with an orthonormal
        # null-space basis Z the pencil is the standard eigenproblem of Z^T K Z (fewer LAPACK
        # calls: multithreaded BLAS on these small matrices is slow on a busy machine)
        r = cholesky((phi * self.w) @ phi.T)

        def orthonormal(v):
            return solve_triangular(r, v, trans="T")
        self.phi, self.dphi = orthonormal(phi), orthonormal(dphi)
        self.at0, self.at1 = orthonormal(at0), orthonormal(at1)


BASIS = LegendreBasis()


def dense_count(form: Form, basis: LegendreBasis = BASIS):
    """(number of negative eigenvalues, smallest |eigenvalue|, eigenvalues) of Q on the
    admissible space by Legendre-Galerkin (module docstring)."""
    k = form.k
    e0, e1, g0, g1 = form.ends()
    a, b, c = form.coefficients(basis.s)
    p, dp, w = basis.phi, basis.dphi, basis.w
    n = p.shape[0]
    # K[(a, i), (b, j)] = int A_ab Di Dj + C_ab Di Pj + C_ba Pi Dj + B_ab Pi Pj (+ ends)
    kk = (np.einsum("qab,iq,jq->aibj", a * w[:, None, None], dp, dp)
          + np.einsum("qab,iq,jq->aibj", c * w[:, None, None], dp, p)
          + np.einsum("qba,iq,jq->aibj", c * w[:, None, None], p, dp)
          + np.einsum("qab,iq,jq->aibj", b * w[:, None, None], p, p))
    kk += np.einsum("ab,i,j->aibj", e0, basis.at0, basis.at0)
    kk += np.einsum("ab,i,j->aibj", e1, basis.at1, basis.at1)
    kk = kk.reshape(k * n, k * n)
    kk = 0.5 * (kk + kk.T)
    rows = [np.kron(g0, basis.at0), np.kron(g1, basis.at1)]   # G h(end) as rows on (a, i)
    for g, d0, d1 in form.constraints:
        gq = np.asarray(g(basis.s), dtype=float).reshape(len(basis.s), k)
        row = (np.einsum("qa,iq->ai", gq * w[:, None], p)
               + np.outer(np.asarray(d0, dtype=float).reshape(k), basis.at0)
               + np.outer(np.asarray(d1, dtype=float).reshape(k), basis.at1))
        rows.append(row.reshape(1, k * n))
    con = np.concatenate(rows, axis=0)
    z = np.eye(k * n)
    if con.shape[0]:
        # orthonormal basis of null(con): the last columns of a complete QR of con^T
        q, r = np.linalg.qr(con.T, mode="complete")
        diag = np.abs(np.diag(r))
        assert np.min(diag) > 1e-10 * np.max(diag), "dependent conditions"
        z = q[:, con.shape[0]:]
    mu = np.linalg.eigvalsh(z.T @ kk @ z)
    return int(np.count_nonzero(mu < 0)), float(np.min(np.abs(mu))), mu
