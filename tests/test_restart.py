"""Restarts: continuing a different parameter from a labelled solution of an earlier run, at its
parameter values or at changed ones."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import elastica_auto as ea
import shooting
from helpers import elastica_run_file, invariant, invariant_bound, run_cli, run_plan
from elastica_auto.execution import runfile
from elastica_auto.core.errors import StartError
from elastica_auto.storage.store import BranchFile


def _restart_toml(path, start, directions="both", bounds=("0", "1")):
    path.write_text(f'description = "eps from a psi-run label"\n'
                    f'equation = "elastica_lever_arm"\nstart = "{start}"\n'
                    f'[continuation]\nparameter = "eps"\ndirections = "{directions}"\n'
                    f'bounds = ["{bounds[0]}", "{bounds[1]}"]\n')
    return path


@pytest.fixture(scope="module")
def restart_run(small_cli_run, cli_exe, tmp_path_factory):
    """start = "small.h5:UZ3", resolved relative to --out (the run file lives elsewhere)."""
    out, h5, proc = small_cli_run
    assert proc.returncode == 0, proc.stderr
    here = tmp_path_factory.mktemp("restart_toml")
    toml = _restart_toml(here / "restart.toml", "small.h5:UZ3")
    rproc = run_cli(cli_exe, "run", toml, "--out", out)
    return BranchFile(h5), out / "restart.h5", rproc


def test_restart_runs_and_starts_at_the_stored_solution(restart_run):
    src, path, proc = restart_run
    assert proc.returncode == 0, proc.stderr
    uz3 = src.label("UZ3").state
    rf = BranchFile(path)
    assert len(rf.branches) == 2
    grid = rf.profile_grid
    for b in rf.branches:
        assert b.parameter == "eps"
        c = b.columns
        first = {k: float(c[k][0]) for k in rf.parameters}
        assert first == uz3.params          # exactly the stored parameters
        # and the stored solution itself (same state, merely resampled on the profile grid)
        np.testing.assert_allclose(b.profiles[0], uz3(grid), rtol=0, atol=1e-12)
        # only eps moves
        for k in ("P", "psi", "alpha", "theta0"):
            assert np.all(c[k] == uz3.params[k])
        assert np.ptp(c["eps"]) > 0.1


def test_restarted_solutions_conserve_the_moment_invariant(restart_run):
    _, path, proc = restart_run
    assert proc.returncode == 0
    rf = BranchFile(path)
    for name in rf.labels:
        st = rf.label(name).state
        opt = json.loads(rf.branches[rf.labels[name][0] - 1].attrs["options"])
        tol = opt["fold_tol"] if name.startswith("LP") else opt["tol"]
        assert np.ptp(invariant(st.y, st.params)) <= invariant_bound(tol, st.params["P"],
                                                                      st.params["alpha"])


def test_restart_from_a_missing_label_is_a_user_error(small_cli_run, cli_exe, tmp_path):
    out, _, _ = small_cli_run
    toml = _restart_toml(tmp_path / "restart_bad.toml", "small.h5:UZ999")
    proc = run_cli(cli_exe, "run", toml, "--out", out)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "UZ999" in proc.stderr


# ---- the eps-branch through psi = pi/6, against the shooting graph eps(k0) -------------------

P = math.pi ** 2 / 4
PSI = math.pi / 6


def _eps_of_k0(k0):
    """With P, psi fixed, r(k0, eps) = kappa(1) + eps P sin(psi - theta(1)) = 0 is linear in eps:
    the solutions form the graph eps(k0) = -kappa(1) / (P sin(psi - theta(1))), which has poles
    (eps -> +-inf) where sin(psi - theta(1)) = 0. Returns (eps, sin(psi - theta(1)))."""
    th1, k1, _, _ = shooting.integrate(P, 0.0, 0.0, k0)
    s = math.sin(PSI - th1)
    return -k1 / (P * s), s


def test_eps_branch_follows_the_solution_curve(small_cli_run, tmp_path):
    out, h5, _ = small_cli_run
    src = BranchFile(h5)
    # the psi = pi/6 solution past the first fold (m1 > 0.3), whatever its label number
    name = next(n for n in src.labels if n.startswith("UZ")
                and src.label(n).state.params["psi"] == pytest.approx(PSI, abs=1e-12)
                and src.label(n).state.y[1, -1] > 0.3)
    toml = _restart_toml(tmp_path / "eps_down.toml", f"small.h5:{name}", directions="-",
                         bounds=("-1", "1"))
    br = run_plan(runfile.load(toml, out_dir=out), tmp_path).result.branches[0]
    k0 = np.array([p.ordinates["m0"] for p in br.points])
    eps = np.array([p.params["eps"] for p in br.points])
    # every point is a solution: on the graph eps(k0)
    for k, e in zip(k0, eps):
        assert _eps_of_k0(k)[0] == pytest.approx(e, abs=1e-4)
    # consecutive points are joined by the graph: no pole between them
    for a, b in zip(k0[:-1], k0[1:]):
        signs = {np.sign(_eps_of_k0(k)[1]) for k in np.linspace(a, b, 40)}
        assert len(signs) == 1, f"the step from k0 = {a:.4f} to {b:.4f} crosses a pole"
    # every LP is an extremum of eps(k0)
    for p in br.folds:
        k, e = p.ordinates["m0"], p.params["eps"]
        side = [_eps_of_k0(k + d)[0] - e for d in (-0.02, 0.02)]
        assert side[0] * side[1] > 0, f"LP at eps = {e:.3g}, k0 = {k:.3g} is no extremum"


# ---- restarts at a fold and at a branch point, in both directions ------------------------------

def _both_ways(path, start, parameter, bounds):
    path.write_text(f'description = "{parameter} both ways from {start}"\n'
                    f'equation = "elastica_lever_arm"\nstart = "{start}"\n'
                    f'[continuation]\nparameter = "{parameter}"\ndirections = "both"\n'
                    f'bounds = ["{bounds[0]}", "{bounds[1]}"]\n')
    return path


def _run_ok(cli_exe, toml, out):
    proc = run_cli(cli_exe, "run", toml, "--out", out, "-j", "1")
    assert proc.returncode == 0, proc.stderr
    return BranchFile(out / f"{toml.stem}.h5")


def test_restart_from_a_fold_in_both_directions(tmp_path, cli_exe):
    """start = "FILE.h5:LP1" with directions = "both": the parameter is stationary at a fold,
    so only the tangent stored with the label tells the two ways apart (+ on along the way the
    run passed the fold, - back); each leaves on its side of the fold, with that side's
    index, and neither ends MX (without the stored tangent the start is singular)."""
    out = tmp_path / "out"
    src = _run_ok(cli_exe, elastica_run_file(tmp_path / "psi.toml", bounds=("-pi", "pi")), out)
    k, pt = src.labels["LP1"]
    c = src.branches[k - 1].columns
    lp = src.label("LP1").state
    m1 = c["m1"][pt - 1]
    before, after = (int(i) for i in c["transition"][pt - 1].split(" -> "))
    assert {before, after} == {0, 1}                      # LP1 1 -> 0 of this run
    assert (c["m1"][pt - 2] - m1) * (c["m1"][pt] - m1) < 0  # m1 is monotone through the fold
    rf = _run_ok(cli_exe, _both_ways(tmp_path / "from_lp.toml", "psi.h5:LP1", "psi",
                                     ("-pi", "pi")), out)
    assert [b.attrs["direction"] for b in rf.branches] == [1, -1]
    for b, neighbour, index in zip(rf.branches, (pt, pt - 2), (after, before)):
        bc = b.columns
        assert b.attrs["end"] == "EP" and "MX" not in list(bc["type"]), b.attrs["message"]
        assert {q: float(bc[q][0]) for q in rf.parameters} == lp.params
        # psi turns at the fold: it moves away on both sides the same way, as in the source
        assert (bc["psi"][1] - lp.params["psi"]) * (c["psi"][pt] - lp.params["psi"]) > 0
        # on the side of the source's neighbour, with its index (the fold rule's)
        assert (bc["m1"][1] - m1) * (c["m1"][neighbour] - m1) > 0
        assert bc["index"][1] == index and bc["index"][-1] >= 0


def test_restart_from_a_branch_point_in_both_directions(tmp_path, cli_exe):
    """start = "FILE.h5:BP1" (not switch) with directions = "both": both ways along the straight
    rod, the branch the run was on, with index 0 below the first critical load and 1 above."""
    out = tmp_path / "out"
    rod = tmp_path / "rod.toml"
    rod.write_text('description = "the straight rod"\nequation = "elastica_lever_arm"\n'
                   'start = "trivial"\n[parameters]\neps = 0.25\nP = 0\npsi = 0\nalpha = 0\n'
                   'theta0 = 0\n[continuation]\nparameter = "P"\ndirections = "+"\n'
                   'bounds = [-1, 5]\n')
    src = _run_ok(cli_exe, rod, out)
    bp = src.label("BP1").state
    assert bp.params["P"] == pytest.approx(1.5991918, abs=1e-6)
    k, pt = src.labels["BP1"]
    assert src.branches[k - 1].columns["transition"][pt - 1] == "0 -> 1"
    rf = _run_ok(cli_exe, _both_ways(tmp_path / "from_bp.toml", "rod.h5:BP1", "P", ("-1", "5")),
                 out)
    assert [b.attrs["direction"] for b in rf.branches] == [1, -1]
    for b, end, index in zip(rf.branches, (5.0, -1.0), (1, 0)):
        bc = b.columns
        assert b.attrs["end"] == "EP" and "MX" not in list(bc["type"]), b.attrs["message"]
        assert {q: float(bc[q][0]) for q in rf.parameters} == bp.params
        assert bc["P"][-1] == pytest.approx(end)
        assert np.all(np.sign(np.diff(bc["P"])) == np.sign(end - bp.params["P"]))
        assert np.max(np.abs(bc["m0"])) < 1e-9 and np.max(np.abs(bc["m1"])) < 1e-9   # straight
        assert np.all(bc["index"][1:] == index)


# ---- restarts at changed parameter values: the label continued to them --------------------------
# Checked against the shooting solver (tests/shooting.py, no elastica_auto code): the start is an
# equilibrium at exactly the new values, next to the label, and exists exactly where shooting
# finds equilibria next to the label.

P2 = 9 * math.pi ** 2 / 4


@pytest.fixture(scope="module")
def cusps(rotating_arm, elastica):
    """The four CP labels of the fold curves through rotating_arm's folds at eps = 0.5,
    P = 9 pi^2/4, psi = 4.7695 and 1.5137 (as tests/test_codim2.py's cusp_curves): two mirror
    pairs, at eps = 0.3611 and 0.2114."""
    bf = BranchFile(rotating_arm.result.path)
    starts = [bf.label(n) for n in bf.labels if n.startswith("LP")]
    starts = [x for x in starts if x.state.params["eps"] == 0.5
              and abs(x.state.params["P"] - P2) < 1e-9
              and min(abs(x.state.params["psi"] - v) for v in (4.7695, 1.5137)) < 1e-3]
    curves = ea.continuation(elastica, starts, ["psi", "eps"], bounds=(0.2, 0.5), directions="-")
    labels = [curves.label(p.name) for b in curves for p in b.points if p.type == "CP"]
    assert len(labels) == 4
    return labels


@pytest.fixture(scope="module")
def folds(rotating_arm):
    """The first LP label of rotating_arm at each of its four (eps, P), with the side of the
    fold (+1, -1) on which the branch lies in psi (that of the points next to it)."""
    bf = BranchFile(rotating_arm.result.path)
    out = {}
    for name in sorted(bf.labels, key=lambda n: bf.labels[n]):
        if name.startswith("LP"):
            k, pt = bf.labels[name]
            label = bf.label(name)
            psi = bf.branches[k - 1].columns["psi"]
            side = np.sign(psi[pt] - psi[pt - 1])
            assert side == np.sign(psi[pt - 2] - psi[pt - 1])    # psi turns there
            out.setdefault((label.state.params["eps"], label.state.params["P"]), (label, side))
    assert len(out) == 4
    return list(out.values())


def _start(elastica, label, params, parameter, **options):
    """The start of a restart from ``label`` at ``params`` continued in ``parameter``: the
    first point of its branch."""
    (branch,) = ea.continuation(elastica, label, parameter, params=params, max_points=2,
                                **options)
    return branch.points[0]


def _psi_error(state) -> float:
    """How far psi is from one at which the state is an equilibrium, by shooting from its own
    theta(0), kappa(0): the free-end residual r = kappa(1) + eps P sin(psi + alpha - theta(1))
    over dr/dpsi."""
    p = state.params
    th1, k1, _, _ = shooting.integrate(p["P"], p["alpha"], state.y[0, 0], state.y[1, 0])
    a = p["psi"] + p["alpha"] - th1
    return abs(k1 + p["eps"] * p["P"] * math.sin(a)) / abs(p["eps"] * p["P"] * math.cos(a))


def _assert_equilibrium(point, params, psi_error=1e-9):
    """``point`` is at exactly ``params``, and its state is an equilibrium there: shot from its
    own theta(0), kappa(0), the IVP reproduces the whole state, and its psi is within
    ``psi_error`` of one where it is exact (by default a hundred times below the smallest
    change tested, 1e-7)."""
    assert point.params == params
    st = point.state
    p = st.params
    np.testing.assert_allclose(shooting.profile(p["P"], p["alpha"], st.y[:, 0], st.s), st.y,
                               rtol=0, atol=1e-7)
    assert _psi_error(st) <= psi_error


def _distance(point, label) -> float:
    """The rms distance between the start and the label's solution, on the label's mesh."""
    s, y = label.state.s, label.state.y[:4]
    return float(np.sqrt(np.mean((point.state(s) - y) ** 2)))


def _roots_beside(label, params, change):
    """The equilibria at ``params`` next to the fold ``label``, by shooting: the roots of
    r(kappa(0)) on either side of the fold's kappa(0), within 10 sqrt(|change|) of it (at a
    fold they are about sqrt(|change|) away); none if r has one sign there (no equilibria
    on this side of the fold)."""
    k0 = label.state.y[1, 0]

    def r(k):
        return shooting.residual(k, params["psi"], params["P"], params["eps"], params["alpha"],
                                 params["theta0"])[0]

    w = 10 * math.sqrt(abs(change))
    lo, mid, hi = r(k0 - w), r(k0), r(k0 + w)
    if lo * mid > 0 and mid * hi > 0:
        return []
    assert lo * mid < 0 and mid * hi < 0
    return [brentq(r, k0 - w, k0, xtol=1e-15), brentq(r, k0, k0 + w, xtol=1e-15)]


@pytest.mark.parametrize("sign", [1, -1])
@pytest.mark.parametrize("q, parameter", [("psi", "eps"), ("eps", "psi")])
def test_a_restart_from_a_cusp_at_changed_values_reaches_both_sides(cusps, elastica, q,
                                                                   parameter, sign):
    """At a cusp the Jacobian is singular (a Newton solve at the new values fails there, even
    1e-7 away); psi and eps at the other fixed pass through it, so both sides are reached:
    an equilibrium at exactly the new values, moved from the label by a root of the change
    of order above two: 1e4 times the change moves it 5 to 50 times as far (a cube root,
    the cusp's normal form lam ~ x^3, gives 21.5; a fold's square root would give 100)."""
    for label in cusps:
        moved = []
        for change in (sign * 1e-7, sign * 1e-3):
            params = {**label.state.params, q: label.state.params[q] + change}
            point = _start(elastica, label, {q: params[q]}, parameter)
            _assert_equilibrium(point, params)
            moved.append(_distance(point, label))
            assert 0.03 <= moved[-1] / abs(change) ** (1 / 3) <= 3, label.name
        assert 5 <= moved[1] / moved[0] <= 50, (label.name, moved)


@pytest.mark.parametrize("change", [1e-7, -1e-7, 1e-3, -1e-3])
@pytest.mark.parametrize("q, parameter", [("psi", "eps"), ("eps", "psi"), ("P", "eps")])
def test_a_restart_from_a_fold_at_changed_values_reaches_its_side(folds, elastica, q,
                                                                 parameter, change):
    """At an LP the solutions at a changed value lie on one side of the fold only: there the
    restart is one of the two equilibria shooting finds next to the fold (at exactly the new
    values); on the other side it is refused, naming the parameter and the fold. In psi, the
    side is the branch's."""
    for label, side in folds:
        params = {**label.state.params, q: label.state.params[q] + change}
        roots = _roots_beside(label, params, change)
        if q == "psi":
            assert bool(roots) == (np.sign(change) == side), label.name
        if not roots:
            with pytest.raises(StartError, match=f"{q} = .* not reached .* turns back at "
                                                 f"{q} = .* \\(a fold\\)"):
                _start(elastica, label, {q: params[q]}, parameter)
            continue
        point = _start(elastica, label, {q: params[q]}, parameter)
        _assert_equilibrium(point, params)
        k0 = point.state.y[1, 0]
        assert min(abs(k0 - r) for r in roots) <= 0.01 * abs(roots[1] - roots[0]), label.name


