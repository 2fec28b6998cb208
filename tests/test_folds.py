"""Folds (LP) of psi-branches, against exact symmetries and an independent shooting solve."""

from __future__ import annotations

import dataclasses
import math
from collections import defaultdict

import numpy as np
import pytest

import shooting
from helpers import REPO, elastica_run_file, run_plan
from elastica_auto.execution import runfile

TWO_PI = 2 * math.pi

# Fold locations: the engine locates folds on meshes that resolve the solution and its null
# vector to fold_tol = 1e-7, documented (options.py) as putting them within ~1e-10 of a shooting
# solve; we check 1e-9 in psi. The tip moment m1 = kappa(1) at a fold is first order in the
# state error (psi is stationary there), which at fold_tol = 1e-7 is ~1e-9 here: 1e-8.
PSI_ATOL = 1e-9
FOLD_ATOL = 1e-8


def _by_pair(run):
    """Branches grouped by (eps, P): {(eps, P): {direction: StoredBranch}}."""
    out = defaultdict(dict)
    for b in run.file.branches:
        key = (float(b.columns["eps"][0]), float(b.columns["P"][0]))
        out[key][int(b.attrs["direction"])] = b
    return out


def _lps(b):
    c = b.columns
    i = np.nonzero(c["type"] == "LP")[0]
    return {k: c[k][i] for k in ("psi", "m1", "m0", "fold_residual")}


# ---- the shooting solver itself -----------------------------------------------------------

@pytest.mark.parametrize("P", [0.5, math.pi ** 2 / 4, 9 * math.pi ** 2 / 4])
def test_shooting_jacobi_field_on_the_straight_rod(P):
    """On theta = 0 the Jacobi field solves u'' + P u = 0: u = sin(sqrt P s) / sqrt P."""
    th1, k1, u1, up1 = shooting.integrate(P, 0.0, 0.0, 0.0)
    w = math.sqrt(P)
    assert th1 == 0.0 and k1 == 0.0
    assert u1 == pytest.approx(math.sin(w) / w, abs=1e-11)
    assert up1 == pytest.approx(math.cos(w), abs=1e-11)


@pytest.mark.parametrize("eps", [0.25, 0.5])
def test_shooting_critical_loads_of_the_straight_rod(eps):
    """dr/dk0 on the straight rod is cos(w) - eps w sin(w), w = sqrt(P): it vanishes at the
    critical loads cot(w) = eps w (docs/design.md, "The straight rod"; found here by brentq on
    the formula)."""
    from scipy.optimize import brentq
    w = brentq(lambda w: math.cos(w) - eps * w * math.sin(w), 0.1, math.pi / 2)
    _, dr = shooting.residual(0.0, 0.0, w * w, eps)
    assert abs(dr) < 1e-11


# ---- 6. every fold of the rotating_arm run, against shooting ------------------------------

def test_every_fold_matches_an_independent_shooting_solve(rotating_arm):
    pairs = _by_pair(rotating_arm)
    wanted = {(0.25, math.pi ** 2 / 4), (0.25, 9 * math.pi ** 2 / 4),
              (0.5, math.pi ** 2 / 4), (0.5, 9 * math.pi ** 2 / 4)}
    for eps, P in wanted:   # all four (eps, P) pairs of the paper's figures are covered
        assert any(abs(e - eps) < 1e-15 and abs(p - P) < 1e-12 for e, p in pairs)
    nfolds = 0
    for (eps, P), dirs in pairs.items():
        for b in dirs.values():
            lp = _lps(b)
            assert len(lp["psi"]) >= 2
            for psi, m1, m0, res in zip(lp["psi"], lp["m1"], lp["m0"], lp["fold_residual"]):
                assert np.isfinite(res)    # located, not merely detected
                k0, psi_s, m1_s = shooting.fold(P, eps, m0, psi)
                assert abs(psi - psi_s) <= PSI_ATOL, (eps, P, psi, psi_s)
                assert abs(m0 - k0) <= FOLD_ATOL * (1 + abs(k0))
                assert abs(m1 - m1_s) <= FOLD_ATOL * (1 + abs(m1_s))
                nfolds += 1
    assert nfolds >= 40


# ---- 3. mirror symmetry ---------------------------------------------------------------------

