"""Small defects a sixth careful user met (brief hostile6): the default step inside bounds
given alone, a user value on a bound, an end spring on an essential end, the hint of a
refused resume. Each checked against what the option or the docs promise, not against a
stored output."""

from __future__ import annotations

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.core.options import ContinuationOptions, OptionsError
from helpers import REPO, run_cli

BRATU = str(REPO / "examples" / "bratu.py")


# -- the default ds clipped into [ds_min, ds_max] -----------------------------------------

@pytest.mark.parametrize("bounds, ds", [({}, 0.05), ({"ds_max": 0.01}, 0.01),
                                        ({"ds_min": 0.1}, 0.1),
                                        ({"ds_min": 0.2, "ds_max": 0.3}, 0.2)])
def test_default_ds_is_clipped_into_the_bounds_given(bounds, ds):
    assert ContinuationOptions(**bounds).ds == ds


@pytest.mark.parametrize("kw, text", [
    ({"ds": 0.05, "ds_max": 0.01}, "ds_min <= |ds| <= ds_max"),   # a ds given is not clipped
    ({"ds_min": 1.0, "ds_max": 0.5}, "need 0 < ds_min <= ds_max, got ds_min=1.0, ds_max=0.5"),
])
def test_a_ds_given_outside_its_bounds_is_still_refused(kw, text):
    with pytest.raises(OptionsError, match=text.replace("|", r"\|")):
        ContinuationOptions(**kw)


def test_continuation_with_ds_max_alone_takes_steps_within_it():
    """``ds_max=0.01`` without ``ds``: the branch is computed, and no two successive points
    are farther apart in arclength than 0.01 (the steps' bound, which the option promises)."""
    (br,) = ea.continuation(ea.load_problem(BRATU), {"lam": 0.0}, "lam", ds_max=0.01,
                            max_points=6)
    steps = np.diff([p.arclength for p in br.points])
    assert len(br.points) == 6 and steps.max() <= 0.01 * (1 + 1e-12)
    assert br.options["ds"] == 0.01


# -- a uz value on a bound: the EP there, solved at the value -----------------------------

def _bratu_u_half(lam: float) -> float:
    """u(1/2) on Bratu's lower family at ``lam`` from its closed form u(1/2) = 2 ln cosh(z/2),
    lam = 2 z^2 / cosh(z/2)^2 (z below the fold's, z tanh(z/2) = 2), by bisection."""
    lo, hi = 0.0, 2.3994      # z tanh(z / 2) = 2 at z = 2.39935: lam increases on [lo, hi]
    for _ in range(200):
        z = (lo + hi) / 2
        lo, hi = (z, hi) if 2 * z * z / np.cosh(z / 2) ** 2 < lam else (lo, z)
    return 2 * np.log(np.cosh(lo / 2))


def test_a_uz_value_on_a_bound_is_the_end_point_there():
    """``bounds = (-1, 2)``, ``uz = [0, 1, 2]`` from lam = 0: each end is one EP (the start
    at 0, the bound at 2), not UZ as well (docs/run-files.md, ``uz``); the EP at 2 is solved
    exactly there: its u(1/2) is the closed form's."""
    (br,) = ea.continuation(ea.load_problem(BRATU), {"lam": 0.0}, "lam", bounds=(-1, 2),
                            uz=[0, 1, 2], ds_max=0.3)
    labelled = [(p.type, p.params["lam"]) for p in br.points if p.type]
    assert labelled == [("EP", 0.0), ("UZ", 1.0), ("EP", 2.0)]
    end = br.points[-1]
    assert end.ordinates["u_half"] == pytest.approx(_bratu_u_half(2.0), rel=1e-6)


# -- a refused resume says the two ncol, and the way back only where it is one --------------

KAR = REPO / "benchmarks" / "auto" / "kar.toml"


def test_a_resume_refused_for_ncol_names_both_values_and_hints_only_at_the_old_default(
        cli_exe, tmp_path):
    """A file by ``ncol = 0``: resumed with ``--set ncol=4`` (the user's own choice) the
    refusal names both values and does not tell the user to ``--set ncol=0`` (which undoes
    what they asked); resumed under the default "auto" (kar may turn to Gauss, so that is
    another run) it says that 0 was the old default and how to resume."""
    run = ("run", KAR, "--out", tmp_path, "-q", "-j", "1", "--set", "max_points=4")
    assert run_cli(cli_exe, *run, "--set", "ncol=0").returncode == 0
    mine = run_cli(cli_exe, *run, "--resume", "--set", "ncol=4")
    assert mine.returncode == 2
    assert "options.ncol (the file's 0, this run's 4)" in mine.stderr
    assert "--set ncol=0" not in mine.stderr
    default = run_cli(cli_exe, *run, "--resume")
    assert default.returncode == 2
    assert ("options.ncol (the file's 0, this run's \"auto\"; 0, the cubic scheme, was the "
            "default before \"auto\": --set ncol=0 resumes it)") in default.stderr


