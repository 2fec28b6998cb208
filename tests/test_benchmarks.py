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