def test_the_two_directions_are_mirror_images(rotating_arm):
    """With alpha = theta0 = 0, (theta, kappa, x, y, psi) -> (-theta, -kappa, -x, y, -psi) maps
    solutions to solutions (sin is odd). The branch leaving psi = 0 upward is the mirror image
    of the one leaving downward: its k-th fold is at -psi_k with m1 -> -m1."""
    for (eps, P), dirs in _by_pair(rotating_arm).items():
        assert set(dirs) == {1, -1}
        up, down = _lps(dirs[1]), _lps(dirs[-1])
        assert len(up["psi"]) == len(down["psi"]) > 0
        np.testing.assert_allclose(up["psi"], -down["psi"], rtol=0, atol=FOLD_ATOL)
        np.testing.assert_allclose(up["m1"], -down["m1"], rtol=0,
                                   atol=FOLD_ATOL * (1 + np.abs(up["m1"]).max()))


# ---- 4. 2 pi periodicity ----------------------------------------------------------------------

def test_folds_repeat_with_period_two_pi(rotating_arm):
    """psi is an angle: the equations depend on it only through sin(psi + alpha - theta(1)),
    so a fold at psi recurs at psi + 2 pi k with the same solution (same m1, m0). Folds are
    grouped loosely (psi mod 2 pi and m1 within 1e-3), then each group must match to 1e-8."""
    for (eps, P), dirs in _by_pair(rotating_arm).items():
        psi = np.concatenate([_lps(b)["psi"] for b in dirs.values()])
        m1 = np.concatenate([_lps(b)["m1"] for b in dirs.values()])
        m0 = np.concatenate([_lps(b)["m0"] for b in dirs.values()])
        partners = 0
        for i in range(len(psi)):
            found = False
            for j in range(len(psi)):
                k = round((psi[j] - psi[i]) / TWO_PI)
                if i == j or k == 0:
                    continue
                if abs(psi[j] - psi[i] - k * TWO_PI) < 1e-3 and abs(m1[j] - m1[i]) < 1e-3:
                    assert abs(psi[j] - psi[i] - k * TWO_PI) <= FOLD_ATOL, (eps, P, i, j)
                    assert abs(m1[j] - m1[i]) <= FOLD_ATOL * (1 + abs(m1[i]))
                    assert abs(m0[j] - m0[i]) <= FOLD_ATOL * (1 + abs(m0[i]))
                    found = True
            partners += found
        # The shipped run spans 12 pi: every fold it finds has a translate it also finds.
        assert partners == len(psi), (eps, P, partners, len(psi))


def _fast_and_whole(make_plan, tmp_path, monkeypatch):
    """(branches as the engine makes them, the same with every period computed) of the plan
    ``make_plan()``, in this process (jobs = 1: the patch of the period kind does not reach a
    cluster's workers)."""
    from elastica_auto.branches import loops
    fast = run_plan(make_plan(), tmp_path / "fast").result.branches
    with monkeypatch.context() as m:
        m.setattr(loops.Period, "begin", lambda self, walk, course: None)
        full = run_plan(make_plan(), tmp_path / "full").result.branches
    return fast, full


def _periodic_runs(tmp_path, monkeypatch, uz):
    """The rotating arm at eps = 0.5, P = 9 pi^2/4 (its richest branches: 10 folds each),
    psi both ways to +-6 pi, UZ values ``uz`` (None: none): `_fast_and_whole`."""
    path = elastica_run_file(tmp_path / "periodic.toml", eps="0.5", P="9*pi^2/4",
                             bounds=("-6*pi", "6*pi"), uz=uz)
    return _fast_and_whole(lambda: runfile.load(path), tmp_path, monkeypatch)


def _translated_from(branch):
    """(index of the first point that is the start translated by whole periods, the shift in
    psi), or None: the points from there on repeat the first period exactly."""
    pts = branch.points
    for i, p in enumerate(pts[1:], start=1):
        shift = p.params["psi"] - pts[0].params["psi"]
        if np.array_equal(p.profile, pts[0].profile) and abs(shift) > 1.0:
            return i, shift
    return None