# -- an end term on an essential end is refused ---------------------------------------------

SPRING = '''
import numpy as np

def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy, Param
    s, P, k = sp.symbols("s P k", real=True)
    th = sp.Function("theta")(s)
    return Energy(density=th.diff(s) ** 2 / 2 + P * sp.cos(th), s=s, coordinates=[th],
                  FIXED, end0=k * th ** 2 / 2, parameters={P: Param(1.0), k: Param(2.0)})

def exact_start(s, p):
    return np.zeros((2, len(s)))
'''


def _spring(tmp_path, fixed: str):
    path = tmp_path / "spring.py"
    path.write_text(SPRING.replace("FIXED", fixed))
    return ea.load_problem(path, cache=False)


def test_a_spring_at_an_essential_end_is_refused(tmp_path):
    """``end0 = k theta(0)^2 / 2`` with ``fixed0 = {theta: 0}``: on every admissible
    configuration the term is 0 (a constant), so ``k`` changes no equilibrium; it was
    accepted, ``k`` called ``free`` with an ordinate dE/dk identically 0. Refused in one
    line naming the term, the coordinate and both ways out."""
    with pytest.raises(ea.ProblemError, match=r"end0 contains the term k\*theta\*\*2/2 in "
                       r"theta at s = 0, which fixed0 prescribes.*leave theta out of fixed0"):
        _spring(tmp_path, "fixed0={th: 0}")


def test_the_same_spring_at_a_natural_end_is_accepted(tmp_path):
    """The spring at s = 0 with the essential condition moved to s = 1 (``fixed1``):
    accepted, ``k`` entering the end terms (the check refuses inert terms only)."""
    problem = _spring(tmp_path, "fixed1={th: 0}")
    assert problem.parameters["k"].enters == "free"


# -- numpy values are numbers ---------------------------------------------------------------

def test_numpy_values_and_options_give_the_branches_of_python_values():
    """A user looping over ``np.arange`` or ``np.linspace`` passes numpy scalars and arrays:
    ``np.int64`` start values, bounds, uz values and ``max_points``, and an array of
    ``params`` values, were refused as "expected a finite number, got np.int64(1)". They
    are numbers: the branches are those of the same call with Python values, number for
    number, and the options stored with a branch are Python numbers (JSON)."""
    import json

    problem = ea.load_problem(BRATU)
    plain = ea.continuation(problem, {}, "lam", bounds=(-1, 3), uz=[1, 2],
                            max_points=12, ds=0.2, params={"lam": [0]})
    numpy = ea.continuation(problem, {}, "lam", bounds=(np.int64(-1), np.int32(3)),
                            uz=np.arange(1, 3), max_points=np.int64(12), ds=np.float64(0.2),
                            params={"lam": np.zeros(1, dtype=np.int64)})
    start = ea.continuation(problem, {"lam": np.int64(0)}, "lam", bounds=(-1, 3), ds=0.2,
                            max_points=np.int64(3))
    assert np.array_equal(start[0].columns["u_half"], plain[0].columns["u_half"][:3])
    assert len(plain) == len(numpy) == 1
    for name in ("lam", "du0", "u_half", "arclength", "index"):
        assert np.array_equal(plain[0].columns[name], numpy[0].columns[name])
    assert list(plain[0].columns["type"]) == list(numpy[0].columns["type"])
    assert json.dumps(numpy[0].options) == json.dumps(plain[0].options)


def test_a_numpy_bool_is_not_a_number():
    with pytest.raises(OptionsError, match="tol must be a finite number, got np.True_"):
        ContinuationOptions(tol=np.True_)


# -- docs/hdf5.md's reading with h5py alone -------------------------------------------------