def test_a_restart_at_changed_values_is_the_user_point_of_a_plain_continuation(
        cusps, folds, rotating_arm, elastica):
    """Another route to the same solution: a continuation in the changed parameter from the
    label, both ways, with a user point at the new value (UZ). The restart's start is that
    UZ point, at the same tol; from a fold, where both ways reach it, the one nearer in
    arclength. From an ordinary label (a UZ of the run), too."""
    bf = BranchFile(rotating_arm.result.path)
    cases = [(cusps[0], "psi", 1e-7), (cusps[1], "eps", -1e-3),
             *[(label, "psi", side * d) for label, side in folds[:2] for d in (1e-7, 1e-3)],
             (bf.label("UZ3"), "P", 0.1), (bf.label("UZ41"), "psi", -1e-3)]
    for label, q, change in cases:
        c = label.state.params
        value = c[q] + change
        point = _start(elastica, label, {q: value}, "alpha", tol=1e-7)
        plain = ea.continuation(elastica, label, q, uz=[value], directions="both",
                                bounds=(c[q] - 2 * abs(change), c[q] + 2 * abs(change)),
                                tol=1e-7)
        uz = min((p for b in plain for p in b.points if p.type == "UZ"),
                 key=lambda p: p.arclength)
        assert uz.params == point.params == {**c, q: value}
        np.testing.assert_allclose(uz.state(point.state.s), point.state.y, rtol=0, atol=1e-10,
                                   err_msg=label.name)


