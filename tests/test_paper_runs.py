"""The paper's runs (runs/*.toml, chained by restart labels) checked against the symmetries
the paper states: 2 pi periodicity in the angles, the rotating base as the mirror image of the
rotating load (alpha -> -theta0, same ordinate), the left-right mirror at psi = 0, the
reversal of the load (P, alpha) -> (-P, alpha + pi), and the unloaded straight rod at P = 0.

The runs are computed once per session by the Makefile's own rules (``make runs``), from copies
of the run files with smaller bounds where a symmetry can be checked on less; tests/
test_figures.py draws the figures from the same files. rotating_arm is the conftest's full run.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

import shooting
from elastica_auto.storage.store import BranchFile

#: one worker of `pytest -n` builds the reduced paper runs for both files (make test)
pytestmark = pytest.mark.xdist_group("paper")

REPO = Path(__file__).resolve().parents[1]
TWO_PI = 2 * math.pi
P1, P2 = math.pi ** 2 / 4, 9 * math.pi ** 2 / 4

#: run -> [(text in the shipped run file, replacement)]: smaller bounds for the tests
REDUCED = {
    # eps > 0 only: the buckled branches reaching the pitchfork at eps = 0 are the slow ones
    "arm_length": [("bounds = [-0.5, 0.5]", "bounds = [0.05, 0.5]")],
    "load_magnitude": [('bounds = ["-9*pi^2/4", "9*pi^2/4"]', 'bounds = [-2, "9*pi^2/4"]')],
    # eps = 0.25 keeps its whole period of folds; eps = 0.5 stops in the first excursion, whose
    # winding up to psi = 28.6 is most of the shipped run's 25 s (reduced: 13 s)
    "higher_loads": [('bounds = ["-12*pi", "12*pi"]', 'bounds = ["-3*pi", "3*pi"]')],
    "pinned_arm": [('stop = ["n_abs > 80"]', 'stop = ["n_abs > 40"]')],
    # S3 and its copy a period on, weakly and strongly damped (about 4 s a landing)
    # the spatial rod (figures rotating-arm-3d, configurations-3d): one (eps, P, b2), psi
    # within [-pi, pi] (the shipped run: 16 branches over [-6 pi, 6 pi], minutes)
    "rotating_arm_3d": [("eps = [0.25, 0.5]", "eps = [0.5]"),
                        ('P = ["pi^2/4", "9*pi^2/4"]', 'P = ["9*pi^2/4"]'),
                        ("b2 = [1, 2]", "b2 = [2]"),
                        ('bounds = ["-6*pi", "6*pi"]', 'bounds = ["-pi", "pi"]')],
    # the curves through eps = 0.25 and both cusps (eps 0.211 and 0.361), and the load plane up to
    # P = 25 (the UZ at 9 pi^2 / 4 = 22.2 inside): 10 and 12 s instead of 18 and 15
    "fold_curves_arm": [("bounds = [0, 1]", "bounds = [0.2, 0.6]")],
    "fold_curves_load": [("bounds = [0.5, 30]", "bounds = [1, 25]")],
    "snap_damping": [("damping = [0.05, 0.1, 0.2, 0.4, 0.6, 0.8, 0.9, 1.0, 1.1, 1.25, 1.5, "
                      "2.0, 4.0, 8.0]", "damping = [0.5, 20.0]"),
                     ('damping_folds = ["LP13", "LP10", "LP18", "LP20"]',
                      'damping_folds = ["LP18", "LP1"]')],
}

_BUILT: dict = {}


def make(root: Path, *targets, check=True, extra=()):
    """``make`` in the repository with the run files, branch files and figures under
    ``root``; never reinstalls the virtual environment."""
    bin_dir = Path(sys.executable).parent
    cmd = ["make", "-j2", f"RUNS={root / 'runs'}", f"OUT={root / 'out'}",
           f"FIG={root / 'fig'}", f"BIN={bin_dir}", "-o", f"{bin_dir}/elastica-auto",
           *extra, *targets]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=900)
    if check and proc.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} failed ({proc.returncode}):\n"
                             f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


def build_paper(root: Path, rotating_arm_file: Path, targets=("runs",)) -> Path:
    """The reduced copies of the run files under ``root``/runs, the shipped rotating_arm
    file as ``root``/out/rotating_arm.h5 (newer than its run file and the engine, so make
    takes it as up to date), then ``make`` the targets. Done once per root."""
    key = (str(root), tuple(targets))
    if key in _BUILT:
        return root
    runs = root / "runs"
    if not runs.is_dir():
        runs.mkdir(parents=True)
        for src in sorted((REPO / "runs").glob("*.toml")):
            text = src.read_text()
            for old, new in REDUCED.get(src.stem, []):
                assert old in text, f"{src.name}: expected {old!r} to reduce it for the tests"
                text = text.replace(old, new)
            (runs / src.name).write_text(text)
        (root / "out").mkdir()
        shutil.copyfile(rotating_arm_file, root / "out" / "rotating_arm.h5")
    make(root, *targets)
    _BUILT[key] = True
    return root


@pytest.fixture(scope="session")
def paper(tmp_path_factory, rotating_arm) -> Path:
    root = tmp_path_factory.getbasetemp() / "paper"
    return build_paper(root, rotating_arm.result.path) / "out"


def _open(paper, run) -> BranchFile:
    return BranchFile(paper / f"{run}.h5")


def _fixed(b, names):
    return {q: float(b.columns[q][0]) for q in names}


def _folds(b, ordinate):
    """(value, ordinate, {index on either side}) of every located LP of a branch, in order."""
    c = b.columns
    out = []
    for i in np.flatnonzero(c["type"] == "LP"):
        if not np.isfinite(c["fold_residual"][i]):
            continue
        a, _, z = str(c["transition"][i]).partition("->")
        out.append((float(c[b.parameter][i]), float(c[ordinate][i]),
                    frozenset((a.strip(), z.strip()))))
    return out


def _period_of_folds(folds, period=TWO_PI, tol=1e-6):
    """The smallest N such that fold i + N is fold i moved by +-period (one sign throughout)
    with the same ordinate and the same index change, or None."""
    for N in range(1, len(folds) - 1):
        shifts = [folds[i + N][0] - folds[i][0] for i in range(len(folds) - N)]
        if not all(abs(abs(d) - period) < tol for d in shifts):
            continue
        if len({math.copysign(1, d) for d in shifts}) != 1:
            continue
        if all(abs(folds[i + N][1] - folds[i][1]) < tol * (1 + abs(folds[i][1]))
               and folds[i + N][2] == folds[i][2] for i in range(len(folds) - N)):
            return N
    return None


def _to_first_fold(b, x, y):
    """The branch up to its first fold in ``x`` (x monotone there)."""
    xs, ys = b.columns[x].astype(float), b.columns[y].astype(float)
    d = np.sign(np.diff(xs))
    n = len(xs) if np.all(d == d[0]) else int(np.flatnonzero(d != d[0])[0]) + 1
    return xs[:n], ys[:n]


def _spline(x, y):
    """A cubic spline through a monotone stretch (points are up to ds_max apart)."""
    order = np.argsort(x)
    return CubicSpline(x[order], y[order])


# ---- 1. 2 pi periodicity: along every branch the folds repeat, a period apart ---------------

@pytest.mark.parametrize("run", ["rotating_arm", "rotating_load", "rotating_base",
                                 "rotating_arm_stable"])
def test_folds_repeat_every_period_of_the_angle(paper, run):
    """The solution set is 2 pi periodic in psi, alpha and theta0 (paper 4.1.1), so along a
    branch that runs through several periods the folds come back, each moved by 2 pi with the
    same ordinate and the same index change; at least two repetitions are required."""
    bf = _open(paper, run)
    checked = 0
    for b in bf.branches:
        folds = _folds(b, b.attrs["ordinate"])
        if len(folds) < 4:
            continue
        N = _period_of_folds(folds)
        assert N is not None, (f"{run} branch {b.number}: folds do not repeat with period 2 pi: "
                               + ", ".join(f"({v:.6f}, {m:.6f}, {sorted(t)})"
                                           for v, m, t in folds))
        if len(folds) - N >= 2:
            checked += 1
    assert checked >= 2, f"{run}: too few branches run through enough periods to check"


def test_rotating_base_folds_a_period_apart_land_alike(paper):
    """Moving theta0 by 2 pi turns theta by 2 pi: the same rod. Every fold of rotating_base
    ending a stable branch has one landing (run file: landing = true), and folds a period
    apart (same branch, same stable side, theta0 differing by a multiple of 2 pi) land on
    the same equilibrium (its shooting value k) with the same energy released."""
    rows = _open(paper, "rotating_base").snaps
    folds = {}
    for r in rows:
        folds.setdefault((int(r["branch"]), r["lp"]), []).append(r)
    assert len(folds) >= 20
    landed = {}
    for fold, mine in folds.items():
        hit = [r for r in mine if r["landed"] == 1]
        assert len(hit) == 1, fold
        landed[fold] = hit[0]
    copies = 0
    for a in landed.values():
        for b in landed.values():
            turns = (b["value"] - a["value"]) / TWO_PI
            if (a["branch"] != b["branch"] or a["stable_side"] != b["stable_side"]
                    or a["lp"] == b["lp"] or abs(turns - round(turns)) > 1e-6):
                continue
            copies += 1
            assert b["k"] == pytest.approx(a["k"], abs=1e-6), (a["lp"], b["lp"])
            assert b["energy_released"] == pytest.approx(a["energy_released"], rel=1e-3)
    assert copies >= 10


def test_damped_snaps_a_period_apart_land_alike_and_strong_damping_as_the_flow(paper):
    """snap_damping (reduced): the damped model from S3 (LP18) and from its copy a period
    of theta0 on (LP1) lands on the same equilibrium for each damping, always a stable one
    at the fold (of its snap-back table); strongly damped (c = 20), where the overdamped
    flow lands (its limit)."""
    bf = _open(paper, "snap_damping")
    by = {(r["lp"], r["damping"]): r for r in bf.landings}
    assert sorted(by) == [("LP1", 0.5), ("LP1", 20.0), ("LP18", 0.5), ("LP18", 20.0)]
    assert by["LP1", 0.5]["value"] - by["LP18", 0.5]["value"] == pytest.approx(TWO_PI)
    for (lp, c), r in by.items():
        assert r["landed"] == 1, (lp, c)
        assert any(abs(t["target_m0"] - r["target_m0"]) < 1e-6
                   for t in bf.snaps if t["lp"] == lp), (lp, c)
        copy = by["LP1" if lp == "LP18" else "LP18", c]
        assert r["target_m0"] == pytest.approx(copy["target_m0"], abs=1e-6)
        assert r["energy_released"] == pytest.approx(copy["energy_released"], rel=1e-3)
    for lp in ("LP1", "LP18"):
        over = next(t for t in bf.snaps if t["lp"] == lp and t["landed"] == 1)
        assert by[lp, 20.0]["target_m0"] == pytest.approx(over["target_m0"], abs=1e-6)


# ---- 2. the rotating base is the rotating load mirrored ----------------------------------------

def test_rotating_base_is_the_rotating_load_mirrored(paper):
    """Turning the clamp by theta0 is turning the load by -theta0 (paper 4.2.1): from the same
    start, the m0-theta0 diagram is the mA-alpha diagram with the abscissa reversed. Every fold
    of one run is a fold of the other at the mirrored value, with the same ordinate and the
    same pair of indices, and the branches end at the mirrored bounds with equal ordinates."""
    load, base = _open(paper, "rotating_load"), _open(paper, "rotating_base")
    assert load.branches and len(load.branches) == len(base.branches)
    for name in ("P", "eps", "psi"):
        assert sorted(float(b.columns[name][0]) for b in load.branches) == pytest.approx(
            sorted(float(b.columns[name][0]) for b in base.branches), abs=1e-12)

    def fold_set(bf, ordinate, sign):
        return sorted((round(float(b.columns["P"][0]), 9), sign * v, m, tuple(sorted(t)))
                      for b in bf.branches for v, m, t in _folds(b, ordinate))

    fl = fold_set(load, "mA", +1)
    fb = fold_set(base, "m0", -1)
    assert len(fl) == len(fb) and len(fl) >= 10
    for (p1, v1, m1, t1), (p2, v2, m2, t2) in zip(fl, fb):
        assert v1 == pytest.approx(v2, abs=1e-6)
        assert m1 == pytest.approx(m2, abs=1e-5 * (1 + abs(m1)))
        assert t1 == t2 and p1 == p2
    ends_l = sorted((round(float(b.columns["alpha"][-1]), 9), round(float(b.columns["mA"][-1]), 5),
                     round(float(b.columns["P"][0]), 6)) for b in load.branches)
    ends_b = sorted((round(-float(b.columns["theta0"][-1]), 9),
                     round(float(b.columns["m0"][-1]), 5), round(float(b.columns["P"][0]), 6))
                    for b in base.branches)
    assert ends_l == ends_b


def test_rotating_load_and_base_start_from_stable_equilibria_at_psi_half_pi(paper):
    """Both runs start (by label) from an index-0 equilibrium of the eps = 0.5 psi-branch at
    psi = pi/2 (mod 2 pi) of each load; the starts keep index 0 after re-solving at pi/2."""
    arm = _open(paper, "rotating_arm")
    for run in ("rotating_load", "rotating_base"):
        bf = _open(paper, run)
        loads = set()
        for b in bf.branches:
            label = b.attrs["start"].split(":")[-1]
            br, pt = arm.labels[label]
            c = arm.branches[br - 1].columns
            assert c["eps"][pt - 1] == 0.5 and c["index"][pt - 1] == 0
            assert abs(math.remainder(c["psi"][pt - 1] - math.pi / 2, TWO_PI)) < 1e-9
            assert b.columns["psi"][0] == pytest.approx(math.pi / 2, abs=1e-12)
            assert b.columns["index"][0] == 0
            loads.add(round(float(c["P"][pt - 1]), 9))
        assert loads == {round(P1, 9), round(P2, 9)}


# ---- 3. the left-right mirror at psi = 0 ---------------------------------------------------

def test_arm_length_branches_of_mirror_images_coincide_at_psi_zero(paper):
    """At psi = alpha = theta0 = 0 the mirror x -> -x maps equilibria to equilibria with
    theta -> -theta and the same beta = P cos(theta(1)) (paper 4.1.2: the left and right
    deflections overlap in the beta-eps diagram): the eps-branches from two mirror-image starts
    have the same folds, and so do branches from the same equilibrium reached twice."""
    bf = _open(paper, "arm_length")
    groups: dict = {}
    for b in bf.branches:
        if abs(math.remainder(float(b.columns["psi"][0]), TWO_PI)) > 1e-9:
            continue
        key = (round(float(b.columns["P"][0]), 9), round(abs(float(b.columns["m0"][0])), 4))
        groups.setdefault(key, []).append(b)
    pairs = 0
    for (P, m0), brs in groups.items():
        signs = {np.sign(round(float(b.columns["m0"][0]), 6)) for b in brs}
        if m0 == 0 or signs != {-1.0, 1.0}:
            continue
        ref = _folds(brs[0], "beta")
        for b in brs[1:]:
            other = _folds(b, "beta")
            assert len(other) == len(ref), (P, m0)
            for (v1, y1, t1), (v2, y2, t2) in zip(ref, other):
                assert v1 == pytest.approx(v2, abs=1e-6)
                assert y1 == pytest.approx(y2, abs=1e-5 * (1 + abs(y1)))
                assert t1 == t2
            # and they end at the same point (a bound, located exactly, or the start's eps)
            for k in (0, -1):
                assert b.columns["eps"][k] == pytest.approx(brs[0].columns["eps"][k], abs=1e-9)
                beta = float(brs[0].columns["beta"][k])
                assert b.columns["beta"][k] == pytest.approx(beta, abs=1e-5 * (1 + abs(beta)))
        pairs += 1
    assert pairs >= 3, "expected mirror pairs of buckled starts at psi = 0 for both loads"


# ---- 4. the load reversed, and the unloaded rod ---------------------------------------------

def test_load_magnitude_reversed_load_is_the_load_turned_by_pi(paper):
    """F = P (sin alpha, -cos alpha) is unchanged by (P, alpha) -> (-P, alpha + pi), and
    gamma = dB/dP changes sign: wherever an alpha = 0 branch and an alpha = pi branch are both
    computed, gamma(P) at alpha = 0 is -gamma(-P) at alpha = pi."""
    bf = _open(paper, "load_magnitude")

    def curves(alpha):
        return [b for b in bf.branches
                if abs(math.remainder(float(b.columns["alpha"][0]) - alpha, TWO_PI)) < 1e-9]

    compared = 0
    for b0 in curves(0.0):
        P0, g0 = _to_first_fold(b0, "P", "gamma")
        for bp in curves(math.pi):
            Pp, gp = _to_first_fold(bp, "P", "gamma")
            lo, hi = max(P0.min(), -Pp.max()), min(P0.max(), -Pp.min())
            if hi - lo < 1.0:
                continue
            q = np.linspace(lo, hi, 25)
            a, z = _spline(P0, g0)(q), -_spline(Pp, gp)(-q)
            # exact symmetry; the tolerance is the splines' error between points ~1 apart
            if np.max(np.abs(a - z)) < 5e-3:
                compared += 1
    assert compared >= 1, "no pair of mirror branches (alpha = 0, P) and (alpha = pi, -P)"


def test_load_magnitude_branches_reach_the_unloaded_straight_rod(paper):
    """At P = 0 the only equilibrium is the unloaded straight rod, theta = theta0 = 0, so a
    branch crossing P = 0 has gamma = y(1) cos alpha + eps cos(alpha + psi) = cos alpha -
    eps sin alpha there (psi = pi/2, eps = 0.5)."""
    bf = _open(paper, "load_magnitude")
    crossed = 0
    for b in bf.branches:
        c = b.columns
        for i in np.flatnonzero((c["type"] == "UZ") & (c["P"] == 0)):
            a, eps, psi = (float(c[q][i]) for q in ("alpha", "eps", "psi"))
            assert c["gamma"][i] == pytest.approx(math.cos(a) + eps * math.cos(a + psi),
                                                   abs=1e-6)
            assert c["m0"][i] == pytest.approx(0, abs=1e-6)   # no load, no moment
            crossed += 1
    assert crossed >= 4


# ---------------------------------------------------------------- fold curves and maps
def test_the_fold_curves_pass_through_every_fold_of_rotating_arm_at_eps_quarter(paper):
    """fold_curves_arm starts from the eps = 0.5 folds only; its UZ points at eps = 0.25 are
    every fold of the eps = 0.25 branches (modulo 2 pi), to 1e-7 in psi (the curves are
    solved at the default tol; tests/test_codim2.py checks 1e-9 at tol = 1e-7)."""
    curves, arm = _open(paper, "fold_curves_arm"), _open(paper, "rotating_arm")
    on_curves = [(float(b.columns["P"][i]), float(b.columns["psi"][i]), float(b.columns["m1"][i]))
                 for b in curves.branches for i in np.flatnonzero(b.columns["type"] == "UZ")]
    for b in arm.branches:
        if b.columns["eps"][0] != 0.25:
            continue
        for i in np.flatnonzero(b.columns["type"] == "LP"):
            P, psi, m1 = (float(b.columns[q][i]) for q in ("P", "psi", "m1"))
            assert any(abs(P - Q) < 1e-12 and abs(math.remainder(psi - x, TWO_PI)) < 1e-7
                       and abs(m1 - m) < 1e-6 for Q, x, m in on_curves), (P, psi)


@pytest.mark.parametrize("run", ["fold_curves_arm", "fold_curves_load"])
def test_every_region_of_the_stability_maps_holds_one_count(paper, run, elastica):
    """Enumerations at random points of the maps' regions, away from the curves, find each
    region's number of stable equilibria."""
    from scipy import ndimage
    from elastica_auto.analysis.equilibria import enumerate_equilibria
    maps = _open(paper, run).maps
    assert maps
    rng = np.random.default_rng(7)
    for m in maps:
        ny, nx = m.cells.shape
        x0, x1, y0, y1 = m.extent
        inside = ndimage.binary_erosion(m.cells >= 0, iterations=3)
        js, is_ = np.nonzero(inside)
        for p in rng.choice(len(js), size=12, replace=False):
            j, i = js[p], is_[p]
            x, y = x0 + (i + 0.5) * (x1 - x0) / nx, y0 + (j + 0.5) * (y1 - y0) / ny
            eqs = enumerate_equilibria(elastica, {**m.fixed, m.x: x, m.y: y})
            assert sum(e.index == 0 for e in eqs) == m.stable[m.cells[j, i]], (m.fixed, x, y)


