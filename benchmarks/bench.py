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

8. The cost of a step as the system grows (``--size`` prints only this): one continuation
   step on a fixed mesh of 100 intervals for n = 4 (the elastica), 6 (the rotating disk of
   ``examples/karman_disk.py`` with its free parameter), 10 (the spatial rod; the planar
   elastica's fold-curve system), 13 (the spatial Cosserat rod, S = 1000) and 20 (five copies
   of the elastica stacked as one system),
   for the cubic scheme (ncol 0) and Gauss collocation (ncol 4): median ms per step, and the
   mean split into assembly (residuals and Jacobian blocks), factorisation, solves, the
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

    from elastica_auto.numerics.correctors import Collocation
    from elastica_auto.branches.events import Step, locate_fold
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.model.problem import load_problem
    from elastica_auto.core.solution import State, secant
    from elastica_auto.numerics.stability import index
    from elastica_auto.branches.stepper import start_solution

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
    from elastica_auto.execution.jobs import Callbacks
    from elastica_auto.execution.run import execute
    from elastica_auto.execution.runfile import load
    import dataclasses

    plan = load(REPO / "runs" / "rotating_arm.toml")
    plan.options = dataclasses.replace(plan.options, corrector=corrector)
    stamps: dict[int, list[float]] = {}

    def progress(k, npts, nfolds, lam):
        stamps.setdefault(k, []).append(time.perf_counter())

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        result = execute(plan, Path(tmp), Callbacks(progress=progress), jobs=1)
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
from elastica_auto.execution.run import execute
from elastica_auto.execution.runfile import load
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
    from elastica_auto.execution import cluster
    from elastica_auto.execution.plan import Request, make_plan
    from elastica_auto.execution.run import start_job, _in_process
    problem = ea.load_problem("elastica_lever_arm")
    eps = [0.2 + 0.3 * k / (branches // 2 - 1) for k in range(branches // 2)]
    plan = make_plan(problem, {"P": math.pi ** 2 / 4, "psi": 0.0}, "psi",
                     Request(params={"eps": eps}, bounds=(-math.pi, math.pi), directions="both"))
    first = [start_job(plan, spec) for spec in plan.branches]
    print(f"sweep of {len(first)} branches (psi in [-pi, pi], 32 arm lengths):")
    for workers in (0, 1, 2):
        client = cluster.local(workers) if workers else None
        if client is not None:
            client.run(importlib.import_module, "elastica_auto.execution.run")
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
    """CPU seconds of the snap-back scans at every fold ending a stable branch; seconds of
    the overdamped landing from each, and of the damped model's from the first ``damped`` of
    them for each ``damping``."""
    import numpy as np

    import elastica_auto as ea
    from elastica_auto.analysis.landing import land
    from elastica_auto.analysis.equilibria import enumerate_equilibria, snap_lps
    problem = ea.load_problem("elastica_lever_arm")
    branches = ea.continuation(problem, {"eps": 0.5, "P": 9 * math.pi ** 2 / 4}, "psi",
                               directions="both", bounds=(-6 * math.pi, 6 * math.pi))
    folds = []
    scan = time.process_time()
    for br in branches:
        for p, side in snap_lps(br):
            k = br.points.index(p)
            other = br.points[k - 1 if side == "before" else k + 1]
            folds.append((p, int(np.sign(p.params["psi"] - other.params["psi"])),
                          enumerate_equilibria(problem, p.params)))
    scan = time.process_time() - scan
    print(f"the snap-back scans there: {len(folds)} folds {scan:.2f} s CPU "
          f"({1000 * scan / len(folds):.0f} ms a scan)")
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

    from elastica_auto.model.problem import load_problem
    from elastica_auto.model.second_variation import Constraint, SecondVariation
    from elastica_auto.core.solution import State
    from elastica_auto.numerics.stability import count, count_form

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


class _Phases:
    """Wall time per phase of a step: the outermost call of a wrapped function counts."""

    GROUPS = {
        "assembly": [("numerics.collocation", "Discretisation", "evaluate"),
                     ("numerics.collocation", "Discretisation", "blocks"),
                     ("numerics.gauss", "GaussDiscretisation", "evaluate"),
                     ("numerics.gauss", "GaussDiscretisation", "blocks")],
        "factor": [("numerics.bordered", None, "factor")],
        "solves": [("numerics.bordered", "Factorization", "solve"),
                   ("numerics.bordered", "Factorization", "solve_transpose"),
                   ("numerics.bordered", "Factorization", "solve_with_border")],
        "estimate+tests": [("numerics.collocation", "Discretisation", "rms_residuals"),
                           ("numerics.gauss", "GaussDiscretisation", "rms_residuals"),
                           ("numerics.bordered", "Factorization", "sign")],
    }

    def __init__(self):
        self.total = dict.fromkeys(self.GROUPS, 0.0)
        self.depth = 0
        self.saved = []

    def _wrap(self, group, fn):
        def timed(*args, **kwargs):
            self.depth += 1
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.depth -= 1
                if self.depth == 0:
                    self.total[group] += time.process_time() - t0
        return timed

    def __enter__(self):
        for group, where in self.GROUPS.items():
            for module, cls, name in where:
                try:
                    mod = importlib.import_module(f"elastica_auto.{module}")
                except ImportError:          # an older commit without Gauss collocation
                    continue
                owner = mod if cls is None else getattr(mod, cls)
                attr = owner.__dict__[name]
                if isinstance(attr, property):
                    new = property(self._wrap(group, attr.fget))
                else:
                    new = self._wrap(group, attr)
                self.saved.append((owner, name, attr))
                setattr(owner, name, new)
        return self

    def __exit__(self, *exc):
        for owner, name, attr in reversed(self.saved):
            setattr(owner, name, attr)


def _stacked_elastica(copies):
    """``copies`` copies of the planar elastica as one system of 4 copies states (a generic
    module object: the engine sees one BVP with block-diagonal Jacobians)."""
    import dataclasses
    import types

    import numpy as np

    from elastica_auto.model.problem import Problem, load_problem

    base = load_problem("elastica_lever_arm")
    n = base.n
    mod = types.ModuleType("stacked")
    mod.STATES = tuple(f"{x}{j}" for j in range(copies) for x in base.states)
    # one copy's period maps name its states ("theta"), not the stack's ("theta0", ...): left
    # out (the steps here are timed on fixed meshes, no branch repeats)
    mod.PARAMETERS = [dataclasses.replace(q, period_shift=(), period_flip=())
                      for q in base.parameters.values()]
    mod.ORDINATES = []

    def split(y):
        return [y[j * n:(j + 1) * n] for j in range(copies)]

    def diag(blocks, shape_tail=()):
        out = np.zeros((n * copies, n * copies) + shape_tail)
        for j, b in enumerate(blocks):
            out[j * n:(j + 1) * n, j * n:(j + 1) * n] = b
        return out

    mod.rhs = lambda s, y, p: np.vstack([base.rhs(s, x, p) for x in split(y)])
    mod.rhs_jac = lambda s, y, p: diag([base.rhs_jac(s, x, p) for x in split(y)],
                                       (y.shape[1],))
    mod.rhs_dp = lambda s, y, p, name: np.vstack([base.rhs_dp(s, x, p, name) for x in split(y)])
    mod.bc = lambda ya, yb, p: np.concatenate([base.bc(a, b, p)
                                               for a, b in zip(split(ya), split(yb))])

    def bc_jac(ya, yb, p):
        pairs = [base.bc_jac(a, b, p) for a, b in zip(split(ya), split(yb))]
        return diag([a for a, _ in pairs]), diag([b for _, b in pairs])

    mod.bc_jac = bc_jac
    mod.bc_dp = lambda ya, yb, p, name: np.concatenate([base.bc_dp(a, b, p, name)
                                                        for a, b in zip(split(ya), split(yb))])
    mod.exact_start = lambda s, p: (None if (y := base.exact_start(s, p)) is None
                                    else np.vstack([y] * copies))
    return Problem(mod, f"{copies} x elastica_lever_arm")


def _size_systems():
    """(label, problem, parameter, start State on 100 intervals, ds, counts the index)."""
    import numpy as np

    import elastica_auto as ea
    from elastica_auto.branches.codim2 import fold_problem
    from elastica_auto.numerics.correctors import Collocation
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.model.problem import load_problem
    from elastica_auto.core.solution import State

    s = np.linspace(0.0, 1.0, 101)
    out = []
    elastica = load_problem("elastica_lever_arm")
    params = {**elastica.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    out.append(("n = 4, elastica", elastica, "psi",
                State.from_values(elastica, s, elastica.exact_start(s, params), params), 0.03,
                True))
    disk = load_problem(str(REPO / "examples" / "karman_disk.py")).with_free(("inflow",))
    p = disk.defaults()
    guess = State.from_values(disk, s, disk.guess(s, p), p)
    point = Collocation(disk, "a", ContinuationOptions(tol=0.99)).point(guess)
    out.append((f"n = {disk.n}, rotating disk", disk, "a", point.state, 0.05, False))
    rod = load_problem("kirchhoff_lever_arm")
    params = {**rod.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    out.append((f"n = {rod.n}, spatial rod", rod, "psi",
                State.from_values(rod, s, rod.exact_start(s, params), params), 0.03, True))
    cosserat = load_problem("cosserat_rod")
    params = {**cosserat.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    out.append((f"n = {cosserat.n}, Cosserat rod", cosserat, "psi",
                State.from_values(cosserat, s, cosserat.exact_start(s, params), params), 0.03,
                True))
    arm = ea.continuation(elastica, {"eps": 0.25, "P": math.pi ** 2 / 4}, "psi",
                          bounds=(-2 * math.pi, 2 * math.pi))
    (curve,) = ea.continuation(elastica, arm.label("LP1"), ["psi", "eps"], bounds=(0, 1),
                               max_points=4)
    end = curve.points[-1].state
    folds = fold_problem(elastica, "psi")
    out.append((f"n = {folds.n}, elastica fold curve", folds, "eps",
                State.from_values(folds, s, end(s), end.params), 0.02, False))
    stacked = _stacked_elastica(5)
    params = {**stacked.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    out.append((f"n = {stacked.n}, 5 x elastica", stacked, "psi",
                State.from_values(stacked, s, stacked.exact_start(s, params), params), 0.03,
                False))
    return out


def size_cost(steps=30, schemes=(0, 4)):
    """Section 8: the step cost at 100 intervals by system size, split into phases."""
    import dataclasses

    import numpy as np

    from elastica_auto.numerics.correctors import Collocation
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.numerics.stability import index
    from elastica_auto.branches.stepper import start_solution

    has_ncol = "ncol" in {f.name for f in dataclasses.fields(ContinuationOptions)}
    if not has_ncol:
        schemes = (0,)
    print("one continuation step on a fixed mesh of 100 intervals, by system size: median CPU "
          "ms, and the mean split (ms)")
    head = ["system", "ncol", "ms/step", "assembly", "factor", "solves", "estimate+tests",
            "index", "rest"]
    print(f"{head[0]:>28} {head[1]:>4} " + " ".join(f"{h:>9}" for h in head[2:]))
    for label, problem, name, start, ds, counted in _size_systems():
        for ncol in schemes:
            # tol just below 1: no regridding, the mesh stays as given
            opt = ContinuationOptions(tol=0.99, ds_max=1.0, **({"ncol": ncol} if has_ncol
                                                               else {}))
            corr = Collocation(problem, name, opt)
            a = start_solution(corr, start, 1, None, False)
            for _ in range(3):                                  # warm-up
                a = corr.step(a, ds)
            times, idx = [], 0.0
            with _Phases() as phases:
                for _ in range(steps):
                    t0 = time.process_time()
                    b = corr.step(a, ds)
                    _ = b.sign
                    if counted:
                        t1 = time.process_time()
                        index(problem, b.state)
                        idx += time.process_time() - t1
                    times.append(time.process_time() - t0)
                    a = b
            split = {k: 1e3 * v / steps for k, v in phases.total.items()}
            split["index"] = 1e3 * idx / steps
            rest = 1e3 * float(np.mean(times)) - sum(split.values())
            print(f"{label:>28} {ncol:>4} {1e3 * statistics.median(times):>9.2f} "
                  + " ".join(f"{split[k]:>9.2f}" for k in head[3:-1]) + f" {rest:>9.2f}")


def _disk_reference(a, z_inf):
    """(F'(0), G'(0), inflow) of the rotating disk with suction a by scipy's solve_bvp in z."""
    import numpy as np
    from scipy.integrate import solve_bvp

    def fun(z, y, q):
        F, dF, G, dG, H = y
        return np.vstack((dF, F * F - G * G + H * dF, dG, 2 * F * G + H * dG, -2 * F))

    def bc(ya, yb, q):
        return np.array((ya[0], ya[2] - 1, ya[4] + a, yb[0], yb[2], yb[4] + q[0]))

    z = np.linspace(0, z_inf, 400)
    e = np.exp(-(1 + a) * z)
    y0 = np.vstack((0.3 * z * e, 0.3 * e, e, -(1 + a) * e, -a - 0.9 * (1 - e)))
    sol = solve_bvp(fun, bc, z, y0, p=[a + 0.9], tol=1e-10, max_nodes=100000)
    return sol.y[1, 0], sol.y[3, 0], sol.p[0]


def disk_unknowns(tols=(1e-5, 1e-7), schemes=(0, 2, 3, 4, 5, 6, 7)):
    """``--disk``: unknowns per point and accuracy of each scheme on the rotating disk."""
    import dataclasses

    import numpy as np

    from elastica_auto.execution.run import execute
    from elastica_auto.execution.runfile import load

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        text = (REPO / "examples" / "karman_disk.toml").read_text()
        (tmp / "karman_disk.py").write_text((REPO / "examples" / "karman_disk.py").read_text())
        (tmp / "disk.toml").write_text(text.replace("bounds = [-1, 4]", "bounds = [-1, 10]"))
        plan = load(tmp / "disk.toml")
        refs = {}
        print("rotating disk to a = 10 (ntst = 10): per point, and the largest error at the "
              "UZ points against solve_bvp (tol 1e-10)")
        for tol in tols:
            for ncol in schemes:
                p = dataclasses.replace(plan, options=dataclasses.replace(
                    plan.options, ncol=ncol, tol=tol, ntst=10))
                t0 = time.perf_counter()
                (br,) = execute(p, tmp / f"out{ncol}_{tol:g}", jobs=1).branches
                seconds = time.perf_counter() - t0
                nodes = np.array([q.nodes for q in br.points])
                n = 6                                  # five states and the free inflow
                unknowns = (nodes - 1) * ncol * n + n if ncol else nodes * n
                err = 0.0
                for q in br.points:
                    if q.type == "UZ":
                        a = q.params["a"]
                        ref = refs.setdefault(a, _disk_reference(a, q.params["z_inf"]))
                        err = max(err, abs(q.ordinates["dF0"] - ref[0]),
                                  abs(q.ordinates["dG0"] - ref[1]),
                                  abs(q.params["inflow"] - ref[2]))
                print(f"  tol {tol:.0e}, ncol {ncol}: {len(br.points)} points, "
                      f"{nodes.mean():6.1f} nodes, {unknowns.mean():6.0f} unknowns per point; "
                      f"error {err:.1e}; {seconds:.2f} s")


def saves(rounds=3):
    """The share of the rotating_arm run (``--jobs 1``, in this process) spent writing its
    branch file: every save after a branch and the run's last write (`store.Writer`'s
    ``save``, ``finish`` and the leaving of its context), best of ``rounds``."""
    from elastica_auto.storage import store
    from elastica_auto.execution.run import execute
    from elastica_auto.execution.runfile import load

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


#: (hand-written reference, the module derived from its energy) of section 9.
ENERGY_PAIRS = ((REPO / "tests" / "reference" / "elastica_lever_arm.py", "elastica_lever_arm"),
                (REPO / "tests" / "reference" / "kirchhoff_lever_arm.py", "kirchhoff_lever_arm"),
                (REPO / "tests" / "reference" / "bratu.py", REPO / "examples" / "bratu.py"))
#: The step of section 9 for each pair with one: the start (parameters, from the straight rod)
#: and the continued parameter.
ENERGY_STEPS = {"elastica_lever_arm": {"eps": 0.5, "P": 9 * math.pi ** 2 / 4},
                "kirchhoff_lever_arm": {"eps": 0.25, "P": 9 * math.pi ** 2 / 4, "b2": 2.0}}
#: The runs of section 9, with the equation each names.
ENERGY_RUNS = (("rotating_arm", "elastica_lever_arm"),
               ("rotating_arm_3d", "kirchhoff_lever_arm"))


def energy():
    """Section 9: modules derived from an energy side by side with their hand-written
    references, alternated in one sitting: one continuation step on a fixed mesh of 100
    intervals (as section 1), the rotating_arm and rotating_arm_3d runs in one process, a
    warm load (the cache filled; a fresh process, the load alone) and a cold derivation
    (sympy's import separately)."""
    import numpy as np

    from elastica_auto.branches.stepper import start_solution
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.core.solution import State
    from elastica_auto.model.problem import load_problem
    from elastica_auto.numerics.correctors import Collocation
    from elastica_auto.numerics.stability import index

    print("energy-first modules against their hand-written references (alternated):")
    for reference, derived in ENERGY_PAIRS:
        if derived not in ENERGY_STEPS:
            continue
        problems = [load_problem(name) for name in (reference, derived)]
        params = {**problems[0].defaults(), **ENERGY_STEPS[derived]}
        s = np.linspace(0.0, 1.0, 101)
        times = {0: [], 1: []}
        for _ in range(5):
            for which, problem in enumerate(problems):
                corr = Collocation(problem, "psi", ContinuationOptions(tol=0.99, ds_max=1.0))
                a = start_solution(corr, State.from_values(
                    problem, s, problem.exact_start(s, params), params), 1, None, False)
                for _ in range(20):
                    t0 = time.perf_counter()
                    b = corr.step(a, 0.03)
                    index(problem, b.state)
                    times[which].append(time.perf_counter() - t0)
                    a = b
        step = [1e3 * statistics.median(times[w]) for w in (0, 1)]
        print(f"  one continuation step of {derived} (100 intervals, its index): hand-written "
              f"{step[0]:.2f} ms, derived {step[1]:.2f} ms ({step[1] / step[0]:.2f}x)")
    import dataclasses

    from elastica_auto.execution.run import execute
    from elastica_auto.execution.runfile import load
    with tempfile.TemporaryDirectory() as tmp:
        for name, derived in ENERGY_RUNS:
            reference = next(r for r, d in ENERGY_PAIRS if d == derived)
            text = (REPO / "runs" / f"{name}.toml").read_text()
            hand_run = Path(tmp) / f"{name}.toml"
            hand_run.write_text(text.replace(f'equation = "{derived}"',
                                             f'equation = "{reference}"'))
            runs = {0: [], 1: []}
            for _ in range(2):
                for which, path in enumerate((hand_run, REPO / "runs" / f"{name}.toml")):
                    plan = load(path)
                    plan.options = dataclasses.replace(plan.options)
                    t0 = time.perf_counter()
                    execute(plan, Path(tmp) / f"out{which}", jobs=1)
                    runs[which].append(time.perf_counter() - t0)
            run = [min(runs[w]) for w in (0, 1)]
            print(f"  {name} in one process (best of 2): hand-written {run[0]:.2f} s, "
                  f"derived {run[1]:.2f} s ({run[1] / run[0]:.2f}x)")
    code = ("import sys, time; t0 = time.perf_counter(); "
            "from elastica_auto.model.problem import load_problem; load_problem({!r}); "
            "print(time.perf_counter() - t0, 'sympy' in sys.modules)")
    for reference, derived in ENERGY_PAIRS:
        load_problem(derived)                               # the cache filled
        loads = {0: [], 1: []}
        for _ in range(5):
            for which, what in enumerate((str(reference), str(derived))):
                out = subprocess.run([sys.executable, "-c", code.format(what)], cwd=REPO,
                                     capture_output=True, text=True, check=True).stdout.split()
                assert out[1] == "False"
                loads[which].append(float(out[0]))
        warm = [1e3 * statistics.median(loads[w]) for w in (0, 1)]
        print(f"  warm load of {Path(str(derived)).stem} (fresh process, median of 5): "
              f"hand-written {warm[0]:.1f} ms, derived {warm[1]:.1f} ms "
              f"(+{warm[1] - warm[0]:.1f} ms), no sympy")
    cold = ("import time; t0 = time.perf_counter(); import sympy; t1 = time.perf_counter(); "
            "from elastica_auto.model.problem import load_problem; "
            "load_problem({!r}, cache=False); print(t1 - t0, time.perf_counter() - t1)")
    for _, derived in ENERGY_PAIRS:
        out = [subprocess.run([sys.executable, "-c", cold.format(str(derived))], cwd=REPO,
                              capture_output=True, text=True, check=True).stdout.split()
               for _ in range(3)]
        print(f"  cold derivation of {Path(str(derived)).stem} (median of 3): import sympy "
              f"{statistics.median(float(o[0]) for o in out):.2f} s, derivation, code and "
              f"load {statistics.median(float(o[1]) for o in out):.2f} s")


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
