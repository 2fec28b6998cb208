"""Issue 48 item 5: the scripts outside the package run. ``tools/three_d.py`` (the answer
script of docs/three-d.md) prints its tables from a small planar branch file: the rotating
arm at eps = 0.25, P = pi^2/4 (`viewer_file`: folds LP1, LP2 at psi = +-0.8173, a user point
at psi = pi/2). What it reads from the file is checked against the file itself; the
out-of-plane counts are the spatial module's own (`part_counts`), tested in
tests/test_kirchhoff.py."""

from __future__ import annotations

import math
import re
import subprocess
import sys

from elastica_auto.storage.store import BranchFile
from helpers import REPO

THREE_D = REPO / "tools" / "three_d.py"


def _table(*args) -> list[list[str]]:
    """The markdown table ``tools/three_d.py ARGS`` prints: its rows (header first) as cells."""
    proc = subprocess.run([sys.executable, str(THREE_D), *map(str, args)], capture_output=True,
                          text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("|")]
    assert len(lines) >= 2 and set(lines[1]) <= set("|-")
    return [[c.strip() for c in ln.strip("|").split("|")] for ln in lines[:1] + lines[2:]]


def test_three_d_lists_its_tables():
    proc = subprocess.run([sys.executable, str(THREE_D), "--help"], capture_output=True,
                          text=True, check=True)
    for table in ("stretches", "changes", "embedding", "targets", "snaps", "equilibria",
                  "embedded-labels", "embedded-stretches", "embedded-changes", "folds"):
        assert table in proc.stdout


def test_three_d_embedded_tables_of_a_planar_file(viewer_file):
    bf = BranchFile(viewer_file)
    header, *rows = _table("embedded-labels", viewer_file, "--b2", 1, 2, "--c", 0.5)
    assert header[3:] == ["b2 = 1, c = 0.5", "b2 = 2, c = 0.5"]
    nb, pt = bf.labels["UZ1"]
    br = bf.branches[nb - 1]
    (row,) = rows                       # the one stable user point
    assert float(row[1]) == round(math.pi / 2, 4)
    assert float(row[2]) == round(float(br.columns["m0"][pt - 1]), 3)
    assert all(re.fullmatch(r"\d+", c) for c in row[3:])
    header, *rows = _table("embedded-stretches", viewer_file, "--b2", 1, "--c", 0.5)
    assert header[-2:] == ["index_in", "index_out"] and rows
    folds = {round(float(psi) % (2 * math.pi), 4) for b in bf.branches
             for psi, kind in zip(b.columns["psi"], b.columns["type"]) if kind == "LP"}
    ends = {float(c.split()[1]) % (2 * math.pi) for r in rows for c in r[1:3]
            if c.startswith("LP")}
    assert ends and {round(e, 4) for e in ends} <= folds
    assert {r[4] for r in rows} == {"0"}          # the planar stable stretches
