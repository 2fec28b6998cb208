"""The answer of docs/three-d.md: which planar stable stretches and snap-back targets of the
paper stay stable for the spatial rod, from the branch files of the 3D runs.

    python tools/three_d.py stretches out/rotating_arm_3d.h5     # index_in = 0 stretches
    python tools/three_d.py changes out/rotating_arm_3d.h5       # where index_out changes
    python tools/three_d.py embedding out/rotating_arm_3d.h5 out/rotating_arm.h5
    python tools/three_d.py targets out/rotating_arm.h5 --b2 1 2 [--c 0.5]
    python tools/three_d.py snaps out/rotating_arm_3d.h5         # the 3D run's own targets

Every table is markdown, computed from the files (and, for ``targets``, by the 3D shooting
enumeration `elastica_auto.snaps.enumerate_equilibria` of ``kirchhoff_lever_arm``).
In the tables, "LP 0.8173" is a stretch ending at a located fold, "BP" at a located branch
point, "~" between two points where nothing was located (the midpoint). Along a branch, a
stretch is a run of points with one (index_in, index_out); the rows where
a block has a zero eigenvalue (index -1: folds, branch points) separate stretches. Each
branch's stretches are reduced modulo 2 pi in the continued parameter and repeated copies
(the branch's periodic translates) are listed once.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from elastica_auto.store import BranchFile

TWO_PI = 2 * math.pi
FIXED = ("eps", "P", "b2", "c")


def _key(br, parameter):
    c = br.columns
    return tuple(float(c[q][0]) for q in FIXED if q in c and q != parameter)


def stretches(br, parameter):
    """[(i0, i1, index_in, index_out)] along ``br``: runs of rows with one split index."""
    iin = br.columns["index_in"].astype(int)
    iout = br.columns["index_out"].astype(int)
    out, start = [], None
    for i in range(len(br)):
        if iin[i] < 0 or iout[i] < 0:
            if start is not None:
                out.append((start, i - 1, iin[start], iout[start]))
                start = None
            continue
        if start is not None and (iin[i], iout[i]) != (iin[start], iout[start]):
            out.append((start, i - 1, iin[start], iout[start]))
            start = None
        if start is None:
            start = i
    if start is not None:
        out.append((start, len(br) - 1, iin[start], iout[start]))
    return out


def _end(br, i, j):
    """What lies between rows i and j (i < j, or a branch end): located labels' types and
    parameter values."""
    types = br.columns["type"]
    labels = br.label_names()
    found = [(str(types[k]), labels[k], k) for k in range(min(i, j), max(i, j) + 1)
             if str(types[k]) in ("LP", "BP")]
    return found


def _fmt(x):
    return f"{x:.4f}"


def _reduce(a):
    """``a`` moved by whole periods into [0, 2 pi)."""
    return a - TWO_PI * math.floor(a / TWO_PI + 1e-12)


def _boundary(br, lam, j, k):
    """Where a stretch ends between rows j and k: a located LP or BP there (its type and
    parameter value), else the bracket's midpoint ('~')."""
    found = _end(br, j, k)
    if found:
        t, _, m = found[0]
        return t, float(lam[m])
    return "~", 0.5 * float(lam[j] + lam[k])


def distinct_stretches(bf, in_plane=None):
    """The stretches of every branch of ``bf`` (index_in = ``in_plane`` if given), each
    once: as (fixed values, (type, value) at the lower end, (type, value) at the upper end,
    the ordinate at the point nearest the middle, index_in, index_out), the lower end
    reduced into [0, 2 pi); copies (the other direction, a translate by 2 pi) within 0.02
    in the ends and 0.2 in the ordinate are left out.
    Stretches cut by a branch's start or end are left out, and those of one value of the
    parameter (points where a label and a user point coincide, counted apart)."""
    parameter = bf.branches[0].parameter
    ordinate = bf.branches[0].attrs.get("ordinate", "m1")
    out = []
    for br in bf.branches:
        lam = br.columns[parameter].astype(float)
        y = br.columns[ordinate].astype(float)
        for i0, i1, a, b in stretches(br, parameter):
            if (in_plane is not None and a != in_plane) or i0 == 0 or i1 == len(br) - 1 \
                    or np.ptp(lam[i0:i1 + 1]) < 1e-9:
                continue
            ends = [_boundary(br, lam, i0 - 1, i0), _boundary(br, lam, i1, i1 + 1)]
            ends.sort(key=lambda e: e[1])
            shift = ends[0][1] - _reduce(ends[0][1])
            lo, hi = [(t, v - shift) for t, v in ends]
            mid = i0 + int(np.argmin(np.abs(lam[i0:i1 + 1] - 0.5 * (ends[0][1] + ends[1][1]))))
            row = (_key(br, parameter), lo, hi, float(y[mid]), a, b)
            if any(r[0] == row[0] and r[4:] == row[4:] and abs(r[1][1] - lo[1]) < 0.02
                   and abs(r[2][1] - hi[1]) < 0.02 and abs(r[3] - row[3]) < 0.2 for r in out):
                continue
            out.append(row)
    out.sort(key=lambda r: (r[0], r[1][1], r[3]))
    return out