def test_a_periodic_branch_is_its_first_period_translated(tmp_path, monkeypatch):
    """Both branches pass the straight rod, their start, at psi = -+2 pi the way they left
    it: from there on each is its first period translated by 2 pi. Against the same run
    with every period computed: the same labels in the same order at the same psi (1e-9)
    and m1 (1e-8 at the folds, 1e-6 at the user points, solved to ``tol``), the same index
    on every labelled point and on either side of each (the transitions). The copies
    repeat the first period exactly (profiles equal, psi shifted by exactly the period),
    and each labelled copy solves the BVP at its own parameters as its original does at
    its own: the residuals of the boundary conditions and of the differential equation are
    the original's to rounding (periodicity in psi, exact)."""
    fast, full = _periodic_runs(tmp_path, monkeypatch, uz=[0, "pi/12", "pi/6", "pi/2"])
    from elastica_auto.model.problem import load_problem
    problem = load_problem("elastica_lever_arm")
    for a, b in zip(fast, full):
        assert a.end == b.end == "EP" and a.warnings == [] and a.disagreements == []
        la = [p for p in a.points if p.type]
        lb = [p for p in b.points if p.type]
        assert [p.type for p in la] == [p.type for p in lb]
        np.testing.assert_allclose([p.params["psi"] for p in la],
                                   [p.params["psi"] for p in lb], rtol=0, atol=PSI_ATOL)
        folds = [k for k, p in enumerate(la) if p.type == "LP"]
        m1a, m1b = (np.array([p.ordinates["m1"] for p in pts]) for pts in (la, lb))
        np.testing.assert_allclose(m1a[folds], m1b[folds], rtol=0, atol=FOLD_ATOL)
        # the other labels are solved to tol = 1e-5 (rms residual) on their own meshes
        np.testing.assert_allclose(m1a, m1b, rtol=0, atol=1e-6)
        assert [p.index for p in la] == [p.index for p in lb]
        assert [a.transition(p) for p in la] == [b.transition(p) for p in lb]
        found = _translated_from(a)
        assert found is not None and _translated_from(b) is None
        i, shift = found
        assert abs(abs(shift) - TWO_PI) <= 1e-12
        copies = []     # the points past the translate that repeat the first period
        for m, q in enumerate(a.points[i + 1:]):
            p, k = a.points[m % i + 1], m // i + 1
            if not (np.array_equal(q.profile, p.profile) and q.type == p.type
                    and abs(q.params["psi"] - p.params["psi"] - k * shift) <= 1e-12 * k):
                break
            copies.append((q, p))
        assert len(copies) >= i // 2        # at least half a period copied
        for q, p in ((q, p) for q, p in copies if q.state is not None):
            # the residuals of the copy at its parameters are the original's at its own
            s, y, yp = q.state.s, q.state.y, q.state.yp
            r_q = problem.bc(y[:, 0], y[:, -1], q.state.params)
            r_p = problem.bc(y[:, 0], y[:, -1], p.state.params)
            assert np.abs(r_q - r_p).max() <= 1e-13
            f_q, f_p = (problem.rhs(s, y, x.state.params) for x in (q, p))
            assert np.abs(f_q - f_p).max() <= 1e-13 * (1.0 + np.abs(yp).max())
            assert np.abs(f_p - yp).max() <= 1e-10 * (1.0 + np.abs(yp).max())


def test_the_rotating_base_repeats_with_theta_turned(rotating_arm, tmp_path, monkeypatch):
    """The paper's rotating base from its first start (theta0 continued both ways to
    +-6 pi): the clamp turned by a whole turn turns theta by 2 pi (the module's
    ``period_shift``), so each branch passes its start turned that way and is its first
    turn translated from there. Against the same branches computed whole: the same labels in
    the same order at the same theta0 (1e-9) and m0 (1e-8), the same index; the copies'
    profiles are their originals' with theta plus 2 pi k (to the rounding of the sum)."""
    import shutil
    shutil.copy(rotating_arm.file.path, tmp_path / "rotating_arm.h5")

    def base():
        plan = runfile.load(REPO / "runs" / "rotating_base.toml", tmp_path)
        plan.branches = plan.branches[:2]
        plan.landing = False
        return plan

    fast, full = _fast_and_whole(base, tmp_path, monkeypatch)
    for a, b in zip(fast, full):
        assert a.end == b.end == "EP" and a.warnings == b.warnings == []
        la = [p for p in a.points if p.type]
        lb = [p for p in b.points if p.type]
        assert [p.type for p in la] == [p.type for p in lb]
        assert [p.index for p in la] == [p.index for p in lb]
        np.testing.assert_allclose([p.params["theta0"] for p in la],
                                   [p.params["theta0"] for p in lb], rtol=0, atol=PSI_ATOL)
        np.testing.assert_allclose([p.ordinates["m0"] for p in la if p.type == "LP"],
                                   [p.ordinates["m0"] for p in lb if p.type == "LP"],
                                   rtol=0, atol=FOLD_ATOL)
        start = a.points[0]
        turned = [(i, round((p.params["theta0"] - start.params["theta0"]) / TWO_PI))
                  for i, p in enumerate(a.points[1:], start=1)
                  if np.array_equal(p.profile[1:], start.profile[1:])]
        assert turned, "the branch never passes its start turned"
        i, k = turned[0]
        assert k != 0
        # theta plus 2 pi k, to the rounding of the addition
        np.testing.assert_allclose(a.points[i].profile[0], start.profile[0] + TWO_PI * k,
                                   rtol=0, atol=1e-13)
        for m, q in enumerate(a.points[i + 1:i + 4]):
            p = a.points[m + 1]
            np.testing.assert_array_equal(q.profile[1:], p.profile[1:])
            np.testing.assert_allclose(q.profile[0], p.profile[0] + TWO_PI * k, rtol=0,
                                       atol=1e-13)


