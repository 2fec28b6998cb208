"""The discretisations side by side (issue 50; not part of ``make bench``): for each case (one
run file, or a chain of them restarting from one another), the cubic scheme (``ncol = 0``),
Gauss collocation at ``ncol = 3, 4, 5`` and the default ``ncol = "auto"``, each as whole
processes (``elastica-auto run FILE --out DIR -q -j 1 --set ncol=...``): CPU seconds (user +
system of the processes, `resource.RUSAGE_CHILDREN`; the wall clock of a loaded machine
drifts 2x), points, mean nodes per point, mean unknowns per point, the scheme each branch
recorded, and every fold's and branch point's distance from a converged reference in the
continued parameter.

Unknowns per point: the node values ``n m`` for the cubic scheme (the banded system's size);
``n (k (m - 1) + 1)`` with Gauss collocation's stage values (what AUTO-07p counts), n the
states of the branch file (a free parameter, carried as one more state at every node, is not
counted); a branch that turned to Gauss along the way (``ncol = "auto"``) is counted at its
recorded ``ncol`` throughout, which overcounts its cubic points. The reference: the same
case by Gauss collocation at ``ncol = 6``, ``tol = 1e-9``, ``fold_tol = 1e-11``
(``--reference gauss``, the default: on smooth problems it sits on the fewest intervals and
its folds are at rounding level; an earlier round found Gauss at 6 and ``tol = 1e-10``
within 9e-16 of the closed forms of Bratu's fold, nep's pi^2/2 and lin's integers), or each
scheme at ``tol = 1e-8``,
``fold_tol = 1e-10`` (``--reference same``, as many more runs). A special point is matched to
the reference's nearest one of the same type; one farther than 1e-3 is counted as unmatched
(the column "unmatched": a branch computed differently, not an error).

    python benchmarks/schemes.py                      # the AUTO demos and the small examples
    python benchmarks/schemes.py --cases kar,exp --rounds 3
    python benchmarks/schemes.py --cases rotating_arm --schemes 0,4,auto
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CLI = str(Path(sys.executable).with_name("elastica-auto"))
AUTO = ROOT / "benchmarks" / "auto"

#: name -> the run files computed in order (a later one restarting from an earlier one's file)
CASES = {
    "exp": [AUTO / "exp.toml", AUTO / "exp_2.toml"],
    "kar": [AUTO / "kar.toml"],
    "int": [AUTO / "int.toml"],
    "non": [AUTO / "non.toml"],
    "nep": [AUTO / "nep.toml"],
    "lin": [AUTO / "lin.toml", AUTO / "lin_2.toml"],
    "pvl": [AUTO / "pvl.toml"],
    "spb12": [AUTO / "spb.toml", AUTO / "spb_2.toml"],
    "spb": [AUTO / "spb.toml", AUTO / "spb_2.toml", AUTO / "spb_3.toml"],
    **{p.stem: [p] for p in sorted((ROOT / "examples").glob("*.toml"))},
    **{p.stem: [p] for p in sorted((ROOT / "runs").glob("*.toml"))},
}
DEFAULT_CASES = ("exp", "kar", "int", "non", "nep", "lin", "pvl", "spb12", "bratu",
                 "karman_disk", "nonlinear_eigenvalue", "clamped_column", "two_modes",
                 "rotating_arm")
SPECIAL = ("LP", "BP")
MATCH = 1e-3


def run_case(files, out: Path, settings: list[str]) -> float:
    """The case's run files as whole processes into ``out``; their CPU seconds."""
    out.mkdir(parents=True, exist_ok=True)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    for f in files:
        # a restart names its file relative to the run file's folder: run from there
        subprocess.run([CLI, "run", str(f), "--out", str(out), "-q", "-j", "1",
                        *[a for s in settings for a in ("--set", s)]],
                       cwd=f.parent, check=False, capture_output=True,
                       env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def read(out: Path, files) -> dict:
    """Points, nodes and unknowns per point, the schemes recorded and the special points
    (type, value of the continued parameter) of the case's files in ``out``."""
    points = nodes = unknowns = 0
    schemes, special = set(), []
    for f in files:
        path = out / f"{f.stem}.h5"
        if not path.exists():
            continue
        with h5py.File(path) as h:
            for br in h["branches"].values():
                opt = json.loads(br.attrs["options"])
                k = opt.get("ncol")
                schemes.add(k)
                cols = br["columns"]
                n = _states(h)
                m = cols["nodes"][()].astype(float)
                points += len(m)
                nodes += float(m.sum())
                unknowns += float((n * m if not k else n * (k * (m - 1) + 1)).sum())
                par = br.attrs["parameter"]
                par = par.decode() if isinstance(par, bytes) else par
                for t, v in zip(cols["type"][()], cols[par][()]):
                    t = t.decode() if isinstance(t, bytes) else str(t)
                    if t in SPECIAL:
                        special.append((t, float(v)))
    return {"points": points, "nodes": nodes / max(points, 1),
            "unknowns": unknowns / max(points, 1), "schemes": sorted(map(str, schemes)),
            "special": special}


def _states(h) -> int:
    states = h.attrs["states"]
    return len(json.loads(states) if isinstance(states, (str, bytes)) else states)


def distances(found, reference) -> tuple[float, int]:
    """The largest distance of ``found``'s special points from ``reference``'s nearest of the
    same type, and how many had none within MATCH."""
    worst, unmatched = 0.0, 0
    for t, v in found:
        d = min((abs(v - w) for u, w in reference if u == t), default=np.inf)
        if d > MATCH:
            unmatched += 1
        else:
            worst = max(worst, d)
    return worst, unmatched


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default=",".join(DEFAULT_CASES),
                    help=f"comma-separated, of: {', '.join(CASES)}")
    ap.add_argument("--schemes", default="0,3,4,5,auto")
    ap.add_argument("--rounds", type=int, default=1,
                    help="rounds, the schemes alternated in each (medians printed)")
    ap.add_argument("--reference", choices=("gauss", "same"), default="gauss")
    args = ap.parse_args(argv)
    schemes = args.schemes.split(",")
    print("case | scheme | CPU s | points | nodes/pt | unknowns/pt | recorded | LP+BP | "
          "|x - ref| | unmatched")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for case in args.cases.split(","):
            files = CASES[case]
            refs = {}
            if args.reference == "gauss":
                run_case(files, tmp / case / "ref", ["ncol=6", "tol=1e-9", "fold_tol=1e-11"])
                refs = dict.fromkeys(schemes, read(tmp / case / "ref", files)["special"])
            else:
                for k in schemes:
                    d = tmp / case / f"ref{k}"
                    run_case(files, d, [f"ncol={_value(k)}", "tol=1e-8", "fold_tol=1e-10"])
                    refs[k] = read(d, files)["special"]
            cpu = {k: [] for k in schemes}
            for r in range(args.rounds):
                for k in (schemes if r % 2 == 0 else schemes[::-1]):
                    d = tmp / case / f"{k}-{r}"
                    cpu[k].append(run_case(files, d, [f"ncol={_value(k)}"]))
            for k in schemes:
                got = read(tmp / case / f"{k}-0", files)
                worst, unmatched = distances(got["special"], refs[k])
                print(f"{case} | {k} | {statistics.median(cpu[k]):.3f} | {got['points']} | "
                      f"{got['nodes']:.0f} | {got['unknowns']:.0f} | "
                      f"{'/'.join(got['schemes'])} | {len(got['special'])} | "
                      f"{worst:.1e} | {unmatched}", flush=True)


def _value(k: str) -> str:
    return '"auto"' if k == "auto" else k


if __name__ == "__main__":
    main()
