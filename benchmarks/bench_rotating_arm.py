"""Benchmark: the rotating_arm run (8 branches to |psi| = 6 pi), as `make bench` prints it;
with ``--memory``, the peak memory of branches of 2500 and 10^4 points.

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


LONG_RUN = """\
equation = "elastica_lever_arm"
[parameters]
eps = 0.25
P = "pi^2/4"
[continuation]
parameter = "psi"
directions = "+"
bounds = ["-1000", "1000"]
[options]
ds_max = 0.05
max_points = {n}
"""

MEMORY_PROBE = """\
import resource, sys
from pathlib import Path
from elastica_auto.run import execute
from elastica_auto.runfile import load
r = execute(load(Path(sys.argv[1])), Path(sys.argv[2]), jobs=1)
print(len(r.branches[0].points), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def memory(sizes=(2500, 10000)):
    """Peak resident memory of one branch of n points, each in a fresh process: it grows in
    proportion to the points stored (profiles on a 101-point grid, columns), not faster."""
    import subprocess
    print("memory of one long branch (fresh process each, one psi-branch, ds_max = 0.05):")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            run = Path(tmp) / f"long{n}.toml"
            run.write_text(LONG_RUN.format(n=n))
            t0 = time.perf_counter()
            out = subprocess.run([sys.executable, "-c", MEMORY_PROBE, str(run), tmp],
                                 capture_output=True, text=True, check=True).stdout.split()
            pts, kib = int(out[0]), int(out[1])
            rows.append((pts, kib))
            print(f"  {pts:>6} points: peak RSS {kib / 1024:7.1f} MiB, "
                  f"{time.perf_counter() - t0:6.1f} s")
    (p1, m1), (p2, m2) = rows[0], rows[-1]
    print(f"  growth: {(m2 - m1) / (p2 - p1):.2f} KiB per point "
          f"(a profile alone is {4 * 101 * 8 / 1024:.2f} KiB)")


if __name__ == "__main__":
    if sys.argv[1:] == ["--memory"]:
        memory()
    else:
        main(*sys.argv[1:])
