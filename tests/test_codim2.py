"""Two-parameter continuation (`elastica_auto.branches.codim2`): fold curves and
branch-point curves.

Checked against methods that are not the engine's: every fold-curve point is a fold of the
shooting formulation (r = 0 and dr/dk0 = 0, tests/shooting.py); a fold curve through the folds
of one arm length passes through those of another, located by one-parameter runs; the
branch-point curves of the straight rod are the closed form cot(sqrt P) = eps sqrt(P); a cusp
has two folds of the one-parameter family on one side of it and none on the other, and the
cusps come in mirror pairs (psi, m1) -> (-psi, -m1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import elastica_auto as ea
import shooting
from elastica_auto.execution import runfile
from helpers import run_plan

P1, P2 = math.pi ** 2 / 4, 9 * math.pi ** 2 / 4
# Fold-curve points are solved to tol; at tol = fold_tol (1e-7) they are as accurate as the
# one-parameter folds (within ~1e-10 of shooting, tests/test_folds.py); 1e-9 in psi.
PSI_ATOL = 1e-9


@pytest.fixture(scope="module")
def arm_quarter(elastica):
    """psi-branches at eps = 0.25 and 0.5, P = pi^2/4, over one period each way."""
    return ea.continuation(elastica, {"P": P1, "psi": 0.0}, "psi", params={"eps": [0.25, 0.5]},
                           bounds=(-2 * math.pi, 2 * math.pi), directions="both")


@pytest.fixture(scope="module")
def fold_curve(elastica, arm_quarter):
    """The fold curve through LP1 (eps = 0.25) in (psi, eps), up to eps = 1, with UZ at 0.5."""
    return ea.continuation(elastica, arm_quarter.label("LP1"), ["psi", "eps"], bounds=(0.1, 1),
                           uz=[0.5], tol=1e-7)


def test_every_fold_curve_point_is_a_fold_by_shooting(fold_curve):
    (br,) = fold_curve
    c = br.columns
    assert br.end == "EP" and c["eps"][-1] == pytest.approx(1.0, abs=1e-12)
    assert len(br.points) >= 8
    for eps, psi, m0, P in zip(c["eps"], c["psi"], c["m0"], c["P"]):
        k0, psi_s, _ = shooting.fold(P, eps, m0, psi)
        assert abs(psi_s - psi) <= PSI_ATOL and abs(k0 - m0) <= 1e-8


def test_the_fold_curve_passes_through_the_folds_of_another_arm_length(arm_quarter, fold_curve):
    """UZ at eps = 0.5 on the curve from eps = 0.25 is a fold of the eps = 0.5 psi-branch."""
    c = fold_curve[0].columns
    (i,) = np.nonzero(c["type"] == "UZ")[0]
    folds = [p for b in arm_quarter for p in b.folds if p.params["eps"] == 0.5]
    near = min(folds, key=lambda p: abs(p.params["psi"] - c["psi"][i]))
    assert abs(near.params["psi"] - c["psi"][i]) <= PSI_ATOL
    assert abs(near.ordinates["m1"] - c["m1"][i]) <= 1e-8
    start = fold_curve[0].points[0]
    assert start.params["psi"] == pytest.approx(arm_quarter.label("LP1").state.params["psi"],
                                                abs=PSI_ATOL)


@pytest.fixture(scope="module")
def critical_curves(elastica):
    """The first two branch points of the straight rod (eps = 0.5) continued in (P, eps)."""
    straight = ea.continuation(elastica, {"P": 0.5, "eps": 0.5}, "P", bounds=(0.1, 20))
    return ea.continuation(elastica, [straight.label("BP1"), straight.label("BP2")],
                           ["P", "eps"], bounds=(-1, 1), directions="both", tol=1e-7)


def test_branch_point_curves_are_the_critical_loads(critical_curves):
    assert len(critical_curves) == 4
    for br in critical_curves:
        assert br.end == "EP" and abs(abs(br.points[-1].params["eps"]) - 1) < 1e-12
        for eps, P in zip(br.columns["eps"], br.columns["P"]):
            w0 = math.sqrt(P)
            w = brentq(lambda w: math.cos(w) - eps * w * math.sin(w), w0 - 0.1, w0 + 0.1,
                       xtol=1e-15)
            assert abs(w * w - P) <= 1e-9
    ends = sorted(round(br.points[-1].params["P"], 6) for br in critical_curves)
    # at eps = -1: cot w = -w (w = 2.7984, 6.1212); at eps = 1: cot w = w (0.8603, 3.4256)
    expected = sorted(round(brentq(lambda w: math.cos(w) - e * w * math.sin(w), a, b,
                                   xtol=1e-15) ** 2, 6)
                      for e, a, b in ((1, 0.1, 3.1), (1, 3.2, 6.2), (-1, 1.6, 3.1),
                                      (-1, 4.8, 6.2)))
    assert ends == expected


@pytest.fixture(scope="module")
def cusp_curves(rotating_arm, elastica):
    """The fold curves through the two folds of rotating_arm at eps = 0.5, P = 9 pi^2/4 with
    psi = 4.7695 and 1.5137 (mirror images, far along the branch), down to eps = 0.15."""
    bf = ea.BranchFile(rotating_arm.result.path)
    starts = []
    for name in bf.labels:
        if not name.startswith("LP"):
            continue
        label = bf.label(name)
        p = label.state.params
        if p["eps"] == 0.5 and abs(p["P"] - P2) < 1e-9 and \
                min(abs(p["psi"] - 4.7695), abs(p["psi"] - 1.5137)) < 1e-3:
            starts.append(label)
    assert len(starts) == 2
    return ea.continuation(elastica, starts, ["psi", "eps"], bounds=(0.15, 0.5),
                           directions="-")


def _cusps(branches):
    return [p for b in branches for p in b.points if p.type == "CP"]


def test_cusps_come_in_mirror_pairs(cusp_curves):
    cps = _cusps(cusp_curves)
    eps = sorted({round(p.params["eps"], 6) for p in cps})
    assert eps == [0.211385, 0.361114]
    for p in cps:
        twin = [q for q in cps if abs(q.params["eps"] - p.params["eps"]) < 1e-9
                and abs(math.remainder(q.params["psi"] + p.params["psi"], 2 * math.pi)) < 1e-7]
        assert twin and abs(twin[0].ordinates["m1"] + p.ordinates["m1"]) < 1e-6


def test_a_cusp_has_two_folds_on_one_side_and_none_on_the_other(cusp_curves, elastica):
    """psi-branches at eps_c -+ 0.01 near a cusp (reached from it by continuing in eps at
    fixed psi, which passes through the cusp): folds within 0.2 of its psi on one side only,
    two of them."""
    for cp in _cusps(cusp_curves)[:2]:
        label = next(b.label(cp.name) for b in cusp_curves if cp in b.points)
        c = label.state.params
        counts = []
        for side in (-1, 1):
            e = c["eps"] + 0.01 * side
            via = ea.continuation(elastica, label, "eps", uz=[e], directions="both",
                                  bounds=(c["eps"] - 0.05, c["eps"] + 0.05))
            uz = [p for b in via for p in b.points if p.type == "UZ"]
            assert uz, f"eps = {e} not reached from {cp.name}"
            psi = ea.continuation(elastica, via.label(uz[0].name), "psi", directions="both",
                                  bounds=(c["psi"] - 0.2, c["psi"] + 0.2))
            counts.append(len({round(p.params["psi"], 6) for b in psi for p in b.folds}))
        assert sorted(counts) == [0, 2], (cp.name, counts)


def _mirror(cp, cps):
    """The cusp that is ``cp``'s mirror image (psi -> -psi, modulo 2 pi)."""
    return next(q for q in cps if abs(q.params["eps"] - cp.params["eps"]) < 1e-9
                and abs(math.remainder(q.params["psi"] + cp.params["psi"], 2 * math.pi)) < 1e-7)


