"""An equation module that fails part-way through a run, through the CLI as a user meets it.

A module's ``rhs``, an ordinate or ``second_variation`` that raises, returns NaN, a list or a
wrong shape somewhere on one branch: that branch ends with an MX label, the exception's type
and message in its message and diagnostics; every other branch is computed and written; the
run exits with status 1 and no traceback, with one process (``-j 1``) or two (``-j 2``).

The modules are the shipped Bratu example (and the elastica, for ``second_variation``) with a
failure inserted; a two-branch run file continues in both directions from the trivial start,
and one direction meets the failure. Last, the snap-back scan at an exact zero of its residual.
"""

from __future__ import annotations

import json
import math
import re
import textwrap

import numpy as np
import pytest

from elastica_auto.storage.store import BranchFile
from helpers import ELASTICA as _ELASTICA
from helpers import EXAMPLES, REFERENCE, run_cli, wait_for

BRATU = (REFERENCE / "bratu.py").read_text()        # written by hand: its functions

RUN = textwrap.dedent("""\
    equation = "mine.py"
    start = "trivial"
    [parameters]
    lam = 0
    [continuation]
    parameter = "lam"
    directions = "both"
    bounds = [-1, 4]
    [options]
    ds = 0.05
    ds_max = 0.5
    max_points = 60
    """)


# the elastica written by hand (tests/reference): the functions the tests break
ELASTICA = _ELASTICA
PSI_RUN = textwrap.dedent("""\
    equation = "mine.py"
    [parameters]
    eps = 0.25
    P = "pi^2/4"
    [continuation]
    parameter = "psi"
    directions = "{directions}"
    bounds = ["-pi", "pi"]
    """)


def _module(tmp_path, source, after, body):
    """Write ``source`` as ``mine.py`` with ``body`` (one indented block) inserted after the
    line ``after``."""
    assert source.count(after) == 1, after
    (tmp_path / "mine.py").write_text(source.replace(after, after + textwrap.indent(body, "    ")))


def _run(tmp_path, cli_exe, jobs, text=RUN):
    """Run ``text`` with ``mine.py`` on ``jobs`` processes: it exits 1, no traceback."""
    toml = tmp_path / "mine.toml"
    toml.write_text(text)
    out = tmp_path / "out"
    proc = run_cli(cli_exe, "run", toml, "--out", out, "-j", jobs)
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr + proc.stdout, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["mine.h5"]   # no temporary files left
    return proc, BranchFile(out / "mine.h5")


def _check_failed(proc, bf, exception, needle):
    """Branch 1 ended MX with ``exception`` and ``needle`` in its message and diagnostics; the
    points before the failure are kept; branch 2 was computed to its bound."""
    assert len(bf.branches) == 2
    failed, other = bf.branches
    assert "failed branches (MX): 1\n" in proc.stderr
    msg = failed.attrs["message"]
    assert failed.attrs["end"] == "MX" and failed.columns["type"][-1] == "MX"
    assert f"{exception}: " in msg and needle in msg and "\n" not in msg
    assert f"MX: {msg}" in proc.stdout                      # the summary line says why
    diag = json.loads(failed.attrs["diagnostics"])
    assert diag["exception"] == exception and needle in diag["error"]
    assert diag["step"] == len(failed) and diag["where"] and diag["traceback"]
    assert len(failed) > 5
    assert other.attrs["end"] == "EP" and other.columns["lam"][-1] == pytest.approx(-1.0)
    assert other.attrs["message"] == "reached lam = -1"
    for name in bf.labels:                                   # every label is a restart point
        assert np.all(np.isfinite(bf.label(name).state.y))
    return failed


FAILURES = {
    # rhs raises above lam = 2
    "raises": ("def rhs(s, y, p):\n",
               'if p["lam"] > 2:\n    raise ValueError("no model above lam = 2")\n',
               "ValueError", "no model above lam = 2", "mine.py"),
    # rhs returns a list above lam = 2: the check of every rhs call names it
    "list": ("def rhs(s, y, p):\n",
             'if p["lam"] > 2:\n    return [y[1], -p["lam"] * np.exp(y[0])]\n',
             "ProblemError", "rhs(s, y, p) returned a list", "problem.py"),
    # rhs drops a column on meshes finer than the start's (51 nodes): near the fold
    "shape": ("def rhs(s, y, p):\n",
              'if y.shape[1] > 100:\n    return np.zeros((2, y.shape[1] - 1))\n',
              "ProblemError", "rhs(s, y, p) returned shape (2, ", "problem.py"),
    # an ordinate raises above lam = 2
    "ordinate": ("def _u_half(s, y, p):\n",
                 'if p["lam"] > 2:\n    raise ZeroDivisionError("u_half undefined")\n',
                 "ZeroDivisionError", "u_half undefined", "mine.py"),
}


