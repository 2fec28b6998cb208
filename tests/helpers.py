"""Helpers shared by the tests (run files, runs, the console script)."""

from __future__ import annotations

import math
import subprocess
import textwrap
from dataclasses import dataclass
from pathlib import Path

from elastica_auto import runfile
from elastica_auto.run import execute
from elastica_auto.store import BranchFile

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples"

#: The shipped rotating-arm run (paper 4.1.1): psi continued both ways from the straight rod.
ROTATING_ARM = REPO / "runs" / "rotating_arm.toml"


def elastica_run_file(path: Path, *, eps="0.25", P="pi^2/4", directions="both",
                      bounds=("-2*pi", "2*pi"), uz=None, extra="") -> Path:
    """Write a small psi-continuation run file for the elastica and return its path."""
    uz_lines = ""
    if uz is not None:
        uz_lines = f"uz = [{', '.join(repr(v) for v in uz)}]\nuz_period = \"2*pi\"\n"
    path.write_text(textwrap.dedent(f"""\
        description = "test run"
        equation = "elastica_lever_arm"
        start = "trivial"

        [parameters]
        eps = {eps!r}
        P = {P!r}
        psi = 0
        alpha = 0
        theta0 = 0

        [continuation]
        parameter = "psi"
        directions = "{directions}"
        bounds = ["{bounds[0]}", "{bounds[1]}"]
        """) + uz_lines + extra)
    return path


@dataclass
class RunOutput:
    plan: runfile.Plan
    result: object          # elastica_auto.run.RunResult
    file: BranchFile


def run_plan(plan, out_dir: Path, jobs: int = 1) -> RunOutput:
    result = execute(plan, out_dir, jobs=jobs)
    return RunOutput(plan, result, BranchFile(result.path))


def run_cli(exe, *args, cwd=None):
    """Run the console script; return CompletedProcess with text stdout/stderr."""
    return subprocess.run([exe, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


# Solution accuracy bounds that follow from scipy's solve_bvp success criterion (scipy/integrate/
# _bvp.py): a solve succeeds only if every boundary residual is <= bc_tol (the engine passes
# bc_tol <= tol), and every interval's rms residual is <= tol, where the rms
# residual is (0.5 (32/45 r_mid^2 + 49/90 (r_1^2 + r_2^2)))^(1/2), r = (y' - f) / (1 + |f|)
# summed over components, and r_mid = 1.5 col_res / h. Hence, per component,
#     |col_res| <= (2/3) (45/16)^(1/2) h tol (1 + |f_mid|) = 1.118 h tol (1 + |f_mid|).
COL_RES_FACTOR = (2 / 3) * math.sqrt(45 / 16)


def invariant_bound(tol, P, alpha):
    """Largest change of I = kappa - P (x cos alpha + y sin alpha) along a solve_bvp solution.

    I is linear in y with I'(y) . f(y) = 0 identically (-P sin(theta - alpha) + P sin theta
    cos alpha - P cos theta sin alpha = 0), so over a mesh interval the collocation equation
    y_{i+1} - y_i = h/6 (f_i + 4 f_mid + f_{i+1}) + col_res gives I_{i+1} - I_i = c . col_res
    with c = (0, 1, -P cos alpha, -P sin alpha). Summing COL_RES_FACTOR h tol (1 + |f_j|) over
    the intervals (sum h = 1) with |kappa'| <= |P|, |x'|, |y'| <= 1 bounds the total change.
    """
    c = (1 + abs(P)) + 2 * abs(P) * (abs(math.cos(alpha)) + abs(math.sin(alpha)))
    return COL_RES_FACTOR * tol * c


def invariant(y, p):
    return y[1] - p["P"] * (y[2] * math.cos(p["alpha"]) + y[3] * math.sin(p["alpha"]))