@pytest.fixture(scope="module")
def perturbed_cusps(cusp_curves, elastica):
    """{(cusp, dpsi): the eps-branches from the cusp's label restarted at psi + dpsi, both
    ways, with UZ at eps_c -+ 0.01}: starts a hair to either side of each cusp, down to
    1e-10, below the accuracy a cusp is located to, where rounding decides what the
    linearisation at the start says."""
    out = {}
    for cp in _cusps(cusp_curves):
        label = next(b.label(cp.name) for b in cusp_curves if cp in b.points)
        c = label.state.params
        for dpsi in (1e-10, -1e-10, 1e-8, -1e-8):
            out[cp.name, dpsi] = ea.continuation(
                elastica, label, "eps", params={"psi": c["psi"] + dpsi}, directions="both",
                uz=[c["eps"] - 0.01, c["eps"] + 0.01], bounds=(c["eps"] - 0.02, c["eps"] + 0.02))
    return out


def test_starts_beside_a_cusp_pass_it_whatever_the_rounding(cusp_curves, perturbed_cusps):
    """From either side of each cusp: + reaches eps_c + 0.01 and - eps_c - 0.01, with no
    branch point (there is none: the family is a smooth curve through the cusp's
    neighbourhood), and folds come in pairs at eps_c, both located or neither (a start
    between them finds one each way). Mirror cusps at -dpsi give the same folds."""
    cps = _cusps(cusp_curves)
    assert len(cps) == 4
    folds = {}
    for (name, dpsi), via in perturbed_cusps.items():
        cp = next(p for p in cps if p.name == name)
        e = cp.params["eps"]
        assert [b.direction for b in via] == [1, -1]
        for b, target in zip(via, (e + 0.01, e - 0.01)):
            assert b.end == "EP", (name, dpsi, b.message)
            assert not [p for p in b.points if p.type == "BP"], (name, dpsi)
            uz = [p.params["eps"] for p in b.points if p.type == "UZ"]
            assert uz == [pytest.approx(target, abs=1e-12)], (name, dpsi, b.direction, uz)
        lp = [p for b in via for p in b.folds]
        assert len(lp) in (0, 2), (name, dpsi, [p.params["eps"] for p in lp])
        for p in lp:  # a fold by shooting, at the start's psi
            k0, psi, _ = shooting.fold(p.params["P"], p.params["eps"], p.ordinates["m0"],
                                       p.params["psi"])
            assert abs(p.params["eps"] - e) < 1e-6 and abs(psi - p.params["psi"]) <= PSI_ATOL
            assert abs(k0 - p.ordinates["m0"]) <= 1e-6
        if lp:
            assert abs(lp[0].ordinates["m1"] - lp[1].ordinates["m1"]) > 1e-4  # two, not one
        folds[name, dpsi] = len(lp)
    for (name, dpsi), n in folds.items():
        twin = _mirror(next(p for p in cps if p.name == name), cps)
        assert folds[twin.name, -dpsi] == n, (name, twin.name, dpsi)
    # 1e-8 to the side of the cusps at eps_c = 0.3611 with a pair: both folds are found
    assert sum(n for (_, dpsi), n in folds.items() if abs(dpsi) == 1e-8) == 4


