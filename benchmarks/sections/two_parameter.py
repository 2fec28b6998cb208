"""Section 4: one fold curve in process (``--fold-curve``), and the map runs as whole
processes."""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

from . import REPO
from .runs import timed


def fold_curve(points=500):
    """One fold curve of ``points`` points in process, after a warm-up curve."""
    import elastica_auto as ea
    problem = ea.load_problem("elastica_lever_arm")
    arm = ea.continuation(problem, {"eps": 0.25, "P": math.pi ** 2 / 4}, "psi",
                          bounds=(-2 * math.pi, 2 * math.pi))
    lp = arm.label("LP1")
    ea.continuation(problem, lp, ["psi", "eps"], bounds=(0, 1), max_points=20)
    t0, c0 = time.perf_counter(), time.process_time()
    (br,) = ea.continuation(problem, lp, ["psi", "eps"], bounds=(0, 50), max_points=points,
                            ds=0.02, ds_max=0.02)
    dt, dc = time.perf_counter() - t0, time.process_time() - c0
    print(f"fold curve in (psi, eps) from the first fold at P = pi^2/4: {len(br.points)} "
          f"points in {dt:.2f} s ({1000 * dt / len(br.points):.2f} ms/point; CPU "
          f"{1000 * dc / len(br.points):.2f} ms/point; up to {int(br.columns['nodes'].max())} "
          "nodes)")


def map_runs():
    """``make fig-map-arm`` and ``fig-map-load``'s runs from scratch, as whole processes."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        total = 0.0
        for run in ("rotating_arm", "fold_curves_arm", "rotating_load", "fold_curves_load"):
            dt = timed(["run", str(REPO / "runs" / f"{run}.toml"), "--out", str(out),
                         "-q"], tmp)
            total += dt
            print(f"  {run:<18} {dt:6.2f} s")
        print(f"  {'total':<18} {total:6.2f} s")
