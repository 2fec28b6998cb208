"""What a run's exit status and file say when something fails (issue 45 item 2, the hostile
test's H3, H4 and L11).

- Who failed is told apart (`failure_kind`): the equation module (its line on the traceback,
  a ProblemError, sys.exit), a numerical failure, or the engine itself, whose exception is
  an internal error: exit status 4 with its traceback kept in the file (``--debug`` raises
  it), never passed off as a hard problem (MX, status 1).
- A module that calls ``sys.exit()`` in a branch fails that branch (MX, status 1): not the
  command with status 0 and a file missing branches.
- ``--resume`` continues the same run only: a run file changed in anything but its cells is
  refused in one line; the branch lines of a resumed run carry their numbers in the file.
- The exit statuses of docs/cli.md are those of the code.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from elastica_auto.cli import main
from elastica_auto.core import errors
from elastica_auto.core.errors import (ENGINE, MODULE, NUMERICAL, NumericalFailure,
                                       ProblemError, failure_kind, failure_record)
from elastica_auto.numerics.correctors import CorrectorFailure
from elastica_auto.storage.store import BranchFile
from helpers import elastica_run_file, run_cli
from test_robustness import SMALL

DOCS = Path(__file__).resolve().parent.parent / "docs"

BASE = textwrap.dedent("""\
    import sys
    import numpy as np
    from elastica_auto import Ordinate, Parameter
    STATES = ("u", "v")
    PARAMETERS = [Parameter("lam", 0.0, "lam", "ode"), Parameter("q", 1.0, "q", "ode")]
    def rhs(s, y, p):
        {first}
        return np.vstack((y[1], -p["lam"] * p["q"] * np.exp(y[0])))
    def bc(ya, yb, p):
        return np.array((ya[0], yb[0]))
    def exact_start(s, p):
        return np.zeros((2, len(s))) if p["lam"] == 0 else None
    ORDINATES = [Ordinate("du0", "du0", lambda s, y, p: y[1, 0], "lam")]
    """)

RUN = textwrap.dedent("""\
    equation = "mine.py"
    [parameters]
    q = [1, 2]
    [continuation]
    parameter = "lam"
    directions = "+"
    bounds = [-1, 3]
    [options]
    max_points = 40
    """)


# -- who failed ---------------------------------------------------------------------------------

def _raised(fn):
    try:
        fn()
    except BaseException as exc:     # noqa: BLE001 - the test wants whatever it raises
        return exc
    raise AssertionError("did not raise")


def test_failure_kind_tells_the_module_numerics_and_engine_apart(tmp_path):
    """A frame of the module's file on the traceback makes it the module's, whatever raised
    it (here numpy, called by the module); ProblemError and sys.exit are the module's too;
    a corrector's failure and LAPACK's are numerical; anything else raised by the engine's
    own code is an internal error."""
    path = tmp_path / "mod.py"
    path.write_text("import numpy as np\ndef hook(x):\n    return np.linalg.inv(x)\n")
    namespace = {}
    exec(compile(path.read_text(), str(path), "exec"), namespace)
    singular = _raised(lambda: namespace["hook"](np.zeros((2, 2))))
    assert type(singular).__name__ == "LinAlgError"
    assert failure_kind(singular, str(path)) == MODULE
    assert failure_kind(singular, None) == NUMERICAL   # no module frame: LAPACK's failure
    assert failure_kind(_raised(lambda: np.linalg.inv(np.zeros((2, 2)))), str(path)) \
        == NUMERICAL
    assert failure_kind(ProblemError("rhs returned a list"), str(path)) == MODULE
    assert failure_kind(_raised(lambda: sys.exit(3)), str(path)) == MODULE
    assert failure_kind(CorrectorFailure("no convergence"), None) == NUMERICAL
    assert issubclass(CorrectorFailure, NumericalFailure)
    assert failure_kind(_raised(lambda: {}["x"]), str(path)) == ENGINE
    assert failure_kind(_raised(lambda: 1 / 0), None) == ENGINE


def test_failure_record_names_the_hook_the_engine_called(tmp_path):
    """A KeyError raised in a helper of ``rhs`` names the helper's line and the hook, rhs
    (issue 45 item 8: which hook raised); an internal error keeps its whole traceback."""
    path = tmp_path / "mod.py"
    path.write_text("def helper(p):\n    return p['missing']\n"
                    "def rhs(s, y, p):\n    return helper(p)\n")
    namespace = {}
    exec(compile(path.read_text(), str(path), "exec"), namespace)
    record = failure_record(_raised(lambda: namespace["rhs"](0, 0, {})), str(path))
    assert record["kind"] == MODULE and record["exception"] == "KeyError"
    assert record["where"] == "mod.py:2 in helper, called from rhs"
    assert "text" not in record
    engine = failure_record(_raised(lambda: [][1]), str(path))
    assert engine["kind"] == ENGINE and "IndexError" in engine["text"]
    assert engine["text"].startswith("Traceback (most recent call last)")


# -- a module exiting inside a run (hostile H3) -------------------------------------------------

@pytest.mark.parametrize("jobs", ["1", "0"])
def test_a_module_calling_sys_exit_fails_its_branch_not_the_command(tmp_path, cli_exe, jobs):
    """``sys.exit()`` in ``rhs`` once lam passes 1 on the q = 2 branch: that branch ends MX
    saying so, the other is computed whole, the summary is printed and the status is 1
    (before: status 0 and a file without the branch with ``-j 1``; an UnboundLocalError
    masking it by default)."""
    (tmp_path / "mine.py").write_text(BASE.format(
        first='if p["q"] > 1.5 and p["lam"] > 1: sys.exit()'))
    (tmp_path / "mine.toml").write_text(RUN)
    out = tmp_path / "out"
    proc = run_cli(cli_exe, "run", tmp_path / "mine.toml", "--out", out, "-j", jobs)
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr + proc.stdout
    assert "failed branches (MX): 2" in proc.stderr
    assert re.search(r"^mine: 2 branches, \d+ points", proc.stdout, re.M), proc.stdout
    bf = BranchFile(out / "mine.h5")
    first, second = bf.branches
    assert first.attrs["end"] == "EP" and second.attrs["end"] == "MX"
    assert "the equation module called sys.exit(None) (mine.py:7 in rhs)" \
        in second.attrs["message"]
    assert json.loads(second.attrs["diagnostics"])["kind"] == MODULE
    assert float(second.columns["lam"][-1]) <= 1.0
    assert sorted(p.name for p in out.iterdir()) == ["mine.h5"]


def test_an_energy_modules_derived_code_failing_is_the_modules_failure(tmp_path, cli_exe):
    """An energy module whose density divides by a parameter, run with that parameter 0:
    the generated code (a file of the cache, not the module's) raises ZeroDivisionError.
    That is the module's failure (its branch MX, status 1, the derived code's line named),
    not an internal error (status 4 and "a bug: please report"), which it was."""
    (tmp_path / "stiff.py").write_text(textwrap.dedent("""
        def ENERGY():
            import sympy as sp
            from elastica_auto.energy import Energy
            s, q, k = sp.symbols("s q k", real=True)
            theta = sp.Function("theta")(s)
            return Energy(density=theta.diff(s)**2 / (2 * k) + q * sp.cos(theta),
                          s=s, coordinates=[theta], parameters={q: 0.0, k: 1.0},
                          fixed0={theta: 0})

        def exact_start(s, p):
            import numpy as np
            return np.zeros((2, len(s)))
        """))
    (tmp_path / "stiff.toml").write_text(textwrap.dedent("""
        equation = "stiff.py"
        [parameters]
        q = 0.0
        k = 0.0
        [continuation]
        parameter = "q"
        bounds = [-1, 1]
        """))
    out = tmp_path / "out"
    proc = run_cli(cli_exe, "run", tmp_path / "stiff.toml", "--out", out, "-j", "1")
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    assert "internal error" not in proc.stdout + proc.stderr
    diagnostics = json.loads(BranchFile(out / "stiff.h5").branches[0].attrs["diagnostics"])
    assert diagnostics["kind"] == MODULE and diagnostics["exception"] == "ZeroDivisionError"
    assert re.fullmatch(r"energy-[0-9a-f]+\.py:\d+ in \w+.*", diagnostics["where"])


# -- an internal error (issue 45 item 2) --------------------------------------------------------

def _engine_bug(monkeypatch, after: int):
    """Make the stepper's secant (engine code, called once per step) raise a TypeError from
    its ``after``-th call on: an internal error, as a bug would raise it."""
    import elastica_auto.branches.stepper as stepper
    real, calls = stepper.secant, [0]

    def secant(*args):
        calls[0] += 1
        if calls[0] >= after:
            raise TypeError("unsupported operand type(s) for +: 'float' and 'NoneType'")
        return real(*args)

    monkeypatch.setattr(stepper, "secant", secant)


def test_an_engine_error_is_an_internal_error_with_its_traceback_kept(tmp_path, monkeypatch):
    """An exception raised by the engine's own code in a branch: the branch ends MX with
    "internal error:" in its message, the command exits 4 (not 1, a hard problem), the
    file's diagnostics keep the whole traceback and ``show --tracebacks`` prints it; with
    ``--debug`` the command raises it instead."""
    monkeypatch.setenv(errors.DEBUG_ENV, "0")          # restored after the --debug run
    _engine_bug(monkeypatch, after=5)
    toml = elastica_run_file(tmp_path / "small.toml", directions="+")
    runner = CliRunner()
    result = runner.invoke(main, ["run", str(toml), "--out", str(tmp_path), "-j", "1", "-q"])
    assert result.exit_code == 4, result.output
    assert "internal errors (a bug" in result.output and "branch 1" in result.output
    bf = BranchFile(tmp_path / "small.h5")
    (br,) = bf.branches
    assert br.attrs["end"] == "MX"
    assert br.attrs["message"].startswith("internal error: TypeError: unsupported operand")
    diagnostics = json.loads(br.attrs["diagnostics"])
    assert diagnostics["kind"] == ENGINE
    assert "in secant" in diagnostics["text"] and diagnostics["text"].startswith("Traceback")
    shown = runner.invoke(main, ["show", "--tracebacks", str(tmp_path / "small.h5")])
    assert shown.exit_code == 0 and "traceback of the internal error in branch 1" in shown.output
    assert "raise TypeError" in shown.output
    debug = runner.invoke(main, ["--debug", "run", str(toml), "--out", str(tmp_path / "d"),
                                 "-j", "1", "-q"])
    assert isinstance(debug.exception, TypeError), debug.output


def test_an_engine_error_outside_a_branch_says_so_and_keeps_the_branches(tmp_path,
                                                                          monkeypatch):
    """An internal error that escapes the branches (here the snap-back scan's engine code):
    recorded in the file's ``missing`` with its traceback, the branches all there, status
    4."""
    import elastica_auto.execution.run as run
    monkeypatch.setenv(errors.DEBUG_ENV, "0")

    def broken(*args, **kwargs):
        raise AttributeError("'NoneType' object has no attribute 'params'")

    monkeypatch.setattr(run, "snap_targets", broken)
    toml = elastica_run_file(tmp_path / "small.toml", directions="+")
    result = CliRunner().invoke(main, ["run", str(toml), "--out", str(tmp_path), "-j", "1",
                                       "-q"])
    assert result.exit_code == 4, result.output
    bf = BranchFile(tmp_path / "small.h5")
    assert len(bf.branches) == 1 and bf.branches[0].attrs["end"] == "EP"
    (m,) = bf.missing
    assert m["what"] == "snaps" and m["kind"] == ENGINE and "AttributeError" in m["text"]
    assert m["message"].startswith("snap-back scan failed: internal error: AttributeError")


# -- --resume continues the same run only (hostile H4, L11) --------------------------------------

@pytest.fixture(scope="module")
def small_run(tmp_path_factory, cli_exe):
    d = tmp_path_factory.mktemp("resume")
    (d / "small.toml").write_text(SMALL)
    assert run_cli(cli_exe, "run", d / "small.toml", "--out", d / "out", "-j", "1",
                   "-q").returncode == 0
    return d


@pytest.mark.parametrize("sets, named", [
    (["continuation.parameter=P", "bounds=[0, 30]"], "the continued parameter"),
    (["eps=[0.25, 0.5]", 'bounds=["-2*pi", "2*pi"]'], "bounds"),
    (["ds_max=0.1"], "options.ds_max"),
    (['uz=["pi/4"]'], "uz"),
])
def test_resume_refuses_a_changed_run(small_run, tmp_path, cli_exe, sets, named):
    """A run file changed in anything but its cells (the parameter continued, bounds, an
    option, the UZ values) is refused in one line naming what changed (before: "nothing to
    compute", or stale branches beside new ones under the new run file's name)."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "small.h5").write_bytes((small_run / "out" / "small.h5").read_bytes())
    before = (out / "small.h5").read_bytes()
    proc = run_cli(cli_exe, "run", small_run / "small.toml", "--out", out, "-j", "1", "-q",
                   "--resume", *[a for s in sets for a in ("--set", s)])
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith("elastica-auto: error: ") and "--resume continues the same run" \
        in line and named in line, line
    assert (out / "small.h5").read_bytes() == before


def test_resume_with_new_cells_numbers_its_branches_as_in_the_file(small_run, tmp_path,
                                                                   cli_exe):
    """A grid grown by one value is resumed: the kept branches stay, the new ones are
    computed and their lines carry their numbers in the file ("branch 3/4", not "1/4")."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "small.h5").write_bytes((small_run / "out" / "small.h5").read_bytes())
    proc = run_cli(cli_exe, "run", small_run / "small.toml", "--out", out, "-j", "1", "-q",
                   "--resume", "--set", "eps=[0.25, 0.5]")
    assert proc.returncode == 0, proc.stderr
    numbers = re.findall(r"^branch (\d+)/(\d+) eps=([\d.]+)", proc.stdout, re.M)
    assert numbers == [("3", "4", "0.5"), ("4", "4", "0.5")], proc.stdout
    bf = BranchFile(out / "small.h5")
    assert [float(b.columns["eps"][0]) for b in bf.branches] == [0.25, 0.25, 0.5, 0.5]


def test_resume_of_a_file_without_settings_needs_the_same_run_file(small_run, tmp_path,
                                                                   cli_exe):
    """A file written before the settings were stored (0.1) can be resumed only by the
    same run file text: anything else cannot be checked, and is refused."""
    import h5py
    out = tmp_path / "out"
    out.mkdir()
    (out / "small.h5").write_bytes((small_run / "out" / "small.h5").read_bytes())
    with h5py.File(out / "small.h5", "r+") as f:
        del f.attrs["settings"]
    same = run_cli(cli_exe, "run", small_run / "small.toml", "--out", out, "-j", "1", "-q",
                   "--resume")
    assert same.returncode == 0 and "nothing to compute" in same.stdout, same.stderr
    other = run_cli(cli_exe, "run", small_run / "small.toml", "--out", out, "-j", "1", "-q",
                    "--resume", "--set", "ds_max=0.1")
    assert other.returncode == 2 and "its run file's text" in other.stderr, other.stderr


def _settings_ncol_0(path):
    """``path``'s stored settings as a file written when ``ncol`` defaulted to 0 has them."""
    import h5py
    with h5py.File(path, "r+") as f:
        settings = json.loads(f.attrs["settings"])
        assert settings["options"]["ncol"] == "auto"
        settings["options"]["ncol"] = 0
        f.attrs["settings"] = json.dumps(settings, sort_keys=True)


def test_resume_of_a_file_written_when_the_cubic_scheme_was_the_default(small_run, tmp_path,
                                                                         cli_exe):
    """A file of the same run written before ``ncol = "auto"`` became the default (its
    settings hold 0) resumes under the default where "auto" is the cubic scheme by rule (a
    problem with an index count: the elastica); where "auto" could turn to Gauss (Bratu with
    a prescribed mean, no index count) the refusal says what to add, and that resumes."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "small.h5").write_bytes((small_run / "out" / "small.h5").read_bytes())
    _settings_ncol_0(out / "small.h5")
    same = run_cli(cli_exe, "run", small_run / "small.toml", "--out", out, "-j", "1", "-q",
                   "--resume")
    assert same.returncode == 0 and "nothing to compute" in same.stdout, same.stderr

    module = Path(__file__).resolve().parents[1] / "examples" / "bratu_level.py"
    (tmp_path / "level.toml").write_text(
        f'description = "no index count"\nequation = "{module}"\nstart = "trivial"\n'
        '[continuation]\nparameter = "lam"\ndirections = "+"\nbounds = [0, 3]\n')
    run = ("run", tmp_path / "level.toml", "--out", out, "-j", "1", "-q")
    assert run_cli(cli_exe, *run).returncode == 0
    _settings_ncol_0(out / "level.h5")
    refused = run_cli(cli_exe, *run, "--resume")
    assert refused.returncode == 2 and "options.ncol" in refused.stderr \
        and "--set ncol=0" in refused.stderr, refused.stderr
    resumed = run_cli(cli_exe, *run, "--resume", "--set", "ncol=0")
    assert resumed.returncode == 0 and "nothing to compute" in resumed.stdout, resumed.stderr


# -- figures refuse an incomplete file ----------------------------------------------------------

def test_paper_figures_refuse_a_file_whose_analysis_failed(small_run, tmp_path):
    """``python -m elastica_auto.plots`` (what ``make figures`` runs) refuses a branch file
    whose run recorded something missing, rather than drawing the figure without it."""
    import h5py
    data = tmp_path / "out"
    data.mkdir()
    target = data / "rotating_arm.h5"
    target.write_bytes((small_run / "out" / "small.h5").read_bytes())
    with h5py.File(target, "r+") as f:
        f.attrs["missing"] = json.dumps([{"what": "snaps", "kind": "module",
                                          "message": "snap-back scan failed: ValueError: x"}])
    proc = subprocess.run([sys.executable, "-m", "elastica_auto.plots", "rotating-arm-long",
                           "--data", str(data), "--out", str(tmp_path / "fig")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "incomplete: its run could not make snaps" in proc.stderr
    assert not (tmp_path / "fig").exists() or not any((tmp_path / "fig").iterdir())


# -- the table in the docs ------------------------------------------------------------------------

def test_the_exit_status_table_of_the_docs_is_the_codes():
    """docs/cli.md's exit-status table lists each status of `EXIT_STATUSES`, no other."""
    text = (DOCS / "cli.md").read_text()
    section = text[text.index("## Exit status"):]
    section = section[:section.index("\n## ", 1) if "\n## " in section[1:] else len(section)]
    rows = re.findall(r"^\| `?(\d+)`? \|", section, re.M)
    assert sorted(map(int, rows)) == sorted(errors.EXIT_STATUSES)


def test_a_module_raising_at_load_names_the_hook(tmp_path):
    """The load-time check calls each hook once: a KeyError from a misspelt parameter in an
    ordinate names that ordinate and the module's line (issue 45 item 8: before, "calling
    the module failed: KeyError: 'qq'" named neither)."""
    from elastica_auto.model.problem import load_problem
    source = BASE.format(first="pass").replace(
        'lambda s, y, p: y[1, 0]', 'lambda s, y, p: y[1, 0] * p["qq"]')
    (tmp_path / "mine.py").write_text(source)
    with pytest.raises(ProblemError) as err:
        load_problem(tmp_path / "mine.py")
    line = source.splitlines().index(next(x for x in source.splitlines() if '"qq"' in x)) + 1
    assert str(err.value).endswith(f"calling ordinate 'du0' on a test state (the defaults, "
                                   f"y = 0.1) failed: KeyError: 'qq' (mine.py:{line} in "
                                   "<lambda>)")


def test_the_api_lists_what_is_missing_and_save_keeps_it(tmp_path):
    """From Python: a shooting hook that raises leaves ``branches.missing`` saying so (not
    only a warning), and ``ea.save`` writes it to the file."""
    import importlib.resources
    import math

    import elastica_auto as ea
    from elastica_auto.model.problem import load_problem
    source = (importlib.resources.files("elastica_auto.equations")
              / "elastica_lever_arm.py").read_text()
    assert source.count("def shooting(p):\n") == 1
    (tmp_path / "mine.py").write_text(source.replace(
        "def shooting(p):\n", 'def shooting(p):\n    raise ValueError("no shooting")\n'))
    problem = load_problem(tmp_path / "mine.py")
    branches = ea.continuation(problem, {"eps": 0.25, "P": math.pi ** 2 / 4}, "psi",
                               bounds=(-math.pi, math.pi))
    assert [(m["what"], m["kind"], m["error"]) for m in branches.missing] == [
        ("snaps", MODULE, "no shooting")]
    bf = BranchFile(ea.save(branches, tmp_path / "mine.h5"))
    assert [m["what"] for m in bf.missing] == ["snaps"]


def test_an_exception_escaping_any_command_is_an_internal_error(small_run, monkeypatch):
    """Whatever command an engine exception escapes (here ``show``'s table), it is reported
    as an internal error with its traceback and status 4, not Python's report with the
    status 1 of a failed branch."""
    import elastica_auto.storage.store as store
    monkeypatch.setenv(errors.DEBUG_ENV, "0")

    def rows(*args, **kwargs):
        raise KeyError("index")

    monkeypatch.setattr(store, "rows", rows)
    result = CliRunner().invoke(main, ["show", str(small_run / "out" / "small.h5")])
    assert result.exit_code == 4, result.output
    assert "elastica-auto: internal error in show: KeyError: 'index'" in result.output
    assert "Traceback (most recent call last)" in result.output


def test_a_module_failing_on_a_path_is_one_line(tmp_path, cli_exe):
    """``path`` with a module whose shooting hook exits: one line naming it, status 2."""
    import importlib.resources
    source = (importlib.resources.files("elastica_auto.equations")
              / "elastica_lever_arm.py").read_text()
    (tmp_path / "mine.py").write_text(source.replace(
        "def shooting(p):\n", "def shooting(p):\n    raise SystemExit(0)\n"))
    proc = run_cli(cli_exe, "path", tmp_path / "mine.py", "--at", "eps=0.25",
                   "--at", "P=pi^2/4", "--to", "psi=3")
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    (line,) = proc.stderr.strip().splitlines()
    assert "the path failed: SystemExit: the equation module called sys.exit(0)" in line