def test_a_repeating_branch_ends_at_max_points_as_if_computed_whole(tmp_path, monkeypatch):
    """max_points = 100 (about two periods of the branch at eps = 0.25, P = pi^2/4): the
    copies stop there and the branch ends at its 100th point (EP, "reached max_points").
    A copied period has the first period's points, more than a later period computed with
    the steps grown, so the branch ends earlier along the path than when computed whole;
    the labels both have are the same, in the same order at the same psi (1e-9)."""
    path = elastica_run_file(tmp_path / "max.toml", bounds=("-6*pi", "6*pi"),
                             extra="[options]\nmax_points = 100\n")
    fast, full = _fast_and_whole(lambda: runfile.load(path), tmp_path, monkeypatch)
    for a, b in zip(fast, full):
        assert _translated_from(a) is not None
        assert len(a.points) == len(b.points) == 100 and a.end == b.end == "EP"
        assert "max_points" in a.message
        la = [p for p in a.points if p.type][:-1]       # the EP at max_points left out
        lb = [p for p in b.points if p.type][:-1]
        n = min(len(la), len(lb))
        assert n >= 5 and [p.type for p in la[:n]] == [p.type for p in lb[:n]]
        np.testing.assert_allclose([p.params["psi"] for p in la[:n]],
                                   [p.params["psi"] for p in lb[:n]], rtol=0, atol=PSI_ATOL)


def test_ordinates_that_are_not_periodic_stop_the_translation(tmp_path, monkeypatch):
    """An ordinate that is not periodic in psi (here m1 + psi): a copy of the first period
    would carry the wrong values. The branch says so in a warning and is computed whole, its
    folds at the same psi as the module's own run's (1e-9)."""
    from elastica_auto.model.problem import Problem
    path = elastica_run_file(tmp_path / "ordinates.toml", bounds=("-4*pi", "4*pi"))
    plain = run_plan(runfile.load(path), tmp_path / "plain").result.branches
    own = Problem.ordinate_values

    def drifting(self, s, y, p, known=None):
        values = own(self, s, y, p, known)
        return {**values, "m1": values["m1"] + p["psi"]}

    monkeypatch.setattr(Problem, "ordinate_values", drifting)
    drift = run_plan(runfile.load(path), tmp_path / "drift").result.branches
    for a, b in zip(drift, plain):
        assert _translated_from(a) is None and _translated_from(b) is not None
        assert len(a.warnings) == 1 and "ordinates there differ" in a.warnings[0]
        np.testing.assert_allclose([p.params["psi"] for p in a.folds],
                                   [p.params["psi"] for p in b.folds], rtol=0, atol=PSI_ATOL)


def test_user_values_without_a_period_are_not_translated(tmp_path, monkeypatch):
    """UZ values that do not recur with psi's period (uz_period absent): a copy of the first
    period would carry its user points to values that are none, and miss those of the later
    periods. Such a branch is computed whole: UZ exactly where psi crosses 0.3 or -9, and
    the same labels as with every period computed."""
    path = elastica_run_file(tmp_path / "values.toml", eps="0.5", P="9*pi^2/4",
                             bounds=("-6*pi", "6*pi"),
                             extra="uz = [0.3, -9.0]\n")
    fast, full = _fast_and_whole(lambda: runfile.load(path), tmp_path, monkeypatch)
    for a, b in zip(fast, full):
        psi = np.array([p.params["psi"] for p in a.points if p.type != "UZ"])
        uz = [p.params["psi"] for p in a.points if p.type == "UZ"]
        crossed = sum(int(np.count_nonzero((psi[:-1] - v) * (psi[1:] - v) < 0))
                      for v in (0.3, -9.0))
        assert len(uz) == crossed > 0
        assert all(min(abs(v - 0.3), abs(v + 9.0)) <= 1e-12 for v in uz)
        assert [(p.type, round(p.params["psi"], 9)) for p in a.points if p.type] == \
            [(p.type, round(p.params["psi"], 9)) for p in b.points if p.type]


