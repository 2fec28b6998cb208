"""`make bench-auto AUTO_SRC=DIR`: AUTO-07p's boundary value demos against this engine, side by
side, whole processes, alternated rounds; prints one table. Nothing here asserts.

For each demo, AUTO's side is the demo's own script (``DEMO.auto``) as a sequence of runs of
its compiled executable (`auto07p`), ours the run files of this folder for the same work (the
same equations, start, parameter ranges and stopping rules: ``NMX`` as ``max_points``,
``UZSTOP`` as ``bounds`` or ``stop``, ``ILP``/``ISP`` as ``detect``, a restart ``IRS`` as a
label ``start``, ``ISW = -1`` as ``switch``), each an ``elastica-auto run`` process with
this engine's default discretisation and tolerances. A round runs AUTO's sequence then ours
(the order swapped every other round); the table has the medians over the rounds.

Columns: wall seconds of AUTO's processes and of ours and their ratio; points computed
(every point of every branch, labelled points included; AUTO's restarts print their start
again, ours too); unknowns per point (AUTO: NDIM (NTST NCOL + 1) plus its free parameters,
each run's NTST, averaged over the points; ours: the mean number of mesh nodes times the
states the engine solves for, free parameters and integral conditions included, over all
points); milliseconds per
point; and the accuracy of every fold (LP) and branch point (BP): the largest distance, in
the continued parameter, of ours and of AUTO's (at the demo's settings) from AUTO's converged
values, which are AUTO's own run of the same script with ``NTST`` x 8 and ``EPSL = EPSU =
1e-10``, ``EPSS = 1e-8`` (kar: 1e-6), ``NMX`` x 10 (its LP and BP to the 11 digits of
fort.8). A point with no reference of its type within 1e-3 (1 + |value|) is counted as
unmatched. Where the value is known in closed form (exp and pvl: Bratu's fold; nep: p1 =
pi^2 / 2; lin: p1 = 1, 2, ...), the last column has both programs' distance from it.

How each demo maps onto the protocol and what differs is in docs/benchmarks.md ("Against
AUTO-07p").
"""

from __future__ import annotations

import argparse
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import auto07p
from auto07p import Step

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
CLI = Path(sys.executable).parent / "elastica-auto"


@dataclass
class Demo:
    """One AUTO demo: AUTO's steps (its script), our run files (in restart order), the
    parameter whose folds and branch points are compared (ours by name, AUTO's PAR index)."""
    auto: list
    ours: list
    parameter: str
    par: int = 1
    note: str = ""
    fine: dict = field(default_factory=dict)
    exact: list = field(default_factory=list)


def bratu_fold() -> float:
    """Bratu's fold in closed form: lam = 2 z^2 / cosh(z/2)^2 where z tanh(z/2) = 2
    (bisection to the last bit)."""
    lo, hi = 1.0, 4.0
    while hi - lo > 4e-16 * hi:
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if mid * math.tanh(mid / 2) < 2 else (lo, mid)
    z = (lo + hi) / 2
    return 2 * z * z / math.cosh(z / 2) ** 2


DEMOS = {
    "exp": Demo([Step("exp"), Step("exp", {"IRS": 15, "NTST": 20}, restart=True)],
                ["exp.toml", "exp_2.toml"], "lam",
                note="Bratu (examples/bratu.py, energy-first)", exact=[("LP", bratu_fold())]),
    "kar": Demo([Step("kar")], ["kar.toml"], "gamma",
                note="rotating fluid over a disk, z_inf = 500", fine={"EPSS": 1e-6}),
    "int": Demo([Step("int")], ["int.toml"], "lam",
                note="Bratu, u(0) = u(1), mean 0; first run only"),
    "non": Demo([Step("non")], ["non.toml"], "p", note="u'' = -p exp(x^3 u)"),
    "nep": Demo([Step("nep.1"), Step("nep.2", {"IRS": "BP1"}, restart=True)],
                ["nep.toml"], "p1", note="eigenvalue p2 free; switch at the BP",
                exact=[("BP", math.pi ** 2 / 2)]),
    "lin": Demo([Step("lin"),
                 Step("lin", {"IRS": "BP1", "NTST": 6, "ISW": -1, "DSMAX": 0.5, "A1": 5.0},
                      restart=True),
                 Step("lin", {"IRS": "UZ1", "ICP": [1, 2], "NTST": 5, "ISW": 1, "DSMAX": 0.5,
                              "A1": 5.0}, restart=True)],
                ["lin.toml", "lin_2.toml"], "p1", note="integral condition, p3 free",
                exact=[("BP", k) for k in range(1, 20)]),
    "spb": Demo([Step("spb.0"), Step("spb.1", {"IRS": 2}, restart=True),
                 Step("spb.2", {"IRS": "UZ2"}, restart=True),
                 Step("spb.3", {"IRS": 19}, restart=True)],
                ["spb.toml", "spb_2.toml", "spb_3.toml"], "gamma",
                note="layers of width 1e-5"),
    "pvl": Demo([Step("pvl")], ["pvl.toml"], "lam", note="Bratu, AUTO's PVLS as ordinates",
                exact=[("LP", bratu_fold())]),
}


