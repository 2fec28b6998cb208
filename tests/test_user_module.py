"""A user equation module that is not the elastica: the Bratu problem (examples/bratu.py),
against its closed-form solutions.

u'' + lam exp(u) = 0, u(0) = u(1) = 0 has the one-parameter family of solutions

    u(x) = -2 ln( cosh(z (x - 1/2)) / cosh(z / 2) ),   lam = 2 z^2 / cosh^2(z / 2),

(verified below), with u'(0) = 2 z tanh(z / 2) and u(1/2) = 2 ln cosh(z / 2). (The often-quoted
lam = 8 z^2 / cosh^2(z / 2) belongs to u = -2 ln(cosh(2 z (x - 1/2)) / cosh z), i.e. z -> 2 z.)
lam(z) rises from 0 to its maximum lam_c = 3.51383... at z tanh(z / 2) = 2 (where u'(0) = 4) and
falls back to 0 as z -> infinity: the branch from u = 0 folds once, at lam_c.
"""

from __future__ import annotations

import csv
import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from helpers import EXAMPLES, REPO, run_cli, run_plan
from elastica_auto.execution import runfile
from elastica_auto.model.problem import load_problem

BRATU_TOML = EXAMPLES / "bratu.toml"


def lam_of(z):
    return 2 * z * z / math.cosh(z / 2) ** 2


def du0_of(z):
    return 2 * z * math.tanh(z / 2)


def u_half_of(z):
    return 2 * math.log(math.cosh(z / 2))


def u_exact(x, z):
    return -2 * np.log(np.cosh(z * (x - 0.5)) / math.cosh(z / 2))


@pytest.fixture(scope="module")
def lam_c():
    """The fold: the maximum of lam(z), by scipy.optimize, cross-checked against the root of
    d lam / dz = 0 <=> z tanh(z / 2) = 2."""
    res = minimize_scalar(lambda z: -lam_of(z), bounds=(0.5, 5.0), method="bounded",
                          options={"xatol": 1e-12})
    z_root = brentq(lambda z: z * math.tanh(z / 2) - 2, 1.0, 4.0, xtol=1e-15)
    assert res.x == pytest.approx(z_root, abs=1e-6)
    # lam is stationary at the maximum, so lam(res.x) is exact to ~(1e-6)^2
    assert lam_of(res.x) == pytest.approx(lam_of(z_root), abs=1e-13)
    assert du0_of(z_root) == pytest.approx(4.0, abs=1e-14)
    return lam_of(z_root), z_root


@pytest.mark.parametrize("z", [0.3, 1.0, 2.4, 5.0])
def test_closed_form_family_solves_bratu(z):
    """Check the parametrisation itself: fourth-order central differences for u''."""
    x = np.linspace(0.0, 1.0, 2001)
    h = 1e-3
    u = u_exact(x, z)
    upp = (-u_exact(x + 2 * h, z) + 16 * u_exact(x + h, z) - 30 * u
           + 16 * u_exact(x - h, z) - u_exact(x - 2 * h, z)) / (12 * h * h)
    scale = 1 + z * z
    np.testing.assert_allclose(upp + lam_of(z) * np.exp(u), 0.0, atol=1e-7 * scale)
    assert abs(u[0]) < 1e-14 and abs(u[-1]) < 1e-14
    du = (u_exact(h, z) - u_exact(-h, z)) / (2 * h)
    assert du == pytest.approx(du0_of(z), rel=1e-6)
    assert u[1000] == pytest.approx(u_half_of(z), abs=1e-14)


def test_bratu_module_follows_the_protocol():
    pr = load_problem(str(EXAMPLES / "bratu.py"))
    assert pr.states == ("u", "v")
    assert pr.parameter_names == ["lam"] and pr.parameters["lam"].enters == "ode"
    s = np.linspace(0, 1, 11)
    assert pr.exact_start(s, {"lam": 0.0}).tolist() == np.zeros((2, 11)).tolist()
    assert pr.exact_start(s, {"lam": 1.0}) is None
    # the module's analytic Jacobians agree with central differences
    y = np.vstack((np.sin(np.pi * s), np.pi * np.cos(np.pi * s)))
    p = {"lam": 1.7}
    h = 1e-6
    for j in range(2):
        e = np.zeros_like(y)
        e[j] = h
        fd = (pr.rhs(s, y + e, p) - pr.rhs(s, y - e, p)) / (2 * h)
        np.testing.assert_allclose(pr.rhs_jac(s, y, p)[:, j], fd, atol=1e-7)
    fd = (pr.rhs(s, y, {"lam": 1.7 + h}) - pr.rhs(s, y, {"lam": 1.7 - h})) / (2 * h)
    np.testing.assert_allclose(pr.rhs_dp(s, y, p, "lam"), fd, atol=1e-7)


