"""Integral conditions and free parameters: the system the engine factorises for them (the
module's states with the running integrals and the free parameters as extra states,
`elastica_auto.model.augmented`) against the bordered system with the free parameters as
global unknowns and the integral conditions as border rows (docs/numerics.md, "Integral
conditions and free parameters"), written here from the module's own functions alone:

    u_{i+1} - u_i - h_i / 6 (f_i + 4 f_{i+1/2} + f_{i+1}) = 0        (n (m - 1) rows)
    g(u_0, u_{m-1}; p, mu) = 0                                      (n + r rows)
    sum_i h_i / 6 (phi_i + 4 phi_{i+1/2} + phi_{i+1}) = 0           (q rows: the integrals)
    <c, u> + e . mu + d lam = beta                                  (the continuation's row)

with f_{i+1/2} and phi_{i+1/2} at the cubic's midpoint value, unknowns (u (n, m), mu (r + q),
lam), its Jacobian by central differences. The two are the same discretisation: at any
point, solution or not, their Newton corrections of (u, mu, lam) agree, and so do |det|
of their Jacobians (the running integrals and the copies of mu per node are eliminated by
unit-triangular row operations). Checked on AUTO's demos ``lin`` (one integral, its value
free) and ``nep`` (one boundary condition more than states, the eigenvalue free), and the
shipped examples ``bratu_mean`` (an integral and a free parameter that enters the equation)
and ``bratu_level`` (an integral and a free parameter in the boundary conditions), whose fold
is also located both ways.
"""

from __future__ import annotations

import numpy as np
import pytest

from elastica_auto.model.problem import load_problem
from elastica_auto.numerics import bordered
from elastica_auto.numerics.collocation import Discretisation
from elastica_auto.numerics.newton import Linearization, Row
from helpers import REPO

CASES = {
    # module, continued parameter, a point (not a solution) to linearise at
    "lin": (REPO / "benchmarks" / "auto" / "lin.py", "p1", {"p1": 1.3, "p2": 0.1, "p3": 0.2}),
    "nep": (REPO / "benchmarks" / "auto" / "nep.py", "p1", {"p1": 0.7, "p2": 9.0}),
    "bratu_mean": (REPO / "examples" / "bratu_mean.py", None, None),
    "bratu_level": (REPO / "examples" / "bratu_level.py", "lam", {"lam": 2.0, "M": 0.3}),
}


def _case(name):
    path, lam, p = CASES[name]
    base = load_problem(path)
    aug = base.with_free()
    if lam is None:  # the first parameter that is not free
        lam = next(q for q in base.parameters if q not in aug.free)
    p = {**base.defaults(), **(p or {})}
    return base, aug, lam, p


def _bordered_residual(base, free, lam, s, p, u, mu, lam_value, row):
    """The bordered system's residual (the module docstring) at (u, mu, lam)."""
    q = {**p, **dict(zip(free, mu)), lam: lam_value}
    h = np.diff(s)
    f = base.rhs(s, u, q)
    u_mid = (u[:, 1:] + u[:, :-1]) / 2 - h / 8 * (f[:, 1:] - f[:, :-1])
    s_mid = s[:-1] + h / 2
    f_mid = base.rhs(s_mid, u_mid, q)
    col = u[:, 1:] - u[:, :-1] - h / 6 * (f[:, :-1] + 4 * f_mid + f[:, 1:])
    parts = [col.T.ravel(), base.bc(u[:, 0], u[:, -1], q)]
    if base.integral_names:
        phi = base.integrals(s, u, q)
        phi_mid = base.integrals(s_mid, u_mid, q)
        parts.append((h / 6 * (phi[:, :-1] + 4 * phi_mid + phi[:, 1:])).sum(axis=1))
    c, e, d, beta = row
    parts.append([float((c * u).sum() + e @ mu + d * lam_value - beta)])
    return np.concatenate(parts)


def _bordered_jacobian(residual, z, step=1e-6):
    """Central differences of ``residual`` at z, column by column."""
    J = np.empty((len(residual(z)), len(z)))
    for j in range(len(z)):
        dz = np.zeros(len(z))
        dz[j] = step * (1 + abs(z[j]))
        J[:, j] = (residual(z + dz) - residual(z - dz)) / (2 * dz[j])
    return J


