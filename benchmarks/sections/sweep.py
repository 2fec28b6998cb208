"""Section 5 (``--sweep``): 64 short branches in one process and on local Dask clusters."""

from __future__ import annotations

import importlib
import math
import time


def sweep(branches=64):
    """The sweep's branches in one process and on local clusters of 1 and 2 workers (started,
    and the engine imported on each worker, before the clock, so that only the branches and
    their scheduling are timed; no snap-back scan)."""
    import elastica_auto as ea
    from elastica_auto.execution import cluster
    from elastica_auto.execution.plan import Request, make_plan
    from elastica_auto.execution.run import in_process, start_job
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
            in_process(plan, first, branches, lambda: None)
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