def test_beside_a_cusp_two_folds_on_one_side_and_none_on_the_other(cusp_curves, elastica,
                                                                 perturbed_cusps):
    """The psi-branches from the UZ points of the perturbed starts at eps_c -+ 0.01 have, within
    0.2 of the cusp's psi, two folds on one side of the cusp and none on the other, whichever
    side of it (by 1e-10 or 1e-8) the start was."""
    for (name, dpsi), via in perturbed_cusps.items():
        if abs(dpsi) != 1e-10 and name not in ("CP1", "CP2"):
            continue  # the mirror images are checked at 1e-10; 1e-8 for two cusps
        c = next(p for p in _cusps(cusp_curves) if p.name == name).params
        counts = []
        for b in via:
            (uz,) = [p for p in b.points if p.type == "UZ"]
            psi = ea.continuation(elastica, via.label(uz.name), "psi", directions="both",
                                  bounds=(c["psi"] - 0.2, c["psi"] + 0.2))
            counts.append(len({round(p.params["psi"], 6) for b in psi for p in b.folds}))
        assert sorted(counts) == [0, 2], (name, dpsi, counts)


def test_a_fold_curve_from_a_run_file(tmp_path, rotating_arm):
    """parameter = ["psi", "eps"] with an LP selector: both directions from the two distinct
    folds at eps = 0.25, P = pi^2/4 (periodic copies count once)."""
    path = tmp_path / "fold_curves.toml"
    where = '{ eps = 0.25, P = "pi^2/4" }'
    path.write_text(f"""
equation = "elastica_lever_arm"
start = [{{ file = "{rotating_arm.result.path}", type = "LP", where = {where} }}]
[continuation]
parameter = ["psi", "eps"]
bounds = [0.2, 0.3]
""")
    plan = runfile.load(path)
    assert plan.curve == "fold" and plan.parameter == "eps" and plan.problem.free == ("psi",)
    out = run_plan(plan, tmp_path / "out").result
    assert len(out.branches) == 4
    psi = sorted(round(math.remainder(b.points[0].params["psi"], 2 * math.pi), 6)
                 for b in out.branches)
    assert psi[0] == psi[1] == -psi[2] == -psi[3] != 0
    stored = ea.BranchFile(out.path)
    assert set(stored.branches[0].columns) >= {"P", "eps", "psi", "m1", "type"}
    assert stored.maps == []                       # no map = true