@pytest.mark.parametrize("name", sorted(CASES))
def test_augmented_newton_step_is_the_bordered_one(name):
    base, aug, lam, p = _case(name)
    n, m, k = base.n, 9, len(aug.free)
    s = np.linspace(0.0, 1.0, m) ** 1.3           # not uniform: the weights matter
    u = np.vstack([np.sin((j + 1) * np.pi * s) * (0.3 + 0.1 * j) + 0.05 * j for j in range(n)])
    mu = np.array([p[q] + 0.01 * (j + 1) for j, q in enumerate(aug.free)])
    lam_value = p[lam] + 0.05
    c = np.cos(np.arange(n * m).reshape(n, m))     # the continuation's row: generic
    e, d, beta = 0.3 + np.arange(k), 0.7, 0.2

    def residual(z):
        return _bordered_residual(base, aug.free, lam, s, p, z[: n * m].reshape(n, m),
                                  z[n * m: n * m + k], z[-1], (c, e, d, beta))

    z = np.concatenate((u.ravel(), mu, [lam_value]))
    J = _bordered_jacobian(residual, z)
    assert J.shape[0] == J.shape[1] == n * m + k + 1
    dz = np.linalg.solve(J, residual(z))

    # the engine's: the running integrals anything (they cancel), mu copied to every node
    Y = np.zeros((aug.n, m))
    Y[:n] = u
    Y[n: n + aug.q] = 0.1 * s * (1.5 - s)
    Y[aug.n - k:] = mu[:, None]
    disc = Discretisation(aug, s)
    c_aug = np.zeros((aug.n, m))
    c_aug[:n] = c
    c_aug[aug.n - k:] = e[:, None] * disc.weights / disc.weights.sum()
    params = {**p, lam: lam_value}
    split = bordered.split_rows(*aug.bc_jac(Y[:, 0], Y[:, -1], params))
    row = Row(c_aug, d, beta)
    lin = Linearization(disc, lam, params, Y, lam_value, row, split)
    dY, dlam = lin.solve(row, lin.ev.col, lin.ev.bc, row.residual(Y, lam_value))

    scale = np.abs(dz).max()
    assert np.abs(dY[:n].ravel() - dz[: n * m]).max() < 1e-7 * scale
    for j in range(k):      # every node's copy of mu moves alike, by the bordered correction
        assert np.abs(dY[aug.n - k + j] - dz[n * m + j]).max() < 1e-7 * scale
    assert abs(dlam - dz[-1]) < 1e-7 * scale
    # the same |det|: the running integrals and mu's copies are eliminated by unit-triangular
    # operations
    sign, logdet = np.linalg.slogdet(J)
    assert abs(lin.fact.logdet - logdet) < 1e-6 * max(1.0, abs(logdet))


def test_structures_have_the_same_unknowns_per_node():
    """The banded form of the bordered system (bordered.Structure: per node the states, a
    copy of every parameter column and a running sum of every border row) has as many
    unknowns per node for (n states, 1 + r + q columns, 1 + q border rows) as the engine's
    for (n + q + r + q states, 1 column, 1 row): carrying them as states is the banded
    rewriting itself. Where r = 0 (as many border rows as columns, what `bordered.factor`
    takes) both counts are the Structure's own; the r extra boundary rows add rows, not
    unknowns."""
    split = ((), (), ())        # no mixed rows: the count is the node block's
    for name in CASES:
        base, aug, lam, p = _case(name)
        q, k = aug.q, len(aug.free)
        r = k - q
        ours = bordered.structure(aug.n, 5, 1, split).nn
        assert ours == base.n + (1 + k) + (1 + q), name
        if r == 0:
            assert ours == bordered.structure(base.n, 5, 1 + k, split).nn, name


def _bratu_level(x, z, M):
    """examples/bratu_level.py's closed-form family (its docstring): (u, v), lam, c at z."""
    u = -2 * np.log(np.cosh(z * (x - 0.5)) / np.cosh(z / 2))
    v = -2 * z * np.tanh(z * (x - 0.5))
    xs = np.linspace(0.0, 1.0, 4001)        # the mean of u - c, near enough for a start
    mean = float(np.mean(-2 * np.log(np.cosh(z * (xs - 0.5)) / np.cosh(z / 2))))
    c = M - mean
    lam = 2 * z * z / np.cosh(z / 2) ** 2 * np.exp(-c)
    return np.vstack((u + c, v)), lam, c