# ---- 5. the fold does not depend on the step size and converges in fold_tol -----------------

@pytest.fixture(scope="module")
def small_plan_file(tmp_path_factory):
    # One direction, three folds: psi up to LP1 ~ 0.817, down past LP2 ~ -7.10, up to LP3.
    return elastica_run_file(tmp_path_factory.mktemp("folds") / "folds.toml", directions="+",
                             bounds=("-4*pi", "4*pi"))


def _run_with(path, tmp_path, **options):
    plan = runfile.load(path)
    plan.options = dataclasses.replace(plan.options, **options)
    return run_plan(plan, tmp_path).result.branches[0]


def test_fold_location_does_not_depend_on_ds_max(small_plan_file, tmp_path):
    branches = {d: _run_with(small_plan_file, tmp_path / str(d), ds_max=d)
                for d in (0.1, 0.25, 0.5, 1.0)}
    npoints = {d: len(b.points) for d, b in branches.items()}
    assert len(set(npoints.values())) == len(npoints), npoints   # the runs did differ
    ref = [p.params["psi"] for p in branches[0.25].folds]
    assert len(ref) == 3
    for d, b in branches.items():
        psi = [p.params["psi"] for p in b.folds]
        np.testing.assert_allclose(psi, ref, rtol=0, atol=1e-8, err_msg=f"ds_max = {d}")


def test_fold_location_converges_as_fold_tol_shrinks(small_plan_file, tmp_path):
    P, eps = math.pi ** 2 / 4, 0.25
    errors = []
    exact = None
    for ft in (1e-5, 1e-6, 1e-7, 1e-8):
        folds = _run_with(small_plan_file, tmp_path / f"{ft:g}", fold_tol=ft).folds
        assert len(folds) == 3
        if exact is None:   # shooting at its tightest: DOP853 at rtol = atol = 1e-13
            exact = [shooting.fold(P, eps, f.ordinates["m0"], f.params["psi"], rtol=1e-13,
                                   atol=1e-13)[1] for f in folds]
        errors.append([abs(f.params["psi"] - e) for f, e in zip(folds, exact)])
    errors = np.array(errors)   # rows: fold_tol, columns: folds
    print("fold psi errors by fold_tol:\n", errors)
    # each tenfold tightening must reduce every fold's error ...
    assert np.all(errors[1:] < errors[:-1]), errors
    # ... and the tightest is well inside the 1e-8 claimed for the default fold_tol
    assert np.all(errors[-1] < 1e-9)


# ---- 7. no fold pair stepped over, no branch jumping -----------------------------------------

#: Near a cusp of the rotating-arm family at P = 9 pi^2 / 4 (eps_c = 0.3611139756, found by
#: shooting: where the fold condition's two roots in theta'(0) merge), at eps = 0.362 two folds
#: lie 8.5e-4 apart in psi with a stable sliver (index 1 -> 0 -> 1) between them; they recur,
#: mirrored, every 2 pi. The branch from the straight rod meets 17 folds in each direction
#: within |psi| <= 6 pi (a shooting scan of the fold condition over theta'(0)).
CUSP = dict(eps="0.362", P="9*pi^2/4", bounds=("-6*pi", "6*pi"))
#: The pair's width in psi by eps (shooting): it grows like 32.3 (eps - eps_c)^1.5.
GAPS = {"0.3612": 2.555434e-5, "0.3615": 2.436414e-4, "0.362": 8.515e-4}


def _cusp_folds(tmp_path, eps=CUSP["eps"], **options):
    tmp_path.mkdir(exist_ok=True)
    path = elastica_run_file(tmp_path / "cusp.toml", eps=eps, P=CUSP["P"], bounds=CUSP["bounds"])
    plan = runfile.load(path)
    # psi rising only: the falling branch is its mirror image, step for step
    plan.branches = [b for b in plan.branches if b.direction == 1]
    plan.options = dataclasses.replace(plan.options, **options)
    return run_plan(plan, tmp_path).result.branches


