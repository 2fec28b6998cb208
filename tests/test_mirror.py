"""A branch from a symmetric start taken as the mirror image of the other direction's
(`elastica_auto.branches.mirror`), checked against what does not use the mirror:

* each module's declared ``MIRROR`` against the equations: at a state away from every
  symmetry, the image solves the mirrored problem (the collocation residual and the boundary
  conditions as small as the state's own), every ordinate has the declared sign, and the
  index (a direct count at the image) is the same;
* the image against the ``-`` branch computed (``mirror = false``): the same labels in the
  same order, with their parameters, ordinates and index; and against the ``-`` branch
  computed along the course the ``+`` branch was computed along (`mirror_course`), every
  point to rounding;
* the ``+`` branch bit for bit the one computed without the mirror;
* where the mirror does not apply (bounds not symmetric, a start that is not its own
  image, a module without MIRROR, a declaration the check refuses), the ``-`` branch is
  computed.
"""

from __future__ import annotations

import math
import signal
import subprocess

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.core.solution import State
from elastica_auto.numerics import stability

ARM = {"eps": 0.25, "P": math.pi ** 2 / 4, "psi": 0.0, "alpha": 0.0, "theta0": 0.0}
#: UZ values that are not the negatives of one another: the + branch locates their
#: negatives too, and each branch keeps the values asked for
UZ = [0.0, math.pi / 12, math.pi / 2]


@pytest.fixture(scope="module")
def planar():
    return ea.load_problem("elastica_lever_arm")


@pytest.fixture(scope="module")
def rod():
    return ea.load_problem("kirchhoff_lever_arm")


def _generic(problem, params, moves):
    """A state away from every mirror: the straight rod at ``params``, continued in each
    parameter of ``moves`` to its value in turn (a UZ point there)."""
    start = params
    for name, value in moves:
        lo, hi = sorted((0.0, value))
        branches = ea.continuation(problem, start, name, bounds=(lo - 0.1, hi + 0.1),
                                   uz=[value], directions="both", max_points=80, mirror=False)
        (start,) = [br.label(p.name) for br in branches for p in br.points if p.type == "UZ"]
    return start.state


@pytest.mark.parametrize("name, params, moves", [
    ("elastica_lever_arm", {**ARM, "eps": 0.5, "P": 9 * math.pi ** 2 / 4},
     [("psi", 0.7), ("alpha", 0.3), ("theta0", -0.4)]),
    ("kirchhoff_lever_arm", {**ARM, "b2": 2.0},
     [("psi", 0.5), ("chi", 0.4), ("beta", 0.2), ("phi0", 0.3), ("u3", 0.3), ("u1", 0.2)]),
])
def test_the_declared_mirror_maps_solutions_to_solutions(name, params, moves):
    problem = ea.load_problem(name)
    state = _generic(problem, params, moves)
    rows, signs, mirror = problem.mirror
    y, p = problem.mirrored(state.y, state.params)
    yp, _ = problem.mirrored(state.yp, {})
    assert all(p[k] == -state.params[k] for k in mirror.parameters)
    assert any(state.params[k] != 0 for k in mirror.parameters)

    def residual(y, yp, p):
        return max(np.max(np.abs(yp - problem.rhs(state.s, y, p))),
                   np.max(np.abs(problem.bc(y[:, 0], y[:, -1], p))))

    assert residual(y, yp, p) <= max(2 * residual(state.y, state.yp, state.params), 1e-11)
    before = problem.ordinate_values(state.s, state.y, state.params)
    after = problem.ordinate_values(state.s, y, p)
    odd = [k for k in before if abs(before[k]) > 1e-3 and k in mirror.ordinates]
    assert len(odd) >= 3
    for k, v in before.items():
        want = -v if k in mirror.ordinates else v
        assert after[k] == pytest.approx(want, abs=1e-12, rel=1e-12), k
    image = State(state.s, y, yp, p)
    assert stability.index(problem, image) == stability.index(problem, state)
    # the shooting unknowns: the image's initial values are those of k turned by the signs
    k = np.array([[0.7, -1.3, 2.1], [-0.4, 0.9, 1.6]])[: len(mirror.shooting)]
    signs = np.array(mirror.shooting)[:, None]
    _, _, initial, _ = problem.shooting(state.params)
    _, _, initial_image, _ = problem.shooting(p)
    y0, _ = problem.mirrored(initial(k if len(k) > 1 else k[0]), {})
    np.testing.assert_allclose(initial_image(signs * k if len(k) > 1 else -k[0]), y0,
                               rtol=0, atol=1e-14)