@pytest.mark.parametrize("jobs", [1, 2])
@pytest.mark.parametrize("case", sorted(FAILURES))
def test_a_module_failing_mid_run_ends_that_branch_mx(tmp_path, cli_exe, case, jobs):
    after, body, exception, needle, where = FAILURES[case]
    _module(tmp_path, BRATU, after, body)
    proc, bf = _run(tmp_path, cli_exe, jobs)
    failed = _check_failed(proc, bf, exception, needle)
    assert json.loads(failed.attrs["diagnostics"])["where"].startswith(where)
    if case != "shape":  # the failure is above lam = 2: every point kept lies below
        assert np.all(failed.columns["lam"] <= 2) and failed.columns["lam"][-1] > 1


@pytest.mark.parametrize("jobs", [1, 2])
def test_non_finite_rhs_ends_the_branch_mx_with_a_clear_message(tmp_path, cli_exe, jobs):
    """NaN is no exception: Newton fails on the non-finite residual at every ds down to ds_min,
    and the message says that the module returned NaN or inf, and where."""
    _module(tmp_path, BRATU, "def rhs(s, y, p):\n",
            'if p["lam"] > 2:\n    return np.full_like(y, np.nan)\n')
    proc, bf = _run(tmp_path, cli_exe, jobs)
    failed, other = bf.branches
    assert "failed branches (MX): 1\n" in proc.stderr
    msg = failed.attrs["message"]
    assert failed.attrs["end"] == "MX" and failed.columns["type"][-1] == "MX"
    assert "non-finite residual" in msg and "the equation module returned NaN or inf" in msg
    where = re.search(r"after point \d+ \(lam = ([-+.\de]+)\)", msg)
    assert where and float(where[1]) == pytest.approx(2.0, abs=1e-3)   # just below lam = 2
    diag = json.loads(failed.attrs["diagnostics"])
    assert diag["history"] and all(math.isinf(h["residual"]) for h in diag["history"])
    assert other.attrs["end"] == "EP" and other.columns["lam"][-1] == pytest.approx(-1.0)


@pytest.mark.parametrize("jobs", [1, 2])
def test_second_variation_raising_ends_that_branch_mx(tmp_path, cli_exe, jobs):
    """The stability index calls second_variation at every point."""
    _module(tmp_path, ELASTICA, "def second_variation(s, y, p):\n",
            'if p["psi"] > 1:\n    raise FloatingPointError("no index above psi = 1")\n')
    # (computed both ways: a module that fails on one side only is no mirror image of itself)
    text = PSI_RUN.format(directions="both") + "[options]\nmirror = false\n"
    proc, bf = _run(tmp_path, cli_exe, jobs, text)
    # the + branch turns at its fold below psi = 1 and ends at -pi; the - branch turns at the
    # mirror fold and comes up through psi = 1
    other, failed = bf.branches
    assert "failed branches (MX): 2\n" in proc.stderr
    assert failed.attrs["end"] == "MX" and failed.columns["type"][-1] == "MX"
    assert "FloatingPointError: no index above psi = 1" in failed.attrs["message"]
    assert json.loads(failed.attrs["diagnostics"])["where"].startswith("mine.py")
    assert np.all(failed.columns["psi"] <= 1) and failed.columns["psi"][-1] > 0.9
    assert np.all(failed.columns["index"] >= 0)              # indices up to the failure
    assert other.attrs["end"] == "EP" and other.columns["psi"][-1] == pytest.approx(-math.pi)


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_module_failing_at_the_start_keeps_the_start_point(tmp_path, cli_exe, jobs):
    """An ordinate that fails on every mesh finer than the load-time check's (3 nodes) fails
    at the first point of every branch: each branch still holds its start, labelled MX, with
    NaN for the ordinates that could not be computed."""
    _module(tmp_path, BRATU, "def _u_half(s, y, p):\n",
            'if len(s) > 3:\n    raise IndexError("u_half on a fine mesh")\n')
    proc, bf = _run(tmp_path, cli_exe, jobs)
    assert "failed branches (MX): 1, 2\n" in proc.stderr
    assert len(bf.branches) == 2
    for b in bf.branches:
        assert b.attrs["end"] == "MX" and list(b.columns["type"]) == ["MX"]
        assert "IndexError: u_half on a fine mesh" in b.attrs["message"]
        assert "at the start (lam = 0)" in b.attrs["message"]
        assert b.columns["lam"][0] == 0.0 and math.isnan(b.columns["u_half"][0])
    np.testing.assert_array_equal(bf.label("MX1").state.y, 0.0)   # the trivial start