def test_a_restart_by_whole_periods_is_the_labels_translate(folds, rotating_arm, elastica):
    """psi (period 2 pi) changed by whole periods: the solution set repeats, so the start is
    the label's own solution at the new psi, also at a fold (where Newton does not start, and
    a continuation over a period would pass other folds); 1e-7 beyond a fold's translate, on
    the branch's side: an equilibrium there, as next to the fold. theta0 by 2 pi: the clamp
    turned once, the same rod with theta + 2 pi."""
    label, side = folds[0]
    c, s = label.state.params, label.state.s
    for change in (2 * math.pi, -4 * math.pi, -2 * math.pi + side * 1e-7):
        params = {**c, "psi": c["psi"] + change}
        point = _start(elastica, label, {"psi": params["psi"]}, "eps")
        _assert_equilibrium(point, params)
        if change == round(change / math.pi) * math.pi:
            np.testing.assert_allclose(point.state(s), label.state.y, rtol=0, atol=1e-12)
        else:
            roots = _roots_beside(label, params, 1e-7)
            assert min(abs(point.state.y[1, 0] - r) for r in roots) \
                <= 0.01 * abs(roots[1] - roots[0])
    uz = BranchFile(rotating_arm.result.path).label("UZ3")
    params = {**uz.state.params, "theta0": uz.state.params["theta0"] + 2 * math.pi}
    point = _start(elastica, uz, {"theta0": params["theta0"]}, "eps")
    _assert_equilibrium(point, params, 2 * _psi_error(uz.state))   # as exact as the label
    turned = point.state(uz.state.s) - uz.state.y
    np.testing.assert_allclose(turned, np.outer([2 * math.pi, 0, 0, 0], np.ones(len(uz.state.s))),
                               rtol=0, atol=1e-8)