def _labels(br):
    return [(p.type, p.index) for p in br.points if p.type]


def _both(problem, params, mirror):
    return ea.continuation(problem, params, "psi", bounds=(-2 * math.pi, 2 * math.pi),
                           directions="both", uz=UZ, mirror=mirror)


@pytest.fixture(scope="module")
def arm_runs(planar):
    return _both(planar, ARM, True), _both(planar, ARM, False)


def test_the_minus_branch_is_the_mirror_image_of_the_plus_one(planar, arm_runs):
    """The image against the - branch computed: the same labels, in order, at the same
    parameter values (to 1e-12) with the same ordinates (to 1e-8: the folds are located to
    fold_tol) and index; the UZ labels at the values asked for, not at their negatives."""
    (plus, image), (plus0, minus) = arm_runs
    assert image.worker.startswith("mirror of") and minus.worker == "local"
    assert len(image.folds) >= 1 and {p.index for p in image.points} >= {0, 1}
    assert _labels(image) == _labels(minus)
    for a, b in zip(image.labelled, minus.labelled):
        for k in a.params:
            assert a.params[k] == pytest.approx(b.params[k], abs=1e-12), k
        for k in a.ordinates:
            assert a.ordinates[k] == pytest.approx(b.ordinates[k], abs=1e-8), k
    uz = [p.params["psi"] for p in image.points if p.type == "UZ"]
    assert len(uz) >= 3 and all(_asked(v) for v in uz)
    assert image.end == minus.end == "EP" and image.message == minus.message


def _asked(psi) -> bool:
    return any(abs(psi - v - 2 * math.pi * j) < 1e-9 for v in UZ for j in (-1, 0, 1))


def test_the_snap_back_targets_at_the_image_are_those_scanned_there(arm_runs):
    """The rows at the image's folds, made from the + branch's scans, against those of the
    run that scanned there: the same targets, their shooting values and ordinates within the
    scan's root accuracy (7e-9 (1 + |k|), `analysis.equilibria`)."""
    (mirrored, computed) = (run.snaps for run in arm_runs)
    assert len(mirrored) == len(computed) and any(r["branch"] == 2 for r in mirrored)
    for a, b in zip(mirrored, computed):
        assert (a["lp"], a["branch"], a["index"], a["on_branch"]) == \
            (b["lp"], b["branch"], b["index"], b["on_branch"])
        for name in a:
            if name.startswith("target_") or name in ("k", "value"):
                assert a[name] == pytest.approx(b[name], abs=1e-7), name


def test_a_fold_s_image_by_a_period_is_made_from_the_scan_there(planar, monkeypatch):
    """One branch through three periods: LP1 at psi = 0.817 and LP2 at -7.100, the image of
    LP1 moved by -2 pi (psi's period leaves the states as they are). LP2's rows are made
    from LP1's scan, mirrored: half the enumerations of the run without the mirror, and
    the same rows as it, its targets, shooting values and ordinates within the scan's root
    accuracy (7e-9 (1 + |k|))."""
    import elastica_auto.analysis.snaps as snaps

    scanned = []
    enumerate_equilibria = snaps.enumerate_equilibria

    def counted(problem, params):
        scanned.append(params["psi"])
        return enumerate_equilibria(problem, params)
    monkeypatch.setattr(snaps, "enumerate_equilibria", counted)
    runs = {}
    for mirror in (True, False):
        scanned.clear()
        run = ea.continuation(planar, ARM, "psi", bounds=(-3 * math.pi, 3 * math.pi),
                              directions="+", mirror=mirror)
        assert len(run) == 1
        runs[mirror] = (run.snaps, list(scanned))
    (mirrored, once), (computed, twice) = runs[True], runs[False]
    assert len(twice) >= 2 and len(once) == len(twice) // 2
    lps = {r["lp"]: r["value"] for r in computed}
    assert any(abs(v + lps["LP1"] + 2 * math.pi) < 1e-9 for v in lps.values())
    assert len(mirrored) == len(computed)
    for a, b in zip(mirrored, computed):
        assert (a["lp"], a["index"], a["on_branch"]) == (b["lp"], b["index"], b["on_branch"])
        for name in a:
            if name.startswith("target_") or name in ("k", "value"):
                assert a[name] == pytest.approx(b[name], abs=1e-7), name


