"""Where a snap lands (elastica_auto.landing and the elastica's gradient_flow hook).

Independent references: the energy of the module's docstring differentiated by central
differences (the flow's force and Jacobian); the BVP's equilibria found by shooting (the
method of lines converges to them at second order, and every landing is one of them); the
mirror symmetry (psi, theta) -> (-psi, -theta) at alpha = theta0 = 0 (a mirrored fold lands on
the mirrored equilibrium); and the dynamics' own law, dE/dt <= 0.
"""

from __future__ import annotations

import math

import numpy as np

from elastica_auto.landing import NODES, PUSH, land
from elastica_auto.snaps import enumerate_equilibria, snap_lps


def _folds(rotating_arm, P, count=None):
    """(point, beyond, equilibria) of the folds ending a stable segment at load P."""
    out = []
    for br in rotating_arm.result.branches:
        for p, side in snap_lps(br):
            if abs(p.params["P"] - P) > 1e-9:
                continue
            k = br.points.index(p)
            nb = br.points[k - 1 if side == "before" else k + 1]
            beyond = int(np.sign(p.params["psi"] - nb.params["psi"]))
            out.append((p, beyond, enumerate_equilibria(rotating_arm.plan.problem, p.params)))
    return out[:count]


P_HIGH = 9 * math.pi ** 2 / 4


def test_the_flow_is_the_gradient_of_its_energy(elastica):
    """force = -grad E / mass and its Jacobian, against central differences of the energy."""
    p = {**elastica.defaults(), "P": P_HIGH, "eps": 0.5, "psi": 1.0, "theta0": 0.3}
    s = np.linspace(0.0, 1.0, 41)
    flow = elastica.gradient_flow(p, s)
    rng = np.random.default_rng(1)
    u = 0.3 + rng.normal(size=40)
    d = 1e-6
    grad = np.array([(flow.energy(u + d * e) - flow.energy(u - d * e)) / (2 * d)
                     for e in np.eye(40)])
    np.testing.assert_allclose(-flow.force(u) * flow.mass, grad, atol=1e-6)
    jac = np.array([(flow.force(u + d * e) - flow.force(u - d * e)) / (2 * d)
                    for e in np.eye(40)]).T
    np.testing.assert_allclose(flow.jacobian(u).toarray(), jac, rtol=1e-6, atol=1e-4)


def test_the_method_of_lines_converges_at_second_order(elastica):
    """The discrete equilibrium next to each shooting equilibrium (Newton on force(u) = 0)
    is O(h^2) from it: halving h divides the distance by about 4."""
    from scipy.sparse.linalg import spsolve
    p = {**elastica.defaults(), "P": P_HIGH, "eps": 0.5, "psi": 2.0}
    ratios = []
    for eq in enumerate_equilibria(elastica, p):
        dist = []
        for n in (50, 100, 200):
            s = np.linspace(0.0, 1.0, n + 1)
            flow = elastica.gradient_flow(p, s)
            u = exact = flow.to_u(eq.state(s))
            for _ in range(20):
                u = u - spsolve(flow.jacobian(u), flow.force(u))
            assert np.max(np.abs(flow.force(u))) < 1e-8
            dist.append(np.max(np.abs(u - exact)))
        ratios += [dist[0] / dist[1], dist[1] / dist[2]]
    assert len(ratios) >= 10
    assert 3.5 < min(ratios) and max(ratios) < 4.5, ratios


def test_every_fold_lands_on_a_stable_equilibrium_of_the_table(rotating_arm):
    """Each fold of the snap-back table has exactly one target marked landed, with the energy
    released and the transit time; the others have none."""
    rows = rotating_arm.file.snaps
    folds = {(int(r["branch"]), r["lp"]) for r in rows}
    for fold in folds:
        mine = [r for r in rows if (int(r["branch"]), r["lp"]) == fold]
        landed = [r for r in mine if r["landed"] == 1]
        assert len(landed) == 1, fold
        assert landed[0]["index"] == 0
        assert landed[0]["energy_released"] > 0 and landed[0]["transit_time"] > 0
        assert all(math.isnan(r["energy_released"]) for r in mine if r["landed"] == 0)


def test_mirrored_folds_land_on_mirrored_equilibria(rotating_arm):
    """At alpha = theta0 = 0 the fold at psi has a mirror image at -psi (theta -> -theta);
    the rod lands from it on the mirror image (k = theta'(0) -> -k) of the first landing."""
    rows = [r for r in rotating_arm.file.snaps if r["landed"] == 1]
    assert len(rows) >= 20
    for r in rows:
        assert any(abs(q["value"] + r["value"]) < 1e-6 and abs(q["k"] + r["k"]) < 1e-6
                   for q in rows), (r["lp"], r["value"], r["k"])


def test_the_energy_decreases_and_the_landing_is_robust(rotating_arm):
    """Along the dynamics the energy never increases; halving the push or doubling the
    spatial resolution lands on the same equilibrium. The folds at P = 9 pi^2/4, where each
    fold has three or more stable equilibria to choose from."""
    folds = _folds(rotating_arm, P_HIGH, count=3)
    assert len(folds) == 3
    problem = rotating_arm.plan.problem
    for p, beyond, eqs in folds:
        assert sum(e.index == 0 for e in eqs) >= 3
        first = land(problem, p.state, p.tangent, eqs, "psi", beyond)
        assert first.target is not None and eqs[first.target].index == 0
        e = first.energies
        assert np.all(np.diff(e) <= 1e-12 * (1 + np.abs(e[:-1]))), p.name
        assert first.energy_released > 1.0
        for change in (dict(push=PUSH / 2), dict(nodes=2 * NODES)):
            again = land(problem, p.state, p.tangent, eqs, "psi", beyond, **change)
            assert again.target == first.target, (p.name, change)


def test_the_damped_model_loses_energy_and_lands(rotating_arm):
    """The damped model's total energy (potential + kinetic) never increases; with strong
    damping it lands where the overdamped flow does."""
    p, beyond, eqs = _folds(rotating_arm, P_HIGH, count=1)[0]
    problem = rotating_arm.plan.problem
    over = land(problem, p.state, p.tangent, eqs, "psi", beyond)
    strong = land(problem, p.state, p.tangent, eqs, "psi", beyond, damping=50.0)
    assert strong.target == over.target
    e = strong.energies
    assert np.all(np.diff(e) <= 1e-9 * (1 + np.abs(e[:-1])))
    weak = land(problem, p.state, p.tangent, eqs, "psi", beyond, damping=8.0)
    assert weak.target is not None and eqs[weak.target].index == 0


def test_modules_without_dynamics_have_targets_but_no_landing(rotating_arm, tmp_path):
    """The landing columns come with the hook: without it the table is as before."""
    from elastica_auto.problem import load_problem
    from elastica_auto.snaps import snap_targets
    from helpers import REPO
    source = (REPO / "equations" / "elastica_lever_arm.py").read_text()
    (tmp_path / "no_flow.py").write_text(source.replace("def gradient_flow(",
                                                        "def _gradient_flow("))
    problem = load_problem(tmp_path / "no_flow.py")
    assert not problem.has_gradient_flow
    rows = snap_targets(problem, rotating_arm.result.branches[:2])
    assert rows and not any("landed" in r for r in rows)
