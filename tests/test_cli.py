"""The console script elastica-auto: run, show, export and its user-error handling."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from helpers import elastica_run_file, run_cli
from elastica_auto.storage.store import BranchFile

PARAMS = ["P", "eps", "psi", "alpha", "theta0"]
ORDS = ["gamma", "beta", "m1", "mA", "m0", "E"]     # derived: the parameters' order, then E
HEADER = ["branch", "pt", "type", "label", *PARAMS, *ORDS, "index", "index_rule", "index_direct"]


def test_run_writes_a_branch_file(small_cli_run):
    out, h5, proc = small_cli_run
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    bf = BranchFile(h5)
    assert len(bf.branches) == 2
    assert {int(b.attrs["direction"]) for b in bf.branches} == {1, -1}
    for b in bf.branches:
        psi = b.columns["psi"]
        assert psi[0] == 0.0 and b.attrs["end"] == "EP"
        assert abs(abs(psi[-1]) - 2 * math.pi) < 1e-12      # ends at a bound +-2 pi
    assert any(n.startswith("LP") for n in bf.labels)
    assert any(n.startswith("UZ") for n in bf.labels)


def test_show_lists_every_label(small_cli_run, cli_exe):
    _, h5, _ = small_cli_run
    proc = run_cli(cli_exe, "show", h5)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    head = lines[0].split()
    assert head[:4] == ["BR", "PT", "TY", "LAB"]
    assert head[4:15] == PARAMS + ORDS
    shown = [ln.split()[3] for ln in lines[1:]
             if len(ln.split()) > 3 and ln.split()[2] in ("EP", "LP", "UZ", "MX", "BP")]
    bf = BranchFile(h5)
    assert sorted(shown) == sorted(bf.labels)
    # each row names the label's branch and point, as recorded in the file
    for ln in lines[1:]:
        f = ln.split()
        if len(f) > 3 and f[3] in bf.labels:
            assert (int(f[0]), int(f[1])) == tuple(bf.labels[f[3]])


def test_export_has_the_documented_header_and_one_row_per_point(small_cli_run, cli_exe, tmp_path):
    _, h5, _ = small_cli_run
    out = tmp_path / "small.csv"
    proc = run_cli(cli_exe, "export", h5, "-o", out)
    assert proc.returncode == 0, proc.stderr
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == HEADER
    bf = BranchFile(h5)
    body = rows[1:]
    assert len(body) == sum(len(b) for b in bf.branches)
    expected_keys = [(b.number, i + 1) for b in bf.branches for i in range(len(b))]
    assert [(int(r[0]), int(r[1])) for r in body] == expected_keys
    # the values survive the round trip (17 significant digits)
    for b in bf.branches:
        rs = [r for r in body if int(r[0]) == b.number]
        for j, name in enumerate(PARAMS + ORDS, start=4):
            np.testing.assert_array_equal([float(r[j]) for r in rs], b.columns[name])
        assert [r[2] for r in rs] == list(b.columns["type"])
        assert [r[3] for r in rs] == b.label_names()
    for r in body:   # index columns: an integer, or empty where unknown
        assert all(v == "" or v.lstrip("-").isdigit() for v in r[-3:])


def _assert_one_line_user_error(proc, *needles):
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])


def test_run_file_with_an_unknown_key_is_a_user_error(cli_exe, tmp_path):
    path = tmp_path / "bad_key.toml"
    path.write_text('equation = "elastica_lever_arm"\ncolour = "red"\n'
                    '[continuation]\nparameter = "psi"\n')
    _assert_one_line_user_error(run_cli(cli_exe, "run", path, "--out", tmp_path / "o"),
                                "bad_key.toml", "colour")
    assert not (tmp_path / "o" / "bad_key.h5").exists()


def test_run_file_with_an_unknown_option_is_a_user_error(cli_exe, tmp_path):
    path = tmp_path / "bad_option.toml"
    path.write_text('equation = "elastica_lever_arm"\n[continuation]\nparameter = "psi"\n'
                    '[options]\nstep = 0.1\n')
    _assert_one_line_user_error(run_cli(cli_exe, "run", path, "--out", tmp_path / "o"),
                                "bad_option.toml", "step")


def test_run_file_with_a_bad_parameter_name_is_a_user_error(cli_exe, tmp_path):
    path = tmp_path / "bad_param.toml"
    path.write_text('equation = "elastica_lever_arm"\n[parameters]\nlength = 2\n'
                    '[continuation]\nparameter = "psi"\n')
    _assert_one_line_user_error(run_cli(cli_exe, "run", path, "--out", tmp_path / "o"),
                                "bad_param.toml", "length")
    path = tmp_path / "bad_cont.toml"
    path.write_text('equation = "elastica_lever_arm"\n[continuation]\nparameter = "phi"\n')
    _assert_one_line_user_error(run_cli(cli_exe, "run", path, "--out", tmp_path / "o"),
                                "bad_cont.toml", "phi")


def test_export_refuses_a_suffix_it_does_not_write(small_cli_run, cli_exe, tmp_path):
    """User round: `export -o x.json` wrote CSV into x.json, exit 0. A suffix other than
    .csv is one line, exit 2, naming the format, and writes nothing; a .CSV, a name without
    a suffix and standard output are written."""
    _, h5, _ = small_cli_run
    for name in ("x.json", "x.txt", "x.csv.gz"):
        _assert_one_line_user_error(run_cli(cli_exe, "export", h5, "-o", tmp_path / name),
                                    name, "CSV only", ".csv")
        assert not (tmp_path / name).exists()
    want = None
    for name in ("x.CSV", "table"):
        proc = run_cli(cli_exe, "export", h5, "-o", tmp_path / name)
        assert proc.returncode == 0, proc.stderr
        want = want or (tmp_path / name).read_text()
        assert (tmp_path / name).read_text() == want
    # -o /dev/stdout: the CSV on standard output, written in place (renamed over it, the
    # device's link would become a file: as root, /dev/stdout itself); shown here through a
    # link of the test's own to the process's standard output, which a rename would replace
    out = tmp_path / "out"
    out.symlink_to("/proc/self/fd/1")
    proc = run_cli(cli_exe, "export", h5, "-o", out)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == want and out.is_symlink()
    assert proc.stderr.endswith(f"-> {out}\n")      # the summary line: not in the CSV


def test_show_and_export_on_a_file_that_is_not_hdf5(cli_exe, tmp_path):
    fake = tmp_path / "fake.h5"
    fake.write_text("not an HDF5 file\n")
    _assert_one_line_user_error(run_cli(cli_exe, "show", fake), "fake.h5")
    _assert_one_line_user_error(run_cli(cli_exe, "export", fake, "-o", tmp_path / "x.csv"),
                                "fake.h5")
    _assert_one_line_user_error(run_cli(cli_exe, "show", tmp_path / "missing.h5"), "missing.h5")


def test_unknown_run_name_is_a_user_error(cli_exe, tmp_path):
    _assert_one_line_user_error(run_cli(cli_exe, "run", "no_such_run", "--out", tmp_path),
                                "no_such_run")


def test_plot_writes_a_png(small_cli_run, cli_exe, tmp_path):
    _, h5, _ = small_cli_run
    png = tmp_path / "diagram.png"
    proc = run_cli(cli_exe, "plot", h5, "-o", png)
    assert proc.returncode == 0, proc.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_list_names_the_shipped_runs(cli_exe):
    proc = run_cli(cli_exe, "list")
    assert proc.returncode == 0, proc.stderr
    assert any(ln.split()[0] == "rotating_arm" for ln in proc.stdout.splitlines() if ln.split())


def test_set_overrides_like_an_edited_run_file(cli_exe, tmp_path):
    """--set of an option, a parameter (a grid) and a [continuation] key gives the branches
    of the run file edited to say the same."""
    plain = elastica_run_file(tmp_path / "plain.toml")
    edited = elastica_run_file(tmp_path / "edited.toml", directions="+", extra="[options]\n"
                               "ds_max = 0.3\n")
    edited.write_text(edited.read_text().replace("eps = '0.25'", "eps = [0.3, 0.4]"))
    proc = run_cli(cli_exe, "run", plain, "--out", tmp_path / "a", "-q", "-j1",
                   "--set", "ds_max=0.3", "--set", "eps=[0.3, 0.4]",
                   "--set", "continuation.directions=+")
    assert proc.returncode == 0, proc.stderr
    assert run_cli(cli_exe, "run", edited, "--out", tmp_path / "b", "-q",
                   "-j1").returncode == 0
    a, b = BranchFile(tmp_path / "a" / "plain.h5"), BranchFile(tmp_path / "b" / "edited.h5")
    assert len(a.branches) == len(b.branches) == 2
    for x, y in zip(a.branches, b.branches):
        assert x.columns["eps"][0] in (0.3, 0.4) and x.attrs["direction"] == 1
        assert json.loads(x.attrs["options"])["ds_max"] == 0.3
        for name in PARAMS + ORDS + ["type", "index"]:
            np.testing.assert_array_equal(x.columns[name], y.columns[name], err_msg=name)
    assert "#   --set options.ds_max=0.3" in a.attrs["run_file"]


def test_from_restarts_at_a_label_with_its_parameters(small_cli_run, cli_exe, tmp_path):
    """--from FILE:LABEL replaces the start and the run file's parameter values (eps = 0.9,
    P = 0 here): each branch starts at the label's solution, eps = 0.25, and runs to a
    bound."""
    _, h5, _ = small_cli_run
    label = "UZ2"
    stored = BranchFile(h5).label(label)
    toml = elastica_run_file(tmp_path / "eps.toml", eps="0.9", P="0")
    toml.write_text(toml.read_text().replace('parameter = "psi"', 'parameter = "eps"')
                    .replace('bounds = ["-2*pi", "2*pi"]', "bounds = [0.2, 0.3]"))
    proc = run_cli(cli_exe, "run", toml, "--out", tmp_path / "out", "-q",
                   "--from", f"{h5}:{label}")
    assert proc.returncode == 0, proc.stderr
    bf = BranchFile(tmp_path / "out" / "eps.h5")
    for b in bf.branches:
        assert b.attrs["start"] == f"small.h5:{label}"
        first = {q: b.columns[q][0] for q in PARAMS}
        assert first == pytest.approx(stored.state.params, abs=0)
        assert abs(b.columns["eps"][-1] - 0.25) == pytest.approx(0.05, abs=1e-12)


@pytest.mark.parametrize("args, words", [
    (["--set", "nonsense=1"], "--set nonsense=1: 'nonsense' is not an option"),
    # a typo gets the name meant, a top-level key what to do instead (they are in no table:
    # "write TABLE.switch" led to "[continuation] switch: unknown key")
    (["--set", "ds_maxx=1"], "'ds_maxx' is not an option, parameter or [continuation] key; "
     "did you mean ds_max?"),
    (["--set", "Eps=0.3"], "did you mean eps?"),
    (["--set", "switch=1"], "'switch' is a key at the top of the run file, which --set does "
     "not change: edit the run file"),
    (["--set", "start=trivial"], "edit the run file, or give --from FILE.h5:LABEL"),
    (["--set", "ds_max"], "expected NAME=VALUE"),
    (["--set", "ds_max=abc"], "[options] ds_max"),
    (["--set", "ds=5"], "[options]"),
    (["--set", "table.ds=5"], "no table [table]"),
    (["--set", "eps=[]"], "[parameters] eps: empty list"),
    (["--from", "nolabel.h5"], "expected FILE.h5:LABEL"),
    (["--from", "missing.h5:UZ1"], "restart file 'missing.h5' not found"),
])
def test_bad_overrides_are_one_line_user_errors(cli_exe, tmp_path, args, words):
    toml = elastica_run_file(tmp_path / "r.toml")
    proc = run_cli(cli_exe, "run", toml, "--out", tmp_path / "out", *args)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and words in proc.stderr, proc.stderr


def test_the_snap_back_line_counts_folds_and_branch_points(capsys):
    """Targets at folds and at subcritical branch points are counted apart; two targets at
    one point count that point once."""
    from types import SimpleNamespace

    from elastica_auto.cli import report_run
    rows = [{"branch": 1, "lp": "LP1"}, {"branch": 1, "lp": "LP1"}, {"branch": 2, "lp": "LP1"},
            {"branch": 2, "lp": "BP3"}]
    result = SimpleNamespace(warnings=[], snaps=rows, landings=[], maps=[], kept=0,
                             branches=[], seconds=1.0, path="out/x.h5")
    report_run(SimpleNamespace(name="x"), result)
    assert ("snap-back: 4 stable targets at 2 folds and 1 branch points ending a stable "
            "branch (elastica-auto snaps out/x.h5)") in capsys.readouterr().out
    report_run(SimpleNamespace(name="x"), SimpleNamespace(**{**vars(result),
                                                              "snaps": rows[:3]}))
    assert "3 stable targets at 2 folds ending" in capsys.readouterr().out


def _closed_stdout(*command):
    """Run ``command`` with its standard output a pipe nobody reads (its read end closed
    before the command starts, as ``| head`` leaves it once it has its lines): every write
    meets EPIPE."""
    import os
    import subprocess
    read, write = os.pipe()
    os.close(read)
    try:
        return subprocess.run([str(c) for c in command], stdout=write,
                              stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        os.close(write)


def test_a_reader_that_stops_reading_loses_nothing(cli_exe, small_cli_run, tmp_path):
    """`elastica-auto show FILE | head` (the README's own command) and `run ... | head`: a
    closed standard output is no internal error. `show`, `snaps`, `list` end with status 0
    and nothing on stderr; a run (default jobs: its local cluster) computes and saves every
    branch, the same ones as with its output read."""
    _, h5, first = small_cli_run
    assert first.returncode == 0, first.stderr
    for command in (("show", "--all", h5), ("snaps", h5), ("list",)):
        proc = _closed_stdout(cli_exe, *command)
        assert (proc.returncode, proc.stderr) == (0, ""), (command, proc.stderr)
    toml = elastica_run_file(tmp_path / "small.toml", uz=[0, "pi/12", "pi/6", "pi/2"])
    proc = _closed_stdout(cli_exe, "run", toml, "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    assert "internal error" not in proc.stderr
    mine, theirs = BranchFile(tmp_path / "out" / "small.h5"), BranchFile(h5)
    assert not mine.missing
    assert len(mine.branches) == len(theirs.branches) == 2
    for a, b in zip(mine.branches, theirs.branches):
        np.testing.assert_array_equal(a.columns["psi"], b.columns["psi"])


@pytest.mark.parametrize("args, says", [
    (("plot", "x.h5", "-o", "x.png", "--where", "eps=1"),
     "elastica-auto plot: No such option '--where'"),
    (("path", "elastica_lever_arm", "--at", "eps=0.25", "P=2", "--to", "psi=1"),
     "elastica-auto path: Got unexpected extra argument (P=2)"),
    (("run", "rotating_arm", "-j", "abc"), "elastica-auto run: Invalid value for '--jobs'"),
    (("show",), "elastica-auto show: Missing argument 'FILE'"),
    (("nope",), "elastica-auto: No such command 'nope'"),
    (("--nope",), "elastica-auto: No such option '--nope'"),
])
def test_a_command_line_that_does_not_parse_is_one_line(cli_exe, tmp_path, args, says):
    """hostile2: an unknown option, an extra argument, a value of the wrong type, a missing
    argument, an unknown command were click's three lines (usage, hint, ``Error: ...``); a
    user error is one line, ``elastica-auto: error: ...``, exit status 2, naming the command
    and its --help."""
    proc = run_cli(cli_exe, *args, cwd=tmp_path)
    assert proc.returncode == 2
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith(f"elastica-auto: error: {says}"), line
    name = says.split(":")[0]
    assert line.endswith(f"('{name} --help' lists the options)"), line
    assert proc.stdout == ""