def test_a_restart_past_a_fold_says_which_parameter_and_where_it_turned(folds, elastica):
    """psi moved off a fold to the side without solutions: a one-line StartError with the
    parameter, the value asked for, and where the continuation turned back (the fold)."""
    label, side = folds[0]
    psi = label.state.params["psi"]
    value = psi - side * 1e-3
    with pytest.raises(StartError) as exc:
        ea.continuation(elastica, label, "eps", params={"psi": value})
    assert str(exc.value) == (f"{label.path.name}:{label.name}: psi = {value:.12g} not reached "
                              f"by continuation from psi = {psi:.12g}: the branch turns back at "
                              f"psi = {psi:.12g} (a fold)")


def test_restart_from_a_fold_at_changed_values_from_the_command_line(small_cli_run, cli_exe,
                                                                    tmp_path):
    """start = "small.h5:LP1" with [parameters] psi 1e-7 past the fold on the branch's side:
    the branches start at exactly that psi; on the other side: exit status 2 and one line
    naming psi and the fold."""
    out, h5, _ = small_cli_run
    src = BranchFile(h5)
    k, pt = src.labels["LP1"]
    psi = src.branches[k - 1].columns["psi"]
    side = np.sign(psi[pt] - psi[pt - 1])
    for sign in (side, -side):
        value = float(psi[pt - 1] + sign * 1e-7)
        toml = _restart_toml(tmp_path / f"lp_{sign:+.0f}.toml", "small.h5:LP1",
                             bounds=("0.2", "0.3"))
        toml.write_text(toml.read_text() + f"[parameters]\npsi = {value!r}\n")
        proc = run_cli(cli_exe, "run", toml, "--out", out, "-j", "1", "-q")
        if sign == side:
            assert proc.returncode == 0, proc.stderr
            rf = BranchFile(out / f"{toml.stem}.h5")
            assert [b.columns["psi"][0] for b in rf.branches] == [value, value]
        else:
            assert proc.returncode == 2 and "Traceback" not in proc.stderr
            assert len(proc.stderr.strip().splitlines()) == 1
            assert f"psi = {value:.12g} not reached" in proc.stderr
            assert f"turns back at psi = {psi[pt - 1]:.12g} (a fold)" in proc.stderr


