"""Sweeps: parameter ranges in run files, and ``--resume``.

A range ``{ from = A, to = B, num = N }`` is N equally spaced values, ends included. A run
interrupted and then resumed holds every cell of the plan once, each number for number what an
uninterrupted run computes; resuming a complete file computes nothing.
"""

from __future__ import annotations

import json
import signal
import subprocess

import numpy as np
import pytest

from elastica_auto.execution import runfile
from elastica_auto.storage.store import BranchFile
from helpers import run_cli, signalling_elastica, wait_for

SWEEP = """\
equation = "elastica_lever_arm"
start = "trivial"
[parameters]
eps = { from = 0.2, to = 0.5, num = 4 }
P = "pi^2/4"
[continuation]
parameter = "psi"
directions = "both"
bounds = [-3.2, 3.2]
[options]
ds_max = 0.05
"""


@pytest.fixture
def sweep(tmp_path):
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    return path


def test_a_range_is_equally_spaced_values_ends_included(sweep):
    plan = runfile.load(sweep)
    eps = [spec.params["eps"] for spec in plan.branches]
    assert eps == [0.2, 0.2, 0.3, 0.3, 0.4, 0.4, 0.5, 0.5]
    assert [spec.direction for spec in plan.branches] == [1, -1] * 4


@pytest.mark.parametrize("text, words", [
    ("{ from = 0.2, to = 0.5 }", "a range is { from = A, to = B, num = N }"),
    ("{ from = 0.2, to = 0.5, num = 0 }", "eps.num: expected a positive integer"),
    ("{ from = 'x', to = 0.5, num = 3 }", "eps.from: "),
])
def test_a_bad_range_is_one_line(sweep, text, words):
    sweep.write_text(SWEEP.replace("{ from = 0.2, to = 0.5, num = 4 }", text))
    with pytest.raises(runfile.RunFileError, match=words.replace("{", r"\{").replace("}", r"\}")
                       .replace(".", r"\.")):
        runfile.load(sweep)


def _by_cell(path):
    return {b.attrs["cell"]: b for b in BranchFile(path).branches}


