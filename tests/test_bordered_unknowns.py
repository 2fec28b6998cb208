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
shipped example ``bratu_mean`` (an integral and a free parameter that enters the equation).
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
}


def _case(name):
    path, lam, p = CASES[name]
    base = load_problem(path)
    aug = base.with_free()
    if lam is None:  # the first parameter that is neither free nor fixed by the module
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
    rewriting itself."""
    for name in ("lin", "nep", "bratu_mean"):
        base, aug, lam, p = _case(name)
        q, k = aug.q, len(aug.free)
        split_aug = ((), (), ())        # no mixed rows: the count is the node block's
        ours = bordered.structure(aug.n, 5, 1, split_aug).nn
        theirs_states = base.n + (1 + k) + (1 + q)
        assert ours == theirs_states, name