# ---- a stored solution is checked before it becomes a start (hostile M5) -----------------------

def _shifted(src, dst, label, state, shift):
    """A copy ``dst`` of the branch file ``src`` whose stored solution of ``label`` has
    ``shift`` added to the state ``state`` (row of y), rewritten by h5py as the report
    edited it."""
    import shutil

    import h5py
    shutil.copy(src, dst)
    with h5py.File(dst, "r+") as f:
        br, _ = json.loads(f.attrs["labels"])[label]
        g = f[f"branches/{br:03d}/solutions"]
        k = [x.decode() for x in g["label"][()]].index(label)
        n = g["nodes"][()]
        y = g["y"][()]
        y[state, n[k]:n[k + 1]] += shift
        g["y"][...] = y
    return dst


def test_a_restart_from_an_edited_solution_is_refused(small_cli_run, cli_exe, tmp_path):
    """Hostile M5 (b): the report's edit, kappa of a stored solution shifted by 0.3, became
    the new branch's first point (EP1 with m1 = 0.8638875, not a solution). The stored
    solution is solved again at its own parameters first: it moves, and the restart is a
    user error naming the label. The same file rewritten without a shift restarts."""
    out, h5, _ = small_cli_run
    # a name of its own: the output folder is shared with the other restarts of this file
    toml = _restart_toml(tmp_path / "from_edited.toml", "edited.h5:UZ2")
    _shifted(h5, out / "edited.h5", "UZ2", 1, 0.3)
    proc = run_cli(cli_exe, "run", toml, "--out", out, "-j", "1")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and "edited.h5:UZ2: the stored solution of UZ2 does not solve the " \
        "problem: solved again, it moves by" in err[0] and "most in kappa" in err[0], err
    assert not (out / "from_edited.h5").exists()
    _shifted(h5, out / "edited.h5", "UZ2", 1, 0.0)       # the same edit, shifting nothing
    assert run_cli(cli_exe, "run", toml, "--out", out, "-j", "1").returncode == 0


