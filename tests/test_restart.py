"""Restarts: continuing a different parameter from a labelled solution of an earlier run."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import shooting
from helpers import elastica_run_file, invariant, invariant_bound, run_cli, run_plan
from elastica_auto import runfile
from elastica_auto.store import BranchFile


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