def table_stretches(bf, only_stable_in_plane=True):
    parameter = bf.branches[0].parameter
    ordinate = bf.branches[0].attrs.get("ordinate", "m1")
    print(f"| {', '.join(q for q in FIXED if q != parameter)} | {parameter} from | to | "
          f"{ordinate} (middle) | index_in | index_out |")
    print("|---|---|---|---|---|---|")
    for fixed, lo, hi, ymid, a, b in distinct_stretches(bf, 0 if only_stable_in_plane
                                                        else None):
        print(f"| {', '.join(f'{v:g}' for v in fixed)} | {lo[0]} {_fmt(lo[1])} | "
              f"{hi[0]} {_fmt(hi[1])} | {_fmt(ymid)} | {a} | {b} |")


def table_changes(bf):
    """Every change of index_out between neighbouring stretches of one index_in, each once
    (either direction, translates by 2 pi): at the located BP between them, else at the
    middle of the bracket of the two points."""
    parameter = bf.branches[0].parameter
    ordinate = bf.branches[0].attrs.get("ordinate", "m1")
    print(f"| {', '.join(q for q in FIXED if q != parameter)} | {parameter} (mod 2 pi) | "
          f"bracket | {ordinate} | index_in | index_out on either side | located |")
    print("|---|---|---|---|---|---|---|")
    rows = {}
    for br in bf.branches:
        lam = br.columns[parameter].astype(float)
        y = br.columns[ordinate].astype(float)
        runs = [r for r in stretches(br, parameter) if np.ptp(lam[r[0]:r[1] + 1]) >= 1e-9]
        for (i0, i1, a, b), (j0, j1, c, d) in zip(runs, runs[1:]):
            if b == d or a != c:
                continue
            found = [f for f in _end(br, i1, j0) if f[0] == "BP"]
            at = lam[found[0][2]] if found else 0.5 * (lam[i1] + lam[j0])
            red = round(_reduce(at + 1e-7) - 1e-7, 4)
            ym = float(y[found[0][2]]) if found else 0.5 * (y[i1] + y[j0])
            key = (_key(br, parameter), a, min(b, d), max(b, d),
                   red if found else round(ym, 1))
            bracket = sorted((_reduce(lam[i1] - at + red), _reduce(lam[j0] - at + red)))
            rows.setdefault(key, (red, bracket, ym, a, min(b, d), max(b, d), bool(found)))
    for key, (red, bracket, ym, a, lo, hi, located) in sorted(
            rows.items(), key=lambda t: (t[0][0], t[1][0])):
        fixed = ", ".join(f"{v:g}" for v in key[0])
        print(f"| {fixed} | {red:.4f} | [{bracket[0]:.4f}, {bracket[1]:.4f}] | {ym:.4f} | "
              f"{a} | {lo} / {hi} | {'BP' if located else 'not located'} |")


def table_embedding(bf3, bf2):
    """The in-plane index of each 3D point against the planar run's index at the same
    parameter values, interpolated on the planar branch with the same fixed values and the
    nearest ordinate: the number of points compared and of disagreements, per branch."""
    parameter = bf3.branches[0].parameter
    print(f"| branch (3D) | {', '.join(q for q in FIXED if q != parameter)} | points compared "
          "| index_in = planar index |")
    print("|---|---|---|---|")
    total = bad = 0
    for br in bf3.branches:
        fixed = {q: float(br.columns[q][0]) for q in ("eps", "P")}
        planar = [b for b in bf2.branches if all(abs(float(b.columns[q][0]) - v) < 1e-12
                                                 for q, v in fixed.items())]
        pts = np.array([(float(b.columns[parameter][i]), float(b.columns["m1"][i]),
                         int(b.columns["index"][i])) for b in planar for i in range(len(b))
                        if str(b.columns["type"][i]) not in ("LP", "BP")])
        n = k = 0
        for i in range(len(br)):
            iin = int(br.columns["index_in"][i])
            if iin < 0:
                continue
            lam, m1 = float(br.columns[parameter][i]), float(br.columns["m1"][i])
            d = np.hypot(np.remainder(pts[:, 0] - lam + math.pi, TWO_PI) - math.pi,
                         pts[:, 1] - m1)
            j = int(np.argmin(d))
            if d[j] > 1e-6:          # no planar point at this state: not compared
                continue
            n += 1
            k += int(pts[j, 2] != iin)
        total, bad = total + n, bad + k
        print(f"| {br.number} | {', '.join(f'{v:g}' for v in _key(br, parameter))} | {n} | "
              f"{n - k} |")
    print(f"\n{total} points compared, {bad} disagreements")


