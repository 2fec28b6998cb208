"""The spatial rod's runs, drawing and snap-back targets (docs/three-d.md) against oracles
that do not use the spatial rod's own derivation:

* the planar module (equations/elastica_lever_arm.py): with chi = beta = phi0 = 0 the 3D
  rotating arm's folds are the planar ones, its in-plane index is the planar index, and the
  3D shooting scan finds the planar scan's equilibria (k2 = 0, k1 = theta'(0));
* the collocation solutions of the continuation: the shooting hook's residual vanishes there;
* the conjugate-point count of the 3 x 3 Jacobi system (tests/form_reference.py, the Morse
  index theorem) for the index of the 3D snap-back targets;
* a system with known roots for the box scan (`elastica_auto.analysis.equilibria.scan_box`).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.model.problem import load_problem

K3 = "kirchhoff_lever_arm"
#: eps = 0.5, P = pi^2/4, b2 = 2: the straight rod is unstable out of the plane (b2 times the
#: critical load of eps = 0.5, 1.1597, lies below P), so along the rotating arm's branch the
#: out-of-plane index goes 1 -> 0 at a branch point past the fold (docs/three-d.md).
BASE = {"P": math.pi ** 2 / 4, "eps": 0.5}
UZ = (-1.0, 0.3, 0.6, 1.0, 1.2)


@pytest.fixture(scope="module")
def arms():
    planar, rod = load_problem("elastica_lever_arm"), load_problem(K3)
    kw = dict(bounds=(-1.4, 1.4), directions="both", uz=UZ, max_points=200)
    return (planar, rod, ea.continuation(planar, BASE, "psi", **kw),
            ea.continuation(rod, {**BASE, "b2": 2.0}, "psi", **kw))


def labelled(branches, kind):
    return [(br, p) for br in branches for p in br.points if p.type == kind]


def test_in_plane_index_and_folds_are_the_planar_module_s(arms):
    """Planar embedding: at the user points (the same psi on both branches) index_in is the
    planar index, and the folds agree to 1e-9."""
    _, _, planar, rod = arms
    uz2, uz3 = labelled(planar, "UZ"), labelled(rod, "UZ")
    assert len(uz2) == len(uz3) >= 8
    for (_, p2), (_, p3) in zip(uz2, uz3):
        assert p3.params["psi"] == pytest.approx(p2.params["psi"], abs=1e-12)
        assert p3.ordinates["m1"] == pytest.approx(p2.ordinates["m1"], abs=1e-7)
        assert p3.ordinates["index_in"] == p2.index >= 0
        assert p3.ordinates["index_in"] + p3.ordinates["index_out"] == p3.index
    # along the whole branch, every counted point: the planar index where the planar branch
    # passes the same state (interpolated in psi between two of its points of one index, the
    # same m1 to 1e-3)
    segments = []
    for br in planar:
        pts = br.points
        for a, b in zip(pts, pts[1:]):
            if a.index == b.index >= 0 and a.params["psi"] != b.params["psi"]:
                segments.append((a.params["psi"], b.params["psi"], a.ordinates["m1"],
                                 b.ordinates["m1"], a.index))
    compared = 0
    for br in rod:
        for p in br.points:
            if p.ordinates["index_in"] < 0:
                continue
            psi, m1 = p.params["psi"], p.ordinates["m1"]
            for x0, x1, y0, y1, k in segments:
                w = (psi - x0) / (x1 - x0)
                if 0 <= w <= 1 and abs(y0 + w * (y1 - y0) - m1) < 1e-3:
                    compared += 1
                    assert p.ordinates["index_in"] == k, (psi, m1)
                    break
    assert compared >= 40
    folds2 = sorted(p.params["psi"] for _, p in labelled(planar, "LP"))
    folds3 = sorted(p.params["psi"] for _, p in labelled(rod, "LP"))
    assert len(folds2) == len(folds3) == 2
    assert np.max(np.abs(np.subtract(folds2, folds3))) < 1e-9
    # the out-of-plane branch point after the fold (index_out 1 -> 0), where nothing moves
    # in the plane: located, with the in-plane index unchanged across it
    bps = [p for _, p in labelled(rod, "BP")]
    assert bps and all(abs(abs(p.params["psi"]) - 1.1695) < 1e-3 for p in bps)


def _frame_k(mod, y, p):
    e1, e2 = mod.load_frame(p)
    return np.array((e1 @ y[7:10, 0], e2 @ y[7:10, 0]))


def test_shooting_residual_vanishes_at_collocation_solutions(arms):
    """The shooting hook's y(0) is the collocation solution's (r = 0, the clamp, m(0)), and
    integrating from it meets the tip condition to the collocation's accuracy; at a
    non-planar state (the arm tilted by chi) as well, where k2 != 0."""
    import elastica_auto.equations.kirchhoff_lever_arm as mod
    from elastica_auto.analysis.equilibria import integrate
    _, rod, _, rods = arms
    states = [br.label(p.name).state for br, p in labelled(rods, "UZ")[:4]]
    br, pt = labelled(rods, "UZ")[1]
    # the arm tilted out of its plane: chi folds at 0.11 and comes back to -0.1, z(1) = 0.37
    (tilted,) = ea.continuation(rod, br.label(pt.name), "chi", bounds=(-0.1, 0.8),
                                directions="+", max_points=60)
    states.append(tilted.points[-1].state)
    assert abs(states[-1].y[2, -1]) > 0.05                       # out of the plane
    assert abs(_frame_k(mod, states[-1].y, states[-1].params)[1]) > 1e-3
    for st in states:
        p = st.params
        y = st.y
        lo, hi, initial, residual, _ = mod.shooting(p)
        k = _frame_k(mod, y, p)
        assert np.all(np.abs(k) <= hi[0])                        # inside the bound
        assert abs(mod.load(p) @ y[7:10, 0]) < 1e-8              # m(0).F = 0
        y0 = initial(k[:, None])
        assert np.max(np.abs(y0[:, 0] - y[:, 0])) < 1e-8
        assert np.max(np.abs(residual(y0, integrate(rod, p, y0)))) < 1e-6
        # and a wrong start does not satisfy it
        assert np.max(np.abs(residual(y0 + 0.05, integrate(rod, p, y0 + 0.05)))) > 1e-3


def jacobi_count(mod, state):
    from form_reference import Form, conjugate_count

    def field(name):
        return lambda s: getattr(mod.second_variation(s, state(s), state.params), name)
    end = mod.second_variation(state.s, state.y, state.params).E1
    return conjugate_count(Form(k=3, A=field("A"), B=field("B"), C=field("C"), E1=end,
                                G0=np.eye(3))).index


@pytest.mark.parametrize("b2", [1.0, 2.0])
def test_snap_targets_in_3d_are_equilibria_with_the_index_two_ways(arms, b2):
    """At the rotating arm's fold (eps = 0.5, P = pi^2/4): the 3D scan's equilibria satisfy
    the boundary conditions, include the planar scan's (k = (theta'(0), 0)), and each has the
    same index by the engine's count and the conjugate-point count of the Jacobi system."""
    import elastica_auto.equations.kirchhoff_lever_arm as mod
    from elastica_auto.analysis.equilibria import enumerate_equilibria
    planar, rod, planars, _ = arms
    lp = labelled(planars, "LP")[0][1]
    p3 = {**rod.defaults(), **lp.params, "b2": b2}
    eqs = enumerate_equilibria(rod, p3)
    flat = enumerate_equilibria(planar, lp.params)
    assert [e.index for e in flat].count(0) >= 1
    for e in flat:          # the planar equilibria, found again with k2 = 0
        hit = [f for f in eqs if abs(f.k[0] - e.k) < 1e-6 and abs(f.k[1]) < 1e-8]
        assert len(hit) == 1
        assert hit[0].ordinates["index_in"] in (e.index, -1)
    for e in eqs:
        y = e.state.y
        assert np.max(np.abs(rod.bc(y[:, 0], y[:, -1], p3))) < 1e-8
        assert e.index == jacobi_count(mod, e.state) >= 0
    assert len(eqs) >= len(flat)