# ---- higher loads (beyond the paper): the straight rod at index 3 ---------------------------

P3 = 25 * math.pi ** 2 / 4


def _critical_loads_below(P, eps):
    """The critical loads of the straight rod below P: q^2 for the roots q of cot q = eps q,
    one in each (n pi, n pi + pi/2) for eps > 0 (paper section 3.2), by brentq."""
    out, n = [], 0
    while (n * math.pi) ** 2 < P:
        q = brentq(lambda q: math.cos(q) - eps * q * math.sin(q), n * math.pi + 1e-12,
                   (n + 0.5) * math.pi, xtol=1e-14)
        if q * q < P:
            out.append(q * q)
        n += 1
    return out


def _higher_loads(paper):
    bf = _open(paper, "higher_loads")
    assert len(bf.branches) == 4
    assert {(float(b.columns["eps"][0]), int(b.attrs["direction"])) for b in bf.branches} == {
        (0.25, 1), (0.25, -1), (0.5, 1), (0.5, -1)}
    return bf


def test_higher_loads_start_at_the_index_of_the_critical_loads_below_P(paper):
    """At psi = 0 the straight rod's index is the number of critical loads below P (the
    closed form, solved here); P = 25 pi^2/4 lies between the third and the fourth at both eps,
    so the run starts at index 3."""
    for b in _higher_loads(paper).branches:
        c = b.columns
        eps, P = float(c["eps"][0]), float(c["P"][0])
        assert P == pytest.approx(P3, rel=1e-14)
        assert c["psi"][0] == 0 and c["m0"][0] == 0 and c["m1"][0] == 0
        below = _critical_loads_below(P, eps)
        assert len(below) == 3, (eps, below)
        assert c["index"][0] == c["index_direct"][0] == len(below)