@pytest.mark.parametrize("start, parameter, key, words", [
    ("dict", ["psi", "eps"], "start", "starts from LP or BP labels"),
    ("LP", ["psi", "psi"], "parameter", "two different names"),
    ("LP", ["eps", "P"], "start", "is a fold in 'psi', not in 'eps'"),
    ("LP", ["psi", "nope"], "parameter", "unknown parameter 'nope'"),
    ("mix", ["psi", "eps"], "start", "EP1: not an LP or BP label"),
    # one label that is neither (a curve's own UZ or EP, say) said "not a mix"
    ("EP", ["psi", "eps"], "start", r"EP2: not an LP or BP label; a two-parameter "
     r"continuation starts from LP labels \(fold curves\) or BP labels \(branch-point or "
     r"pitchfork curves\), and any label restarts a one-parameter run"),
    ("map", "psi", "map", "stability maps are drawn from fold curves"),
])
def test_two_parameter_arguments_are_checked(elastica, arm_quarter, start, parameter, key,
                                             words):
    given = {"dict": {"P": 1.0}, "LP": arm_quarter.label("LP1"), "map": {"P": 1.0},
             "mix": [arm_quarter.label("LP1"), arm_quarter.label("EP1")],
             "EP": arm_quarter.label("EP2")}[start]
    with pytest.raises(ea.PlanError, match=words) as exc_info:
        ea.continuation(elastica, given, parameter, map=start == "map")
    assert exc_info.value.key == key


# ------------------------------------------------------------------------ stability maps
@pytest.fixture(scope="module")
def wedge(elastica, arm_quarter):
    """Both fold curves of the straight rod's branch at P = pi^2/4 (LP1, then on through
    eps -> 0 to its mirror image), with the map of their plane."""
    return ea.continuation(elastica, arm_quarter.label("LP1"), ["psi", "eps"], bounds=(0, 1),
                           directions="both", map=True)


def _cell_point(m, j, i):
    x0, x1, y0, y1 = m.extent
    ny, nx = m.cells.shape
    return x0 + (i + 0.5) * (x1 - x0) / nx, y0 + (j + 0.5) * (y1 - y0) / ny