def test_the_h5py_recipe_of_the_docs_reads_what_branchfile_reads(tmp_path):
    """The snippet of docs/hdf5.md ("Reading a file with h5py alone"), run on a file with a
    fold: the label's mesh and states and the point's profile are
    BranchFile's, bit for bit."""
    import json

    import h5py

    problem = ea.load_problem(BRATU)
    branches = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), uz=[1],
                               directions="both", max_points=40)
    path = tmp_path / "b.h5"
    ea.save(branches, path)
    bf = ea.BranchFile(path)
    (name,) = [n for n in bf.labels if n.startswith("LP")]
    with h5py.File(path, "r") as f:
        states = json.loads(f.attrs["states"])
        branch, pt = json.loads(f.attrs["labels"])[name]
        g = f["branches"][f"{branch:03d}"]
        sol = g["solutions"]
        i = [n.decode() for n in sol["label"][()]].index(name)
        j = sol["mesh"][i]
        a, b = sol["nodes"][j], sol["nodes"][j + 1]
        s, y = sol["s"][a:b], sol["y"][:, a:b]
        profile = g["profiles"][g["profile_rows"][pt - 1]]
        grid = f["profile_grid"][()]
    label = bf.label(name)
    assert states == list(problem.states) and grid.shape == (101,)
    assert np.array_equal(s, label.state.s) and np.array_equal(y, label.state.y)
    assert np.array_equal(profile, bf.branches[branch - 1].profiles_at([pt - 1])[0])
    assert bf.branches[branch - 1].columns["type"][pt - 1] == "LP"


# -- `snaps` on a file without targets says which reason holds ------------------------------

def test_snaps_without_targets_says_why(cli_exe, tmp_path):
    """Bratu has a fold ending its stable segment (LP1, 0 -> 1) and no shooting hook: the
    command names the fold and the module; stopped before the fold, the file has no such
    fold, and the command says that instead (it said both reasons at once, either way)."""
    problem = ea.load_problem(BRATU)
    folded = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), max_points=40)
    short = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 2))
    ea.save(folded, tmp_path / "folded.h5")
    ea.save(short, tmp_path / "short.h5")
    (lp,) = [p for p in folded[0].points if p.type == "LP"]
    assert folded[0].transition(lp) == "0 -> 1"
    out = run_cli(cli_exe, "snaps", tmp_path / "folded.h5")
    assert out.returncode == 0
    assert out.stdout.startswith("no snap-back targets: LP1 ends a stable segment, but the "
                                 "run computed none: its equation module (")
    assert "has no shooting hook" in out.stdout
    out = run_cli(cli_exe, "snaps", tmp_path / "short.h5")
    assert out.returncode == 0
    assert out.stdout.strip() == ("no snap-back targets: no fold with a known index ends a "
                                  "stable segment (index 0 on one side)")


# -- a user's spatial rod: intrinsic curvature kappa s, a spring on the tip's frame ----------

PRECURVED = '''
"""A pre-curved, pre-twisted rod in space: clamped at s = 0 along e_z, a dead load P along
-e_z at s = 1 and a rotational spring kr (1 - d3(1).e_z) on the tip's frame. Intrinsic
strains (kappa s, 0, tau); stiffnesses 1, b2, c."""
import numpy as np


def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy, Param, Rotation
    s, P, kappa, tau, kr, b2, c = sp.symbols("s P kappa tau kr b2 c", real=True)
    R = Rotation("R")
    x, y, z = (sp.Function(n)(s) for n in ("x", "y", "z"))
    u1, u2, u3 = R.strain
    W = ((u1 - kappa * s) ** 2 + b2 * u2 ** 2 + c * (u3 - tau) ** 2) / 2
    return Energy(density=W, end1=P * z + kr * (1 - R.d3[2]), s=s, coordinates=[R],
                  quadratures={x: R.d3[0], y: R.d3[1], z: R.d3[2]},
                  fixed0={R: (1, 0, 0, 0), x: 0, y: 0, z: 0},
                  parameters={P: Param(1.0), kappa: Param(0.0), tau: Param(0.3),
                              kr: Param(0.5), b2: Param(2.0), c: Param(0.8)})


def exact_start(s, p):
    """Straight along e_z, twisted by tau s about it, no moment: exact at kappa = 0."""
    if p["kappa"] != 0:
        return None
    out = np.zeros((10, len(s)))
    out[0] = np.cos(p["tau"] * s / 2)
    out[3] = np.sin(p["tau"] * s / 2)
    out[9] = s
    return out
'''