def test_higher_loads_reach_index_three_and_rule_and_count_agree_everywhere(paper):
    """No point has an unknown index (-1): off the folds the fold rule and the direct count give
    the same index, along the whole branch, and each fold changes it by one. Index 3 is reached
    again a period from the start (the straight rod's stretch moved by 2 pi, eps = 0.25)."""
    top, away = 0, 0
    for b in _higher_loads(paper).branches:
        c = b.columns
        assert np.all(c["index"] >= 0), c["note"][c["index"] < 0][:5]
        regular = ~np.isin(c["type"], ["LP", "BP"])
        np.testing.assert_array_equal(c["index_rule"][regular], c["index_direct"][regular])
        np.testing.assert_array_equal(c["index"][regular], c["index_direct"][regular])
        for i in np.flatnonzero(c["type"][:-1] == "LP"):   # a final LP has no far side
            a, _, z = str(c["transition"][i]).partition("->")
            assert abs(int(a) - int(z)) == 1, c["transition"][i]
        top = max(top, int(c["index"].max()))
        away += int(np.sum((c["index"] == 3) & (np.abs(c["psi"].astype(float)) > math.pi)))
    assert top >= 3
    assert away > 0


def test_higher_loads_the_two_directions_are_mirror_images(paper):
    """(theta, psi) -> (-theta, -psi) maps equilibria to equilibria (alpha = theta0 = 0): the
    branch leaving psi = 0 downward is, point by point, the upward one with (psi, m1, m0)
    negated and the same index."""
    by_eps: dict = {}
    for b in _higher_loads(paper).branches:
        by_eps.setdefault(float(b.columns["eps"][0]), {})[int(b.attrs["direction"])] = b
    for eps, d in by_eps.items():
        up, down = d[1].columns, d[-1].columns
        assert len(up["psi"]) == len(down["psi"]), eps
        for q in ("psi", "m1", "m0"):
            u, w = up[q].astype(float), down[q].astype(float)
            np.testing.assert_allclose(u, -w, rtol=0, atol=1e-8 * (1 + np.abs(u).max()))
        np.testing.assert_array_equal(up["index"], down["index"])