@pytest.fixture(scope="module")
def bratu_run(tmp_path_factory):
    plan = runfile.load(BRATU_TOML)
    return run_plan(plan, tmp_path_factory.mktemp("bratu"))


def test_bratu_fold_is_the_analytic_fold(bratu_run, lam_c):
    lam_fold, z_fold = lam_c
    (br,) = bratu_run.result.branches
    assert br.end == "EP"
    assert br.points[0].type == "EP" and br.points[0].params["lam"] == 0.0
    (lp,) = br.folds
    assert abs(lp.params["lam"] - lam_fold) <= 1e-8
    # the fold's state: a fold_tol = 1e-7 solve, good to ~1e-7 relative in u'(0) = 4
    assert lp.ordinates["du0"] == pytest.approx(4.0, rel=1e-6)
    assert lp.ordinates["u_half"] == pytest.approx(u_half_of(z_fold), rel=1e-6)
    # and it is a fold: lam rises before it and falls after it
    lam = br.column("lam")
    k = br.points.index(lp)
    assert np.all(lam[:k] < lam[k]) and np.all(lam[k + 1:] < lam[k])


def test_bratu_branch_lies_on_the_closed_form_family(bratu_run):
    """Each point (lam, u'(0)) determines z by u'(0) = 2 z tanh(z / 2) (monotone in z); lam must
    then be lam(z). Points are solve_bvp solutions at tol = 1e-5 (relative residual and absolute
    boundary residual); lam(z(u'(0))) is insensitive to u'(0) near the fold (d lam/dz = 0), so
    the mismatch is of the order of tol."""
    (br,) = bratu_run.result.branches
    tol = bratu_run.plan.options.tol
    du0, lam, u_half = br.column("du0"), br.column("lam"), br.column("u_half")
    assert du0.max() > 10        # well past the fold, on the upper family
    for d, lm, uh in zip(du0, lam, u_half):
        z = brentq(lambda z: du0_of(z) - d, 0.0, 60.0, xtol=1e-15) if d > 0 else 0.0
        assert abs(lm - lam_of(z)) <= tol, (lm, lam_of(z))
        assert abs(uh - u_half_of(z)) <= tol * (1 + uh)


def test_bratu_user_points_find_both_solutions(bratu_run, lam_c):
    """Each requested lam < lam_c has two solutions, z below and above z_c; the branch passes
    both, so each value is labelled twice, once with each closed-form solution."""
    _, z_c = lam_c
    (br,) = bratu_run.result.branches
    tol = bratu_run.plan.options.tol
    values = bratu_run.plan.user_values[0].values
    uz = [p for p in br.points if p.type == "UZ"]
    for v in values:
        at = sorted(p.ordinates["du0"] for p in uz if p.params["lam"] == v)
        z_lo = brentq(lambda z: lam_of(z) - v, 1e-12, z_c, xtol=1e-15)
        z_hi = brentq(lambda z: lam_of(z) - v, z_c, 60.0, xtol=1e-15)
        expected = [du0_of(z_lo), du0_of(z_hi)]
        assert len(at) == 2, (v, at)
        np.testing.assert_allclose(at, expected, rtol=tol)


