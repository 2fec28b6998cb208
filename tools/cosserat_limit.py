"""The inextensible limit of docs/soft-robots.md ("Cosserat rods"): the rotating arm's folds
(runs/rotating_arm.toml's four (eps, P) pairs, psi from the straight rod one way; the other
way is the mirror image) of the planar Cosserat rod at growing stiffnesses against the shipped
elastica's, or of the spatial rod against the Kirchhoff rod's.

    python tools/cosserat_limit.py                    # planar: EA = k, GA = k / 3
    python tools/cosserat_limit.py --k 1000 2000 4000 --ratio 3
    python tools/cosserat_limit.py --spatial --b2 1 2 --k 50 1000

A markdown table, one row per fold: its psi for the inextensible module, the gap
d(k) = psi(k) - psi_inf at each stiffness, k d(k) (constant where the rate is 1 / k), the
observed order log2(d(k) / d(2k)) between consecutive stiffnesses that double, and the error
of Richardson's extrapolation 2 psi(k_last) - psi(k_last / 2) (where both are listed); the
index before each fold, which is the inextensible module's wherever the column "index" shows
one number.
"""

from __future__ import annotations

import argparse
import math

import elastica_auto as ea
from elastica_auto.core.errors import ProblemError

ARM = [(e, P, tex) for e in (0.25, 0.5)
       for P, tex in ((math.pi ** 2 / 4, "pi^2/4"), (9 * math.pi ** 2 / 4, "9 pi^2/4"))]


def folds(problem, params):
    """[(psi, index before the fold)] of the psi branch from the straight rod, direction +."""
    (branch,) = ea.continuation(problem, {**problem.defaults(), **params}, "psi",
                                bounds=(-6 * math.pi, 6 * math.pi), ds_max=1.0)
    out, before = [], branch.points[0].index
    for pt in branch.points:
        if pt.type == "LP":
            out.append((pt.params["psi"], before))
        if pt.index >= 0 and pt.type not in ("LP", "BP"):
            before = pt.index
    return out


def table(reference, model, stiff, ks, extra) -> list[str]:
    head = ["pair", "LP", "psi (inextensible)", *(f"d({k:g})" for k in ks),
            *(f"{k:g} d" for k in ks), "order", "Richardson error", "index"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for eps, P, tex in ARM:
        base = {"eps": eps, "P": P, **extra}
        ref = folds(reference, base)
        rows = [folds(model, {**base, **stiff(k)}) for k in ks]
        if any(len(r) != len(ref) for r in rows):
            lines.append(f"| eps = {eps}, P = {tex} | fold counts differ: "
                         f"{len(ref)} and {[len(r) for r in rows]} |")
            continue
        for j, (psi, index) in enumerate(ref):
            got = [r[j][0] for r in rows]
            gaps = [g - psi for g in got]
            orders = [f"{math.log2(a / b):.3f}" for a, b, k1, k2 in
                      zip(gaps, gaps[1:], ks, ks[1:]) if k2 == 2 * k1 and a and b]
            rich = (f"{2 * got[-1] - got[-2] - psi:.1e}" if len(ks) > 1 and ks[-1] == 2 * ks[-2]
                    else "")
            indices = sorted({index, *(r[j][1] for r in rows)})
            lines.append(f"| eps = {eps}, P = {tex} | {j + 1} | {psi:.8f} | "
                         + " | ".join(f"{g:.3e}" for g in gaps) + " | "
                         + " | ".join(f"{k * g:.4f}" for k, g in zip(ks, gaps)) + " | "
                         + (", ".join(orders) or "") + f" | {rich} | "
                         + " ".join(map(str, indices)) + " |")
    return lines


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spatial", action="store_true",
                        help="cosserat_rod (S) against kirchhoff_lever_arm")
    parser.add_argument("--k", type=float, nargs="+", default=[1000.0, 2000.0, 4000.0],
                        help="the stiffnesses (EA, or S)")
    parser.add_argument("--ratio", type=float, default=3.0, help="EA / GA (planar)")
    parser.add_argument("--b2", type=float, nargs="+", default=[2.0], help="spatial: b2")
    args = parser.parse_args(argv)
    try:
        if args.spatial:
            model = ea.load_problem("equations/cosserat_rod.py")
            reference = ea.load_problem("kirchhoff_lever_arm")
            for b2 in args.b2:
                print(f"\ncosserat_rod (S = k) against kirchhoff_lever_arm, b2 = {b2:g}:\n")
                print("\n".join(table(reference, model, lambda k: {"S": k}, args.k,
                                      {"b2": b2})))
        else:
            model = ea.load_problem("equations/cosserat_planar.py")
            reference = ea.load_problem("elastica_lever_arm")
            print(f"cosserat_planar (EA = k, GA = k / {args.ratio:g}) against "
                  "elastica_lever_arm:\n")
            print("\n".join(table(reference, model,
                                  lambda k: {"EA": k, "GA": k / args.ratio}, args.k, {})))
    except ProblemError as exc:
        raise SystemExit(f"cosserat_limit: error: {exc}") from None


if __name__ == "__main__":
    main()