def test_a_worker_process_dying_costs_only_its_branches(tmp_path, cli_exe):
    """A module that ends the process (a crash in compiled code, say) takes its worker with
    it, and every worker its task is given to after that: the branch ends MX at its start,
    the other is kept, and the run still writes its file and exits 1 without a traceback."""
    _module(tmp_path, BRATU, "def rhs(s, y, p):\n",
            'if p["lam"] > 2:\n    import os\n    os._exit(3)\n')
    proc, bf = _run(tmp_path, cli_exe, 2)
    assert len(bf.branches) == 2
    failed, other = bf.branches
    assert failed.attrs["end"] == "MX" and list(failed.columns["type"]) == ["MX"]
    assert failed.attrs["message"].startswith("not computed: ")
    assert "workers died" in failed.attrs["message"] or "KilledWorker" in failed.attrs["message"]
    assert other.attrs["end"] == "EP"
    assert "failed branches (MX): 1" in proc.stderr


def test_a_branch_queued_behind_a_crashing_one_is_computed(tmp_path, cli_exe):
    """A worker holds two tasks (the one it runs and the next); one that crashes its worker
    each time takes the other with it, three times over, until Dask gives up on both
    (KilledWorker). Computed again alone, every branch but the crashing one is complete."""
    source = BRATU.replace(
        'Parameter("lam", 0.0,',
        'Parameter("c", 0.0, "c", "ode", doc="enters nothing: tells the branches apart"),\n'
        '    Parameter("lam", 0.0,')
    _module(tmp_path, source, "def rhs(s, y, p):\n",
            'if p["lam"] > 2 and p["c"] == 0:\n    import os\n    os._exit(3)\n')
    run = RUN.replace('directions = "both"', 'directions = "+"').replace(
        "lam = 0", "lam = 0\nc = [0, 1, 2, 3, 4, 5]")
    proc, bf = _run(tmp_path, cli_exe, 2, run)
    assert [b.attrs["end"] for b in bf.branches] == ["MX"] + ["EP"] * 5, proc.stderr
    assert "failed branches (MX): 1\n" in proc.stderr
    assert "KilledWorker" in bf.branches[0].attrs["message"]


# -- the module failing outside any branch: at the start, in the snap-back scan, at a switch ----

def test_a_module_failing_in_its_exact_start_is_one_line(tmp_path, cli_exe):
    _module(tmp_path, BRATU, "def exact_start(s, p):\n",
            'raise RuntimeError("no start today")\n')
    (tmp_path / "mine.toml").write_text(RUN)
    proc = run_cli(cli_exe, "run", tmp_path / "mine.toml", "--out", tmp_path / "out")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    line = (tmp_path / "mine.py").read_text().splitlines().index(
        '    raise RuntimeError("no start today")') + 1
    assert proc.stderr.strip().splitlines() == [
        f"elastica-auto: error: trivial: RuntimeError: no start today (mine.py:{line} in "
        "exact_start)"]




