"""Shared fixtures. Expensive continuations run once per session."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

from elastica_auto.execution import runfile
from elastica_auto.model.problem import load_problem
from helpers import ROTATING_ARM, RunOutput, elastica_run_file, run_cli, run_plan


#: the tests of an xdist_group that --dist loadgroup does not keep on one worker
_UNGROUPED: set[str] = set()


def pytest_collection_finish(session):
    """Under ``--dist loadgroup`` (``make test``), each test of an ``xdist_group`` runs on its
    group's worker only because pytest-xdist appends the group to its node id: the paper's
    reduced runs are then built once (tests/test_paper_runs.py). Where the pytest in use
    ignores that (pytest 9.2 with pytest-xdist 3.8: nothing fails, and every worker builds
    the runs, minutes of CPU each), those tests fail at once instead (`pytest_runtest_setup`)."""
    if getattr(session.config.option, "loadgroup", False):     # set on xdist's workers
        _UNGROUPED.update(item.nodeid for item in session.items
                          if item.get_closest_marker("xdist_group") and "@" not in item.nodeid)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    if item.nodeid in _UNGROUPED:      # before its fixtures are set up
        pytest.fail("--dist loadgroup does not group the tests of an xdist_group with this "
                    "pytest (pytest-xdist's group suffix is not in their node ids): install "
                    "a pytest that the test extra of pyproject.toml allows", pytrace=False)


@pytest.fixture(scope="session")
def elastica():
    return load_problem("elastica_lever_arm")


@pytest.fixture(scope="session")
def elastica_reference():
    """The hand-written elastica that the shipped energy-first module replaced (issue 47)."""
    from helpers import REFERENCE
    return load_problem(REFERENCE / "elastica_lever_arm.py")


@pytest.fixture(scope="session")
def rotating_arm(tmp_path_factory) -> RunOutput:
    """The shipped rotating_arm run, all branches, computed once (about 10-15 s)."""
    plan = runfile.load(ROTATING_ARM)
    # The symmetry tests below assume the paper's configuration; fail loudly if it changed.
    assert plan.parameter == "psi"
    for spec in plan.branches:
        assert spec.start.kind == "trivial"
        assert spec.params.get("alpha", 0.0) == 0.0 and spec.params.get("theta0", 0.0) == 0.0
    return run_plan(plan, tmp_path_factory.mktemp("rotating_arm"), jobs=2)


@pytest.fixture(scope="session")
def cli_exe() -> str:
    """The installed console script."""
    exe = shutil.which("elastica-auto") or str(Path(sys.executable).parent / "elastica-auto")
    assert Path(exe).is_file(), "console script elastica-auto not installed"
    return exe


@pytest.fixture(scope="session")
def small_cli_run(tmp_path_factory, cli_exe):
    """A one-(eps, P) rotating-arm run through the console script: (out_dir, h5 path, process)."""
    root = tmp_path_factory.mktemp("small_cli")
    toml = elastica_run_file(root / "small.toml", uz=[0, "pi/12", "pi/6", "pi/2"])
    out = root / "out"
    proc = run_cli(cli_exe, "run", toml, "--out", out)
    return out, out / "small.h5", proc


@pytest.fixture(scope="session")
def trivial_buckling(tmp_path_factory) -> RunOutput:
    """The shipped trivial_buckling run (P from the straight rod, switching at its first two
    branch points), computed once (about 5 s)."""
    from helpers import REPO
    plan = runfile.load(REPO / "runs" / "trivial_buckling.toml")
    # The tests assume the shipped configuration: straight rods with psi = alpha = theta0 = 0.
    assert plan.parameter == "P" and plan.switch_count == 2
    for spec in plan.branches:
        assert spec.start.kind == "trivial"
        assert all(spec.params.get(k, 0.0) == 0.0 for k in ("psi", "alpha", "theta0", "P"))
    return run_plan(plan, tmp_path_factory.mktemp("trivial_buckling"))


@pytest.fixture(scope="session")
def good_file(tmp_path_factory, cli_exe):
    """A small complete branch file (test_robustness's SMALL run), computed once."""
    from test_robustness import SMALL
    d = tmp_path_factory.mktemp("good")
    (d / "small.toml").write_text(SMALL)
    assert run_cli(cli_exe, "run", d / "small.toml", "--out", d).returncode == 0
    return d / "small.h5"


@pytest.fixture(scope="session")
def viewer_file(tmp_path_factory, elastica):
    """A small branch file for the viewer: the rotating arm at eps = 0.25, P = pi^2/4, psi in
    [-2 pi, 2 pi] both ways from the straight rod (71 points, folds LP1 and LP2, snap-back
    targets), computed once (about 1 s)."""
    import math

    import elastica_auto as ea
    branches = ea.continuation(elastica, {"eps": 0.25, "P": math.pi ** 2 / 4}, "psi",
                               directions="both", bounds=(-2 * math.pi, 2 * math.pi),
                               uz=[math.pi / 2])
    return ea.save(branches, tmp_path_factory.mktemp("viewer") / "arm.h5")