def run_ours(demo: Demo, out: Path) -> float:
    """Our run files in turn, each a fresh ``elastica-auto run`` process writing to ``out``
    (where the later ones find the labels they restart from); wall seconds."""
    seconds = 0.0
    for name in demo.ours:
        t0 = time.perf_counter()
        done = subprocess.run([str(CLI), "run", str(HERE / name), "--out", str(out), "-q"],
                              capture_output=True, text=True)
        seconds += time.perf_counter() - t0
        if done.returncode not in (0, 1):          # 1: a branch ended MX, as AUTO's kar does
            raise RuntimeError(f"{name}: exit {done.returncode}: {done.stderr[-800:]}")
    return seconds


def read_ours(demo: Demo, out: Path):
    """Points, mean unknowns per point and the LP/BP values of the compared parameter, from
    the branch files of our runs."""
    import numpy as np

    import elastica_auto as ea
    points, unknowns, special = 0, [], []
    for name in demo.ours:
        run = tomllib.loads((HERE / name).read_text())
        free = run["continuation"].get("free")
        width = ea.load_problem(str(HERE / run["equation"])).with_free(free).n
        for br in ea.BranchFile(out / (Path(name).stem + ".h5")).branches:
            c = br.columns
            points += len(c["pt"])
            unknowns.extend(np.asarray(c["nodes"], dtype=float) * width)
            for t, v in zip(c["type"], c[demo.parameter]):
                if t in ("LP", "BP"):
                    special.append((str(t), float(v)))
    return points, float(np.mean(unknowns)), special


def auto_unknowns(folder: Path, step: Step) -> int:
    """NDIM (NTST NCOL + 1) + NFPR of AUTO's run (NFPR = NBC + NINT - NDIM + 1)."""
    text = auto07p.constants(folder, step)
    found = re.findall(r"\b(NDIM|NTST|NCOL|NBC|NINT)\s*=\s*([-\d.eE+]+)", text)
    get = {k: int(float(v)) for k, v in found}          # the last of each wins
    nfpr = get["NBC"] + get["NINT"] - get["NDIM"] + 1
    return get["NDIM"] * (get["NTST"] * get["NCOL"] + 1) + nfpr