def test_check_stored_passes_every_label_of_a_run_and_refuses_a_moved_one(small_cli_run,
                                                                        elastica):
    """Every label a run stored (EP, UZ, LP, with or without a tangent) solves its problem
    again in place; a solution moved by 1e-3 (100 times the tolerance) does not."""
    from elastica_auto.branches import restart
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.core.solution import State
    _, h5, _ = small_cli_run
    bf = BranchFile(h5)
    options = ContinuationOptions()
    kinds = set()
    for name in bf.labels:
        label = bf.label(name)
        restart.check_stored(elastica, label, "psi", options, name)
        kinds.add((name[:2], label.tangent is not None))
    assert {"EP", "UZ", "LP"} <= {k for k, _ in kinds}
    label = bf.label(next(n for n in bf.labels if n.startswith("UZ")))
    s = label.state
    moved = State(s.s, s.y + 1e-3 * (1 + np.abs(s.y)), s.yp, s.params)
    with pytest.raises(StartError, match="does not solve the problem"):
        restart.check_stored(elastica, dataclasses.replace(label, state=moved), "psi", options,
                             label.name)



def test_check_stored_at_a_branch_point_reads_the_residual(elastica):
    """At a branch point the linearisation is singular, whatever its border: Newton from the
    stored solution cannot converge, and the check reads the residual of the equations
    instead (wherever Newton does not converge, not at branch points only): the exact
    branch point of the straight rod passes (a switch from it is computed, the isotropic
    rod's out-of-plane branch points alike: tests/test_kirchhoff_runs.py), the same solution
    with kappa shifted by 1e-3 does not."""
    import math

    from elastica_auto.branches import restart
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.core.solution import State
    straight = ea.continuation(elastica, {"eps": 0.25, "P": 0.0}, "P", bounds=(-1, 4))
    label = straight.label("BP1")
    k = math.sqrt(label.state.params["P"])      # the first critical load: cot k = eps k
    assert 0 < k < math.pi / 2 and abs(math.cos(k) - 0.25 * k * math.sin(k)) < 1e-8
    options = ContinuationOptions()
    restart.check_stored(elastica, label, "P", options, "BP1")
    s = label.state
    y = s.y.copy()
    y[1] += 1e-3
    with pytest.raises(StartError, match="does not converge .*, and the residual of its "
                                         "equations is"):
        restart.check_stored(elastica, dataclasses.replace(label, state=State(s.s, y, s.yp,
                                                                             s.params)),
                             "P", options, "BP1")