def test_bratu_through_the_cli(tmp_path, cli_exe, lam_c):
    lam_fold, _ = lam_c
    out = tmp_path / "out"
    proc = run_cli(cli_exe, "run", BRATU_TOML, "--out", out)
    assert proc.returncode == 0, proc.stderr
    h5 = out / "bratu.h5"
    assert h5.is_file()

    show = run_cli(cli_exe, "show", h5)
    assert show.returncode == 0, show.stderr
    lines = [ln.split() for ln in show.stdout.splitlines()]
    assert lines[0][:4] == ["BR", "PT", "TY", "LAB"] and "lam" in lines[0]
    lp_rows = [ln for ln in lines[1:] if len(ln) > 3 and ln[2] == "LP"]
    assert len(lp_rows) == 1 and lp_rows[0][3] == "LP1"
    # show prints 7 significant digits
    assert float(lp_rows[0][lines[0].index("lam")]) == pytest.approx(lam_fold, rel=1e-6)

    csv_path = tmp_path / "bratu.csv"
    exp = run_cli(cli_exe, "export", h5, "-o", csv_path)
    assert exp.returncode == 0, exp.stderr
    with open(csv_path, newline="") as fh:
        rows = list(csv.reader(fh))
    # the derived ordinates (examples/bratu.py is energy-first), then the module's own
    assert rows[0] == ["branch", "pt", "type", "label", "lam", "dE_dlam", "E", "du0", "u_half",
                       "index", "index_rule", "index_direct"]
    lp = [r for r in rows[1:] if r[2] == "LP"]
    assert len(lp) == 1 and lp[0][3] == "LP1"
    assert abs(float(lp[0][4]) - lam_fold) <= 1e-8
    assert float(lp[0][rows[0].index("du0")]) == pytest.approx(4.0, rel=1e-6)


def test_restart_with_the_same_user_module_file_from_another_directory(tmp_path, cli_exe):
    """The same module file, spelled 'examples/bratu.py' in one run and by its absolute path in
    the restart, is the same equation. (Regression: the spelled paths were compared.)"""
    out = tmp_path / "out"
    first = run_cli(cli_exe, "run", "examples/bratu.toml", "--out", out, cwd=REPO)
    assert first.returncode == 0, first.stderr
    toml = tmp_path / "bratu_restart.toml"
    toml.write_text(f'equation = "{EXAMPLES / "bratu.py"}"\nstart = "bratu.h5:UZ2"\n'
                    '[continuation]\nparameter = "lam"\ndirections = "+"\n'
                    '[options]\nmax_points = 5\n')
    second = run_cli(cli_exe, "run", toml, "--out", out)
    assert second.returncode == 0, second.stderr


# ---- user points and bounds beside the fold, whatever the step -----------------------------

def _sweep_plan(lam_value_list, upper, ds):
    plan = runfile.load(BRATU_TOML)
    plan.user_values = [type(plan.user_values[0])(tuple(lam_value_list))]
    plan.stops = type(plan.stops)(plan.stops.lower, upper, None)
    plan.options = dataclasses.replace(plan.options, ds=ds, ds_max=ds, max_points=60)
    return plan


@pytest.mark.parametrize("ds", np.linspace(0.2, 0.6, 21))
def test_user_points_beside_the_fold_are_found_on_both_sides(tmp_path, lam_c, ds):
    """Values 1e-2, 1e-3 and 1e-4 below lam_c, for steps of 0.2 to 0.6 (a fold inside a step,
    on either side of its midpoint): each is labelled twice, once on each closed-form
    solution, and the step is split at the fold wherever it lies. Bratu has no stability hook,
    so only the parameter's tangent sees the fold."""
    lam_fold, z_c = lam_c
    values = [lam_fold - d for d in (1e-2, 1e-3, 1e-4)]
    plan = _sweep_plan(values, 4.0, float(ds))
    (br,) = run_plan(plan, tmp_path).result.branches
    assert len(br.folds) == 1 and br.warnings == []
    uz = [p for p in br.points if p.type == "UZ"]
    for v in values:
        at = sorted(p.ordinates["du0"] for p in uz if p.params["lam"] == v)
        z_lo = brentq(lambda z: lam_of(z) - v, 1e-12, z_c, xtol=1e-15)
        z_hi = brentq(lambda z: lam_of(z) - v, z_c, 60.0, xtol=1e-15)
        assert len(at) == 2, (ds, v, at)
        np.testing.assert_allclose(at, [du0_of(z_lo), du0_of(z_hi)], rtol=1e-5)
    # in travel order: the values rise to the fold, then fall after it
    lam = [p.params["lam"] for p in br.points if p.type in ("UZ", "LP")]
    k = lam.index(max(lam))
    assert lam[:k] == sorted(values) and lam[k + 1:] == sorted(values, reverse=True)


@pytest.mark.parametrize("ds", np.linspace(0.2, 0.6, 5))
def test_a_bound_just_below_the_fold_ends_the_branch_there(tmp_path, lam_c, ds):
    lam_fold, _ = lam_c
    plan = _sweep_plan([], lam_fold - 1e-3, float(ds))
    (br,) = run_plan(plan, tmp_path).result.branches
    assert br.end == "EP" and br.folds == []
    assert br.points[-1].type == "EP"
    assert br.points[-1].params["lam"] == pytest.approx(lam_fold - 1e-3, abs=1e-12)
    assert all(p.params["lam"] <= lam_fold - 1e-3 + 1e-12 for p in br.points)