def accuracy(points, ref):
    """The largest distance of ``points`` ((type, value) pairs) from the nearest reference
    point of their type, over those with one within 1e-3 (1 + |value|) (None if none), and
    how many have none."""
    errors, unmatched = [], 0
    for kind, value in points:
        d = min((abs(value - v) for t, v in ref if t == kind), default=float("inf"))
        if d <= 1e-3 * (1 + abs(value)):
            errors.append(d)
        else:
            unmatched += 1
    return (max(errors) if errors else None), unmatched


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--auto-src", type=Path, help="AUTO-07p's source (a copy of its repository)")
    ap.add_argument("--build", type=Path, default=REPO / "build" / "auto-07p",
                    help="where AUTO-07p is built (default build/auto-07p, ignored by git)")
    ap.add_argument("--rounds", type=int, default=5, help="alternated rounds (default 5)")
    ap.add_argument("--demos", default=",".join(DEMOS), help="comma-separated demos")
    args = ap.parse_args(argv)
    if not (args.build / ".built").exists() and args.auto_src is None:
        ap.error("AUTO-07p is not built yet: give --auto-src DIR (make bench-auto AUTO_SRC=DIR)")
    auto = auto07p.build(args.auto_src, args.build)
    names = [d.strip() for d in args.demos.split(",") if d.strip()]
    for name in names:
        if name not in DEMOS:
            ap.error(f"unknown demo {name!r}; expected some of {', '.join(DEMOS)}")
    work = args.build.parent / "auto-demos"
    env_note = os.environ.get("OPENBLAS_CORETYPE", "-")
    print(f"AUTO-07p from {args.build} (gfortran -O, no OpenMP/MPI); ours: {CLI}; "
          f"{args.rounds} alternated rounds, medians; OPENBLAS_CORETYPE={env_note}")
    rows = []
    for name in names:
        demo = DEMOS[name]
        folder = auto07p.compile_demo(auto, name, work)
        auto_s, ours_s = [], []
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp)
            for r in range(args.rounds):
                order = ("auto", "ours") if r % 2 == 0 else ("ours", "auto")
                for who in order:
                    if who == "auto":
                        seconds, auto_steps, _ = auto07p.run(folder, name, demo.auto)
                        auto_s.append(seconds)
                    else:
                        ours_s.append(run_ours(demo, out))
            points, unknowns, special = read_ours(demo, out)
        _, _, auto_labels = auto07p.run(folder, name, demo.auto)
        _, _, fine_labels = auto07p.run(folder, name, demo.auto, fine=demo.fine or True)
        auto_special = [(lab.type, lab.par[demo.par - 1]) for lab in auto_labels
                        if lab.type in ("LP", "BP")]
        ref = [(lab.type, lab.par[demo.par - 1]) for lab in fine_labels
               if lab.type in ("LP", "BP")]
        ours_err = accuracy(special, ref)
        auto_err = accuracy(auto_special, ref)
        exact = (accuracy(special, demo.exact), accuracy(auto_special, demo.exact)) \
            if demo.exact else None
        a, o = statistics.median(auto_s), statistics.median(ours_s)
        auto_points = sum(auto_steps)
        auto_mean = sum(n * auto_unknowns(folder, step)
                        for n, step in zip(auto_steps, demo.auto)) / auto_points
        rows.append((name, a, o, auto_points, points, auto_mean, unknowns, special,
                     auto_special, ours_err, auto_err, exact))
        print(f"  {name}: AUTO {', '.join(f'{s:.3f}' for s in auto_s)} s; "
              f"ours {', '.join(f'{s:.2f}' for s in ours_s)} s", flush=True)
    print()
    head = ("demo", "AUTO s", "ours s", "ratio", "points A/o", "unknowns/pt A/o",
            "ms/pt A/o", "LP+BP A/o", "|o-ref|", "|A-ref|", "|o-exact|, |A-exact|")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for (name, a, o, ap_, op, au, ou, special, auto_special, oe, ae, exact) in rows:
        def err(e):
            text = "-" if e[0] is None else f"{e[0]:.1e}"
            return text + (f" ({e[1]} unmatched)" if e[1] else "")

        print(f"| `{name}` | {a:.3f} | {o:.2f} | {o / a:.0f}x | {ap_}/{op} | {au:.0f}/{ou:.0f} | "
              f"{1e3 * a / ap_:.2f}/{1e3 * o / op:.1f} | {len(auto_special)}/{len(special)} | "
              f"{err(oe)} | {err(ae)} | "
              + ("-" if exact is None else f"{err(exact[0])}, {err(exact[1])}") + " |")
    print()
    for (name, *_rest) in rows:
        special, auto_special = _rest[6], _rest[7]
        listed = ("; ours " + ", ".join(f"{t} {v:.10g}" for t, v in special)
                  + "; AUTO " + ", ".join(f"{t} {v:.10g}" for t, v in auto_special)) \
            if special or auto_special else ""
        print(f"  {name} ({DEMOS[name].note}){listed}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
