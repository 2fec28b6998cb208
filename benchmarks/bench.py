"""Benchmarks, as `make bench` prints them; nothing here asserts.

1. The cost of one continuation step of the elastica (4 states) on fixed meshes of 100, 400 and
   1600 intervals (collocation corrector: Newton with the previous point's factorisation,
   the linearisation at the new point, its tangent, the determinant's sign, the direct
   index), and of locating one fold.
2. The rotating_arm run in one process, for each corrector: points, median milliseconds per
   continuation step (wall time between accepted points, so rejected attempts and the
   location of LP/UZ/EP points are included), folds and the largest fold residual.
3. Whole processes, for each corrector: ``elastica-auto run rotating_arm`` with ``--jobs 1``
   and with the default (one process per core), ``examples/bratu.toml``, the tendon robot's
   ``tendon_lift`` (after ``tendon_weight``; issue 49's target, under 10 s), and every run
   of ``make runs`` (in restart order) with their sum.

4. Two-parameter continuation: one fold curve of 500 points (the rotating arm's first fold
   at P = pi^2/4 followed in eps, ds = ds_max = 0.02), its seconds and milliseconds per
   point; and the map runs of ``make fig-map-arm`` / ``fig-map-load`` as whole processes
   (their one-parameter runs first).

5. A sweep of 64 short branches (32 arm lengths, both directions) on a local Dask cluster of
   1 and 2 workers, and in one process: branches per second, and the scheduling overhead per
   task (the cluster's busy time not spent in the branches, over the tasks).

6. Where a snap lands: the rotating arm at eps = 0.5, P = 9 pi^2/4 (psi both ways to 6 pi),
   the overdamped landing from each of its folds that end a stable branch, and the damped
   model's at c = 0.5 and 2 from the first three (``make runs`` times ``snap_damping`` without
   its damping sweep, which this measures per landing).

7. The direct count of the stability index: one point of the planar elastica (k = 1, on its
   own mesh) and a three-component form with coupling (k = 3) on 100 intervals, with and
   without a constraint; median milliseconds (``--index`` prints only these).

8. The cost of a step as the system grows (``--size`` prints only this): one continuation
   step on a fixed mesh of 100 intervals for n = 4 (the elastica), 6 (the rotating disk of
   ``examples/karman_disk.py`` with its free parameter), 10 (the spatial rod; the planar
   elastica's fold-curve system), 13 (the spatial Cosserat rod, S = 1000) and 20 (five copies
   of the elastica stacked as one system),
   for the cubic scheme (ncol 0) and Gauss collocation (ncol 4), each step predicted as a run
   predicts it (tangent and curvature): median ms per step, the mean Newton iterations, and
   the mean split into assembly (residuals and Jacobian blocks), factorisation, solves, the
   error estimate and test functions, the index, and the rest (Newton's bookkeeping). CPU
   time of the process (``time.process_time``), which a loaded machine disturbs less than
   the wall clock.

``--disk``: the rotating disk (``examples/karman_disk.toml`` continued to a = 10, ntst = 10) at
tol 1e-5 and 1e-7 for each ``ncol``: nodes and unknowns per point, the largest error of
F'(0), G'(0) and the inflow at its UZ points against scipy's solve_bvp at tol 1e-10, seconds.

9. Energy-first modules (``--energy`` prints only this): the shipped modules derived from
   their energies (``elastica_lever_arm``, ``kirchhoff_lever_arm``) against the hand-written
   modules they replaced (``tests/reference/``), alternated: one continuation step on a fixed
   mesh, the rotating_arm and rotating_arm_3d runs in one process; the warm load (cache
   filled, a fresh process) of them and of ``examples/bratu.py`` against their references;
   the cold derivation (``cache=False``), sympy's import separately.

``--memory``: the peak memory of one branch of 2500 and of 10^4 points. ``--saves``: the share
of the rotating_arm run spent writing its branch file (also in ``main``). ``--fold-curve``:
section 4's fold curve alone (wall and CPU milliseconds per point).
This machine's speed drifts: compare two commits by running this alternately on both.

The sections are the modules of ``benchmarks/sections/`` (`sections.steps`, `sections.runs`,
...); this script is their command line.
"""

from __future__ import annotations

import sys

from sections.energy import energy
from sections.landing import landing
from sections.runs import (disk_unknowns, in_process, memory, saves,  # noqa: F401 (SECTIONS)
                           whole_processes)
from sections.steps import index_cost, size_cost, step_cost
from sections.sweep import sweep
from sections.two_parameter import fold_curve, map_runs
from sections import CORRECTORS


def main():
    step_cost()
    print()
    index_cost()
    print("\nrotating_arm in one process (8 branches to |psi| = 6 pi):")
    print(f"{'corrector':>12} {'points':>7} {'ms/step':>9} {'folds':>6} "
          f"{'max fold res.':>14} {'seconds':>9}")
    for corrector in CORRECTORS:
        in_process(corrector)
    print("\nwhole processes:")
    for corrector in CORRECTORS:
        whole_processes(corrector)
    print("\ntwo-parameter continuation:")
    fold_curve()
    print("the runs of the stability maps, whole processes (default --jobs):")
    map_runs()
    print()
    sweep()
    print()
    landing()
    print()
    size_cost()
    print()
    saves()
    print()
    energy()


#: The sections a flag runs alone; without one, `main`.
SECTIONS = {"--memory": "memory", "--sweep": "sweep", "--landing": "landing",
            "--index": "index_cost", "--size": "size_cost", "--fold-curve": "fold_curve",
            "--disk": "disk_unknowns", "--saves": "saves", "--energy": "energy"}

if __name__ == "__main__":
    if sys.argv[1:] and (len(sys.argv) > 2 or sys.argv[1] not in SECTIONS):
        sys.exit(f"usage: bench.py [{' | '.join(SECTIONS)}]")
    globals()[SECTIONS[sys.argv[1]] if sys.argv[1:] else "main"]()