def _inner_cells(m, rng, per_region, margin=3):
    """Random cells of each region at least ``margin`` cells from any curve."""
    from scipy import ndimage
    inside = ndimage.binary_erosion(m.cells >= 0, iterations=margin)
    out = []
    for k in range(len(m.stable)):
        js, is_ = np.nonzero(inside & (m.cells == k))
        if len(js):
            pick = rng.choice(len(js), size=min(per_region, len(js)), replace=False)
            out += [(k, js[p], is_[p]) for p in pick]
    return out


def test_each_region_of_a_map_holds_one_count(wedge, elastica):
    """Enumerations at random points of each region (not the one the run used) find the
    region's number of stable equilibria: the fold curves bound the regions completely."""
    from elastica_auto.analysis.equilibria import enumerate_equilibria
    (m,) = wedge.maps
    assert sorted(m.stable.tolist()) == [1, 2] and m.fixed["P"] == pytest.approx(P1)
    for k, j, i in _inner_cells(m, np.random.default_rng(1), per_region=6):
        x, y = _cell_point(m, j, i)
        eqs = enumerate_equilibria(elastica, {**m.fixed, m.x: x, m.y: y})
        assert sum(e.index == 0 for e in eqs) == m.stable[k], (x, y)


def test_a_map_is_mirror_symmetric_and_saved_as_computed(wedge, tmp_path):
    """psi -> -psi maps the plane onto itself: the map's counts are symmetric away from
    the curves; the file holds the map as computed."""
    (m,) = wedge.maps
    counts = m.stable_cells()
    both = (counts >= 0) & (counts[:, ::-1] >= 0)
    assert np.mean(both) > 0.9 and np.array_equal(counts[both], counts[:, ::-1][both])
    (stored,) = ea.BranchFile(ea.save(wedge, tmp_path / "wedge.h5")).maps
    assert (stored.x, stored.y, stored.fixed) == (m.x, m.y, m.fixed)
    assert stored.extent == pytest.approx(m.extent)
    for name in ("cells", "region_x", "region_y", "stable", "equilibria"):
        np.testing.assert_array_equal(getattr(stored, name), getattr(m, name))


# ------------------------------------------------------------------ snap-backs along a path
def test_turning_the_arm_snaps_at_the_fold_of_the_rotating_arm(elastica, arm_quarter):
    """eps = 0.25, P = pi^2/4, psi from 0 to 2 pi: one snap, at the fold LP1 of the
    one-parameter run, to one stable equilibrium, which a followed branch passes through."""
    snaps, _ = ea.snaps_along(elastica, {"P": P1, "eps": 0.25, "psi": 0.0}, {"psi": 2 * math.pi})
    (snap,) = snaps
    lp1 = arm_quarter.label("LP1").state.params["psi"]
    assert abs(snap.params["psi"] - lp1) <= 1e-8 and snap.t == pytest.approx(lp1 / (2 * math.pi))
    (target,) = snap.targets
    assert target["index"] == 0 and target["on_branch"] > 0
    assert target["target_m1"] * snap.ordinates["m1"] < 0        # to the other side


def test_snaps_on_an_oblique_path_are_folds_by_shooting(elastica):
    """P = 9 pi^2/4, (psi, eps) from (0, 0.2) to (2 pi, 0.5): every snap point is a fold of
    the shooting formulation at its (eps, psi), and lies on the segment."""
    snaps, _ = ea.snaps_along(elastica, {"P": P2, "eps": 0.2, "psi": 0.0},
                           {"psi": 2 * math.pi, "eps": 0.5})
    assert len(snaps) >= 2
    for s in snaps:
        p = s.params
        assert p["psi"] == pytest.approx(2 * math.pi * s.t, abs=1e-12)
        assert p["eps"] == pytest.approx(0.2 + 0.3 * s.t, abs=1e-12)
        _, psi, _ = shooting.fold(P2, p["eps"], s.ordinates["m0"], p["psi"])
        assert abs(psi - p["psi"]) <= 1e-7
        assert s.targets and all(r["index"] == 0 for r in s.targets)