# ---- free parameters matched by name (issue 45 item 4) -----------------------------------------

TWO_FREE = '''
"""u'' = -lam exp(u) + a + b s on [0, 1] with u(0) = u(1) = 0, u'(0) = c, u'(1) = d: four
conditions for two states, so the loads a and b are solved for (FREE)."""
import numpy as np
from elastica_auto import Ordinate, Parameter
STATES = ("u", "v")
PARAMETERS = [Parameter("lam", 0.0, "lam", "ode"), Parameter("a", 0.0, "a", "ode"),
              Parameter("b", 0.0, "b", "ode"), Parameter("c", 1.0, "c", "fixed"),
              Parameter("d", 0.0, "d", "free")]
FREE = ("a", "b")
def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0]) + p["a"] + p["b"] * s))
def bc(ya, yb, p):
    return np.array((ya[0], yb[0], ya[1] - p["c"], yb[1] - p["d"]))
def exact_start(s, p):
    if p["lam"] != 0:
        return None
    # u = c s + a s^2 / 2 + b s^3 / 6 with u(1) = 0 and u'(1) = d
    b = 6 * (p["d"] + p["c"])
    a = -2 * p["c"] - b / 3
    return np.vstack((p["c"] * s + a * s ** 2 / 2 + b * s ** 3 / 6,
                      p["c"] + a * s + b * s ** 2 / 2))
ORDINATES = [Ordinate("u_half", "u(1/2)", lambda s, y, p: float(np.interp(0.5, s, y[0])),
                      "lam")]
'''


def _two_free_toml(path, module, free, start=None):
    """lam continued from 0 (or from the label ``start``, at its values) to 0.5, a user point
    at 0.3, the parameters ``free`` solved for."""
    path.write_text((f'start = "{start}"\n' if start else "")
                    + f'equation = "{module}"\n' + ("" if start else "[parameters]\nlam = 0\n")
                    + f'[continuation]\nparameter = "lam"\ndirections = "+"\nbounds = [0, 0.5]\n'
                    f'uz = [0.3]\nfree = {json.dumps(free)}\n')
    return path