def test_an_interrupted_sweep_resumes_to_the_whole_file(sweep, tmp_path, cli_exe):
    """The signal comes in a step of the second branch, held until it comes (by a copy of
    the elastica that says so): the first branch is saved whole, the second up to there."""
    whole = tmp_path / "whole"
    # every branch computed (none the mirror image of another): the signal comes in a step;
    # the whole run with the same module (the elastica written by hand), unsignalled
    signalling_elastica(tmp_path / "plain.py")
    sweep.write_text(SWEEP.replace('"elastica_lever_arm"', '"plain.py"') + "mirror = false\n")
    assert run_cli(cli_exe, "run", sweep, "--out", whole, "-j", "1").returncode == 0
    out, held = tmp_path / "out", tmp_path / "held"
    sweep.write_text(SWEEP.replace('"elastica_lever_arm"', '"mine.py"') + "mirror = false\n")
    # the first step beyond |psi| = 1 once the first branch is saved
    signalling_elastica(tmp_path / "mine.py", hold=(
        f'abs(p["psi"]) > 1 and _os.path.exists({str(out / "sweep.h5")!r})', held))
    proc = subprocess.Popen([cli_exe, "run", sweep, "--out", out, "-j", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for("a step of the second branch", held.exists, proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    first = BranchFile(out / "sweep.h5").branches
    assert [b.attrs["end"] for b in first] == ["EP", "MX"]
    assert first[1].attrs["message"] == "interrupted by the user"
    again = run_cli(cli_exe, "run", sweep, "--out", out, "-j", "1", "--resume")
    assert again.returncode == 0, again.stderr
    kept = sum(b.attrs["message"] != "interrupted by the user" for b in first)
    assert f"sweep: {kept} branches kept, {8 - kept} branches" in again.stdout
    resumed, reference = _by_cell(out / "sweep.h5"), _by_cell(whole / "sweep.h5")
    assert len(BranchFile(out / "sweep.h5").branches) == 8
    assert resumed.keys() == reference.keys()
    for key, b in reference.items():
        for name in ("psi", "m1", "index", "arclength"):
            np.testing.assert_array_equal(resumed[key].columns[name], b.columns[name])
    labels = BranchFile(out / "sweep.h5").labels
    assert sorted(labels) == sorted(BranchFile(whole / "sweep.h5").labels)
    assert {json.loads(k)["params"]["eps"] for k in resumed} == {0.2, 0.3, 0.4, 0.5}


def test_resuming_a_complete_file_computes_nothing(sweep, tmp_path, cli_exe):
    out = tmp_path / "out"
    assert run_cli(cli_exe, "run", sweep, "--out", out).returncode == 0
    before = (out / "sweep.h5").stat().st_mtime_ns
    proc = run_cli(cli_exe, "run", sweep, "--out", out, "--resume")
    assert proc.returncode == 0
    assert proc.stdout.strip() == (f"sweep: every cell is in {out / 'sweep.h5'} already "
                                   "(8 branches); nothing to compute")
    assert (out / "sweep.h5").stat().st_mtime_ns == before


# -- a resumed file has a whole run's snap-back targets and landings (user round, resume45) --
FOLDS = """\
equation = "elastica_lever_arm"
[parameters]
eps = [0.25, 0.5]
P = "pi^2/4"
[continuation]
parameter = "psi"
directions = "both"
bounds = ["-pi", "pi"]
landing = true
damping = [1.0]
[options]
mirror = false
"""


#: Snaps at subcritical branch points (`test_kirchhoff_runs`: b2 = 2, eps = 0.5), none at folds.
BPS = """\
equation = "kirchhoff_lever_arm"
[parameters]
P = "pi^2/4"
eps = 0.5
b2 = 2.0
[continuation]
parameter = "psi"
directions = "both"
bounds = [-1.4, 1.4]
[options]
max_points = 200
mirror = false
"""


def _interrupted_after_first_branch(plan, out, monkeypatch):
    """The run stopped by a Ctrl-C just after its first branch is computed (as the
    robustness tests stop one, `test_an_interruption_after_a_branch_is_computed_keeps_it`):
    its file holds that branch and no analysis."""
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution import schedule as schedule_module
    real = schedule_module.compute_branch

    def interrupted(*args, **kwargs):
        branch = real(*args, **kwargs)
        signal.raise_signal(signal.SIGINT)
        return branch

    monkeypatch.setattr(schedule_module, "compute_branch", interrupted)
    assert run_module.execute(plan, out, jobs=1).interrupted
    monkeypatch.undo()
    saved = BranchFile(out / plan.output_name)
    assert [b.attrs["end"] for b in saved.branches] == ["EP"] and saved.snaps == []


def _same_rows(a, b):
    assert len(a) == len(b)
    for r, s in zip(a, b):
        assert r.keys() == s.keys()
        for key in r:
            assert np.array_equal(r[key], s[key], equal_nan=not isinstance(r[key], str)), key


@pytest.mark.parametrize("name, text, snaps, landings", [
    ("folds", FOLDS, [("LP1", 2), ("LP2", 1), ("LP3", 4), ("LP4", 3)], {1, 2, 3, 4}),
    ("bps", BPS, [("BP1", 2), ("BP2", 1)], set()),
], ids=["folds", "bps"])
def test_a_resumed_file_has_the_whole_runs_snap_targets_and_landings(tmp_path, monkeypatch,
                                                                      name, text, snaps,
                                                                      landings):
    """User round: an interrupted run resumed had the snap-back targets and landings of the
    branches computed after the resume only (the kept branches' folds had none, and nothing
    said so), and the new branches' targets named no kept branch as theirs. Now the resumed
    file's tables are the whole run's, row for row: in ``folds`` branch 1's target lies on
    branch 2, computed after the resume, and branch 2's on branch 1, kept; in ``bps`` the
    kept branch's snap is at a subcritical branch point (its decision read back from the
    file). (No branch is the mirror image of another: a resumed run computes branch 2, whose
    image branch 1 is kept, by continuation, whole runs by reflection, equal to rounding
    only.)"""
    from elastica_auto.execution import run as run_module
    (tmp_path / f"{name}.toml").write_text(text)
    plan = runfile.load(tmp_path / f"{name}.toml")
    whole = run_module.execute(plan, tmp_path / "whole", jobs=1)
    reference = BranchFile(tmp_path / "whole" / f"{name}.h5")
    assert not whole.missing
    assert [(r["lp"], r["on_branch"]) for r in reference.snaps] == snaps
    assert {r["branch"] for r in reference.landings} == landings
    out = tmp_path / "out"
    _interrupted_after_first_branch(plan, out, monkeypatch)
    resumed = run_module.execute(plan, out, jobs=1, resume=True)
    assert resumed.kept == 1 and not resumed.missing and not resumed.interrupted
    bf = BranchFile(out / f"{name}.h5")
    assert bf.missing == []
    for b, c in zip(bf.branches, reference.branches, strict=True):
        assert np.array_equal(b.columns["psi"], c.columns["psi"])
    _same_rows(bf.snaps, reference.snaps)
    _same_rows(bf.landings, reference.landings)


def test_kept_branches_that_cannot_be_read_back_are_missing_their_targets(tmp_path,
                                                                         monkeypatch):
    """Where the kept branches cannot be read back (a file damaged since it was opened, here
    a StoreError in their reading), their snap-back targets and landings are recorded as
    missing (kind "file", the run's exit status 3), and the branches computed now have
    theirs, numbered in the file."""
    from elastica_auto.execution import run as run_module
    from elastica_auto.storage.store import StoreError
    (tmp_path / "folds.toml").write_text(FOLDS)
    plan = runfile.load(tmp_path / "folds.toml")
    out = tmp_path / "out"
    _interrupted_after_first_branch(plan, out, monkeypatch)

    def unreadable(self, b, problem):
        raise StoreError(f"{self.path}: damaged branch file: branch 001 unreadable")

    monkeypatch.setattr(BranchFile, "in_memory", unreadable)
    resumed = run_module.execute(plan, out, jobs=1, resume=True)
    bf = BranchFile(out / "folds.h5")
    assert [(m["what"], m["kind"]) for m in bf.missing] == [("snaps", "file"),
                                                             ("landings", "file")]
    assert all("kept branches 1-1 not computed" in m["message"] for m in bf.missing)
    assert [m["what"] for m in resumed.missing] == ["snaps", "landings"]
    assert not resumed.internal
    assert sorted({r["branch"] for r in bf.snaps}) == [2, 3, 4]
    assert sorted({r["branch"] for r in bf.landings}) == [2, 3, 4]


def test_a_branch_read_back_is_the_branch_computed(tmp_path):
    """`BranchFile.in_memory` gives back the branch a run computed, as the analyses use it:
    each point's parameters, ordinates, index columns, label and profile, each labelled
    point's solution and tangent, and each BP's subcritical decision (read back from its
    note), compared with the run's branches in memory."""
    from elastica_auto.execution import run as run_module
    (tmp_path / "bps.toml").write_text(BPS)
    plan = runfile.load(tmp_path / "bps.toml")
    computed = run_module.execute(plan, tmp_path / "out", jobs=1).branches
    bf = BranchFile(tmp_path / "out" / "bps.h5")
    decided = [p.subcritical for br in computed for p in br.points if p.type == "BP"]
    assert decided == [True, True]
    for br, b in zip(computed, bf.branches, strict=True):
        back = bf.in_memory(b, plan.problem)
        assert (back.parameter, back.direction, back.number) == (br.parameter, br.direction,
                                                                   br.number)
        assert len(back.points) == len(br.points)
        for p, q in zip(br.points, back.points):
            assert (p.params, p.ordinates, p.type, p.label, p.note, p.subcritical) == \
                (q.params, q.ordinates, q.type, q.label, q.note, q.subcritical)
            assert (p.index, p.index_rule, p.index_direct) == (q.index, q.index_rule,
                                                               q.index_direct)
            assert np.array_equal(p.profile, q.profile)
            if p.type:
                assert np.array_equal(p.state.y, q.state.y)
                assert np.array_equal(p.state.s, q.state.s)
                assert p.state.params == q.state.params
                assert (p.tangent is None) == (q.tangent is None)
                if p.tangent is not None:
                    assert np.array_equal(p.tangent.y, q.tangent.y)
                    assert p.tangent.lam == q.tangent.lam