def test_the_branch_born_out_of_the_plane_is_a_closed_loop_through_the_mirror_point(arms):
    """Switching at the rotating arm's out-of-plane branch point (b2 = 2, psi = 1.1695, a
    subcritical pitchfork): the non-planar branch born there leaves the plane towards smaller
    psi, passes psi = 0 out of the plane, comes into the plane at the mirror image's branch
    point (-psi) and returns to its start as the mirror image (z -> -z) of its first half: a
    closed loop, where the branch ends (EP), without a warning (at the mirror point the
    parameter turns and the fold system is singular: the branch point is labelled there to
    the step, as one reached along its bifurcating branch). Its states at psi = 0 are the non-planar
    equilibria the shooting scan finds there, with index 1 by the engine's count and by the
    conjugate points of the Jacobi system."""
    import elastica_auto.equations.kirchhoff_lever_arm as mod
    from elastica_auto.analysis.equilibria import enumerate_equilibria
    _, rod, _, rods = arms
    (br, bp), = [(br, p) for br, p in labelled(rods, "BP") if p.params["psi"] > 1.1]
    psi_bp = bp.params["psi"]
    loops = ea.continuation(rod, ea.Switch(br.label(bp.name)), "psi", bounds=(-1.4, 1.4),
                            uz=(0.0,), max_points=200, ds_max=1.0)   # as the run files
    for loop in loops:
        assert loop.end == "EP" and loop.message.startswith("closed loop"), loop.message
        assert not loop.warnings, loop.warnings   # the mirror point: a BP, not a failure
        first, last = loop.points[0], loop.points[-1]
        assert last.params == first.params and last.index == first.index
        psi = loop.columns["psi"]
        assert psi.max() == pytest.approx(psi_bp, abs=1e-12)
        assert psi.min() == pytest.approx(-psi_bp, abs=1e-4)       # the mirror branch point
        assert np.all(np.abs(loop.columns["z1"][1:-1]) > 0)         # off the plane between
        at_zero = [p for p in loop.points if p.type == "UZ"]
        assert len(at_zero) == 2                                    # once on each half
        z = [p.ordinates["z1"] for p in at_zero]
        assert z[0] == pytest.approx(-z[1], abs=1e-8) and abs(z[0]) > 0.3
        assert at_zero[0].ordinates["m1"] == pytest.approx(at_zero[1].ordinates["m1"], abs=1e-8)
    up, down = loops
    np.testing.assert_allclose(sorted(up.columns["z1"]), sorted(-down.columns["z1"]), atol=1e-8)
    params = next(p for p in up.points if p.type == "UZ").params
    eqs = [e for e in enumerate_equilibria(rod, params) if abs(e.k[1]) > 1e-6]
    assert len(eqs) == 2                                   # the non-planar pair
    for p in (p for p in up.points if p.type == "UZ"):
        state = up.label(p.name).state
        k = _frame_k(mod, state.y, state.params)
        (e,) = [e for e in eqs if np.max(np.abs(np.array(e.k) - k)) < 1e-6]
        assert p.index == e.index == jacobi_count(mod, state) == 1