@pytest.fixture(scope="module")
def precurved(tmp_path_factory):
    path = tmp_path_factory.mktemp("precurved") / "precurved.py"
    path.write_text(PRECURVED)
    return ea.load_problem(path)


def _tip_spring_loads(B: float, kr: float, n: int) -> list[float]:
    """The straight clamped column's critical loads with a rotational spring kr on its tip's
    tangent: B theta'' + P theta = 0, theta(0) = 0, B theta'(1) + kr theta(1) = 0, so
    theta = sin(w s), P = B w^2 with B w cos w + kr sin w = 0 (w in ((k - 1/2) pi, (k + 1/2)
    pi), k = 1..n)."""
    from scipy.optimize import brentq
    f = lambda w: B * w * np.cos(w) + kr * np.sin(w)     # noqa: E731
    return [B * brentq(f, (k - 0.5) * np.pi + 1e-9, (k + 0.5) * np.pi - 1e-9) ** 2
            for k in range(1, n + 1)]


def test_a_users_rod_with_a_spring_on_its_tip_frame_buckles_at_the_closed_form(precurved):
    """Untwisted (tau = 0) and straight (kappa = 0), the rod buckles in each principal plane
    (stiffness 1, then b2 = 2) where the tip spring's closed form says; the index counts the
    loads passed."""
    (br,) = ea.continuation(precurved, {"P": 0.0, "kappa": 0.0, "tau": 0.0}, "P",
                            bounds=(-1, 30), ds_max=0.5)
    bps = [p for p in br.points if p.type == "BP"]
    exact = sorted(_tip_spring_loads(1.0, 0.5, 2) + _tip_spring_loads(2.0, 0.5, 1))
    assert [p.params["P"] for p in bps] == pytest.approx(exact, rel=1e-8)
    assert [br.transition(p) for p in bps] == ["0 -> 1", "1 -> 2", "2 -> 3"]


def test_a_users_precurved_rod_against_shooting(precurved):
    """kappa continued from the straight twisted rod at P = 1: at the UZ points the clamp's
    moment m(0) and the tip's position agree with a shooting solve written here (the frame
    as a 3 x 3 matrix, R' = R [u]_x, m' = P d3 x e_z, r' = d3, u = K^-1 R^T m + u_hat;
    m(1) = kr d3(1) x e_z, the spring's moment), and dE/dP is z(1)."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import root

    (br,) = ea.continuation(precurved, {"P": 1.0, "kappa": 0.0}, "kappa", bounds=(-1, 3),
                            uz=[1.0, 2.5], ds_max=0.2)

    def cross_matrix(v):
        return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])

    def shoot(m0, p):
        K = np.diag([1.0, p["b2"], p["c"]])

        def rhs(s, y):
            R, m = y[:9].reshape(3, 3), y[9:12]
            u = np.linalg.solve(K, R.T @ m) + np.array([p["kappa"] * s, 0.0, p["tau"]])
            return np.concatenate([(R @ cross_matrix(u)).ravel(),
                                   np.cross(R[:, 2], [0.0, 0.0, p["P"]]), R[:, 2]])
        y0 = np.concatenate([np.eye(3).ravel(), m0, np.zeros(3)])
        return solve_ivp(rhs, (0, 1), y0, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]

    def mismatch(m0, p):
        end = shoot(m0, p)
        return end[9:12] - p["kr"] * np.cross(end[:9].reshape(3, 3)[:, 2], [0.0, 0.0, 1.0])

    uz = [p for p in br.points if p.type == "UZ"]
    assert [p.params["kappa"] for p in uz] == [1.0, 2.5]
    for p in uz:
        y = p.state.y                       # R_q0..R_q3, m_R1..m_R3, x, y, z
        sol = root(mismatch, y[4:7, 0] + 0.05, args=(p.params,), tol=1e-13)
        assert sol.success
        assert np.abs(sol.x - y[4:7, 0]).max() < 1e-8
        assert np.abs(shoot(sol.x, p.params)[12:15] - y[7:10, -1]).max() < 1e-8
        assert p.ordinates["dE_dP"] == pytest.approx(y[9, -1], rel=1e-12)


# -- a missing label's message lists the labels compactly -----------------------------------

def test_a_missing_label_lists_the_labels_as_ranges():
    """``Branches.label`` and ``Branch.label`` of a name not there list the labels as
    BranchFile's message does (``UZ1-UZ40``), not each of them (hundreds on a paper run):
    the ranges are those counted on the branch's own points."""
    (br,) = branches = ea.continuation(ea.load_problem(BRATU), {"lam": 0.0}, "lam",
                                       bounds=(-1, 4), uz=np.linspace(0.1, 3.4, 20),
                                       max_points=80)
    n_uz = sum(p.type == "UZ" for p in br.points)
    assert n_uz > 20                            # values below and above the fold
    expected = f"labels: EP1-EP2, LP1, UZ1-UZ{n_uz}"
    with pytest.raises(KeyError, match=f"no label 'UZ999'; {expected}"):
        branches.label("UZ999")
    with pytest.raises(KeyError, match=f"no label 'LP2' on this branch; {expected}"):
        br.label("LP2")


