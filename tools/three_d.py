"""The answer of docs/three-d.md: which planar stable stretches and snap-back targets of the
paper stay stable for the spatial rod, from the branch files of the 3D runs.

    python tools/three_d.py stretches out/rotating_arm_3d.h5     # index_in = 0 stretches
    python tools/three_d.py changes out/rotating_arm_3d.h5       # where index_out changes
    python tools/three_d.py embedding out/rotating_arm_3d.h5 out/rotating_arm.h5
    python tools/three_d.py folds out/rotating_arm_3d.h5 out/rotating_arm.h5
    python tools/three_d.py targets out/rotating_arm.h5 --b2 1 2 [--c 0.5]
    python tools/three_d.py snaps out/rotating_arm_3d.h5         # the 3D run's own targets
    python tools/three_d.py equilibria --set eps=0.5 "P=pi^2/4" psi=1.18 --b2 2
    python tools/three_d.py embedded-labels out/rotating_arm.h5 --b2 1 2 --c 0.5 2
    python tools/three_d.py embedded-stretches out/rotating_arm.h5 --b2 1 2 --c 0.5
    python tools/three_d.py embedded-changes out/rotating_arm.h5 --b2 1 2 --c 0.5

The ``embedded-`` tables need no 3D run: the planar run's states are planar states of the
spatial rod whatever b2 and c, and the out-of-plane block of its second variation is
counted at each stored point (the planar profile embedded: r = (x, y, 0), q = q_z(theta) (x)
Q_REF, m = kappa e_z), with index_in the planar index.

Every table is markdown, computed from the files (and, for ``targets``, by the 3D shooting
enumeration `elastica_auto.analysis.equilibria.enumerate_equilibria` of ``kirchhoff_lever_arm``).
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

from elastica_auto.storage.store import BranchFile

TWO_PI = 2 * math.pi
FIXED = ("eps", "P", "b2", "c")


def _key(br, parameter):
    c = br.columns
    return tuple(float(c[q][0]) for q in FIXED if q in c and q != parameter)


def stretches(br, parameter):
    """[(i0, i1, index_in, index_out)] along ``br``: runs of rows with one split index (the
    folds and branch points left out: the count at a singular point is one side's, or, at a
    symmetric branch point, the count on the complement of the zero mode)."""
    iin = br.columns["index_in"].astype(int)
    iout = br.columns["index_out"].astype(int)
    singular = np.isin(br.columns["type"], ("LP", "BP"))
    out, start = [], None
    for i in range(len(br)):
        if iin[i] < 0 or iout[i] < 0 or singular[i]:
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
    return f"{round(x, 4) + 0.0:.4f}"


def _reduce(a):
    """``a`` moved by whole periods into [0, 2 pi)."""
    return a - TWO_PI * math.floor(a / TWO_PI + 1e-9)


def _boundary(br, lam, j, k):
    """Where a stretch ends between rows j and k: a located LP or BP there (its type and
    parameter value), else the bracket's midpoint ('~')."""
    found = _end(br, j, k)
    if found:
        t, _, m = found[0]
        return t, float(lam[m])
    return "~", 0.5 * float(lam[j] + lam[k])


def _near(a, b):
    """Two stretch ends alike: within 0.02 where both are located labels, 0.3 otherwise."""
    tol = 0.02 if a[0] != "~" and b[0] != "~" else 0.3
    return abs(a[1] - b[1]) < tol