def _check_cusp(branches, eps=0.362, gap=GAPS["0.362"]):
    P = 9 * math.pi ** 2 / 4
    assert [len(b.folds) for b in branches] == [17]
    slivers = 0
    for b in branches:
        for p in b.folds:
            _, psi, _ = shooting.fold(P, eps, p.ordinates["m0"], p.params["psi"])
            assert abs(psi - p.params["psi"]) <= PSI_ATOL
        psi = np.array([p.params["psi"] for p in b.folds])
        close = np.flatnonzero(np.abs(np.diff(psi)) < 1e-3)     # the pairs, in travel order
        assert len(close) >= 4
        for k in close:
            assert abs(abs(psi[k + 1] - psi[k]) - gap) < 1e-6
            assert b.transition(b.folds[k]) == "1 -> 0"
            assert b.transition(b.folds[k + 1]) == "0 -> 1"
            slivers += 1
        assert b.disagreements == [] and b.warnings == []
    assert slivers >= 4


@pytest.mark.parametrize("eps", ["0.3612", "0.362"])
@pytest.mark.parametrize("ds_max", [1.0, 3.0])
def test_a_fold_pair_near_a_cusp_is_never_stepped_over(tmp_path, eps, ds_max):
    _check_cusp(_cusp_folds(tmp_path, eps=eps, ds_max=ds_max), float(eps), GAPS[eps])


def test_the_translate_check_alone_finds_the_fold_pairs(tmp_path, monkeypatch):
    """Without the probe of a dipping parameter slope, steps pass over some translates of the
    pair; the periodic translates of the folds that were found bring every missing one back.
    (Without the probe the translate check is all there is: where every translate of a pair
    is passed over, as at eps = 0.3615 with ds_max = 1, nothing brings it back.) The check
    compares periods computed apart, so the branches are computed whole here: a branch that
    repeats is otherwise its first period copied (`Walk._repeat`), and a pair its steps
    pass over is then missing from every copy, the probe being what finds it. In this
    process (jobs = 1): the patches of the kinds do not reach a cluster's
    workers."""
    from elastica_auto.branches import kinds, loops

    def patch(translates: bool):
        # the fold kind's probe of a dipping slope (`Fold.detect`) never starts
        monkeypatch.setattr(kinds, "pair_suspected", lambda step, dip=0.5: None)
        monkeypatch.setattr(loops.Period, "begin", lambda self, walk, course: None)
        if not translates:  # nor its search for folds at their translates after the walk
            monkeypatch.setattr(kinds.Fold, "finish", lambda self, walk: None)

    patch(translates=False)
    missed = _cusp_folds(tmp_path / "without", ds_max=1.0)
    assert all(len(b.folds) < 17 for b in missed), "choose a case where pairs are missed"
    monkeypatch.undo()
    patch(translates=True)
    _check_cusp(_cusp_folds(tmp_path / "with", ds_max=1.0))


def test_the_rotating_arm_folds_do_not_depend_on_ds_max(tmp_path):
    """From tiny steps to steps longer than the folds' spacing: the same 15 folds of the
    rotating arm at eps = 0.5 (both loads, the closest-spaced folds of the run; psi rising
    only, the other direction being its mirror image), equal to 1e-9, and the fold rule and
    direct count agree everywhere (no jump between branches)."""
    folds = {}
    for ds_max in (0.1, 1.0, 3.0):
        plan = runfile.load(REPO / "runs" / "rotating_arm.toml")
        plan.branches = [b for b in plan.branches
                         if b.params["eps"] == 0.5 and b.direction == 1]
        plan.options = dataclasses.replace(plan.options, ds=min(0.05, ds_max), ds_max=ds_max,
                                           max_points=20000)
        plan.user_values = []
        branches = run_plan(plan, tmp_path / str(ds_max)).result.branches
        assert [len(b.folds) for b in branches] == [5, 10]
        for b in branches:
            assert b.disagreements == [] and b.warnings == [] and b.end == "EP"
        folds[ds_max] = np.concatenate([[p.params["psi"] for p in b.folds] for b in branches])
    for ds_max, psi in folds.items():
        np.testing.assert_allclose(psi, folds[0.1], rtol=0, atol=1e-9, err_msg=str(ds_max))
