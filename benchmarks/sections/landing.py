"""Section 6 (``--landing``): where a snap lands, overdamped and damped."""

from __future__ import annotations

import math
import time


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