def test_the_rod_snaps_at_its_subcritical_out_of_plane_branch_points(arms):
    """b2 = 2, eps = 0.5: the planar stable stretch ends at the branch points psi = +-1.1695,
    before its folds (index 1 in 3D there). The branches born there are unstable (the loop
    above), so the snap-back table has a row at each: the stable equilibria there are the
    planar module's stable ones at those parameters (found by its own scan, with k2 = 0),
    mirror images of each other between the two branch points."""
    from elastica_auto.analysis.equilibria import enumerate_equilibria
    planar, rod, _, rods = arms
    rows = rods.snaps
    assert {r["lp"][:2] for r in rows} == {"BP"}
    bps = {p.name: p for _, p in labelled(rods, "BP")}
    by_bp = {}
    for r in rows:
        bp = bps[r["lp"]]
        assert r["value"] == bp.params["psi"] and abs(abs(r["value"]) - 1.169504) < 1e-6
        assert r["index"] == 0 and abs(r["k_2"]) < 1e-8
        flat = [e for e in enumerate_equilibria(planar, {**BASE, "psi": r["value"],
                                                         "alpha": 0.0, "theta0": 0.0})
                if e.index == 0]
        assert min(abs(e.k - r["k"]) for e in flat) < 1e-6
        by_bp.setdefault(np.sign(r["value"]), []).append(r["k"])
    assert len(by_bp[1.0]) == len(by_bp[-1.0]) >= 1
    np.testing.assert_allclose(sorted(by_bp[1.0]), sorted(-np.array(by_bp[-1.0])), atol=1e-8)