@pytest.mark.parametrize("jobs", ["1", "0"])
@pytest.mark.parametrize("damped", [False, True])
def test_a_module_failing_in_the_snap_scan_keeps_the_branches(tmp_path, cli_exe, damped, jobs):
    """The scan runs after the branches (the run has a fold ending a stable segment): a
    ``shooting`` hook that raises costs the snap-back targets only, and, with ``damping``,
    the damped landings; but the run says so: exit status 3 (not 0, issue 45 item 2), a
    ``missing:`` line naming each analysis, and the file's ``missing`` records, which
    ``show`` prints. In the default run (``-j 0``: two branches, so that a cluster may help)
    the command computes scans itself while it waits (`_scan_here`): no traceback there
    either."""
    _module(tmp_path, ELASTICA, "def shooting(p):\n", 'raise ValueError("no shooting")\n')
    (tmp_path / "mine.toml").write_text(PSI_RUN.format(directions="both") + (
        "landing = true\ndamping = [1.0]\n" if damped else ""))
    proc = run_cli(cli_exe, "run", tmp_path / "mine.toml", "--out", tmp_path / "out", "-j",
                   jobs)
    assert proc.returncode == 3 and "Traceback" not in proc.stderr, proc.stderr
    line = (tmp_path / "mine.py").read_text().splitlines().index(
        '    raise ValueError("no shooting")') + 1
    where = f"(mine.py:{line} in shooting)"
    missing = [ln for ln in proc.stderr.splitlines() if ln.startswith("missing: ")]
    assert missing == [f"missing: snaps: snap-back scan failed: ValueError: no shooting {where}"]\
        + ([f"missing: landings: damped landings failed: ValueError: no shooting {where}"]
           if damped else [])
    bf = BranchFile(tmp_path / "out" / "mine.h5")
    assert len(bf.branches) == 2 and all(b.attrs["end"] == "EP" for b in bf.branches)
    assert any(n.startswith("LP") for n in bf.labels) and bf.snaps == [] and bf.landings == []
    assert [(m["what"], m["kind"], m["exception"]) for m in bf.missing] == \
        [("snaps", "module", "ValueError")] + ([("landings", "module", "ValueError")]
                                               if damped else [])
    shown = run_cli(cli_exe, "show", tmp_path / "out" / "mine.h5").stdout
    assert missing[0] in [f"missing: {ln[len('missing: '):]}" for ln in shown.splitlines()]


def test_a_module_failing_at_a_stored_branch_point_is_one_line(tmp_path, cli_exe):
    """A switch from a stored BP linearises the module there before any branch: a Jacobian
    that raises is a one-line error naming the branch point."""
    (tmp_path / "mine.py").write_text(ELASTICA)
    run = textwrap.dedent("""\
        equation = "mine.py"
        [parameters]
        eps = 0.25
        P = 0
        [continuation]
        parameter = "P"
        directions = "+"
        bounds = [-1, 2]
        """)
    (tmp_path / "first.toml").write_text(run)
    out = tmp_path / "out"
    assert run_cli(cli_exe, "run", tmp_path / "first.toml", "--out", out).returncode == 0
    _module(tmp_path, ELASTICA, "def rhs_jac(s, y, p):\n",
            'if p["P"] < 2:  # not at the default P = pi^2/4 of the load-time check\n'
            '    raise ArithmeticError("no Jacobian today")\n')
    (tmp_path / "second.toml").write_text('equation = "mine.py"\nswitch = ["first.h5:BP1"]\n'
                                          '[continuation]\nparameter = "P"\n')
    proc = run_cli(cli_exe, "run", tmp_path / "second.toml", "--out", out)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    line = next(i for i, text in enumerate((tmp_path / "mine.py").read_text().splitlines(), 1)
                if 'raise ArithmeticError("no Jacobian today")' in text)
    assert proc.stderr.strip().splitlines() == [
        "elastica-auto: error: switch at first.h5:BP1: ArithmeticError: no Jacobian today "
        f"(mine.py:{line} in rhs_jac)"]


# -- the snap-back scan meets an exact zero of the shooting residual ------------------------------

def test_the_snap_scan_survives_an_exact_zero_of_the_residual():
    """At these parameters (next to the rotating arm's fold at eps = 0.364, P = 9 pi^2/4, psi =
    -5.0239) regula falsi lands on a k where the residual is exactly 0.0 while other brackets
    are still refined: iterating that bracket again gave 0 / 0, a NaN root, and solve_ivp's
    "initial state must be finite" ended the run after its last branch. Whether a float sum is
    exactly 0.0 depends on the floating point of the machine; the next test makes the same
    degenerate case by construction."""
    import shooting
    from elastica_auto.model.problem import load_problem
    from elastica_auto.analysis.equilibria import enumerate_equilibria

    P, eps, psi = 9 * math.pi ** 2 / 4, 0.364, -5.02385641025641
    elastica = load_problem("elastica_lever_arm")
    eqs = enumerate_equilibria(elastica, {**elastica.defaults(), "P": P, "eps": eps, "psi": psi})
    assert len(eqs) >= 5
    for e in eqs:
        assert math.isfinite(e.k) and e.index >= 0
        assert abs(shooting.residual(e.k, psi, P, eps)[0]) < 1e-8 * (1 + abs(eps * P))


