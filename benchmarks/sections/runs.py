"""Whole runs: section 2 (rotating_arm in one process, per corrector), 3 (whole processes:
``make runs``), ``--memory``, ``--saves`` and ``--disk``."""

from __future__ import annotations

import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from . import REPO, CLI


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


def run_files(corrector, folder: Path) -> Path:
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


def timed(args, cwd) -> float:
    """Seconds of ``elastica-auto ARGS`` as a whole process in ``cwd`` (exit 0 or 1)."""
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
        files = run_files(corrector, tmp / "runs")
        out = tmp / "out"
        one = timed(["run", files / "rotating_arm.toml", "--out", out, "-q", "-j", "1"], tmp)
        default = timed(["run", files / "rotating_arm.toml", "--out", out, "-q"], tmp)
        bratu = min(timed(["run", files / "bratu.toml", "--out", out, "-q", "-j", "1"], tmp)
                    for _ in range(3))
        print(f"{corrector}: rotating_arm {one:.2f} s with --jobs 1, {default:.2f} s with "
              f"--jobs {os.cpu_count()}; examples/bratu.toml {bratu:.2f} s (best of 3)")
        # issue 49's target: the tendon robot's tension continuation under 10 s
        timed(["run", files / "tendon_weight.toml", "--out", out, "-q"], tmp)
        lift = timed(["run", files / "tendon_lift.toml", "--out", out, "-q"], tmp)
        print(f"    tendon_lift {lift:.2f} s (after tendon_weight; the target: under 10 s)")
        total = 0.0
        for name in runs:
            seconds = timed(["run", files / f"{name}.toml", "--out", out, "-q"], tmp)
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
