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

import numpy as np

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


class _Branch:
    """A branch as `tools/three_d.py` reads one: columns, labels, the continued parameter."""

    def __init__(self, lam, y, kinds):
        n = len(lam)
        self.parameter = "alpha"
        self.attrs = {"ordinate": "mA"}
        self.columns = {"alpha": np.asarray(lam, float), "mA": np.asarray(y, float),
                        "type": np.array(kinds), "index_in": np.zeros(n),
                        "index_out": np.zeros(n), "eps": np.full(n, 0.5), "P": np.full(n, 1.0)}

    def __len__(self):
        return len(self.columns["alpha"])

    def label_names(self):
        return [f"{t}{k}" if t in ("LP", "BP") else "" for k, t in enumerate(self.columns["type"])]


def test_three_d_lists_a_stretch_once_whatever_its_points():
    """Hostile round 3: `stretches out/rotating_load_3d.h5` listed the stretch from BP 5.8680
    to BP 11.6189 twice (m1 -0.5825 and -0.0457), though docs/three-d.md says each stretch is
    listed once: its two directions have their points at different places, and the ordinate
    was read at the point nearest the middle, 0.37 from it on a steep stretch. It is now
    interpolated at the middle: both directions of one stretch (here y = tanh(5 (a - m)),
    steep at its middle m, its points 0.6 apart on one and 0.5 apart on the other, shifted)
    give y(m) = 0 to the interpolation's error, and one row."""
    sys.path.insert(0, str(REPO / "tools"))
    try:
        import three_d
    finally:
        sys.path.remove(str(REPO / "tools"))
    lo, hi = 5.8680, 11.6189
    mid = 0.5 * (lo + hi)

    def branch(step, offset, reverse):
        inner = np.arange(lo + offset, hi, step)
        lam = np.concatenate(([lo - 0.3, lo], inner, [hi, hi + 0.3]))
        kinds = ["RG", "BP", *["RG"] * len(inner), "BP", "RG"]
        if reverse:                     # the other direction: the same stretch backwards
            lam, kinds = lam[::-1], kinds[::-1]
        return _Branch(lam, np.tanh(5 * (lam - mid)), kinds)

    class _File:
        branches = [branch(0.6, 0.05, False), branch(0.5, 0.37, True)]

    rows = three_d.distinct_stretches(_File(), in_plane=0)
    assert len(rows) == 1, rows
    (_, (t0, v0), (t1, v1), ymid, _, _), = rows
    assert (t0, t1) == ("BP", "BP") and abs(v0 - lo) < 1e-12 and abs(v1 - hi) < 1e-12
    assert abs(ymid) < 0.5                 # tanh between neighbours at most 0.6 apart