def test_regula_falsi_stops_at_an_exact_zero():
    """The bracket [0, 1] of k - 1/2 is solved exactly by the first regula falsi step (0.5 and
    its residual 0.0 are exact); the bracket [2, 3] of (k - 2.2)^3 needs many more, during
    which the first must not be iterated into 0 / 0."""
    from elastica_auto.analysis.equilibria import refine_brackets

    calls = []

    def r(k):
        calls.append(len(k))
        return np.where(k < 1.5, k - 0.5, (k - 2.2) ** 3)

    a, b = np.array([0.0, 2.0]), np.array([1.0, 3.0])
    with np.errstate(divide="raise", invalid="raise"):
        roots = refine_brackets(r, a, b, r(a), r(b))
    assert roots[0] == 0.5
    assert roots[1] == pytest.approx(2.2, abs=1e-4)   # a triple root: |k - 2.2| ~ |r|^(1/3)
    assert calls[:3] == [2, 2, 2] and set(calls[3:]) == {1}   # the solved one is done after one
    # a bracket whose end is exactly a root, and a bracket already short enough: returned as is
    a, b = np.array([0.0, 2.2]), np.array([0.5, 2.2 + 1e-15])
    with np.errstate(divide="raise", invalid="raise"):
        roots = refine_brackets(lambda k: k - 0.5, a, b, a - 0.5, np.array([0.0, 1.7]))
    np.testing.assert_array_equal(roots, b)


# -- a command killed outright leaves no worker behind ---------------------------------------