def test_a_fold_of_the_augmented_system_is_the_bordered_ones():
    """examples/bratu_level.py (an integral condition, the level c free) folds in lam at fixed
    M. On one mesh, the fold the engine locates (bordered Newton on the minimally augmented
    system of the Augmented problem, `numerics.newton.fold_newton`) against the fold of the
    bordered system of the module docstring, found without any fold locator: that system
    solved by dense Newton with the border row u'(0) = a instead of the continuation's, for
    a range of a, lam(a) maximised by golden section (lam is flat at its maximum, so an a
    found to 1e-6 gives lam to ~1e-12)."""
    from elastica_auto.core.solution import Tangent
    from elastica_auto.numerics.newton import fold_newton

    base = load_problem(REPO / "examples" / "bratu_level.py")
    aug = base.with_free()
    M, n, m = 0.3, base.n, 17
    s = np.linspace(0.0, 1.0, m) ** 1.2
    p = {**base.defaults(), "M": M}
    row_c = np.zeros((n, m))
    row_c[1, 0] = 1.0                       # the border row picks u'(0)

    def solve_at_slope(a, z0):
        y, lam, c = _bratu_level(s, z0, M)
        z = np.concatenate((y.ravel(), [c, lam]))
        for _ in range(30):
            def residual(zz):
                return _bordered_residual(base, aug.free, "lam", s, p,
                                          zz[: n * m].reshape(n, m), zz[n * m: n * m + 1],
                                          zz[-1], (row_c, np.zeros(1), 0.0, a))
            dz = np.linalg.solve(_bordered_jacobian(residual, z), residual(z))
            z = z - dz
            if np.abs(dz).max() < 1e-14 * (1 + np.abs(z).max()):
                break
        assert np.abs(residual(z)).max() < 1e-12
        return z

    z_star = 4.7            # near the continuous problem's fold, where z I(z) = 1
    lo, hi = 8.3, 10.1      # u'(0) = 2 z tanh(z / 2) there: 9.2; this brackets it
    golden = (np.sqrt(5) - 1) / 2

    def lam_of(a):
        return solve_at_slope(a, z_star)[-1]

    x1, x2 = hi - golden * (hi - lo), lo + golden * (hi - lo)
    f1, f2 = lam_of(x1), lam_of(x2)
    while hi - lo > 1e-7:
        if f1 > f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - golden * (hi - lo)
            f1 = lam_of(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + golden * (hi - lo)
            f2 = lam_of(x2)
    lam_bordered = max(f1, f2)

    # the engine's, from the bordered system's solution at the slope found, the difference of
    # two solutions beside it the approximate null vector
    a_star = (lo + hi) / 2

    def augmented_state(a):
        zz = solve_at_slope(a, z_star)
        y = np.vstack((zz[: n * m].reshape(n, m), np.full(m, zz[n * m])))
        return aug.complete(s, y, {**p, "lam": zz[-1]}), zz[-1]

    Y, lam0 = augmented_state(a_star + 0.05)
    T = augmented_state(a_star + 0.01)[0] - augmented_state(a_star - 0.01)[0]
    disc = Discretisation(aug, s)
    split = bordered.split_rows(*aug.bc_jac(Y[:, 0], Y[:, -1], p))
    res = fold_newton(disc, "lam", p, Y, lam0, Tangent(s, T, np.zeros_like(T), 0.0), split)
    assert res.converged, res.message
    assert abs(res.lam - lam_bordered) < 1e-10


@pytest.mark.parametrize("name", ["lin", "bratu_level"])
def test_gauss_collocation_newton_step_is_the_bordered_one(name):
    """The same with Gauss collocation at k = 4 points: the bordered system's unknowns are
    the node values, the module's stage values K (n, k, m-1), mu and lam; its rows the stage
    equations ``K_j - y_i - h sum_l a_jl F_l``, the node equations ``y_{i+1} - y_i - h sum_l
    b_l F_l``, the boundary conditions, the integral rows ``sum_i h_i sum_l b_l phi(K_l)``
    (Gauss-Legendre on the collocation polynomial) and the continuation's row. The engine's
    correction (condensed, its stage correction recovered) of y, K, mu and lam is the
    bordered one."""
    from elastica_auto.numerics.gauss import GaussDiscretisation, tableau

    base, aug, lam, p = _case(name)
    n, m, k, nf = base.n, 7, 4, len(aug.free)
    tau, A, b, _, _ = tableau(k)
    s = np.linspace(0.0, 1.0, m) ** 1.3
    h = np.diff(s)
    s_stage = (s[:-1] + np.multiply.outer(tau, h))            # (k, m-1)
    u = np.vstack([np.sin((j + 1) * np.pi * s) * (0.3 + 0.1 * j) + 0.05 * j for j in range(n)])
    K = np.stack([np.sin((j + 1) * np.pi * s_stage) * (0.3 + 0.1 * j) + 0.05 * j + 0.01
                  for j in range(n)])                          # (n, k, m-1): not solved
    mu = np.array([p[q] + 0.01 * (j + 1) for j, q in enumerate(aug.free)])
    lam_value = p[lam] + 0.05
    c = np.cos(np.arange(n * m).reshape(n, m))
    e, d, beta = 0.3 + np.arange(nf), 0.7, 0.2
    nK = n * k * (m - 1)

    def residual(z):
        y = z[: n * m].reshape(n, m)
        KK = z[n * m: n * m + nK].reshape(n, k, m - 1)
        mm = z[n * m + nK: n * m + nK + nf]
        q = {**p, **dict(zip(aug.free, mm)), lam: z[-1]}
        F = base.rhs(s_stage.ravel(), KK.reshape(n, -1), q).reshape(n, k, m - 1)
        stage = KK - y[:, None, :-1] - np.matmul(A, F) * h
        col = y[:, 1:] - y[:, :-1] - (b @ F) * h
        parts = [stage.ravel(), col.ravel(), base.bc(y[:, 0], y[:, -1], q)]
        if base.integral_names:
            phi = base.integrals(s_stage.ravel(), KK.reshape(n, -1), q)
            parts.append((phi.reshape(-1, k, m - 1) * b[None, :, None] * h).sum(axis=(1, 2)))
        parts.append([float((c * y).sum() + e @ mm + d * z[-1] - beta)])
        return np.concatenate(parts)

    z = np.concatenate((u.ravel(), K.ravel(), mu, [lam_value]))
    J = _bordered_jacobian(residual, z)
    assert J.shape[0] == J.shape[1]
    dz = np.linalg.solve(J, residual(z))

    Y = np.zeros((aug.n, m))
    Y[:n] = u
    Y[n: n + aug.q] = 0.1 * s * (1.5 - s)
    Y[aug.n - nf:] = mu[:, None]
    KA = np.zeros((aug.n, k, m - 1))
    KA[:n] = K
    KA[n: n + aug.q] = 0.02
    KA[aug.n - nf:] = mu[:, None, None]
    disc = GaussDiscretisation(aug, s, k)
    c_aug = np.zeros((aug.n, m))
    c_aug[:n] = c
    c_aug[aug.n - nf:] = e[:, None] * disc.weights / disc.weights.sum()
    params = {**p, lam: lam_value}
    split = bordered.split_rows(*aug.bc_jac(Y[:, 0], Y[:, -1], params))
    row = Row(c_aug, d, beta)
    lin = Linearization(disc, lam, params, Y, lam_value, row, split, KA)
    dY, dlam, dK = lin.correct(row, lin.ev, row.residual(Y, lam_value))

    scale = np.abs(dz).max()
    assert np.abs(dY[:n].ravel() - dz[: n * m]).max() < 1e-7 * scale
    assert np.abs(dK[:n].ravel() - dz[n * m: n * m + nK]).max() < 1e-7 * scale
    for j in range(nf):
        assert np.abs(dY[aug.n - nf + j] - dz[n * m + nK + j]).max() < 1e-7 * scale
    assert abs(dlam - dz[-1]) < 1e-7 * scale
