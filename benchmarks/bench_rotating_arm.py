"""Benchmark: the rotating_arm run (8 branches to |psi| = 6 pi), as `make bench` prints it.

Prints, per branch: points, median ms per continuation step (wall time between accepted
points, so rejected attempts and the location of LP/UZ/EP points are included), seconds,
folds located and the largest fold-condition residual; then the whole run in one process and
with one process per core. Not a test: nothing here asserts.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from elastica_auto.cli import resolve_run
from elastica_auto.run import execute
from elastica_auto.runfile import load


def main(run="rotating_arm"):
    plan = load(resolve_run(run))
    stamps: dict[int, list[float]] = {}

    def progress(k, npts, nfolds, lam):
        stamps.setdefault(k, []).append(time.perf_counter())

    with tempfile.TemporaryDirectory() as tmp:
        serial = execute(plan, Path(tmp), progress, jobs=1)
        cores = os.cpu_count() or 1
        parallel = execute(plan, Path(tmp), jobs=cores)

    print(f"{run}: {len(plan.branches)} branches, continuation parameter {plan.parameter}")
    print(f"{'branch':>6} {'params':<22} {'dir':>3} {'points':>6} {'ms/step':>8} "
          f"{'seconds':>8} {'folds':>5} {'max fold residual':>18}")
    all_steps, worst = [], 0.0
    for k, br in enumerate(serial.branches, start=1):
        t = stamps.get(k, [])
        steps = [1e3 * (b - a) for a, b in zip(t, t[1:])]
        all_steps += steps
        res = max((p.fold_residual for p in br.folds), default=float("nan"))
        worst = max(worst, res) if res == res else worst
        p = br.points[0].params
        label = " ".join(f"{n}={p[n]:.4g}" for n in plan.varying)
        print(f"{k:>6} {label:<22} {'+' if br.direction > 0 else '-':>3} {len(br.points):>6} "
              f"{statistics.median(steps) if steps else float('nan'):>8.2f} {br.seconds:>8.2f} "
              f"{len(br.folds):>5} {res:>18.2e}")
    npts = sum(len(b.points) for b in serial.branches)
    nfolds = sum(len(b.folds) for b in serial.branches)
    located = sum(1 for b in serial.branches for p in b.folds if not p.note)
    print(f"points {npts}, median ms/step {statistics.median(all_steps):.2f}, "
          f"folds located {located}/{nfolds}, largest fold residual {worst:.2e}")
    print(f"whole run: {serial.seconds:.2f} s in one process, "
          f"{parallel.seconds:.2f} s with {min(cores, len(plan.branches))} processes "
          f"({cores} cores)")


if __name__ == "__main__":
    main(*sys.argv[1:])