def table_targets(bf2, b2_values, c_values):
    """For each fold of the planar file's snap-back table: its stable planar targets and
    their 3D index (the 3D enumeration at the fold's parameters, the same state: k1 =
    theta'(0), k2 = 0), and every other stable 3D equilibrium there."""
    from elastica_auto.problem import load_problem
    from elastica_auto.snaps import enumerate_equilibria
    rod = load_problem("kirchhoff_lever_arm")
    folds = {}
    for r in bf2.snaps:
        folds.setdefault(r["lp"], []).append(r)
    print("| fold | eps, P | psi (mod 2 pi) | b2, c | planar targets k = m(0).e_z: 3D index "
          "(in + out) | other stable 3D equilibria |")
    print("|---|---|---|---|---|---|")
    done = {}
    for lp, rows in sorted(folds.items(), key=lambda t: int(t[0][2:])):
        pt = bf2.label(lp)
        p = {q: float(v) for q, v in pt.params.items()} if hasattr(pt, "params") else None
        if p is None:
            br, i = bf2.labels[lp]
            b = bf2.branches[br - 1]
            p = {q: float(b.columns[q][i - 1]) for q in bf2.parameters}
        psi = _reduce(p["psi"])
        for b2 in b2_values:
            for c in c_values:
                key = (round(p["eps"], 9), round(p["P"], 9), round(psi, 8), b2, c)
                if key in done:
                    continue
                q = {**rod.defaults(), **{k: p[k] for k in ("P", "eps", "alpha", "theta0")},
                     "psi": psi, "b2": b2, "c": c}
                eqs = enumerate_equilibria(rod, q)
                done[key] = eqs
                cells = []
                for r in rows:
                    hit = min(eqs, key=lambda e: abs(e.k[0] - r["k"]) + abs(e.k[1]))
                    ok = abs(hit.k[0] - r["k"]) < 1e-5 and abs(hit.k[1]) < 1e-8
                    cells.append(f"{r['k']:.4f}: " + (
                        f"{hit.index} ({int(hit.ordinates['index_in'])} + "
                        f"{int(hit.ordinates['index_out'])})" if ok else "not found"))
                others = [e for e in eqs if e.index == 0 and abs(e.k[1]) > 1e-8]
                other = ", ".join(f"({e.k[0]:.4f}, {e.k[1]:.4f})" for e in others) or "none"
                print(f"| {lp} | {p['eps']:g}, {p['P']:.4f} | {psi:.4f} | {b2:g}, {c:.4g} | "
                      f"{'; '.join(cells)} | {other} |", flush=True)


def table_snaps(bf):
    """The 3D run's own snap-back table: per fold, its stable targets (k = (k1, k2), z(1))."""
    print("| fold | branch | psi | k1 | k2 | z(1) | index (in + out) | on branch |")
    print("|---|---|---|---|---|---|---|---|")
    for r in bf.snaps:
        print(f"| {r['lp']} | {int(r['branch'])} | {r['value']:.4f} | {r['k']:.4f} | "
              f"{r.get('k_2', 0.0):.4f} | {r['target_z1']:.2e} | {int(r['index'])} "
              f"({int(r['target_index_in'])} + {int(r['target_index_out'])}) | "
              f"{int(r['on_branch'])} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("table", choices=("stretches", "changes", "embedding", "targets", "snaps"))
    ap.add_argument("files", nargs="+")
    ap.add_argument("--all", action="store_true", help="stretches: every stretch, not only "
                    "the planar stable ones")
    ap.add_argument("--b2", type=float, nargs="+", default=[1.0, 2.0])
    ap.add_argument("--c", type=float, nargs="+", default=[1 / 1.3])
    args = ap.parse_args(argv)
    files = [BranchFile(f) for f in args.files]
    if args.table == "stretches":
        table_stretches(files[0], not args.all)
    elif args.table == "changes":
        table_changes(files[0])
    elif args.table == "embedding":
        table_embedding(files[0], files[1])
    elif args.table == "targets":
        table_targets(files[0], args.b2, args.c)
    else:
        table_snaps(files[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
