"""Benchmarks, as `make bench` prints them; nothing here asserts.

1. The cost of one continuation step of the elastica (4 states) on fixed meshes of 100, 400 and
   1600 intervals (collocation corrector: Newton with the previous point's factorisation,
   the linearisation at the new point, its tangent, the determinant's sign, the direct
   index), and of locating one fold.
2. The rotating_arm run in one process, for each corrector: points, median milliseconds per
   continuation step (wall time between accepted points, so rejected attempts and the
   location of LP/UZ/EP points are included), folds and the largest fold residual.
3. Whole processes, for each corrector: ``elastica-auto run rotating_arm`` with ``--jobs 1``
   and with the default (one process per core), ``examples/bratu.toml``, and every run of
   ``make runs`` (in restart order) with their sum.

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

``--memory``: the peak memory of one branch of 2500 and of 10^4 points. ``--saves``: the share
of the rotating_arm run spent writing its branch file (also in ``main``).
This machine's speed drifts: compare two commits by running this alternately on both.
"""

from __future__ import annotations

import importlib
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CORRECTORS = ("collocation", "solve_bvp")
CLI = [str(Path(sys.executable).parent / "elastica-auto")]


def step_cost(intervals=(100, 400, 1600), steps=40):
    """Median ms per continuation step on a fixed mesh (no regridding), and the time to
    locate the first fold met (on meshes refined to fold_tol, as in a run)."""
    import numpy as np

    from elastica_auto.correctors import Collocation
    from elastica_auto.events import Step, locate_fold
    from elastica_auto.options import ContinuationOptions
    from elastica_auto.problem import load_problem
    from elastica_auto.solution import State, secant
    from elastica_auto.stability import index
    from elastica_auto.stepper import start_solution

    problem = load_problem("elastica_lever_arm")
    params = {**problem.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    print("one continuation step of the elastica from the straight rod (psi, eps = 0.5, "
          "P = 9 pi^2/4, ds = 0.03), on a fixed mesh; then the first fold:")
    print(f"{'intervals':>10} {'ms/step':>8} {'ms/fold':>8}")
    for n in intervals:
        # tol = 1: no regridding, the mesh stays as given (folds still meet fold_tol)
        corr = Collocation(problem, "psi", ContinuationOptions(tol=0.99, ds_max=1.0))
        s = np.linspace(0.0, 1.0, n + 1)
        a = start_solution(corr, State.from_values(problem, s, problem.exact_start(s, params),
                                                   params), 1, None, False)
        times, ds, fold = [], 0.03, float("nan")
        while len(times) < steps or fold != fold:
            t0 = time.perf_counter()
            b = corr.step(a, ds)
            index(problem, b.state)
            times.append(time.perf_counter() - t0)
            if a.tangent.lam * b.tangent.lam < 0 and fold != fold:
                sec, dist = secant(a.state, b.state, "psi")
                t0 = time.perf_counter()
                locate_fold(corr, Step(a, b, sec, dist, 0.0, ds, "psi"))
                fold = time.perf_counter() - t0
            a = b
        print(f"{n:>10} {1e3 * statistics.median(times):>8.2f} {1e3 * fold:>8.1f}")


def in_process(corrector):
    from elastica_auto.run import execute
    from elastica_auto.runfile import load
    import dataclasses

    plan = load(REPO / "runs" / "rotating_arm.toml")
    plan.options = dataclasses.replace(plan.options, corrector=corrector)
    stamps: dict[int, list[float]] = {}

    def progress(k, npts, nfolds, lam):
        stamps.setdefault(k, []).append(time.perf_counter())

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        result = execute(plan, Path(tmp), progress, jobs=1)
        seconds = time.perf_counter() - t0
    steps = [1e3 * (b - a) for t in stamps.values() for a, b in zip(t, t[1:])]
    folds = [p for b in result.branches for p in b.folds]
    worst = max((p.fold_residual for p in folds), default=float("nan"))
    npts = sum(len(b.points) for b in result.branches)
    print(f"{corrector:>12} {npts:>7} {statistics.median(steps):>9.2f} "
          f"{len(folds):>6} {worst:>14.1e} {seconds:>9.2f}")


def _run_files(corrector, folder: Path) -> Path:
    """The shipped run files (and Bratu's), with ``corrector`` set, in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for src in list((REPO / "runs").glob("*.toml")) + [REPO / "examples" / "bratu.toml"]:
        text = src.read_text()
        if src.parent.name == "examples":
            text = text.replace('equation = "bratu.py"',
                                f'equation = "{REPO / "examples" / "bratu.py"}"')
        # the damped landings of snap_damping are timed per landing (`landing`), not here
        text = re.sub(r"(?m)^damping(_folds)? = .*$", "", text)
        if "[options]" in text:
            text = text.replace("[options]", f'[options]\ncorrector = "{corrector}"', 1)
        else:
            text += f'\n[options]\ncorrector = "{corrector}"\n'
        (folder / src.name).write_text(text)
    return folder


def _timed(args, cwd) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run(CLI + [str(a) for a in args], cwd=cwd, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if proc.returncode not in (0, 1):
        sys.exit(f"{' '.join(map(str, args))} failed: {proc.stderr.strip()[-300:]}")
    return seconds


def whole_processes(corrector):
    from elastica_auto.plots.__main__ import make_rules
    # the runs of `make runs`, in restart order, as the Makefile's generated rules list them
    runs = re.search(r"^PAPER_RUNS = (.+)$", make_rules(REPO / "runs"), re.M).group(1).split()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        files = _run_files(corrector, tmp / "runs")
        out = tmp / "out"
        one = _timed(["run", files / "rotating_arm.toml", "--out", out, "-q", "-j", "1"], tmp)
        default = _timed(["run", files / "rotating_arm.toml", "--out", out, "-q"], tmp)
        bratu = min(_timed(["run", files / "bratu.toml", "--out", out, "-q", "-j", "1"], tmp)
                    for _ in range(3))
        print(f"{corrector}: rotating_arm {one:.2f} s with --jobs 1, {default:.2f} s with "
              f"--jobs {os.cpu_count()}; examples/bratu.toml {bratu:.2f} s (best of 3)")
        total = 0.0
        for name in runs:
            seconds = _timed(["run", files / f"{name}.toml", "--out", out, "-q"], tmp)
            total += seconds
            print(f"    make runs: {name:<22} {seconds:7.2f} s")
        print(f"    make runs: {'sum':<22} {total:7.2f} s")


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


def fold_curve(points=500):
    """One fold curve of ``points`` points in process, after a warm-up curve."""
    import elastica_auto as ea
    problem = ea.load_problem("elastica_lever_arm")
    arm = ea.continuation(problem, {"eps": 0.25, "P": math.pi ** 2 / 4}, "psi",
                          bounds=(-2 * math.pi, 2 * math.pi))
    lp = arm.label("LP1")
    ea.continuation(problem, lp, ["psi", "eps"], bounds=(0, 1), max_points=20)
    t0 = time.perf_counter()
    (br,) = ea.continuation(problem, lp, ["psi", "eps"], bounds=(0, 50), max_points=points,
                            ds=0.02, ds_max=0.02)
    dt = time.perf_counter() - t0
    print(f"fold curve in (psi, eps) from the first fold at P = pi^2/4: {len(br.points)} "
          f"points in {dt:.2f} s ({1000 * dt / len(br.points):.2f} ms/point; "
          f"up to {int(br.columns['nodes'].max())} nodes)")


def map_runs():
    """``make fig-map-arm`` and ``fig-map-load``'s runs from scratch, as whole processes."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        total = 0.0
        for run in ("rotating_arm", "fold_curves_arm", "rotating_load", "fold_curves_load"):
            dt = _timed(["run", str(REPO / "runs" / f"{run}.toml"), "--out", str(out),
                         "-q"], tmp)
            total += dt
            print(f"  {run:<18} {dt:6.2f} s")
        print(f"  {'total':<18} {total:6.2f} s")


def sweep(branches=64):
    """The sweep's branches in one process and on local clusters of 1 and 2 workers (started,
    and the engine imported on each worker, before the clock, so that only the branches and
    their scheduling are timed; no snap-back scan)."""
    import elastica_auto as ea
    from elastica_auto import cluster
    from elastica_auto.plan import make_plan
    from elastica_auto.run import _built, _in_process
    problem = ea.load_problem("elastica_lever_arm")
    eps = [0.2 + 0.3 * k / (branches // 2 - 1) for k in range(branches // 2)]
    plan = make_plan(problem, {"P": math.pi ** 2 / 4, "psi": 0.0}, "psi",
                     params={"eps": eps}, bounds=(-math.pi, math.pi), directions="both")
    first = [_built(plan, spec) for spec in plan.branches]
    print(f"sweep of {len(first)} branches (psi in [-pi, pi], 32 arm lengths):")
    for workers in (0, 1, 2):
        client = cluster.local(workers) if workers else None
        if client is not None:
            client.run(importlib.import_module, "elastica_auto.run")
        branches = []
        t0 = time.perf_counter()
        if client is None:
            _in_process(plan, first, branches, lambda: None, None, None)
        else:
            cluster.run_on_cluster(client, plan, first, branches, lambda: None)
        wall = time.perf_counter() - t0
        if client is not None:
            cluster.close(client)
        busy = sum(b.seconds for b in branches)
        where = f"{workers} worker{'s' if workers > 1 else ''}" if workers else "one process"
        overhead = ((wall * max(workers, 1) - busy) / len(first)) * 1000
        print(f"  {where:<12} {wall:6.2f} s, {len(first) / wall:5.1f} branches/s; mean branch "
              f"{1000 * busy / len(first):.0f} ms, overhead {overhead:.0f} ms per task "
              f"({100 * overhead / (1000 * busy / len(first)):.0f}%)")


def landing(damped=3, damping=(0.5, 2.0)):
    """Seconds of the overdamped landing of every fold ending a stable branch, and of the
    damped model's from the first ``damped`` of them for each ``damping``."""
    import numpy as np

    import elastica_auto as ea
    from elastica_auto.landing import land
    from elastica_auto.snaps import enumerate_equilibria, snap_lps
    problem = ea.load_problem("elastica_lever_arm")
    branches = ea.continuation(problem, {"eps": 0.5, "P": 9 * math.pi ** 2 / 4}, "psi",
                               directions="both", bounds=(-6 * math.pi, 6 * math.pi))
    folds = []
    for br in branches:
        for p, side in snap_lps(br):
            k = br.points.index(p)
            other = br.points[k - 1 if side == "before" else k + 1]
            folds.append((p, int(np.sign(p.params["psi"] - other.params["psi"])),
                          enumerate_equilibria(problem, p.params)))
    t0 = time.perf_counter()
    for p, beyond, eqs in folds:
        land(problem, p.state, p.tangent, eqs, "psi", beyond)
    over = time.perf_counter() - t0
    print(f"where a snap lands (rotating arm, eps = 0.5, P = 9 pi^2/4): overdamped, "
          f"{len(folds)} folds {over:.2f} s ({1000 * over / len(folds):.0f} ms a fold)")
    for c in damping:
        times = []
        for p, beyond, eqs in folds[:damped]:
            t0 = time.perf_counter()
            land(problem, p.state, p.tangent, eqs, "psi", beyond, damping=c)
            times.append(time.perf_counter() - t0)
        print(f"  damped, c = {c:g}: " + ", ".join(f"{t:.2f}" for t in times)
              + f" s (the first {damped} folds; sum {sum(times):.2f} s)")


def index_cost(repeats=400):
    """Median ms of the direct count: the elastica at a buckled point (k = 1), and a k = 3
    form shaped like a spatial rod's (A = diag(1, 2, 1/1.3), B and C smooth and of the size
    of the paper's loads) on 100 intervals, unconstrained and with one constraint."""
    import numpy as np

    from elastica_auto.problem import load_problem
    from elastica_auto.second_variation import Constraint, SecondVariation
    from elastica_auto.solution import State
    from elastica_auto.stability import count, count_form

    def median_ms(f):
        f()
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            f()
            times.append(time.perf_counter() - t0)
        return 1e3 * statistics.median(times)

    problem = load_problem("elastica_lever_arm")
    s = np.linspace(0.0, 1.0, 101)
    params = {**problem.defaults(), "eps": 0.25, "P": 9 * math.pi ** 2 / 4}
    theta = 1.2 * np.sin(math.pi * s / 2)          # a buckled-like profile (the count does not
    y = np.vstack((theta, 0.6 * math.pi * np.cos(math.pi * s / 2), -np.sin(theta),
                   np.cos(theta)))                 # need an equilibrium)
    state = State.from_values(problem, s, y, params)
    a = np.diag([1.0, 2.0, 1 / 1.3])
    skew = np.array([[0.0, -1.0, 0.5], [1.0, 0.0, -0.3], [-0.5, 0.3, 0.0]])

    def rod(pts, constrained=False):
        c = np.cos(np.pi * pts)
        b = -22.0 * np.einsum("ij,m->ijm", np.array([[1.0, 0.2, 0.0], [0.2, 0.6, 0.1],
                                                     [0.0, 0.1, 0.3]]), c)
        return SecondVariation(a, b, np.einsum("ij,m->ijm", 2.0 * skew, 1 + 0.5 * c),
                               fixed0=[0, 1, 2],
                               constraints=[Constraint(np.vstack((c, c, c)))] * constrained)

    print("the direct count of the index, median ms per point:")
    ms = median_ms(lambda: count(problem, state))
    print(f"  elastica (k = 1, {len(s) - 1} intervals): {ms:.3f}"
          f" (index {count(problem, state).index})")
    for constrained in (False, True):
        ms = median_ms(lambda: count_form(lambda p: rod(p, constrained), s))
        what = "one constraint" if constrained else "no constraint"
        print(f"  k = 3, {len(s) - 1} intervals, {what}: {ms:.3f} (index "
              f"{count_form(lambda p: rod(p, constrained), s).index})")


def saves(rounds=3):
    """The share of the rotating_arm run (``--jobs 1``, in this process) spent writing its
    branch file: every save after a branch and the run's last write (`store.Writer`'s
    ``save``, ``finish`` and the leaving of its context), best of ``rounds``."""
    from elastica_auto import store
    from elastica_auto.run import execute
    from elastica_auto.runfile import load

    spent = [0.0]

    def timed(method):
        def wrapper(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return method(*args, **kwargs)
            finally:
                spent[0] += time.perf_counter() - t0
        return wrapper

    for name in ("save", "finish", "__exit__"):
        setattr(store.Writer, name, timed(getattr(store.Writer, name)))
    best = None
    for _ in range(rounds):
        spent[0] = 0.0
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            result = execute(load(REPO / "runs" / "rotating_arm.toml"), Path(tmp), jobs=1)
            total = time.perf_counter() - t0
            size = result.path.stat().st_size
        if best is None or spent[0] < best[0]:
            best = (spent[0], total, size)
    print(f"saving rotating_arm's branch file (--jobs 1, best of {rounds}): {best[0]:.3f} s of "
          f"{best[1]:.2f} s ({100 * best[0] / best[1]:.1f}%), {best[2] / 1e6:.1f} MB")


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
    saves()


if __name__ == "__main__":
    if sys.argv[1:] == ["--memory"]:
        memory()
    elif sys.argv[1:] == ["--sweep"]:
        sweep()
    elif sys.argv[1:] == ["--landing"]:
        landing()
    elif sys.argv[1:] == ["--index"]:
        index_cost()
    elif sys.argv[1:] == ["--saves"]:
        saves()
    else:
        main()