def test_a_restart_with_the_free_list_reordered_takes_each_by_name(tmp_path, cli_exe):
    """Issue 45 item 4: a restart whose run lists its free parameters in another order
    started each at the other's stored value (they are states of the solution, in the
    order of the run that found it), with no error. Each now starts at its own stored value,
    as h5py reads it from the file, and the branch is continued from there."""
    import h5py
    module = tmp_path / "two_free.py"
    module.write_text(TWO_FREE)
    first = _two_free_toml(tmp_path / "first.toml", module, ["a", "b"])
    assert run_cli(cli_exe, "run", first, "--out", tmp_path, "-j", "1").returncode == 0
    with h5py.File(tmp_path / "first.h5", "r") as f:       # the stored label, read by h5py
        br, pt = json.loads(f.attrs["labels"])["UZ1"]
        g = f[f"branches/{br:03d}/solutions"]
        k = [x.decode() for x in g["label"][()]].index("UZ1")
        stored = json.loads(g["params"][k].decode())
    assert stored["a"] != stored["b"] and stored["lam"] == 0.3
    second = _two_free_toml(tmp_path / "second.toml", module, ["b", "a"], "first.h5:UZ1")
    proc = run_cli(cli_exe, "run", second, "--out", tmp_path, "-j", "1")
    assert proc.returncode == 0, proc.stderr
    with h5py.File(tmp_path / "second.h5", "r") as f:
        cols = f["branches/001/columns"]
        start = {q: float(cols[q][0]) for q in ("lam", "a", "b")}
        assert f["branches/001"].attrs["end"] == "EP" and cols["lam"][-1] == 0.5
    assert start == {q: stored[q] for q in ("lam", "a", "b")}


def test_a_restart_without_a_value_for_a_free_parameter_is_a_user_error(tmp_path, cli_exe):
    """Issue 45 item 4: a free parameter of the restart that the label has no stored value
    for cannot be matched: a user error naming it (PlanError, one line on the command line)."""
    from elastica_auto.core.solution import State
    module = tmp_path / "two_free.py"
    module.write_text(TWO_FREE)
    first = _two_free_toml(tmp_path / "first.toml", module, ["a", "b"])
    assert run_cli(cli_exe, "run", first, "--out", tmp_path, "-j", "1").returncode == 0
    label = BranchFile(tmp_path / "first.h5").label("UZ1")
    keep = [i for i, name in enumerate(label.states) if name != "free:b"]
    s = label.state
    lost = dataclasses.replace(
        label, states=tuple(label.states[i] for i in keep),
        state=State(s.s, s.y[keep], s.yp[keep], {k: v for k, v in s.params.items() if k != "b"}))
    problem = ea.load_problem(str(module))
    with pytest.raises(ea.PlanError, match="UZ1: no stored value for the free parameter 'b'"):
        ea.continuation(problem, lost, "lam", bounds=(0, 0.5), free=["b", "a"])


def test_a_file_of_0_1_restarts_a_module_whose_state_became_a_free_parameter():
    """A user's files survive an upgrade (issue 45): elastica_pinned carried the pin's
    reaction as two states (nx, ny, constant along s) in 0.1 and solves for it as two free
    parameters now (its energy's multipliers). A label of a file written by 0.1
    (tests/data/pinned_0_1.h5, elastica-auto 0.1.0) restarts it: each free parameter is its
    stored state's constant value, and the continuation's first point has the reaction the
    old module stored, to the corrector's tolerance."""
    import h5py
    from pathlib import Path
    path = Path(__file__).parent / "data" / "pinned_0_1.h5"
    bf = BranchFile(path)
    assert bf.attrs["version"] == "0.1.0" and bf.states[-2:] == ["nx", "ny"]
    with h5py.File(path, "r") as f:
        stored_nx = float(f["branches/001/columns/n_x"][-1])
        stored_ny = float(f["branches/001/columns/n_y"][-1])
    problem = ea.load_problem("elastica_pinned")
    assert "nx" not in problem.states
    branches = ea.continuation(problem, bf.label("EP2"), "theta0", bounds=(-0.1, 0.1),
                               directions="both", max_points=10)
    for br in branches:
        first = br.points[0]
        assert first.ordinates["n_x"] == pytest.approx(stored_nx, rel=1e-7)
        assert first.ordinates["n_y"] == pytest.approx(stored_ny, rel=1e-7)
        assert br.end == "EP" and len(br.points) > 2

