"""Section 9 (``--energy``): modules derived from an energy against their hand-written
references."""

from __future__ import annotations

import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from . import REPO


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