def distinct_stretches(bf, in_plane=None):
    """The stretches of every branch of ``bf`` (index_in = ``in_plane`` if given), each
    once: as (fixed values, (type, value) at the lower end, (type, value) at the upper end,
    the ordinate interpolated at the middle, index_in, index_out), the lower end
    reduced into [0, 2 pi); copies (the other direction, a translate by 2 pi) within 0.02
    in the located ends (0.3 where an end is a bracket) and 0.5 in the ordinate are left
    out.
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
            # the ordinate interpolated at the middle (the parameter is monotone along a
            # stretch: it holds no fold); the point nearest the middle lies where the
            # branch's steps put it, so the two directions of one stretch differed by more
            # than the 0.5 that tells copies apart on a steep stretch
            order = np.argsort(lam[i0:i1 + 1])
            ymid = float(np.interp(0.5 * (ends[0][1] + ends[1][1]), lam[i0:i1 + 1][order],
                                   y[i0:i1 + 1][order]))
            row = (_key(br, parameter), lo, hi, ymid, a, b)
            if any(r[0] == row[0] and r[4:] == row[4:] and _near(r[1], lo) and _near(r[2], hi)
                   and abs(r[3] - row[3]) < 0.5 for r in out):
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
    (either direction, translates by 2 pi): at the located BP between them; else, on an
    embedded planar branch, where the eigenvalue crossing zero does by linear interpolation
    ("interpolated"), else at the middle of the bracket of the two points."""
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
            at = lam[found[0][2]] if found else (
                br.crossing(i1, j0, min(b, d)) if hasattr(br, "crossing")
                else 0.5 * (lam[i1] + lam[j0]))
            red = round(_reduce(at + 1e-7) - 1e-7, 4)
            ym = float(y[found[0][2]]) if found else 0.5 * (y[i1] + y[j0])
            key = (_key(br, parameter), a, min(b, d), max(b, d),
                   red if found or hasattr(br, "crossing") else round(ym, 1))
            bracket = sorted((_reduce(lam[i1] - at + red), _reduce(lam[j0] - at + red)))
            rows.setdefault(key, (red, bracket, ym, a, min(b, d), max(b, d), bool(found)))
    for key, (red, bracket, ym, a, lo, hi, located) in sorted(
            rows.items(), key=lambda t: (t[0][0], t[1][0])):
        fixed = ", ".join(f"{v:g}" for v in key[0])
        how = "BP" if located else ("interpolated" if hasattr(bf.branches[0], "crossing")
                                    else "not located")
        print(f"| {fixed} | {red:.4f} | [{bracket[0]:.4f}, {bracket[1]:.4f}] | {ym:.4f} | "
              f"{a} | {lo} / {hi} | {how} |")


def table_folds(bf3, bf2):
    """The folds (LP) of the 3D run against the planar run's at the same (eps, P), per b2:
    how many, and the largest distance of each 3D fold to the nearest planar one."""
    def folds(bf, b2=None):
        out = {}
        for br in bf.branches:
            c = br.columns
            if b2 is not None and float(c["b2"][0]) != b2:
                continue
            key = (float(c["eps"][0]), float(c["P"][0]))
            out.setdefault(key, []).extend(c["psi"][c["type"] == "LP"].astype(float))
        return {k: np.sort(v) for k, v in out.items()}
    planar = folds(bf2)
    print("| eps, P | b2 | folds (3D) | folds (planar) | largest difference |")
    print("|---|---|---|---|---|")
    for b2 in sorted({float(br.columns["b2"][0]) for br in bf3.branches}):
        for key, got in sorted(folds(bf3, b2).items()):
            want = planar[key]
            worst = max(float(np.min(np.abs(want - v))) for v in got)
            print(f"| {key[0]:g}, {key[1]:.4f} | {b2:g} | {len(got)} | {len(want)} | "
                  f"{worst:.1e} |")


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
    from elastica_auto.model.problem import load_problem
    from elastica_auto.analysis.equilibria import enumerate_equilibria
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
                    ok = abs(hit.k[0] - r["k"]) < 1e-5 and abs(hit.k[1]) < 1e-6
                    cells.append(f"{r['k']:.4f}: " + (
                        f"{hit.index} ({int(hit.ordinates['index_in'])} + "
                        f"{int(hit.ordinates['index_out'])})" if ok else "not found"))
                others = [e for e in eqs if e.index == 0 and abs(e.k[1]) > 1e-6]
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