def test_a_branch_point_s_degenerate_root_is_one_equilibrium(arms):
    """At the branch point psi = 1.1695 of b2 = 2 (a pitchfork: across its own state the tip
    residual grows like a cube) the box scan's planar roots (k2 = 0) are the planar
    module's equilibria there, found by its own 1D scan, each once. (Newton's candidates
    settle all along the flat direction: 13 roots within 1.6e-4 of the branch point's own
    before they were merged.)"""
    from elastica_auto.analysis.equilibria import enumerate_equilibria
    planar, rod, _, rods = arms
    (bp,) = [p for _, p in labelled(rods, "BP") if p.params["psi"] > 0]
    roots = enumerate_equilibria(rod, bp.params)
    flat = [e.k[0] for e in roots if abs(e.k[1]) < 1e-3]
    want = [e.k for e in enumerate_equilibria(planar, {**BASE, "psi": bp.params["psi"],
                                                        "alpha": 0.0, "theta0": 0.0})]
    assert len(want) >= 3 and len(flat) == len(want)
    np.testing.assert_allclose(sorted(flat), sorted(want), atol=1e-5)


def test_close_roots_are_merged_only_where_r_stays_small_between_them():
    """`merged_roots`: of a cubic root's settled candidates (r = (x, y^3), 1e-4 apart) one is
    kept, the one of least |r|; two simple roots 5e-4 of the box apart (r = (x, (y - a)(y -
    a - 0.002))) are both kept, as are roots further apart than MERGE_SPAN."""
    from elastica_auto.analysis.equilibria import merged_roots

    width, tol = np.array((4.0, 4.0)), 4e-9

    def cubic(k):
        return np.vstack((k[0], k[1] ** 3))
    k = np.array(((0.0, 0.0, 0.0, 1.0), (-1e-4, 2e-6, 1e-4, 0.0)))
    size = np.max(np.abs(cubic(k)), axis=0)
    np.testing.assert_array_equal(merged_roots(cubic, k, size, width, tol), k[:, [1, 3]])

    def pair(k):
        return np.vstack((k[0], (k[1] - 0.1) * (k[1] - 0.102)))
    k = np.array(((0.0, 0.0), (0.1, 0.102)))
    np.testing.assert_array_equal(merged_roots(pair, k, np.zeros(2), width, tol), k)


def test_a_candidate_circling_a_root_found_is_given_up():
    """r = (x, sign(y) |y|^(1/1.95)): Newton maps y to -0.95 y, so a candidate started at
    y = 2e-3 (5e-4 of the box) circles the root (0, 0) for ever, its |r| falling by 2.6% a
    step (no stall, no Aitken: the steps alternate). Once the candidate started on y = 0 has
    found the root, the other is given up after STRAGGLE_STEPS, not after all 40."""
    from elastica_auto.analysis.equilibria import STRAGGLE_STEPS, Box, box_newton

    calls = []

    def r(k):
        calls.append(k.shape[1])
        return np.vstack((k[0], np.sign(k[1]) * np.abs(k[1]) ** (1 / 1.95)))
    lo, hi = np.array((-2.0, -2.0)), np.array((2.0, 2.0))
    box = Box(lo, hi, hi - lo, (hi - lo) / 100)
    got = box_newton(r, np.array(((0.3, 0.01), (0.0, 2e-3))), box, 1e-9, 1e-12, 40)
    assert got.shape == (2, 1) and np.max(np.abs(got)) < 1e-12
    assert len(calls) == STRAGGLE_STEPS


def test_a_branch_point_s_own_root_is_no_target_whatever_the_cached_states(arms):
    """The scan cached for a periodic copy of a branch point may have other states for the
    same equilibria (turning the clamp by 2 pi flips the quaternion): the point's own root
    is still left out. Here the cached states are those of such a copy (q -> -q), and the
    own root's cluster of near roots is counted stable, as the rotating base's are in 3D
    (here its index is 1)."""
    from elastica_auto.analysis.equilibria import Equilibrium, enumerate_equilibria
    from elastica_auto.analysis.snaps import scan_key, snap_targets
    from elastica_auto.core.solution import State
    _, rod, _, rods = arms
    (br, bp), = [(br, p) for br, p in labelled(rods, "BP") if p.params["psi"] > 1.1]
    flip = np.ones((rod.n, 1))
    flip[3:7] = -1.0
    k_bp = bp.state.y[7:10, 0]                        # m(0): k is its part across the load
    copy = [Equilibrium(e.k, State(e.state.s, flip * e.state.y, flip * e.state.yp,
                                   e.state.params),
                        0 if abs(e.k[0] - k_bp[2]) < 1e-2 else e.index, e.ordinates)
            for e in enumerate_equilibria(rod, bp.params)]
    assert sum(abs(e.k[0] - k_bp[2]) < 1e-2 for e in copy) >= 1
    cache = {scan_key(rod, "psi", bp.params): (dict(bp.params), copy)}
    rows = [r["k"] for r in snap_targets(rod, [br], cache=cache) if r["lp"] == bp.name]
    assert rows == [r["k"] for r in rods.snaps if r["lp"] == bp.name] and len(rows) == 1


