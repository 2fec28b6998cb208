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