def test_workers_end_when_the_command_is_killed(tmp_path, cli_exe):
    """SIGKILL cannot be caught: the local cluster's workers notice that the command is gone
    and end, with their nannies, within seconds, instead of computing for nobody. Every
    process the command started carries the marker in its environment."""
    import os
    import signal
    import subprocess
    import uuid
    marker = f"ELASTICA_TEST_{uuid.uuid4().hex}"
    proc = subprocess.Popen([cli_exe, "run", "rotating_arm", "--out", tmp_path / "out",
                             "-j", "2"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env={**os.environ, marker: "1"})

    def started():
        pids = []
        for entry in os.listdir("/proc"):
            try:
                with open(f"/proc/{entry}/environ", "rb") as fh:
                    if marker.encode() + b"=1" in fh.read().split(b"\0"):
                        pids.append(int(entry))
            except (OSError, ValueError):
                continue
        return pids

    wait_for("the command and its 2 workers", lambda: len(started()) >= 3, proc)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    try:     # "within seconds" is the deadline
        wait_for("the workers to end after the command was killed", lambda: not started(),
                 seconds=10)
    except AssertionError as exc:
        raise AssertionError(f"{exc}; still running: {started()}") from None


def _gone(pid: int) -> bool:
    """Whether process ``pid`` has ended (a zombie, not reaped yet, has). A process reaped
    between the open and the read of its stat file makes the read fail with ESRCH
    (ProcessLookupError): ended too."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rpartition(")")[2].split()[0] in ("Z", "X")
    except (FileNotFoundError, ProcessLookupError):
        return True


def test_a_second_ctrl_c_does_not_wait_for_a_slow_step(tmp_path, cli_exe):
    """In a module whose step takes a minute, Ctrl-C cancels the branches and ends the
    workers at once; a second Ctrl-C while the command ends changes nothing. The run exits
    130 in seconds and says truthfully what it saved.

    The first Ctrl-C comes once the first branch (lam up to its fold) is saved and the
    second (down to lam = -1) is in its slow step, whose worker's process id the module
    writes as the step begins; the second Ctrl-C once that worker has been ended (the
    command closes its cluster then) or the command has ended."""
    import signal
    import subprocess
    import time
    slow, out = tmp_path / "slow", tmp_path / "out"
    _module(tmp_path, BRATU, "def rhs(s, y, p):\n",
            f'if p["lam"] < -0.5:\n    import os, pathlib, time\n'
            f'    pathlib.Path({str(slow)!r} + ".tmp").write_text(str(os.getpid()))\n'
            f'    os.replace({str(slow)!r} + ".tmp", {str(slow)!r})\n'
            '    time.sleep(60)\n')
    toml = tmp_path / "mine.toml"
    toml.write_text(RUN)
    proc = subprocess.Popen([cli_exe, "run", toml, "--out", out, "-j", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for("the first branch saved, the second in its slow step",
             lambda: slow.exists() and (out / "mine.h5").exists(), proc)
    worker = int(slow.read_text())
    t0 = time.monotonic()
    proc.send_signal(signal.SIGINT)
    wait_for("the slow step's worker to end after a Ctrl-C",
             lambda: _gone(worker) or proc.poll() is not None)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert time.monotonic() - t0 < 10
    assert proc.returncode == 130 and "Traceback" not in err, err
    saved = BranchFile(out / "mine.h5")
    assert f"interrupted: {len(saved.branches)} branches saved to" in err
    # the branch saved before the signal; the one in its slow step is cancelled
    assert [b.attrs["end"] for b in saved.branches] == ["EP"]


def test_a_singular_start_says_so_and_not_that_the_module_returned_nan(tmp_path, cli_exe):
    """The foundation column without its end conditions w(0) = w(1) = 0, at k = 0: nothing
    holds w, and w = const, phi = 0 solves the linearised equations (checked here on the
    module's own rhs and bc: both vanish there), a null direction at the straight start that
    the load P does not fix (the equations are linear in P w'). The branch ends MX at its
    start, exit status 1, its message saying the linearised problem is singular and to check
    the end conditions, not that the module returned NaN (its rhs and bc are finite): the
    bordered Jacobian along the start's tangent has a kernel (its residual at rounding). With
    k = 400 the foundation holds w and the same module starts: its branch has steps."""
    from elastica_auto.model.problem import load_problem
    source = (EXAMPLES / "foundation_column.py").read_text()
    held = "                  fixed0={w: 0}, fixed1={w: 0},\n"
    assert held in source
    (tmp_path / "free_ends.py").write_text(source.replace(held, ""))
    problem = load_problem(str(tmp_path / "free_ends.py"))
    s = np.linspace(0.0, 1.0, 11)
    params = {"P": 0.0, "k": 0.0, "G": 100.0}
    const = np.zeros((problem.n, len(s)))
    const[0] = 1.0       # w = 1 (its momenta Q, M and phi zero): a solution beside w = 0
    assert np.all(np.asarray(problem.rhs(s, const, params)) == 0.0)
    assert np.all(np.asarray(problem.bc(const[:, 0], const[:, -1], params)) == 0.0)
    (tmp_path / "run.toml").write_text(
        'equation = "free_ends.py"\nstart = "trivial"\n[parameters]\nk = 0\n'
        '[continuation]\nparameter = "P"\ndirections = "+"\nbounds = [-1, 60]\n')
    proc = run_cli(cli_exe, "run", tmp_path / "run.toml", "--out", tmp_path / "o")
    assert proc.returncode == 1, proc.stderr
    assert "failed branches (MX): 1" in proc.stderr
    (br,) = BranchFile(tmp_path / "o" / "run.h5").branches
    msg = br.attrs["message"]
    assert br.attrs["end"] == "MX" and len(br.columns["type"]) == 1
    assert "linearised problem is singular" in msg and "end conditions" in msg
    assert "NaN" not in msg and "non-finite" not in msg
    proc = run_cli(cli_exe, "run", tmp_path / "run.toml", "--out", tmp_path / "o400",
                   "--set", "k=400")
    (br,) = BranchFile(tmp_path / "o400" / "run.h5").branches
    assert "singular" not in br.attrs["message"] and len(br.columns["type"]) > 3
    # Newton at w = 1 itself, a solution (its residuals exactly zero) on the same singular
    # Jacobian: the correction is zero, and the solution stays as it is. (With scipy's LAPACK
    # a pivot here was exactly zero and the correction 0/0; whether it is zero or of the size
    # of rounding is the elimination's rounding: the start above is refused by the kernel's
    # test, not by that NaN.)
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.core.solution import State
    from elastica_auto.numerics.correctors import make_corrector
    corr = make_corrector(problem, "P", ContinuationOptions())
    again = corr.solve_again(State.from_values(problem, s, const, params), None, 1e-10)
    assert again.converged and np.array_equal(again.Y, const), again.message