def test_higher_loads_folds_are_folds_by_shooting_and_recur_a_period_on(paper):
    """Every located fold of the upward branches is a fold of the shooting formulation
    (tests/shooting.py, independent of the engine) at the same psi and m0 = theta'(0); a
    branch ended at its 11th fold (stop = LP11) is back at its 1st fold moved by 2 pi, with
    the same ordinates, approached at the same index."""
    checked = periodic = 0
    for b in _higher_loads(paper).branches:
        c = b.columns
        eps = float(c["eps"][0])
        # one direction: the other is its mirror image (the test above)
        for i in np.flatnonzero(c["type"] == "LP") if b.attrs["direction"] == 1 else ():
            assert np.isfinite(c["fold_residual"][i])
            psi, m0, m1 = (float(c[q][i]) for q in ("psi", "m0", "m1"))
            k0, psi_s, m1_s = shooting.fold(P3, eps, m0, psi)
            assert abs(psi - psi_s) <= 1e-9, (eps, psi, psi_s)
            assert abs(m0 - k0) <= 1e-8 * (1 + abs(k0))
            assert abs(m1 - m1_s) <= 1e-8 * (1 + abs(m1_s))
            checked += 1
        if b.attrs["end"] == "LP":
            lp = np.flatnonzero(c["type"] == "LP")
            assert len(lp) == 11 and lp[-1] == len(b) - 1
            first, last = lp[0], lp[-1]
            assert abs(abs(c["psi"][last] - c["psi"][first]) - TWO_PI) < 1e-8
            for q in ("m1", "m0"):
                y = float(c[q][first])
                assert c[q][last] == pytest.approx(y, abs=1e-7 * (1 + abs(y)))
            # the same side of the same fold: approached at the same index
            assert c["index"][last] == c["index"][first]
            periodic += 1
    assert checked >= 10 and periodic >= 2