# ---- a module that imports a file beside it --------------------------------------------------

def _split_module(folder):
    """examples/bratu.py with one ordinate computed by a helper in a file beside it."""
    folder.mkdir()
    (folder / "bratu_helpers.py").write_text(
        "def twice_slope(y):\n    return 2.0 * y[1, 0]\n")
    text = (EXAMPLES / "bratu.py").read_text().replace(
        "from elastica_auto import Ordinate, hermite\n",
        "from elastica_auto import Ordinate, hermite\nfrom bratu_helpers import twice_slope\n")
    text += ('\nORDINATES.append(Ordinate("du0x2", "2 u\'(0)", '
             'lambda s, y, p: twice_slope(y), None, "twice the slope at x = 0"))\n')
    (folder / "bratu_split.py").write_text(text)
    return folder / "bratu_split.py"


def test_a_module_imports_a_file_beside_it_wherever_it_is_run_from(tmp_path, monkeypatch,
                                                                    cli_exe):
    """As `python bratu_split.py` could, the module's top level imports a file from its own
    folder, loaded from another current directory, on a worker (its text executed in a fresh
    interpreter, as a local cluster's worker does) and through the CLI; the folder is not
    left on sys.path."""
    import pickle
    import subprocess
    import sys

    path = _split_module(tmp_path / "models")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    before = list(sys.path)
    problem = load_problem(path)
    assert sys.path == before
    s = np.linspace(0.0, 1.0, 5)
    y = np.vstack((np.zeros(5), np.full(5, 0.75)))
    assert problem.ordinates["du0x2"].fn(s, y, {"lam": 0.0}) == 1.5

    blob = tmp_path / "problem.pickle"
    blob.write_bytes(pickle.dumps(problem))
    sys.modules.pop("bratu_helpers", None)
    worker = subprocess.run(
        [sys.executable, "-c", "import pickle, sys, numpy as np; "
         f"p = pickle.loads(open({str(blob)!r}, 'rb').read()); "
         "print(p.ordinates['du0x2'].fn(np.linspace(0, 1, 3), np.ones((2, 3)), "
         "{'lam': 0.0}))"],
        cwd=elsewhere, capture_output=True, text=True)
    assert worker.returncode == 0, worker.stderr
    assert worker.stdout.split() == ["2.0"]

    toml = tmp_path / "models" / "split.toml"
    toml.write_text('equation = "bratu_split.py"\nstart = "trivial"\n'
                    '[continuation]\nparameter = "lam"\ndirections = "+"\n'
                    '[options]\nmax_points = 5\n')
    proc = run_cli(cli_exe, "run", toml, "--out", tmp_path / "out", cwd=elsewhere)
    assert proc.returncode == 0, proc.stderr


def test_an_energy_built_from_a_file_beside_it_is_derived_again_when_that_file_changes(
        tmp_path, monkeypatch):
    """The cache of generated code is keyed by the module's text and the texts of the files
    beside it that it imports: changing the stiffness K in the imported file changes the
    derived equation u' = v / K (the momentum v = K u' of K u'^2 / 2), not a stale one."""
    import sys

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("ELASTICA_AUTO_ENERGY_CACHE", raising=False)
    # two versions of bratu_k.py of one size within a second: no stale .pyc between them
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    folder = tmp_path / "models"
    folder.mkdir()
    text = (EXAMPLES / "bratu.py").read_text()
    text = text.replace("from elastica_auto import Ordinate, hermite\n",
                        "from elastica_auto import Ordinate, hermite\nfrom bratu_k import K\n")
    text = text.replace("density=u.diff(s) ** 2 / 2", "density=K * u.diff(s) ** 2 / 2")
    assert "density=K *" in text
    (folder / "bratu_stiff.py").write_text(text)
    s, y = np.linspace(0.0, 1.0, 3), np.vstack((np.zeros(3), np.ones(3)))
    slopes = []
    for k in (2.0, 4.0):
        (folder / "bratu_k.py").write_text(f"K = {k}\n")
        sys.modules.pop("bratu_k", None)
        problem = load_problem(folder / "bratu_stiff.py")
        slopes.append(problem.rhs(s, y, {"lam": 0.0})[0, 0])
    assert slopes == [0.5, 0.25]