def test_a_second_level_of_switching_passes_over_the_loops_mirror_points(arms):
    """switch = 1 on both halves of the rotating arm (b2 = 2) finds branch points at psi =
    +-1.1695. The branch switched at +1.1695 is a closed loop through the other, where it is
    labelled only to the step: its other orientation and both at -1.1695 are that loop, not
    computed again. Both branches through that point are computed, so a second level adds
    nothing."""
    _, rod, _, _ = arms
    run = ea.continuation(rod, {**BASE, "b2": 2.0}, "psi", bounds=(-1.4, 1.4),
                          directions="both", max_points=200, ds_max=1.0, switch=1,
                          switch_depth=2)
    assert len(run) == 3 and not run.warnings
    assert sorted(round(p.params["psi"], 6) for br in run[:2] for p in br.points
                  if p.type == "BP") == [-1.169504, 1.169504]
    assert round(run[2].points[0].params["psi"], 6) == 1.169504
    for br in run[2:]:
        assert br.message.startswith("closed loop")
        (bp,) = [p for p in br.points if p.type == "BP"]
        (mirror,) = [p for b in run[:2] for p in b.points
                     if p.type == "BP" and p.params["psi"] * bp.params["psi"] > 0]
        # the step's point, not the branch point itself: only the step says they are one
        a, b = bp.state, mirror.state
        assert np.sqrt(np.trapezoid(np.sum((a.y - b(a.s)) ** 2, axis=0), a.s)) > 1e-3


def test_scan_box_finds_every_root_of_a_known_system():
    """r = (x^2 + y^2 - 4, sin(3 x) - y / 2) in [-3, 3]^2: the roots by an independent 1D
    bracketing along the circle x = 2 cos t, y = 2 sin t."""
    from scipy.optimize import brentq

    from elastica_auto.analysis.equilibria import scan_box

    def r(k):
        x, y = k
        return np.vstack((x * x + y * y - 4, np.sin(3 * x) - y / 2))

    got = scan_box(r, np.array((-3.0, -3.0)), np.array((3.0, 3.0)))

    def g(t):
        return math.sin(6 * math.cos(t)) - math.sin(t)
    ts = np.linspace(0, 2 * math.pi, 4001)
    gs = [g(t) for t in ts]
    want = [brentq(g, a, b) for a, b, fa, fb in zip(ts, ts[1:], gs, gs[1:]) if fa * fb < 0]
    want = np.array([(2 * math.cos(t), 2 * math.sin(t)) for t in want])
    assert got.shape == (2, len(want)) and len(want) >= 6
    for w in want:
        assert np.min(np.max(np.abs(got.T - w), axis=1)) < 1e-9


class _Counted:
    """r, counting the Newton steps of `scan_box` (calls after the grid's)."""

    def __init__(self, r):
        self.r, self.calls = r, 0

    def __call__(self, k):
        self.calls += 1
        return self.r(k)


@pytest.mark.parametrize("a", [0.3, -1.7])
def test_scan_box_finds_a_double_root_in_few_newton_steps(a):
    """r = ((x - a)^2, y - x / 2) has the one root (a, a / 2), where the Jacobian is
    singular (a fold's own equilibrium in a scan at the fold): Newton steps halve the error.
    Extrapolating their geometric sequence finds it to 1e-6; halving alone stops where |r|
    is below 1e-9 of its scale, 1e-4 from it (and took all 40 steps before a root that
    small was accepted)."""
    from elastica_auto.analysis.equilibria import scan_box

    r = _Counted(lambda k: np.vstack(((k[0] - a) ** 2, k[1] - k[0] / 2)))
    got = scan_box(r, np.array((-3.0, -3.0)), np.array((3.0, 3.0)))
    assert got.shape == (2, 1)
    assert np.max(np.abs(got[:, 0] - (a, a / 2))) < 1e-6
    assert r.calls - 1 <= 20         # the grid's call, Newton's, the final check


