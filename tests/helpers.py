"""Helpers shared by the tests (run files, runs, the console script)."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass
from pathlib import Path

from elastica_auto.execution import runfile
from elastica_auto.execution.run import execute
from elastica_auto.storage.store import BranchFile

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples"
#: The hand-written modules that the shipped energy-first ones replaced (issue 47): the
#: references the tests compare the derived modules with.
REFERENCE = REPO / "tests" / "reference"

#: The shipped rotating-arm run (paper 4.1.1): psi continued both ways from the straight rod.
ROTATING_ARM = REPO / "runs" / "rotating_arm.toml"


def elastica_run_file(path: Path, *, eps="0.25", P="pi^2/4", directions="both",
                      bounds=("-2*pi", "2*pi"), uz=None, extra="", mirror=True) -> Path:
    """Write a small psi-continuation run file for the elastica and return its path.
    ``mirror = False``: both directions computed, not one the other's mirror image (where a
    test needs the second computed)."""
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
        """) + uz_lines + extra + ("" if mirror else _options(extra) + "mirror = false\n"))
    return path


def fold_curves_file(path: Path, equation: str, folds, extra: str = "") -> Path:
    """Write a fold-curve run file: from the LP labels of the file ``folds`` at eps = 0.25,
    continued in (psi, eps) over eps in [0.2, 0.3]; ``extra`` lines added to its
    [continuation] table."""
    path.write_text(f"""
equation = "{equation}"
start = [{{ file = "{folds}", type = "LP", where = {{ eps = 0.25 }} }}]
[continuation]
parameter = ["psi", "eps"]
bounds = [0.2, 0.3]
{extra}""")
    return path


def central_jacobian(fun, x0, h: float = 1e-6):
    """The Jacobian of ``fun`` (a vector of a vector) at ``x0`` by central differences of
    step ``h``, dense: an independent reference for the engine's Newton matrices."""
    import numpy as np
    x0 = np.asarray(x0, dtype=float)
    jac = np.empty((len(fun(x0)), len(x0)))
    for j in range(len(x0)):
        e = np.zeros(len(x0))
        e[j] = h
        jac[:, j] = (fun(x0 + e) - fun(x0 - e)) / (2 * h)
    return jac


def _options(extra: str) -> str:
    """The header of the [options] table, unless ``extra`` opened it (and so it is open)."""
    return "" if extra.rstrip("\n").split("\n")[0] == "[options]" or \
        "\n[options]" in extra else "[options]\n"


@dataclass
class RunOutput:
    plan: runfile.Plan
    result: object          # elastica_auto.execution.run.RunResult
    file: BranchFile


def run_plan(plan, out_dir: Path, jobs: int = 1) -> RunOutput:
    result = execute(plan, out_dir, jobs=jobs)
    return RunOutput(plan, result, BranchFile(result.path))