def test_the_path_command(cli_exe):
    from helpers import run_cli
    proc = run_cli(cli_exe, "path", "elastica_lever_arm", "--at", "P=pi^2/4", "--at",
                   "eps=0.25", "--to", "psi=2*pi")
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("path of elastica_lever_arm: psi 0 -> 6.28319 (P=2.4674")
    # the first two ordinates: the derived elastica's gamma (dE/dP) and beta (dE/deps)
    assert lines[1].startswith("snap 1 at t=0.130075 (psi=0.81728493) from gamma=0.89745")
    assert "1 stable equilibrium" in lines[1] and len(lines) == 3
    assert proc.returncode == 0
    bad = run_cli(cli_exe, "path", "elastica_lever_arm", "--to", "psi")
    assert bad.returncode == 2 and bad.stderr.strip().endswith("expected NAME=VALUE")


def test_a_fold_curve_meets_the_critical_load_curve_on_the_straight_rod(wedge, elastica):
    """The wedge's two fold curves join at eps -> 0, psi = 0 on the straight rod: labelled
    BP there, at a load on the critical-load curve cot(sqrt P) = eps sqrt(P)."""
    bps = [p for b in wedge for p in b.points if p.type == "BP"]
    assert len(bps) == 1
    p = bps[0].params
    w = math.sqrt(p["P"])
    assert abs(math.cos(w) - p["eps"] * w * math.sin(w)) < 1e-5 and abs(p["psi"]) < 1e-9
    assert abs(bps[0].ordinates["m0"]) < 1e-9 and "exact family" in bps[0].note
    assert not [q for b in wedge for q in b.points if q.type == "CP"]


def test_export_marks_the_cusps(cusp_curves, tmp_path):
    """The exported rows of a fold-curve file: every parameter, the ordinates, type CP."""
    import csv
    from elastica_auto.storage.store import export_csv
    path = ea.save(cusp_curves, tmp_path / "cusps.h5")
    out = export_csv(ea.BranchFile(path), tmp_path / "cusps.csv")
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {"P", "eps", "psi", "alpha", "theta0", "m1", "m0", "type", "label"} <= set(rows[0])
    cps = [r for r in rows if r["type"] == "CP"]
    assert len(cps) == len(_cusps(cusp_curves)) >= 4
    assert {round(float(r["eps"]), 6) for r in cps} == {0.211385, 0.361114}


def test_every_fold_curve_point_has_its_fold_residual(fold_curve):
    """Every point of a fold curve is a fold: its fold_residual, the error estimate of the
    solution and null vector together, is set and under the curve's tol (1e-7)."""
    res = fold_curve[0].columns["fold_residual"]
    assert np.all(np.isfinite(res)) and np.all(res <= 1e-7) and np.any(res > 0)


def _level_fold():
    """The fold of examples/bratu_level.py in closed form (its docstring): with
    I(z) = int_0^1 (x - 1/2) tanh(z (x - 1/2)) dx, the shifted Bratu solution's mean is
    m(z) = 2 z I(z) (by parts), and G = Lam exp(m) is largest where z I(z) = 1, so m = 2 there:
    the fold curve is lam exp(M) = G(z*) = 2 z*^2 e^2 / cosh(z*/2)^2 with c = M - 2, and
    u'(0) = 2 z* tanh(z*/2) all along it. Returns (G(z*), u'(0))."""
    from scipy.integrate import quad

    def zi(z):
        return z * quad(lambda x: (x - 0.5) * math.tanh(z * (x - 0.5)), 0, 1,
                        epsabs=1e-14, epsrel=1e-14)[0] - 1.0

    z = brentq(zi, 2, 8, xtol=1e-14)
    return 2 * z * z * math.e ** 2 / math.cosh(z / 2) ** 2, 2 * z * math.tanh(z / 2)