def test_scan_box_keeps_a_degenerate_root_and_polishes_coarse_roots():
    """A root where r grows like a cube in one direction (a branch point's own equilibrium)
    is kept, where |r| is small, without its 40 steps; and with ``coarse`` r plus a smooth
    error of 1e-8 of r's scale (the loose integration's), the roots are r's to 1e-12."""
    from elastica_auto.analysis.equilibria import scan_box

    cubic = _Counted(lambda k: np.vstack((k[0] - 0.5, (k[1] + 0.25) ** 3)))
    got = scan_box(cubic, np.array((-2.0, -2.0)), np.array((2.0, 2.0)))
    assert got.shape == (2, 1)                  # one root, not the candidates' settled span
    assert np.max(np.abs(got[0] - 0.5)) < 1e-12 and np.max(np.abs(got[1] + 0.25)) < 2e-3
    assert cubic.calls - 1 < 40

    def r(k):
        x, y = k
        return np.vstack((x * x + y * y - 4, np.sin(3 * x) - y / 2))

    def coarse(k):
        return r(k) + 1e-8 * 5 * np.vstack((np.sin(7 * k[0] + k[1]), np.cos(5 * k[1])))

    exact = scan_box(r, np.array((-3.0, -3.0)), np.array((3.0, 3.0)))
    got = scan_box(r, np.array((-3.0, -3.0)), np.array((3.0, 3.0)), coarse=coarse)
    assert got.shape == exact.shape and np.max(np.abs(got - exact)) < 1e-12


def _mirrored(k):
    return k * np.array((1.0, -1.0))[:, None]


@pytest.mark.parametrize("points", [10201, 10000])
def test_scan_box_with_a_reflection_finds_the_full_scan_s_roots_from_half_the_grid(points):
    """r = (x^2 + y^2 - 4, sin(3 y) - x y / 2) has r(x, -y) = (r1, -r2)(x, y): its roots
    come in pairs (x, +-y), two on the mirror plane y = 0 (x = +-2). With the
    reflection (1, -1) the scan finds the roots of the scan of the whole box (checked against
    an independent bracketing in the test above) from a grid of about half its points, on
    grids with the plane on a grid line (101 points an axis) and between two (100)."""
    from elastica_auto.analysis.equilibria import scan_box

    def r(k):
        x, y = k
        return np.vstack((x * x + y * y - 4, np.sin(3 * y) - x * y / 2))

    lo, hi = np.array((-3.0, -3.0)), np.array((3.0, 3.0))
    grids = []

    def counted(k):
        if not grids:
            grids.append(k.shape[1])
        return r(k)

    full = scan_box(r, lo, hi, points=points)
    half = scan_box(counted, lo, hi, points=points, reflection=(1, -1))
    assert full.shape[1] >= 6 and half.shape == full.shape
    for x in np.hstack((full, _mirrored(half))).T:     # the same roots (a pair's order
        assert np.min(np.max(np.abs(half.T - x), axis=1)) < 1e-9     # is rounding's)
    on_plane = full[:, np.abs(full[1]) < 1e-12]
    assert np.allclose(np.sort(on_plane[0]), (-2.0, 2.0), atol=1e-12)
    assert grids[0] <= 0.53 * points


