"""Snap-back targets and the shooting scan of all equilibria (elastica_auto.analysis.snaps).

Independent references: the straight rod and the mirror symmetry theta -> -theta of the problem
at psi = alpha = theta0 = 0; the critical loads of cot sqrt(P) = eps sqrt(P) (the straight rod's
index); a brute-force sign-change count of the shooting residual with one solve_ivp per grid
point (tests/shooting.py, no engine code); and re-integration of every returned equilibrium.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import shooting
from elastica_auto.analysis.equilibria import enumerate_equilibria
from elastica_auto.analysis.snaps import snap_targets
from helpers import run_cli


def critical_loads(eps, p_max):
    """Roots P of sqrt(P) cos sqrt(P) - P eps sin sqrt(P) = 0 below p_max (sqrt(P) != n pi)."""
    from scipy.optimize import brentq
    g = lambda q: q * math.cos(q) - q * q * eps * math.sin(q)  # noqa: E731
    qs = np.linspace(1e-9, math.sqrt(p_max), 20001)
    v = np.array([g(q) for q in qs])
    roots = [brentq(g, qs[i], qs[i + 1]) for i in np.flatnonzero(v[:-1] * v[1:] < 0)]
    return [q * q for q in roots if abs(math.sin(q)) > 1e-9]


def params(elastica, **kw):
    p = elastica.defaults()
    p.update(kw)
    return p


@pytest.mark.parametrize("P, eps", [(math.pi ** 2 / 4, 0.25), (9 * math.pi ** 2 / 4, 0.25),
                                    (9 * math.pi ** 2 / 4, 0.5), (20.0, -0.5)])
def test_scan_finds_the_straight_rod_and_mirror_pairs(elastica, P, eps):
    eqs = enumerate_equilibria(elastica, params(elastica, P=P, eps=eps))
    ks = np.array([e.k for e in eqs])
    # the straight rod (k = 0) is an equilibrium, with the index counted by the critical loads
    straight = [e for e in eqs if abs(e.k) < 1e-9]
    assert len(straight) == 1
    assert straight[0].index == sum(c < P for c in critical_loads(eps, P + 1))
    # theta -> -theta maps equilibria to equilibria with the same index
    for e in eqs:
        j = np.argmin(np.abs(ks + e.k))
        assert abs(ks[j] + e.k) < 1e-8 * (1 + abs(e.k))
        assert eqs[j].index == e.index


@pytest.mark.parametrize("P, eps, psi, alpha", [(9 * math.pi ** 2 / 4, 0.5, 0.8, 0.0),
                                                (15.0, 0.3, 2.0, 0.7), (-12.0, 0.5, 1.0, 0.0)])
def test_every_equilibrium_solves_the_bvp_and_none_is_missed(elastica, P, eps, psi, alpha):
    p = params(elastica, P=P, eps=eps, psi=psi, alpha=alpha, theta0=0.3)
    eqs = enumerate_equilibria(elastica, p)
    for e in eqs:
        # re-integrate from the equilibrium's y(0): the free-end residual vanishes ...
        r, _ = shooting.residual(e.k, psi, P, eps, alpha, 0.3)
        assert abs(r) < 1e-8 * (1 + abs(eps * P))
        # ... and the stored solution is that trajectory
        y = shooting.profile(P, alpha, e.state.y[:, 0], e.state.s)
        assert np.max(np.abs(y - e.state.y)) < 1e-8 * (1 + np.max(np.abs(y)))
    # brute force: sign changes of r on a grid covering the first-integral bound
    bound = math.sqrt((eps * P) ** 2 + 4 * abs(P))
    grid = np.linspace(-bound, bound, 801)
    r = np.array([shooting.residual(k, psi, P, eps, alpha, 0.3)[0] for k in grid])
    changes = grid[np.flatnonzero(r[:-1] * r[1:] < 0)]
    assert len(changes) == len(eqs)
    for k in changes:
        assert min(abs(e.k - k) for e in eqs) <= grid[1] - grid[0]


def test_no_equilibrium_lies_outside_the_first_integral_bound(elastica):
    """Beyond |k| = sqrt((eps P)^2 + 4|P|) the residual cannot vanish: |kappa(1)| > |eps P|."""
    P, eps = 22.0, 0.5
    bound = math.sqrt((eps * P) ** 2 + 4 * abs(P))
    for k in np.linspace(bound * 1.0001, bound * 3, 40):
        for sign in (1, -1):
            th1, k1, _, _ = shooting.integrate(P, 0.0, 0.0, sign * k)
            assert abs(k1) > abs(eps * P)


def test_snap_targets_of_rotating_arm(rotating_arm, elastica):
    rows = rotating_arm.file.snaps
    assert rows, "rotating_arm has folds ending stable branches (paper figure 4a)"
    branches = rotating_arm.result.branches
    lps = {(nb, p.name): (br, k) for nb, br in enumerate(branches, 1)
           for k, p in enumerate(br.points) if p.type == "LP"}
    for row in rows:
        br, k = lps[(int(row["branch"]), row["lp"])]
        lp = br.points[k]
        # the LP bounds a stable segment on the side the table says
        before, after = lp.index, br.points[k + 1].index
        assert (before, after) in ((0, 1), (1, 0))
        assert row["stable_side"] == ("before" if before == 0 else "after")
        # the target is a stable equilibrium at the LP's parameters, other than the fold
        P, eps, psi = (lp.params[q] for q in ("P", "eps", "psi"))
        assert row["value"] == psi
        r, _ = shooting.residual(row["k"], psi, P, eps)
        assert abs(r) < 1e-8 * (1 + abs(eps * P))
        assert row["index"] == 0
        assert abs(row["k"] - lp.state.y[1, 0]) > 1e-3
        assert row["target_m0"] == pytest.approx(row["k"], abs=1e-9)
    # the table is complete: every stable root of the residual at each LP is listed
    for (nb, name), (br, k) in lps.items():
        lp = br.points[k]
        if not (lp.index == 0 or br.points[k + 1].index == 0):
            continue
        listed = sorted(r["k"] for r in rows if int(r["branch"]) == nb and r["lp"] == name)
        eqs = enumerate_equilibria(elastica, lp.params)
        stable = sorted(e.k for e in eqs if e.index == 0
                        and abs(e.k - lp.state.y[1, 0]) > 1e-3)
        assert np.allclose(listed, stable, atol=1e-9)


def test_snap_target_on_a_computed_branch_lies_on_it(rotating_arm):
    """'on_branch' = n means branch n passes through the target: the branch has a point at the
    same psi (mod 2 pi) with the same clamp moment m0 = k, up to interpolation between points."""
    branches = rotating_arm.result.branches
    checked = 0
    for row in rotating_arm.file.snaps:
        nb = int(row["on_branch"])
        if not nb:
            continue
        br = branches[nb - 1]
        psi = np.array([p.params["psi"] for p in br.points])
        m0 = np.array([p.ordinates["m0"] for p in br.points])
        d = np.remainder(psi - row["value"] + math.pi, 2 * math.pi) - math.pi
        hits = [m0[i] + (m0[i + 1] - m0[i]) * d[i] / (d[i] - d[i + 1])
                for i in np.flatnonzero(d[:-1] * d[1:] <= 0) if abs(d[i] - d[i + 1]) < 1]
        assert min(abs(h - row["k"]) for h in hits) < 0.05 * (1 + abs(row["k"]))
        checked += 1
    assert checked > 0


def test_snaps_command(rotating_arm, cli_exe):
    proc = run_cli(cli_exe, "snaps", rotating_arm.result.path)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].split()[:3] == ["LP", "BR", "param"]
    assert len(lines) == 1 + len(rotating_arm.file.snaps)
    assert {ln.split()[0] for ln in lines[1:]} == {r["lp"] for r in rotating_arm.file.snaps}


def test_modules_without_the_hooks_have_no_targets():
    from elastica_auto.model.problem import load_problem
    from helpers import REPO
    bratu = load_problem(str(REPO / "examples" / "bratu.py"))
    assert not bratu.has_shooting
    assert snap_targets(bratu, []) == []


def test_a_branch_point_is_a_snap_point_only_if_subcritical(trivial_buckling):
    """u'' + p u (1 + u^2) = 0 (examples/nonlinear_eigenvalue.py) stiffens with the amplitude:
    its branches are born at p = (k pi)^2 towards smaller p, unstable, so u = 0 snaps at its
    first branch point. The elastica's straight rod buckles supercritically (the buckled
    branch is born towards larger P, stable: no snap, the rod follows it)."""
    import elastica_auto as ea
    from elastica_auto.analysis.snaps import snap_points, subcritical
    from helpers import EXAMPLES
    eigen = ea.load_problem(str(EXAMPLES / "nonlinear_eigenvalue.py"))
    (line,) = ea.continuation(eigen, {"p": 0.0}, "p", bounds=(-1, 12))
    (bp,) = [p for p in line.points if p.type == "BP"]
    assert bp.params["p"] == pytest.approx(math.pi ** 2, rel=1e-9)
    assert bp.subcritical is True and "subcritical" in bp.note
    assert subcritical(eigen, line, bp) is True
    assert snap_points(line) == [(bp, "before")]
    rod = ea.load_problem("elastica_lever_arm")
    for br in trivial_buckling.result.branches[:4]:        # the straight rods
        first = next(p for p in br.points if p.type == "BP")
        assert first.index == 0 < br.points[br.points.index(first) + 1].index
        assert first.subcritical is False and "supercritical" in first.note
        assert subcritical(rod, br, first) is False
        assert snap_points(br) == []


def test_a_course_without_events_labels_nothing_and_counts_every_index(tmp_path, monkeypatch):
    """What `subcritical` continues the born branches with: u = 0 of u'' + p u (1 + u^2) = 0
    from p = 0 to 50 through its branch points p = (k pi)^2 (k = 1, 2) with no event located:
    no LP or BP label, and every point's direct count is the number of (k pi)^2 below its p
    (the fold rule, which follows the located events, is not asked)."""
    import dataclasses

    import elastica_auto as ea
    from elastica_auto.execution.plan import Plan, Request, make_plan
    from helpers import EXAMPLES, run_plan
    eigen = ea.load_problem(str(EXAMPLES / "nonlinear_eigenvalue.py"))
    plan = make_plan(eigen, {"p": 0.0}, "p", Request(bounds=(-1, 50)))
    course = dataclasses.replace(plan.course, events=False)
    monkeypatch.setattr(Plan, "course", property(lambda self: course))
    (line,) = run_plan(plan, tmp_path).result.branches
    assert {p.type for p in line.points} <= {"", "EP"}
    loads = [(k * math.pi) ** 2 for k in (1, 2)]
    seen = set()
    for p in line.points:
        if min(abs(p.params["p"] - c) for c in loads) > 1e-6:
            assert p.index_direct == sum(c < p.params["p"] for c in loads)
            seen.add(p.index_direct)
    assert seen == {0, 1, 2} and line.points[-1].params["p"] == pytest.approx(50)