@pytest.mark.parametrize("module", ["elastica_lever_arm", "kirchhoff_lever_arm"])
def test_only_a_period_that_leaves_the_states_makes_copies(module):
    """psi's period changes no state: psi and psi + 2 pi have one `copy_key`. theta0's turns
    the clamp and with it the states (the planar theta by 2 pi, the rod's quaternion to
    -q): its copies keep their own keys."""
    from elastica_auto.analysis.snaps import copy_key

    problem = ea.load_problem(module)
    p = {**problem.defaults(), "psi": 0.8, "theta0": 0.3}
    assert copy_key(problem, "psi", p) == copy_key(problem, "psi", {**p, "psi": 0.8 - 4 * math.pi})
    assert copy_key(problem, "psi", p) != copy_key(problem, "psi", {**p, "psi": 0.9})
    moved = {**p, "theta0": 0.3 + 2 * math.pi}
    assert copy_key(problem, "theta0", p) != copy_key(problem, "theta0", moved)


def test_the_plus_branch_is_the_one_computed_without_the_mirror(arm_runs):
    (plus, _), (plus0, _) = arm_runs
    assert len(plus.points) == len(plus0.points) and not plus.mirror_points
    for a, b in zip(plus.points, plus0.points):
        assert (a.type, a.index, a.params, a.ordinates, a.arclength) == \
            (b.type, b.index, b.params, b.ordinates, b.arclength)
        np.testing.assert_array_equal(a.profile, b.profile)


def test_the_image_is_the_minus_branch_computed_along_the_plus_branch_course(planar, arm_runs):
    """Computed with the negatives of the UZ values added (the + branch's course) and the
    points there left out, the - branch is the image point for point, to rounding."""
    (_, image), _ = arm_runs
    both = sorted(set(UZ) | {-v for v in UZ})
    (_, minus) = ea.continuation(planar, ARM, "psi", bounds=(-2 * math.pi, 2 * math.pi),
                                 directions="both", uz=both, mirror=False)
    kept = [p for p in minus.points if p.type != "UZ" or _asked(p.params["psi"])]
    assert len(kept) == len(image.points)
    for a, b in zip(image.points, kept):
        assert (a.type, a.index) == (b.type, b.index)
        assert max(abs(a.params[k] - b.params[k]) for k in a.params) < 1e-12
        assert np.max(np.abs(a.profile - b.profile)) < 1e-12
        if a.state is not None:   # (a fold's refined mesh may place its nodes apart)
            assert np.max(np.abs(a.state.y - b.state(a.state.s))) < 1e-12
            assert a.tangent.lam == pytest.approx(b.tangent.lam, abs=1e-12)


def test_the_spatial_rods_minus_branch_is_a_mirror_image(rod):
    """b2 = 2 through its first folds on both sides: the image's labels, index and the split
    index are the computed - branch's."""
    params = {**ARM, "b2": 2.0}
    kw = dict(bounds=(-2.0, 2.0), directions="both", uz=[0.5])
    (_, image), (_, minus) = (ea.continuation(rod, params, "psi", mirror=m, **kw)
                              for m in (True, False))
    assert image.worker.startswith("mirror of") and minus.worker == "local"
    assert len(image.folds) == 1 and _labels(image) == _labels(minus)
    for a, b in zip(image.labelled, minus.labelled):
        assert a.params["psi"] == pytest.approx(b.params["psi"], abs=1e-12)
        for k in ("m1", "mz1", "twist", "index_in", "index_out", "z1"):
            assert a.ordinates[k] == pytest.approx(b.ordinates[k], abs=1e-8), k