def test_the_rod_s_shooting_reflection_holds_where_it_is_given():
    """At parameters that keep the plane z = 0 (load and arm in or across it, the clamp's
    twist a multiple of pi, in-plane intrinsic curvature only) the tip residual of the
    integrated rod satisfies r(k1, -k2) = (r1, -r2)(k1, k2), and the hook gives the
    reflection (1, -1); where one of beta, chi, phi0, u2, u3 breaks it (b2 = 2), the
    residuals do not, and the hook gives none."""
    import elastica_auto.equations.kirchhoff_lever_arm as mod
    from elastica_auto.analysis.equilibria import integrate

    rod = load_problem(K3)
    base = {**rod.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4, "b2": 2.0, "psi": 1.3,
            "alpha": 0.4, "theta0": 0.2}
    k = np.array(((1.3, 2.0, -3.1), (0.7, -1.1, 2.5)))

    def gap(p):
        _, _, initial, residual = rod.shooting(p)

        def r(k):
            y0 = initial(k)
            return residual(y0, integrate(rod, p, y0))
        return float(np.max(np.abs(r(_mirrored(k)) - _mirrored(r(k)))))

    keeping = [base, {**base, "u1": 0.7, "beta": math.pi, "chi": math.pi, "phi0": math.pi}]
    for p in keeping:
        assert mod.keeps_plane(p)
        assert list(rod.shooting_reflection(p)) == [1.0, -1.0]
        assert gap(p) < 1e-8
    for name, value in (("beta", 0.2), ("chi", 0.3), ("phi0", 0.4), ("u2", 0.5),
                        ("u3", 0.5)):
        p = {**base, name: value}
        assert rod.shooting_reflection(p) is None
        assert gap(p) > 1e-3, name


@pytest.mark.parametrize("bad", ["(1, 1)", "(1, -1, 1)", "(2, -1)", "(-1, 1)"])
def test_a_bad_shooting_reflection_is_a_problem_error(tmp_path, bad):
    """The hook's fifth item must be one sign (1 or -1) per unknown, one -1 at least, and
    flip only components whose box is symmetric: the rod's box with its first component's
    lower bound moved is not symmetric in it."""
    from importlib.resources import files

    from elastica_auto.core.errors import ProblemError

    source = (files("elastica_auto.equations") / "kirchhoff_lever_arm.py").read_text()
    old = "(1, -1) if keeps_plane(p) else None)"
    assert source.count(old) == 1
    source = source.replace(old, bad + ")")
    if bad == "(-1, 1)":
        old = "return ((-bound, -bound),"
        assert source.count(old) == 1
        source = source.replace(old, "return ((-2 * bound, -bound),")
    (tmp_path / "mine.py").write_text(source)
    rod = load_problem(tmp_path / "mine.py")
    with pytest.raises(ProblemError, match="reflection"):
        rod.shooting_reflection(rod.defaults())


def test_draw_hook_draws_the_rod_in_space(arms, tmp_path):
    """The module declares 3D axes; its drawing holds the centreline r(s) in space (its 3D
    data is the profile's), the arm from the tip and the load arrow; the engine's layout
    gives every axis one scale (a cube); on 2D axes it draws the x-y projection."""
    from matplotlib.figure import Figure

    from elastica_auto.plots.layout import Configuration, configuration_axes, \
        draw_configurations
    from elastica_auto.plots.viewer import configuration_images
    import elastica_auto.equations.kirchhoff_lever_arm as mod
    _, rod, _, rods = arms
    assert rod.draw_projection == "3d"
    br, pt = labelled(rods, "UZ")[2]
    st = br.label(pt.name).state
    grid = np.linspace(0, 1, 51)
    y = st(grid)
    y[2] = 0.2 * grid ** 2                      # a spatial centreline to draw
    c = Configuration(K3, y, st.params)
    fig = Figure()
    ax = configuration_axes(fig, fig.add_gridspec(1, 2)[0, 0], c)
    assert ax.name == "3d"
    draw_configurations([ax], [c])
    lines = {ln.get_gid(): ln for ln in ax.lines}
    xs, ys, zs = lines["rod"].get_data_3d()
    assert np.allclose(xs, y[0]) and np.allclose(ys, y[1]) and np.allclose(zs, y[2])
    ax0, ay0, az0 = lines["lever arm"].get_data_3d()
    assert np.allclose((ax0[0], ay0[0], az0[0]), y[0:3, -1])
    end = y[0:3, -1] + mod.tip_arm(y[:, -1], st.params)
    assert np.allclose((ax0[1], ay0[1], az0[1]), end)
    assert "load" in {col.get_gid() for col in ax.collections}
    assert "shadow" in lines                     # the rod leaves the plane z = 0
    spans = [np.ptp(lim) for lim in (ax.get_xlim(), ax.get_ylim(), ax.get_zlim())]
    assert np.allclose(spans, spans[0])
    flat = fig.add_subplot(1, 2, 2)
    rod.draw(flat, y, st.params)
    assert np.allclose(flat.lines[[ln.get_gid() for ln in flat.lines].index("rod")]
                       .get_xydata().T, y[0:2])
    from elastica_auto.storage.store import BranchFile
    ea.save(list(rods)[:1], tmp_path / "arm.h5", problem=rod)
    bf = BranchFile(tmp_path / "arm.h5")
    images = configuration_images(bf, rod, workers=1)
    assert images and all(v.startswith("data:image/png;base64,") for v in images.values())
    # the 3D axes are shared by the drawings: each image is the one drawn alone
    for name in list(bf.labels)[:4]:
        alone = BranchFile(tmp_path / "arm.h5")
        alone.labels = {name: bf.labels[name]}
        assert configuration_images(alone, rod, workers=1)[name] == images[name]