class Embedded:
    """A planar branch seen as the spatial rod's: the columns ``index_in`` (the planar
    index) and ``index_out`` (the out-of-plane block of the spatial rod's second variation
    at the planar state, for stiffnesses ``b2`` and ``c``) next to the planar file's."""

    def __init__(self, br, grid, b2, c):
        import elastica_auto.equations.kirchhoff_lever_arm as rod
        self.number, self.attrs, self._br = br.number, dict(br.attrs), br
        self.attrs["ordinate"] = "m1"
        self._grid, self._b2, self._c = grid, float(b2), float(c)
        cols = {q: np.asarray(br.columns[q]) for q in ("psi", "alpha", "theta0", "eps", "P",
                                                        "m1", "m0", "mA", "type", "index")}
        cols["b2"] = np.full(len(br), float(b2))
        cols["c"] = np.full(len(br), float(c))
        out = np.full(len(br), -1)
        for i, prof in enumerate(br.profiles):
            p = {q.name: q.default for q in rod.PARAMETERS}
            p.update({q: float(cols[q][i]) for q in ("psi", "alpha", "theta0", "eps", "P")},
                     b2=float(b2), c=float(c))
            out[i] = rod.part_counts(grid, embed(rod, prof), p)["index_out"]
        cols["index_in"] = np.where(np.isin(cols["type"], ("LP", "BP")), -1, cols["index"])
        cols["index_out"] = out
        self.columns = cols

    def crossing(self, i, j, k):
        """Where the (k+1)-th lowest out-of-plane eigenvalue crosses zero between rows i and
        j: each found by bisection on the shifted count to 1e-6, then linear interpolation
        in the parameter."""
        import elastica_auto.equations.kirchhoff_lever_arm as rod
        lam = self.columns[self.parameter].astype(float)

        def eigenvalue(row):
            p = {q.name: q.default for q in rod.PARAMETERS}
            p.update({q: float(self.columns[q][row]) for q in ("psi", "alpha", "theta0", "eps",
                                                                "P")},
                     b2=self._b2, c=self._c)
            y = embed(rod, self._br.profiles[row])
            lo, hi = -50.0, 50.0
            while hi - lo > 1e-6:
                mid = 0.5 * (lo + hi)
                n = rod.part_counts(self._grid, y, p, shift=mid)["index_out"]
                lo, hi = (mid, hi) if n <= k else (lo, mid)
            return 0.5 * (lo + hi)
        a, b = eigenvalue(i), eigenvalue(j)
        return lam[i] + (lam[j] - lam[i]) * a / (a - b)

    @property
    def parameter(self):
        return self._br.parameter

    def __len__(self):
        return len(self._br)

    def label_names(self):
        return self._br.label_names()


def embed(rod, profile):
    """The spatial rod's state (10, m) of a planar profile (theta, kappa, x, y): r = (x, y,
    0), q = q_z(theta) (x) Q_REF, m = kappa e_z (docs/kirchhoff.md, "Planar states")."""
    theta, kappa, x, y = profile[:4]
    half = 0.5 * theta
    qz = np.vstack((np.cos(half), 0 * half, 0 * half, np.sin(half)))
    zero = np.zeros_like(theta)
    return np.vstack((x, y, zero, rod.qmul(qz, rod.Q_REF[:, None]), zero, zero, kappa))


class EmbeddedFile:
    """A planar branch file's branches as `Embedded` ones, for the tables above."""

    def __init__(self, bf, b2, c):
        self.branches = [Embedded(br, bf.profile_grid, b2, c) for br in bf.branches]


def table_equilibria(values: dict, b2_values, c_values):
    """Every equilibrium of the spatial rod at the parameter ``values`` (the 3D shooting
    scan), for each (b2, c): k = (k1, k2), z(1), index (in + out where planar)."""
    from elastica_auto.model.problem import load_problem
    from elastica_auto.analysis.equilibria import enumerate_equilibria
    rod = load_problem("kirchhoff_lever_arm")
    print("| " + ", ".join(values) + " | b2, c | k1 | k2 | z(1) | index | in + out |")
    print("|---|---|---|---|---|---|---|")
    for b2 in b2_values:
        for c in c_values:
            for e in enumerate_equilibria(rod, {**rod.defaults(), **values, "b2": b2, "c": c}):
                o = e.ordinates
                split = (f"{int(o['index_in'])} + {int(o['index_out'])}"
                         if o["index_in"] >= 0 else "non-planar")
                print(f"| {', '.join(f'{v:.6g}' for v in values.values())} | {b2:g}, {c:.4g} "
                      f"| {e.k[0]:.4f} | {e.k[1]:.4f} | {o['z1']:.4f} | {e.index} | {split} |",
                      flush=True)