@pytest.mark.parametrize("change", ["bounds", "start", "module", "declaration"])
def test_where_the_mirror_does_not_apply_the_minus_branch_is_computed(tmp_path, planar, change):
    problem, params, bounds = planar, ARM, (-2.0, 2.0)
    if change == "bounds":
        bounds = (-2.0, 2.5)
    elif change == "start":                   # the straight rod along a tilted load
        params = {**ARM, "alpha": 0.3, "theta0": 0.3}
    elif change == "module":
        problem = ea.load_problem(_copy(tmp_path, planar, drop=True))
    else:                                     # mA is odd, declared even: the check refuses
        problem = ea.load_problem(_copy(tmp_path, planar, drop=False))
    plus, minus = ea.continuation(problem, params, "psi", bounds=bounds, directions="both",
                                  uz=UZ)
    assert plus.worker == minus.worker == "local"
    assert minus.end == "EP" and len(minus.points) > 20


def _copy(tmp_path, planar, drop: bool) -> str:
    """The planar module without its MIRROR, or with mA left out of the odd ordinates."""
    text = open(planar.module.__file__).read()
    old, new = (("MIRROR = Mirror(", "_NOT_A_MIRROR = Mirror(") if drop
                else ('("m1", "mA", "m0"), shooting', '("m1", "m0"), shooting'))
    assert text.count(old) == 1
    text = text.replace(old, new)
    path = tmp_path / ("plain.py" if drop else "wrong.py")
    path.write_text(text)
    return str(path)


def test_mirror_is_a_boolean_option(planar):
    with pytest.raises(ea.PlanError, match="mirror must be true or false"):
        ea.continuation(planar, ARM, "psi", bounds=(-1, 1), mirror=1)


def test_a_signal_while_the_image_is_checked_ends_the_run_there(tmp_path, cli_exe):
    """The check calls the module at the image's labelled points: a module that holds there
    (a copy of the elastica that holds its first call beyond |psi| = 1 once the first branch
    is saved) is interrupted like a step: exit 130, the first branch whole, the second
    ending MX at once, interrupted."""
    from elastica_auto.storage.store import BranchFile
    from helpers import elastica_run_file, signalling_elastica, wait_for
    out, held = tmp_path / "out", tmp_path / "held"
    run = elastica_run_file(tmp_path / "two.toml", uz=[0])
    run.write_text(run.read_text().replace('"elastica_lever_arm"', '"mine.py"'))
    signalling_elastica(tmp_path / "mine.py", hold=(
        f'abs(p["psi"]) > 1 and _os.path.exists({str(out / "two.h5")!r})', held))
    proc = subprocess.Popen([cli_exe, "run", str(run), "--out", str(out), "-j", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for("the image's check", held.exists, proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    first, second = BranchFile(out / "two.h5").branches
    assert first.attrs["end"] == "EP" and second.attrs["end"] == "MX"
    assert second.attrs["message"] == "interrupted by the user"
    assert len(second.columns["psi"]) <= 2          # its start, and at most one step


def test_a_fold_stop_is_mirrored_too(planar):
    """stop = LP2 (the n-th fold along the branch, which the image meets in the same
    order): the image ends at its second fold as the computed - branch does."""
    kw = dict(bounds=(-4 * math.pi, 4 * math.pi), directions="both", uz=UZ, stop=["LP2"])
    (_, image), (_, minus) = (ea.continuation(planar, ARM, "psi", mirror=m, **kw)
                              for m in (True, False))
    assert image.worker.startswith("mirror of") and minus.worker == "local"
    assert image.end == minus.end == "LP" and image.message == minus.message
    assert len(image.folds) == 2 and _labels(image) == _labels(minus)
    for a, b in zip(image.labelled, minus.labelled):
        assert a.params["psi"] == pytest.approx(b.params["psi"], abs=1e-12)
