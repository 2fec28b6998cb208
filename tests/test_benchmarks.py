"""Issue 48 item 5: the benchmarks (``make bench``, ``benchmarks/bench.py``) import and run.
Their sections are modules (``benchmarks/sections/``); the cheapest, the direct count of
the index (``--index``), runs here with two repeats, and its printed index is checked
against the counts of two independent ones (`tests/jacobi.py`: the Jacobi field's zeros, P1
elements on 800 intervals) at the same state. Nothing is timed: the numbers themselves
belong to ``make bench``."""

from __future__ import annotations

import ast
import math
import re
import subprocess
import sys

import numpy as np

from helpers import REPO

BENCHMARKS = REPO / "benchmarks"


def test_the_index_section_runs_with_tiny_sizes(capsys, monkeypatch, elastica):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    from sections import steps
    steps.index_cost(repeats=2)
    out = capsys.readouterr().out
    (index,) = map(int, re.findall(r"elastica \(k = 1, 100 intervals\): [\d.]+ \(index (\d+)\)",
                                   out))
    assert len(re.findall(r"k = 3, 100 intervals, (?:no|one) constraint: [\d.]+", out)) == 2
    from jacobi import direct_index
    s = np.linspace(0.0, 1.0, 101)
    theta = 1.2 * np.sin(math.pi * s / 2)     # the section's state
    y = np.vstack((theta, 0.6 * math.pi * np.cos(math.pi * s / 2), -np.sin(theta),
                   np.cos(theta)))
    from elastica_auto.core.solution import State
    params = {**elastica.defaults(), "eps": 0.25, "P": 9 * math.pi ** 2 / 4}
    state = State.from_values(elastica, s, y, params)
    assert (index, index) == direct_index(elastica, state)


def test_bench_keeps_its_command_line():
    """``bench.py`` imports every section (the flags' table names functions it has), and
    refuses an unknown flag with its usage, before running anything."""
    proc = subprocess.run([sys.executable, str(BENCHMARKS / "bench.py"), "--nothing"],
                          capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 1
    assert proc.stderr.strip() == ("usage: bench.py [--memory | --sweep | --landing | --index | "
                                   "--size | --fold-curve | --disk | --saves | --energy]")


def test_the_benchmarks_import_no_private_name_of_the_package():
    bad = []
    for path in sorted(BENCHMARKS.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(
                    "elastica_auto"):
                bad += [f"{path.name}:{node.lineno} {a.name}" for a in node.names
                        if a.name.startswith("_")]
    assert bad == []


def test_the_run_profile_assigns_each_sample_to_its_innermost_part(monkeypatch):
    """``benchmarks/profile_run.py``: a sample is the innermost part of the run it falls in
    (the index counted inside the step's detection is the index, not the detection; a
    stepper helper called in placing the labels is the labels; an import under ``execute``
    is inside the run, before it at start-up); one sampled process
    of Bratu's run file shares its CPU out over parts that include the corrector, and the
    parts and the interpreter's start add up to the process's CPU."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import profile_run
    cli = ("/x/elastica_auto/cli.py", "run")
    execute = ("/x/elastica_auto/execution/run.py", "execute")
    step = [cli, execute, ("/x/elastica_auto/branches/stepper.py", "_walk"),
            ("/x/elastica_auto/branches/stepper.py", "_step")]
    detect = ("/x/elastica_auto/branches/stepper.py", "_detect")
    count = ("/x/elastica_auto/numerics/stability.py", "count")
    numpy = ("/x/numpy/linalg/_linalg.py", "solve")
    load = ("<frozen importlib._bootstrap>", "_find_and_load")
    assert profile_run.part(step + [detect, count, numpy]) == "index (direct count)"
    assert profile_run.part(step + [detect, numpy]) == "test functions (fold and BP signs)"
    assert profile_run.part(step + [detect, load]) == "imports inside the run"
    assert profile_run.part([cli, load, numpy]) == "imports at start-up"
    assert profile_run.part(step) == "the walk's own bookkeeping, progress"
    placed = [("/x/elastica_auto/branches/stepper.py", "_add_events"),
              ("/x/elastica_auto/branches/kinds.py", "place"), numpy]
    assert profile_run.part(step + placed) == "labels (UZ, EP) placed"
    shares, cpu, bare, total = profile_run.profile(str(REPO / "examples" / "bratu.toml"), 1)
    assert total > 0 and "corrector (predictor, Newton, mesh, tangent)" in shares
    assert math.isclose(sum(shares.values()) + bare, cpu)
