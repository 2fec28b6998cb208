"""Where a run's CPU goes, by part: ``python benchmarks/profile_run.py RUN.toml [--runs N]``.

Each of N whole processes (``elastica-auto run RUN.toml`` with ``-q``, into a temporary
folder) has its Python stack sampled by a SIGPROF timer of 0.5 ms of its CPU (the kernel
delivers it at its tick, about every 4 ms here); each sample is assigned to the innermost
part of the run it falls in (`PARTS`), and the median process's CPU (user + sys) is shared
out by the parts' shares of all the samples. The interpreter's own start (before the first
sample) is in that CPU and in no part: it is printed apart, as the CPU of ``python -c pass``.
The table of docs/benchmarks.md ("Where a small demo's time goes") was made by this.
"""

from __future__ import annotations

import argparse
import collections
import pickle
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: (file name ends with, function or "" for any, part), looked up from the innermost frame out:
#: the first frame that matches an entry naming a function names the sample's part; failing
#: that, the first that matches an entry for any function of its file (so that a helper of
#: the stepper called from `_add_events` counts as the labels, not as the walk's own work).
PARTS = [
    ("importlib._bootstrap>", "_find_and_load", "imports"),
    ("execution/runfile.py", "load", "run file, module load, CLI"),
    ("storage/store.py", "", "saving"),
    ("execution/cluster.py", "", "cluster"),
    ("execution/jobs.py", "on_step", "the walk's own bookkeeping, progress"),
    ("analysis/snaps.py", "", "snap-back scans"),
    ("numerics/stability.py", "count", "index (direct count)"),
    ("branches/branch.py", "new_point", "new points: ordinates, profile"),
    ("branches/stepper.py", "_add_events", "labels (UZ, EP) placed"),
    ("branches/stepper.py", "_fold_events", "folds and branch points located"),
    ("branches/stepper.py", "_branch_point", "folds and branch points located"),
    ("branches/stepper.py", "_probe", "folds and branch points located"),
    ("branches/stepper.py", "_detect", "test functions (fold and BP signs)"),
    ("branches/stepper.py", "_correct", "corrector (predictor, Newton, mesh, tangent)"),
    ("branches/stepper.py", "start_solution", "corrector (predictor, Newton, mesh, tangent)"),
    ("branches/stepper.py", "_arc_checked", "corrector (predictor, Newton, mesh, tangent)"),
    ("branches/kinds.py", "finish", "periodic translates"),
    ("branches/stepper.py", "", "the walk's own bookkeeping, progress"),
    ("execution/run.py", "_analyse", "analysis after the branches"),
    ("energy/loader.py", "", "run file, module load, CLI"),
    ("model/problem.py", "load", "run file, module load, CLI"),
    ("elastica_auto/cli.py", "", "run file, module load, CLI"),
]


def part(stack) -> str:
    """The part of a sample, its stack ((file, function), outermost first): the first entry
    of `PARTS` met from the innermost frame out; an import is "at start-up" or "inside the
    run" (under `execution.run.execute`)."""
    inside = any(f.endswith("execution/run.py") and fn == "execute" for f, fn in stack)
    for specific in (True, False):
        for f, fn in reversed(stack):
            for end, name, label in PARTS:
                if f.endswith(end) and (fn == name if specific else not name):
                    if label == "imports":
                        return "imports inside the run" if inside else "imports at start-up"
                    return label
    return "the rest of the run" if inside else "the rest of start-up"


def child(out: str, argv: list[str]):
    """One sampled run: ``elastica-auto`` with ``argv`` in this process; appends its CPU and
    samples to the file ``out``."""
    samples = []

    def record(signum, frame):
        stack = []
        while frame is not None:
            stack.append((frame.f_code.co_filename, frame.f_code.co_name))
            frame = frame.f_back
        samples.append(stack[::-1])

    signal.signal(signal.SIGPROF, record)
    signal.setitimer(signal.ITIMER_PROF, 0.0005, 0.0005)
    try:
        from elastica_auto.cli import main
        sys.argv = ["elastica-auto", *argv]
        try:
            main()
        except SystemExit:
            pass
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0, 0)
    with open(out, "ab") as f:
        pickle.dump({"cpu": time.process_time(), "samples": samples}, f)


def children_cpu(argv: list[str]) -> float:
    """The CPU (user + sys) of the process ``argv``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(argv, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def profile(run: str, runs: int) -> tuple[dict[str, float], float, float, int]:
    """(CPU milliseconds by part, the median process's CPU ms, the interpreter's start ms,
    the number of samples) of ``runs`` processes of ``run``."""
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "samples.pickle")
        for k in range(runs):
            subprocess.run([sys.executable, __file__, "--child", out, "run", run, "--out",
                            str(Path(tmp) / f"out{k}"), "-q"], check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        records = []
        with open(out, "rb") as f:
            while True:
                try:
                    records.append(pickle.load(f))
                except EOFError:
                    break
    bare = sorted(children_cpu([sys.executable, "-c", "pass"]) for _ in range(5))[2]
    cpu = sorted(r["cpu"] for r in records)[len(records) // 2]
    counts = collections.Counter(part(s) for r in records for s in r["samples"])
    total = sum(counts.values())
    shares = {name: 1000 * (cpu - bare) * n / total for name, n in counts.most_common()}
    return shares, 1000 * cpu, 1000 * bare, total


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args[:1] == ["--child"]:
        child(args[1], args[2:])
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", help="a run file or a shipped run's name")
    ap.add_argument("--runs", type=int, default=10, help="processes sampled (default 10)")
    a = ap.parse_args(args)
    shares, cpu, bare, total = profile(a.run, a.runs)
    print(f"{a.run}: {a.runs} processes, {total} samples; CPU ms, the median process's")
    print(f"  {'the interpreter (python -c pass)':48s} {bare:7.1f}")
    for name, ms in shares.items():
        print(f"  {name:48s} {ms:7.1f}")
    print(f"  {'whole process':48s} {cpu:7.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