# -- progress that is not a function; jobs as a numpy integer --------------------------------

def test_a_progress_that_is_not_a_function_is_the_arguments_error():
    """``progress=3`` was accepted, and the branch ended MX as an "internal error" (a bug of
    the engine's, its diagnostics said) at the first step: it is a PlanError naming it."""
    with pytest.raises(ea.PlanError, match=r"progress: expected a function progress\(branch, "
                                           r"points, folds, value\), got 3") as info:
        ea.continuation(ea.load_problem(BRATU), {"lam": 0.0}, "lam", progress=3)
    assert info.value.key == "progress"


def test_jobs_as_a_numpy_integer():
    (br,) = ea.continuation(ea.load_problem(BRATU), {"lam": 0.0}, "lam", max_points=3,
                            jobs=np.int64(1))
    assert len(br.points) == 3


def test_a_spring_on_a_clamped_frame_is_refused(tmp_path):
    """The same for a frame: ``end0 = k (1 - d3(0).e_z)`` with the frame clamped at s = 0."""
    path = tmp_path / "frame_spring.py"
    path.write_text('''
import numpy as np

def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy, Param, Rotation
    s, q, k = sp.symbols("s q k", real=True)
    R = Rotation("R")
    u1, u2, u3 = R.strain
    return Energy(density=(u1 ** 2 + u2 ** 2 + u3 ** 2) / 2 + q * (1 - s) * R.d3[2], s=s,
                  coordinates=[R], fixed0={R: (1, 0, 0, 0)}, end0=k * (1 - R.d3[2]),
                  parameters={q: Param(0.0), k: Param(1.0)})
''')
    with pytest.raises(ea.ProblemError, match=r"end0 contains the term k\*\(1 - R33\(0\)\) in R "
                                              r"at s = 0, which fixed0 prescribes"):
        ea.load_problem(path, cache=False)


def test_save_of_one_branch_says_how(tmp_path):
    """``ea.save(branches[0], path)`` raised a bare TypeError ('Branch' object is not
    iterable); it is a PlanError saying what to pass, and ``[branch]`` with ``problem=``
    writes the file."""
    problem = ea.load_problem(BRATU)
    branches = ea.continuation(problem, {"lam": 0.0}, "lam", max_points=3)
    with pytest.raises(ea.PlanError, match="got one Branch: save the continuation's result "
                                           "whole, or \\[branch\\] with problem="):
        ea.save(branches[0], "/nonexistent/never.h5")
    with pytest.raises(ea.PlanError, match="expected a non-empty list of branches, got int"):
        ea.save(3, "/nonexistent/never.h5")
    path = ea.save([branches[0]], tmp_path / "one.h5", problem=problem)
    assert len(ea.BranchFile(path).branches) == 1


def test_snaps_of_an_interrupted_run_says_so(cli_exe, tmp_path):
    """A run interrupted before its snap-back scan (here Ctrl-C raised from the progress
    callback once a few points are in: an event, not a time) has no targets because of
    that, not for want of a shooting hook: the command says so and how to complete it."""
    problem = ea.load_problem("elastica_lever_arm")

    def interrupt(branch, points, folds, value):
        if points >= 5:
            raise KeyboardInterrupt

    with pytest.raises(ea.Interrupted) as info:
        ea.continuation(problem, {"eps": 0.25, "P": np.pi ** 2 / 4}, "psi", progress=interrupt)
    ea.save(info.value.branches, tmp_path / "cut.h5")
    out = run_cli(cli_exe, "snaps", tmp_path / "cut.h5")
    assert out.returncode == 0
    assert out.stdout.strip() == ("no snap-back targets: the run was interrupted (branch 1) "
                                  "before its snap-back scan; elastica-auto run cut --resume "
                                  "completes it")