def table_embedded_labels(bf2, b2_values, c_values):
    """The stable (index 0) user points of a planar file, each distinct state once, with
    the out-of-plane index of the spatial rod at that planar state for each (b2, c)."""
    import elastica_auto.equations.kirchhoff_lever_arm as rod
    grid = bf2.profile_grid
    pairs = [(b2, c) for b2 in b2_values for c in c_values]
    print("| eps, P | psi (mod 2 pi) | m(0).e_z | " + " | ".join(
        f"b2 = {b2:g}, c = {c:.4g}" for b2, c in pairs) + " |")
    print("|---|---|---|" + "---|" * len(pairs))
    seen = set()
    rows = []
    for name, (nb, pt) in bf2.labels.items():
        br = bf2.branches[nb - 1]
        i = pt - 1
        if not name.startswith("UZ") or int(br.columns["index"][i]) != 0:
            continue
        p2 = {q: float(br.columns[q][i]) for q in bf2.parameters}
        key = (p2["eps"], p2["P"], round(_reduce(p2["psi"] + 1e-9), 6),
               round(float(br.columns["m0"][i]), 3))
        if key in seen:
            continue
        seen.add(key)
        y3 = embed(rod, br.profiles[i])
        cells = []
        for b2, c in pairs:
            p = {q.name: q.default for q in rod.PARAMETERS}
            p.update({q: p2[q] for q in ("psi", "alpha", "theta0", "eps", "P")}, b2=b2, c=c)
            cells.append(str(rod.part_counts(grid, y3, p)["index_out"]))
        rows.append((key, cells))
    for key, cells in sorted(rows):
        print(f"| {key[0]:g}, {key[1]:.4f} | {key[2]:.4f} | {key[3]:.3f} | "
              + " | ".join(cells) + " |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("table", choices=("stretches", "changes", "embedding", "targets", "snaps",
                                      "embedded-stretches", "embedded-changes", "equilibria",
                                      "embedded-labels", "folds"))
    ap.add_argument("files", nargs="*")
    ap.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE",
                    help="equilibria: the parameter values (the others: the defaults)")
    ap.add_argument("--all", action="store_true", help="stretches: every stretch, not only "
                    "the planar stable ones")
    ap.add_argument("--b2", type=float, nargs="+", default=[1.0, 2.0])
    ap.add_argument("--c", type=float, nargs="+", default=[1 / 1.3])
    args = ap.parse_args(argv)
    files = [BranchFile(f) for f in args.files]
    if args.table == "equilibria":
        from elastica_auto.core.expressions import evaluate
        table_equilibria({k: float(evaluate(v)) for k, v in (a.split("=", 1) for a in args.set)},
                         args.b2, args.c)
    elif args.table == "stretches":
        table_stretches(files[0], not args.all)
    elif args.table == "changes":
        table_changes(files[0])
    elif args.table == "folds":
        table_folds(files[0], files[1])
    elif args.table == "embedding":
        table_embedding(files[0], files[1])
    elif args.table == "embedded-labels":
        table_embedded_labels(files[0], args.b2, args.c)
    elif args.table.startswith("embedded"):
        for b2 in args.b2:
            for c in args.c:
                planar = EmbeddedFile(files[0], b2, c)
                (table_stretches if args.table.endswith("stretches")
                 else table_changes)(*((planar, not args.all) if args.table.endswith(
                     "stretches") else (planar,)))
    elif args.table == "targets":
        table_targets(files[0], args.b2, args.c)
    else:
        table_snaps(files[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