def run_cli(exe, *args, cwd=None):
    """Run the console script; return CompletedProcess with text stdout/stderr."""
    return subprocess.run([exe, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


# -- synchronising with a running command ---------------------------------------------------------
# A test that signals or kills a running command waits for an event it can observe (a file
# that the command or a test module writes, a process's state), never for a fixed time: under
# load, a fixed sleep lands in another window than the one the test was written for.

def wait_for(what: str, condition, proc=None, seconds: float = 120.0):
    """Poll ``condition()`` until it is true and return its value. Fails, naming ``what``,
    if ``proc`` (a Popen, to be running while it is waited for) ends first, or if
    ``seconds`` pass (``proc`` is then killed, not left behind)."""
    deadline = time.monotonic() + seconds
    while True:
        value = condition()
        if value:
            return value
        if proc is not None and proc.poll() is not None:
            _, err = proc.communicate()
            raise AssertionError(f"the command ended (status {proc.returncode}) before "
                                 f"{what}; its stderr: {err!r}")
        if time.monotonic() > deadline:
            err = ""
            if proc is not None:
                proc.kill()
                err = f"; the command (killed) wrote to stderr: {proc.communicate()[1]!r}"
            raise AssertionError(f"timed out after {seconds:g} s waiting for {what}{err}")
        time.sleep(0.02)


#: The elastica written by hand (the shipped module is derived from its energy, issue 47): a
#: user module with every function of the protocol, for the tests that hook into them.
ELASTICA = (REFERENCE / "elastica_lever_arm.py").read_text()

_SIGNALLING = """

import os as _os
import time as _time

_done = set()


def _signal_the_test(p):
    if {mark_file!r} and "mark" not in _done and ({mark}):
        _done.add("mark")
        open({mark_file!r}, "a").close()
    if {hold_file!r} and "hold" not in _done and ({hold}):
        _done.add("hold")
        try:  # one hold in all the processes of the run, and of its reruns
            _os.close(_os.open({hold_file!r} + ".claimed", _os.O_CREAT | _os.O_EXCL))
        except FileExistsError:
            return
        with open({hold_file!r} + ".tmp", "w") as fh:
            fh.write(str(_os.getpid()))
        _os.replace({hold_file!r} + ".tmp", {hold_file!r})
        deadline = _time.monotonic() + 600
        while _time.monotonic() < deadline:  # until a signal, a kill or the release
            if _os.path.exists({hold_file!r} + ".release"):
                raise RuntimeError("released by the test")
            _time.sleep(0.02)
"""


def signalling_elastica(path: Path, *, mark=None, hold=None) -> Path:
    """Write the hand-written elastica (ELASTICA) as the module ``path``, its rhs telling the
    test where the run is; the numbers are the shipped module's to rounding.

    ``mark = (condition, file)``: the first call of rhs where ``condition`` (an expression
    in the parameters ``p``) is true, in each process, touches ``file``.
    ``hold = (condition, file)``: the first call where it is true, in whichever process of
    the run gets there first (once only, reruns included), writes that process's id to
    ``file`` and waits there: a step that does not end by itself, until a signal
    interrupts it, the process is killed, or ``file.release`` appears (the step then
    fails, which ends its branch at once)."""
    (mark_cond, mark_file), (hold_cond, hold_file) = mark or ("False", ""), hold or ("False", "")
    head = "def rhs(s, y, p):\n"
    assert ELASTICA.count(head) == 1
    path.write_text(ELASTICA.replace(head, head + "    _signal_the_test(p)\n")
                    + _SIGNALLING.format(mark=mark_cond, mark_file=str(mark_file),
                                         hold=hold_cond, hold_file=str(hold_file)))
    return path


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


def imported_by(commands, modules, then: str = "") -> list[str]:
    """Which of ``modules`` a fresh interpreter has imported once it has run the
    ``elastica-auto`` command lines ``commands`` ([(arguments, exit status)], through click's
    test runner) and then the Python code ``then``."""
    code = ("import sys\nfrom click.testing import CliRunner\nfrom elastica_auto.cli import main\n"
            f"for args, status in {[([str(a) for a in args], st) for args, st in commands]!r}:\n"
            "    r = CliRunner().invoke(main, args)\n"
            "    assert r.exit_code == status, (args, r.exit_code, r.output)\n"
            f"{then}\n"
            f"print(sorted(m for m in {list(modules)!r} if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return eval(out.stdout)


class WorkingBackground:
    """A stand-in for a default run's background cluster (`execution.cluster.Background`):
    up at once with one worker, which computes each task it is handed in a thread of its
    own and reports it as the real one does (the result and a worker's name), or, with
    ``fails``, reports each as failed (its worker died)."""

    def __init__(self, workers, on_result, fails=False):
        import threading
        self.workers, self.on_result, self.fails = 1, on_result, fails
        self.ready = threading.Event()
        self.ready.set()
        self.tasks = []

    def submit(self, tag, function, args):
        import threading

        from elastica_auto.execution.jobs import TaskFailure
        self.tasks.append(tag)

        def work():
            if self.fails:
                self.on_result(tag, False, TaskFailure("KilledWorker", "the worker died",
                                                       lost=True))
            else:
                self.on_result(tag, True, (function(*args), "stand-in"))
        threading.Thread(target=work).start()
        return True

    def finish(self):
        self.ready.clear()

    def close(self, wait=0.0):
        self.ready.clear()


def scaled_module(path: Path, scale: float, folder: Path) -> Path:
    """A module file in ``folder`` that is the module at ``path`` with its states multiplied
    by ``scale``: y = scale u, so y' = scale f(s, y / scale), its boundary conditions
    scale g(y(0) / scale, y(1) / scale), its exact start scale u0, and its ordinates and
    second variation those of u = y / scale (its exact start and guess, scaled, where it has
    them). Its solutions are the module's, scaled; a
    decision of the engine that does not depend on the units of the states (a fold, a branch
    point, a switch) is the same on both."""
    out = folder / f"{Path(path).stem}_scaled_{scale:g}.py".replace("-", "m").replace("+", "")
    out.write_text(textwrap.dedent(f'''\
        """{Path(path).name} with its states multiplied by {scale!r}."""
        import importlib.util

        from elastica_auto import Ordinate

        _spec = importlib.util.spec_from_file_location("_unscaled", {str(path)!r})
        base = importlib.util.module_from_spec(_spec)
        _spec.loader.exec_module(base)
        C = {scale!r}
        STATES, PARAMETERS = base.STATES, base.PARAMETERS


        def rhs(s, y, p):
            return C * base.rhs(s, y / C, p)


        def bc(ya, yb, p):
            return C * base.bc(ya / C, yb / C, p)


        if hasattr(base, "rhs_jac"):
            def rhs_jac(s, y, p):
                return base.rhs_jac(s, y / C, p)
        if hasattr(base, "rhs_dp"):
            def rhs_dp(s, y, p, name):
                return C * base.rhs_dp(s, y / C, p, name)
        if hasattr(base, "bc_jac"):
            def bc_jac(ya, yb, p):
                return base.bc_jac(ya / C, yb / C, p)
        if hasattr(base, "bc_dp"):
            def bc_dp(ya, yb, p, name):
                return C * base.bc_dp(ya / C, yb / C, p, name)
        if hasattr(base, "second_variation"):
            def second_variation(s, y, p):
                return base.second_variation(s, y / C, p)


        if hasattr(base, "exact_start"):
            def exact_start(s, p):
                y = base.exact_start(s, p)
                return None if y is None else C * y
        if hasattr(base, "guess"):
            def guess(s, p):
                y = base.guess(s, p)
                return None if y is None else C * y


        ORDINATES = [Ordinate(o.name, o.tex, (lambda fn: lambda s, y, p: fn(s, y / C, p))(o.fn),
                              o.parameter, o.doc) for o in base.ORDINATES]
        '''))
    return out