def test_a_module_with_an_integral_condition_and_a_free_parameter_has_fold_curves(tmp_path):
    """u'' + lam e^u = 0, u(0) = u(1) = c (c free), int u = M: the fold in lam, and the fold
    curve through it in (lam, M) from the stored label, against the closed form; the free
    level c is a column of the curve."""
    from helpers import EXAMPLES
    level = ea.load_problem(str(EXAMPLES / "bratu_level.py"))
    K, du0 = _level_fold()
    branches = ea.continuation(level, {"lam": 0.0, "M": 0.0}, "lam", bounds=(-1, 20),
                               max_points=60, ds_max=1.0, directions="+")
    (lp,) = branches[0].folds
    assert lp.params["lam"] == pytest.approx(K, rel=1e-9)
    assert lp.params["c"] == pytest.approx(-2.0, abs=1e-9)
    path = ea.save(branches, tmp_path / "level.h5")
    curves = ea.continuation(level, ea.BranchFile(path).label("LP1"), ["lam", "M"],
                             bounds=(-1, 2), tol=1e-7, directions="both")
    assert [b.end for b in curves] == ["EP", "EP"]
    ends = sorted(b.points[-1].params["M"] for b in curves)
    assert ends == pytest.approx([-1, 2], abs=1e-12)
    for b in curves:
        c = b.columns
        assert len(c["M"]) >= 8
        assert np.abs(c["lam"] * np.exp(c["M"]) / K - 1).max() <= 1e-9
        assert np.abs(c["c"] - (c["M"] - 2)).max() <= 1e-9
        assert np.abs(c["du0"] - du0).max() <= 1e-8
    with pytest.raises(ea.PlanError, match="'c' is a free parameter") as exc_info:
        ea.continuation(level, branches.label("LP1"), ["lam", "c"])
    assert exc_info.value.key == "parameter"


@pytest.mark.parametrize("module, name", [("elastica_lever_arm", "theta0"),
                                          ("kirchhoff_lever_arm", "theta0"),
                                          ("kirchhoff_lever_arm", "phi0")])
def test_a_period_turns_the_fold_system_as_it_turns_the_module(module, name):
    """The fold system (the solution y and the null vector v) inherits what a period does to
    the module's states: a shift moves y and leaves v (a direction) alone, a flip turns
    both. With that map the extended equations are equivariant at any Y, solution or not:
    rhs(map Y, p + 2 pi k) = map(rhs(Y, p)) (the map's derivative) and the boundary
    residuals the same up to the sign of each row, for k = 1, -1, 2, 3."""
    from elastica_auto.branches.codim2 import fold_problem
    from elastica_auto.model.problem import load_problem, periods_applied
    base = load_problem(module)
    fold = fold_problem(base, "psi")
    par = fold.parameters[name]
    assert (par.period_shift, par.period_flip) == (
        (("theta", 2 * math.pi),), ()) if module == "elastica_lever_arm" else (
        (), tuple(f"{pre}q{i}" for pre in ("", "null:") for i in range(4)))
    rng = np.random.default_rng(1)
    s = np.linspace(0.0, 1.0, 11)
    Y = rng.normal(size=(len(fold.states), len(s)))
    p = {**fold.defaults(), name: 0.3, "psi": 0.4, "P": 2.0}
    f = fold.rhs(s, Y, p)
    r = fold.bc(Y[:, 0], Y[:, -1], p)
    for k in (1, -1, 2, 3):
        q = {**p, name: p[name] + 2 * math.pi * k}
        Z = periods_applied(fold, name, Y, k)
        assert np.array_equal(Z, Y) != bool(par.period_shift or k % 2)
        np.testing.assert_allclose(fold.rhs(s, Z, q), periods_applied(fold, name, f, k, True),
                                   rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(np.abs(fold.bc(Z[:, 0], Z[:, -1], q)), np.abs(r),
                                   rtol=1e-10, atol=1e-10)