def test_the_snap_back_table_of_a_3d_run_has_both_unknowns():
    """`snap_targets` on the spatial rod's rotating arm (eps = 0.25, P = pi^2/4, b2 = 2: the
    folds end stable stretches in 3D too): every fold's target is the mirror-side buckled rod
    (k1 = -+2.2160 = the planar target's theta'(0), k2 = 0), stable, with both columns."""
    from elastica_auto.analysis.snaps import snap_targets
    rod = load_problem(K3)
    branches = ea.continuation(rod, {"P": math.pi ** 2 / 4, "eps": 0.25, "b2": 2.0}, "psi",
                               bounds=(-1.0, 1.0), directions="both", max_points=100)
    rows = snap_targets(rod, list(branches))
    assert len(rows) == 2
    for r in rows:
        assert r["index"] == 0 and abs(r["k_2"]) < 1e-6
        assert abs(r["k"]) == pytest.approx(2.2160, abs=1e-4)
        assert r["k"] * r["target_m0"] > 0 and abs(r["target_z1"]) < 1e-8


def test_the_copies_of_a_branch_point_are_decided_as_if_alone():
    """b2 = 2, eps = 0.5, psi up from 0, through its folds, down to -6 pi: the branch
    repeats with period 2 pi, so the subcritical branch points at psi = 1.1695 and its
    mirror -1.1695 recur at their translates, as copies with the same solution, each
    decided by the first one's born branches (`snaps.mark_subcritical`). Each decision is
    the one `subcritical` gives at that point alone."""
    from elastica_auto.analysis.snaps import subcritical
    rod = load_problem(K3)
    (br,) = ea.continuation(rod, {**BASE, "b2": 2.0}, "psi", bounds=(-6 * math.pi, 6 * math.pi),
                            directions="+", max_points=400)
    decided = [p for p in br.points if p.type == "BP" and p.subcritical is not None]
    copies = [p for p in decided if any(q is not p and np.array_equal(q.state.y, p.state.y)
                                        for q in decided)]
    assert len(decided) >= 4 and len(copies) >= 2
    for p in decided:
        assert subcritical(rod, br, p) is p.subcritical, p.name


def test_solve_bvp_s_corrector_finds_the_same_branch_points():
    """scipy's solve_bvp as the corrector (a second discretisation, which refines the mesh it
    is given): along the rotating arm at eps = 0.5, P = 9 pi^2/4, b2 = 2 to psi = -6.6 the
    same folds and out-of-plane branch points as the collocation corrector, within 1e-9.
    The branch point at psi = -6.439 is solved again on a mesh made from the error estimate
    of solve_bvp's own (refined) mesh; it ended the branch (MX, a shape mismatch) when that
    mesh was taken for the one it was given."""
    rod = load_problem(K3)
    start = {"eps": 0.5, "P": 9 * math.pi ** 2 / 4, "b2": 2.0}
    located = {}
    for corrector in ("solve_bvp", "collocation"):
        (br,) = ea.continuation(rod, start, "psi", bounds=(-6.6, 6.6), corrector=corrector,
                                max_points=60)
        assert br.end == "EP", br.message
        located[corrector] = [(p.type, p.params["psi"]) for p in br.points
                              if p.type in ("LP", "BP")]
    assert [t for t, _ in located["solve_bvp"]] == [t for t, _ in located["collocation"]] \
        == ["BP", "LP", "BP", "BP"]
    np.testing.assert_allclose([v for _, v in located["solve_bvp"]],
                               [v for _, v in located["collocation"]], rtol=0, atol=1e-9)
