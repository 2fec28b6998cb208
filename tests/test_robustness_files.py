"""The files a run or an export writes and the branch files the commands read, through the CLI.

Each test checks the exit code, the message and what is left on disk: an export never
overwrites its input or leaves half a CSV; an output that cannot be written is found before
anything is computed; a run never restarts from the file it writes; an interrupted rerun keeps
the earlier complete result; two runs never write one file at once; temporary files of a
killed run are removed; new files follow the umask; a damaged branch file is refused with
one line by every command that reads it.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile

import h5py
import numpy as np
import pytest

from elastica_auto.core.errors import EXIT_WRITE
from elastica_auto.storage.store import BranchFile
from helpers import run_cli, signalling_elastica, wait_for
from test_robustness import IN_BRANCH_2, LONG_MINE, SMALL, one_line_error

# A run whose branches all end MX (see test_robustness): it finishes with exit status 1.
FAILS = SMALL.replace('parameter = "psi"', 'parameter = "psi"\ndirections = "+"') + (
    "[options]\nds = 0.05\nds_min = 0.04\nmax_angle = 0.005\n")


def hidden(folder):
    """Names in ``folder`` starting with a dot: temporary and lock files."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def points(path):
    return sum(len(b) for b in BranchFile(path).branches)


# -- 1. export ------------------------------------------------------------------------------------

@pytest.mark.parametrize("spelling", ["same", "relative", "dotdot", "symlink", "hardlink"])
def test_export_onto_its_own_input_is_refused(good_file, tmp_path, cli_exe, spelling):
    h5 = tmp_path / "small.h5"
    shutil.copy(good_file, h5)
    before = h5.read_bytes()
    (tmp_path / "sub").mkdir()
    target = {"same": h5, "relative": "small.h5", "dotdot": tmp_path / "sub" / ".." / "small.h5",
              "symlink": tmp_path / "link.csv", "hardlink": tmp_path / "hard.csv"}[spelling]
    if spelling == "symlink":
        target.symlink_to(h5)
    elif spelling == "hardlink":
        os.link(h5, target)
    one_line_error(run_cli(cli_exe, "export", h5, "-o", target, cwd=tmp_path),
                   "small.h5", "the branch file being exported")
    assert h5.read_bytes() == before
    assert hidden(tmp_path) == []


def test_a_failed_export_leaves_the_old_csv_and_no_partial_one(good_file, tmp_path, cli_exe):
    csv = tmp_path / "small.csv"
    csv.write_text("old\n")

    def small_files():  # the CSV (about 14 kB) cannot be written in full
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    proc = subprocess.run([cli_exe, "export", str(good_file), "-o", str(csv)],
                          capture_output=True, text=True, timeout=300, preexec_fn=small_files)
    one_line_write_error(proc, "small.csv", "cannot write (File too large)")
    assert csv.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.csv"]


# -- 2. an output that cannot be written ----------------------------------------------------------

def _writable(folder) -> bool:
    try:
        fd, name = tempfile.mkstemp(dir=folder)
    except OSError:
        return False
    os.close(fd)
    os.unlink(name)
    return True


@contextlib.contextmanager
def read_only(folder):
    """``folder`` made unwritable: by its mode, or, for root (whom modes do not stop), by the
    immutable attribute; the test is skipped where neither works."""
    folder.chmod(0o555)
    immutable = False
    try:
        if _writable(folder) and shutil.which("chattr"):
            immutable = subprocess.run(["chattr", "+i", str(folder)],
                                       capture_output=True).returncode == 0
        if _writable(folder):
            pytest.skip("cannot make a folder read-only here")
        yield
    finally:
        if immutable:
            subprocess.run(["chattr", "-i", str(folder)], check=True)
        folder.chmod(0o755)


def _run_refused_before_computing(cli_exe, toml, out, *needles):
    proc = run_cli(cli_exe, "run", toml, "--out", out, "-q")
    one_line_error(proc, *needles)
    assert "branch 1/" not in proc.stdout         # refused before the first branch was computed
    return proc


def test_read_only_output_folder(tmp_path, cli_exe):
    (tmp_path / "small.toml").write_text(SMALL)
    out = tmp_path / "out"
    out.mkdir()
    with read_only(out):
        _run_refused_before_computing(cli_exe, tmp_path / "small.toml", out, "small.h5",
                                      "cannot write")
    assert list(out.iterdir()) == []


def test_output_folder_below_a_file(tmp_path, cli_exe):
    (tmp_path / "small.toml").write_text(SMALL)
    (tmp_path / "notes").write_text("a file, not a folder\n")
    _run_refused_before_computing(cli_exe, tmp_path / "small.toml", tmp_path / "notes" / "out",
                                  "small.h5", "cannot write")
    assert (tmp_path / "notes").read_text() == "a file, not a folder\n"


def test_output_file_is_a_directory(tmp_path, cli_exe):
    (tmp_path / "small.toml").write_text(SMALL)
    (tmp_path / "out" / "small.h5").mkdir(parents=True)
    _run_refused_before_computing(cli_exe, tmp_path / "small.toml", tmp_path / "out",
                                  "small.h5", "is a directory")
    assert (tmp_path / "out" / "small.h5").is_dir()


def test_output_name_too_long(tmp_path, cli_exe):
    # the run file's name fits (255 characters), <run>.h5 too, but not the hidden temporary
    # and lock names beside it
    name = "r" * 250
    try:
        (tmp_path / f"{name}.toml").write_text(SMALL)
    except OSError:
        pytest.skip("file names here are shorter than 255 characters")
    _run_refused_before_computing(cli_exe, tmp_path / f"{name}.toml", tmp_path / "out",
                                  f"{name}.h5", "cannot write", "name too long")
    assert list((tmp_path / "out").iterdir()) == []


# -- 3. a run that restarts from its own output ----------------------------------------------------

@pytest.mark.parametrize("start", ['start = "small.h5:UZ1"',
                                   'start = { file = "small.h5", type = "UZ" }',
                                   'start = "link.h5:UZ1"'])
def test_restart_from_the_file_the_run_writes_is_refused(good_file, tmp_path, cli_exe, start):
    shutil.copy(good_file, tmp_path / "small.h5")
    (tmp_path / "link.h5").symlink_to(tmp_path / "small.h5")
    before = (tmp_path / "small.h5").read_bytes()
    (tmp_path / "small.toml").write_text(start + "\n" + SMALL)
    _run_refused_before_computing(cli_exe, tmp_path / "small.toml", tmp_path, "small.toml",
                                  "start", "the file this run writes")
    assert (tmp_path / "small.h5").read_bytes() == before


# -- 4. an interrupted or failed rerun ------------------------------------------------------------

def test_an_interrupted_rerun_keeps_the_complete_file(tmp_path, cli_exe):
    out, run = tmp_path / "out", tmp_path / "again.toml"
    run.write_text(SMALL)
    assert run_cli(cli_exe, "run", run, "--out", out, "-q").returncode == 0
    path, partial = out / "again.h5", out / "again.partial.h5"
    before, npts, inode = path.read_bytes(), points(path), path.stat().st_ino
    run.write_text(LONG_MINE)                            # 4 branches of about a second each
    # the second one holds a step until the signal: the run cannot end before it
    signalling_elastica(tmp_path / "mine.py", hold=(IN_BRANCH_2, tmp_path / "held"))
    proc = subprocess.Popen([cli_exe, "run", str(run), "--out", str(out), "-j", "1", "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # the first branch has been saved (beside the complete file, or over it)
    wait_for("the first branch saved", lambda: partial.exists() or path.stat().st_ino != inode,
             proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert path.read_bytes() == before and points(path) == npts
    saved = BranchFile(partial)
    # the first branch, and the second up to the signal if it came in its continuation
    assert len(saved.branches) in (1, 2) and saved.branches[0].attrs["end"] == "EP"
    last = err.strip().splitlines()[-1]
    assert f"{len(saved.branches)} branches saved to {partial}" in last
    assert f"{path} is unchanged" in last
    assert sorted(p.name for p in out.iterdir()) == ["again.h5", "again.partial.h5"]
    # a rerun that completes replaces the earlier file, and its partial file is gone
    run.write_text(SMALL.replace("eps = 0.25", "eps = 0.5"))
    assert run_cli(cli_exe, "run", run, "--out", out, "-q").returncode == 0
    assert sorted(p.name for p in out.iterdir()) == ["again.h5"]
    assert BranchFile(path).branches[0].columns["eps"][0] == 0.5


def test_a_rerun_with_failed_branches_replaces_the_file(tmp_path, cli_exe):
    run = tmp_path / "again.toml"
    run.write_text(SMALL)
    assert run_cli(cli_exe, "run", run, "--out", tmp_path, "-q").returncode == 0
    run.write_text(FAILS)
    proc = run_cli(cli_exe, "run", run, "--out", tmp_path, "-q")
    assert proc.returncode == 1, proc.stderr
    bf = BranchFile(tmp_path / "again.h5")
    assert [b.attrs["end"] for b in bf.branches] == ["MX"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again.h5", "again.toml"]


# -- 5. two runs writing one file -----------------------------------------------------------------

def test_two_runs_cannot_write_the_same_file_at_once(tmp_path, cli_exe):
    out, run = tmp_path / "out", tmp_path / "long.toml"
    run.write_text(LONG_MINE)
    # the first run holds a step of its second branch until it is signalled: it is still
    # writing the file whenever the second one tries to
    signalling_elastica(tmp_path / "mine.py", hold=(IN_BRANCH_2, tmp_path / "held"))
    first = subprocess.Popen([cli_exe, "run", str(run), "--out", str(out), "-j", "1", "-q"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for("the first run in its second branch", (tmp_path / "held").exists, first)
        second = run_cli(cli_exe, "run", run, "--out", out, "-q")
        assert first.poll() is None                      # the two runs overlapped
        one_line_error(second, str(out / "long.h5"), "another run is writing it")
    finally:
        first.send_signal(signal.SIGTERM)
        _, err = first.communicate(timeout=60)
    assert first.returncode == 130, err
    assert BranchFile(out / "long.h5").branches
    assert hidden(out) == []                             # the lock file went with the run


# -- 6. temporaries of a killed run; file modes ----------------------------------------------------

def test_stale_temporaries_of_the_output_are_removed(tmp_path, cli_exe):
    (tmp_path / "small.toml").write_text(SMALL)
    out = tmp_path / "out"
    out.mkdir()
    # what a run killed while saving leaves, and files that only look alike
    stale = [".small.h5.k3x_9q2a.tmp", ".small.partial.h5.0abcdefg.tmp"]
    kept = [".small.h5.notes.tmp", ".small.h5.k3x_9q2a.txt", ".other.h5.k3x_9q2a.tmp",
            ".small.h5.k3x_9q2a.tmp.bak"]
    for name in stale + kept:
        (out / name).write_bytes(b"half a file")
    assert run_cli(cli_exe, "run", tmp_path / "small.toml", "--out", out, "-q").returncode == 0
    assert hidden(out) == sorted(kept)
    assert BranchFile(out / "small.h5").branches


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o077, 0o600)])
def test_new_files_follow_the_umask(tmp_path, cli_exe, umask, mode):
    (tmp_path / "small.toml").write_text(SMALL)

    def cli(*args):
        return subprocess.run([cli_exe, *map(str, args)], capture_output=True, text=True,
                              timeout=300, preexec_fn=lambda: os.umask(umask))

    assert cli("run", tmp_path / "small.toml", "--out", tmp_path, "-q").returncode == 0
    assert (tmp_path / "small.h5").stat().st_mode & 0o777 == mode
    assert cli("export", tmp_path / "small.h5", "-o", tmp_path / "small.csv").returncode == 0
    assert (tmp_path / "small.csv").stat().st_mode & 0o777 == mode


# -- 7. damaged branch files ----------------------------------------------------------------------

def _first_uz(f):
    return next((k, v) for k, v in json.loads(f.attrs["labels"]).items() if k.startswith("UZ"))


def _delete_column(f):
    del f["branches/001/columns/psi"]


def _shorten_column(f):
    cols = f["branches/001/columns"]
    data = cols["psi"][:-3]
    del cols["psi"]
    cols["psi"] = data


def _column_as_group(f):
    del f["branches/001/columns/psi"]
    f.create_group("branches/001/columns/psi")


def _labels_not_json(f):
    f.attrs["labels"] = '{"UZ1": [1, 2'


def _labels_wrong_shape(f):
    f.attrs["labels"] = json.dumps({name: where[0] for name, where in
                                    json.loads(f.attrs["labels"]).items()})


def _label_beyond_the_branch(f):
    name, (br, _) = _first_uz(f)
    f.attrs["labels"] = json.dumps({**json.loads(f.attrs["labels"]), name: [br, 10 ** 6]})


def _solution_missing(f):
    name, (br, _) = _first_uz(f)
    g = f[f"branches/{br:03d}/solutions"]
    names = [x.decode() for x in g["label"][()]]
    del g["label"]
    g.create_dataset("label", data=[x for x in names if x != name] + ["XX1"],
                     dtype=h5py.string_dtype())


DAMAGES = {
    "column_deleted": (_delete_column, ["no column 'psi'"]),
    "column_short": (_shorten_column, ["column 'psi' has", "rows"]),
    "column_group": (_column_as_group, ["column 'psi' is not a one-dimensional dataset"]),
    "labels_not_json": (_labels_not_json, ["attribute 'labels' is not JSON"]),
    "labels_wrong_shape": (_labels_wrong_shape, ["attribute 'labels'", "[branch, point]"]),
    "label_beyond_the_branch": (_label_beyond_the_branch, ["UZ1", "no point"]),
    "solution_missing": (_solution_missing, ["UZ1", "no stored solution"]),
}


@pytest.mark.parametrize("damage", sorted(DAMAGES))
def test_damaged_branch_file_gives_one_line_everywhere(good_file, tmp_path, cli_exe, damage):
    edit, needles = DAMAGES[damage]
    bad = tmp_path / "bad.h5"
    shutil.copy(good_file, bad)
    with h5py.File(good_file, "r") as f:
        uz, _ = _first_uz(f)
    with h5py.File(bad, "a") as f:
        edit(f)
    (tmp_path / "restart.toml").write_text(f'start = "bad.h5:{uz}"\n' + SMALL)
    commands = {"show": ["show", bad], "export": ["export", bad, "-o", tmp_path / "bad.csv"],
                "snaps": ["snaps", bad], "plot": ["plot", bad, "-o", tmp_path / "bad.png"],
                "restart": ["run", tmp_path / "restart.toml", "--out", tmp_path / "out"]}
    # the five commands at once: each only reads the damaged file
    procs = {cmd: subprocess.Popen([cli_exe, *map(str, args)], stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)
             for cmd, args in commands.items()}
    for cmd, proc in procs.items():
        out, err = proc.communicate(timeout=300)
        done = subprocess.CompletedProcess(commands[cmd], proc.returncode, out, err)
        try:
            one_line_error(done, str(bad), "damaged branch file", *needles)
        except AssertionError as exc:
            raise AssertionError(f"{cmd}: {exc}") from None
    assert not (tmp_path / "bad.csv").exists() and not (tmp_path / "bad.png").exists()
    assert not (tmp_path / "out" / "restart.h5").exists()


# -- 8. a run killed at every stage of its saves -------------------------------------------------

KILLED_AT = """\
import sys
import threading
from pathlib import Path

from elastica_auto.execution import runfile
from elastica_auto.storage import store
from elastica_auto.execution.run import execute

stage, count, marker = sys.argv[3], int(sys.argv[4]), Path(sys.argv[5])
seen = []


def stop_here(name):
    seen.append(name)
    if name == stage and seen.count(name) == count:
        marker.write_text(name)
        threading.Event().wait()              # until the test kills this process


store.save_stage = stop_here
execute(runfile.load(Path(sys.argv[1])), Path(sys.argv[2]), jobs=1)
"""

# (stage, its occurrence in the run) -> branches in the file left behind (None: no file). The
# run saves after each of its 2 branches (a branch file, then the file linking it) and at the
# end (the snap-back table), then writes the file whole.
STAGES = {("branch written", 1): None, ("branch renamed", 1): None, ("index written", 1): None,
          ("index renamed", 1): 1, ("branch written", 2): 1, ("branch renamed", 2): 1,
          ("index written", 2): 1, ("index renamed", 2): 2, ("index written", 3): 2,
          ("index renamed", 3): 2, ("whole written", 1): 2, ("whole renamed", 1): 2}


@pytest.fixture(scope="module")
def whole_run(tmp_path_factory):
    """The two-branch run, not killed: what each branch of a killed one must be."""
    from helpers import elastica_run_file
    root = tmp_path_factory.mktemp("whole")
    toml = elastica_run_file(root / "small.toml", uz=[0, 1])
    from elastica_auto.execution import runfile
    from elastica_auto.execution.run import execute
    return toml, BranchFile(execute(runfile.load(toml), root / "out", jobs=1).path)


@pytest.mark.parametrize("stage, count", sorted(STAGES))
def test_a_run_killed_at_any_stage_of_a_save_leaves_a_whole_file(tmp_path, whole_run, stage,
                                                                 count):
    """SIGKILL when the run reaches a stage of a save (it waits there): the file is absent
    or reads whole, with the branches saved before (each as the run computes it, every
    label's solution readable); the next run writing it makes it one file again and leaves
    no hidden file."""
    toml, whole = whole_run
    out, marker = tmp_path / "out", tmp_path / "reached"
    proc = subprocess.Popen([sys.executable, "-c", KILLED_AT, str(toml), str(out), stage,
                             str(count), str(marker)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        wait_for(f"the run at {stage} ({count})", marker.exists, proc)
    finally:
        proc.kill()
        proc.communicate()
    path = out / "small.h5"
    expected = STAGES[(stage, count)]
    if expected is None:
        assert not path.exists()
    else:
        bf = BranchFile(path)
        assert len(bf.branches) == expected
        for a, b in zip(bf.branches, whole.branches[:expected]):
            for name in ("psi", "index", "type", "label"):
                np.testing.assert_array_equal(a.columns[name], b.columns[name], err_msg=name)
            np.testing.assert_array_equal(a.profiles, b.profiles)
        for name in bf.labels:
            mine, theirs = bf.label(name), whole.label(name)
            np.testing.assert_array_equal(mine.state.y, theirs.state.y)
        assert bool(bf.snaps) == (stage == "whole renamed" or (stage, count) in
                                  {("index renamed", 3), ("whole written", 1)})
    assert run_cli(sys.executable, "-c",
                   "import sys; from elastica_auto.cli import main; sys.argv[0] = "
                   "'elastica-auto'; main()", "run", toml, "--out", out, "-q",
                   "-j", "1").returncode == 0
    assert sorted(p.name for p in out.iterdir()) == ["small.h5"]
    assert len(BranchFile(path).branches) == 2


# -- 9. writes that fail once a command is under way -----------------------------------------------

def one_line_write_error(proc, *needles):
    """A write that failed under way: one line, exit status 5 (EXIT_WRITE), no traceback; the
    line ends what the command wrote to stderr (a run's header line comes before it)."""
    assert proc.returncode == EXIT_WRITE, (proc.returncode, proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout
    lines = proc.stderr.strip().splitlines()
    errors = [line for line in lines if line.startswith("elastica-auto: error: ")]
    assert errors == lines[-1:], proc.stderr
    err = errors[0]
    for n in needles:
        assert n in err, (n, err)
    return err


def leftovers(folder):
    """Lock files and temporaries in ``folder`` and in its hidden branch folders."""
    return sorted(p.name for p in folder.rglob(".*") if p.name.endswith((".lock", ".tmp")))


@contextlib.contextmanager
def disk_full_after(writes: int):
    """``os.write`` to a temporary file of a save (``.<name>.XXXXXXXX.tmp``) fails with ENOSPC
    from the ``writes + 1``-th such call on, as on a full disk; other writes go through."""
    real, count = os.write, [0]

    def write(fd, data):
        try:
            name = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            name = ""
        if name.endswith(".tmp"):
            count[0] += 1
            if count[0] > writes:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(fd, data)

    if not os.path.isdir("/proc/self/fd"):
        pytest.skip("needs /proc/self/fd to tell a save's writes from others")
    os.write = write
    try:
        yield
    finally:
        os.write = real


def _run_in_process(toml, out):
    """``elastica-auto run TOML --out OUT -j 1 -q`` in this process (CliRunner)."""
    from click.testing import CliRunner

    from elastica_auto.cli import main
    handler = signal.getsignal(signal.SIGTERM)      # `run` sets its own
    try:
        result = CliRunner().invoke(main, ["run", str(toml), "--out", str(out), "-j", "1",
                                           "-q"])
    finally:
        signal.signal(signal.SIGTERM, handler)
    return subprocess.CompletedProcess(["run"], result.exit_code, result.stdout, result.stderr)


@pytest.mark.parametrize("earlier", [False, True], ids=["new output", "rerun over a file"])
def test_a_full_disk_during_a_run_is_one_line_with_status_5(tmp_path, earlier):
    """Hostile H2: the disk fills up while a run saves its second branch (os.write raising
    ENOSPC; the report's tmpfs segfaulted in h5py's File.close, exit 139, and a rerun over a
    complete file ended in an h5py traceback, exit 1). Now: one line, exit 5, no lock or
    temporary left; a new output holds the first branch, an earlier complete file is as it
    was."""
    toml, out = tmp_path / "small.toml", tmp_path / "out"
    toml.write_text(SMALL)
    path = out / "small.h5"
    if earlier:
        assert _run_in_process(toml, out).returncode == 0
        before = path.read_bytes()
    with disk_full_after(1):              # the first branch's file, not the file linking it
        proc = _run_in_process(toml, out)
    err = one_line_write_error(proc, "cannot write (No space left on device)")
    assert leftovers(out) == []
    if earlier:
        assert path.read_bytes() == before
        assert f"no branch saved; the earlier {path} is unchanged" in err
    else:
        assert err.endswith("no branch saved") and not path.exists()
    with disk_full_after(2):              # the first branch saved (its file, then the link)
        proc = _run_in_process(toml, out)
    err = one_line_write_error(proc, "cannot write (No space left on device)")
    assert leftovers(out) == []
    if earlier:
        assert path.read_bytes() == before
        assert len(BranchFile(out / "small.partial.h5").branches) == 1
    else:
        assert f"{path} holds the 1 branch saved before it" in err
        assert len(BranchFile(path).branches) == 1
    assert _run_in_process(toml, out).returncode == 0      # room again: a whole file
    assert sorted(p.name for p in out.iterdir()) == ["small.h5"]
    assert len(BranchFile(path).branches) == 2


def _file_size_limit(limit: int):
    """For a subprocess: files at most ``limit`` bytes; a write beyond fails with EFBIG
    (SIGXFSZ ignored, as Python does, so that the write returns the error)."""
    def set_limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return set_limit


def test_a_file_size_limit_during_a_run_is_one_line_with_status_5(good_file, tmp_path, cli_exe):
    """Hostile L7: ``ulimit -f`` (EFBIG) during a run gave a traceback and exit 1. Now: one
    line, exit 5, no lock or temporary left, an earlier complete file unchanged."""
    out = tmp_path / "out"
    out.mkdir()
    shutil.copy(good_file, out / "small.h5")
    before = (out / "small.h5").read_bytes()
    (tmp_path / "small.toml").write_text(SMALL)
    # below the size of a branch's file: the run's first save fails
    proc = subprocess.run([cli_exe, "run", str(tmp_path / "small.toml"), "--out", str(out),
                           "-q", "-j", "1"], capture_output=True, text=True, timeout=300,
                          preexec_fn=_file_size_limit(8192))
    one_line_write_error(proc, "cannot write (File too large)", "is unchanged")
    assert (out / "small.h5").read_bytes() == before
    assert leftovers(out) == [] and sorted(p.name for p in out.iterdir()) == ["small.h5"]


# -- 10. damaged bytes; an empty branch; a file without its folder -------------------------------

def _reading_commands(bad, tmp_path):
    """Every command that reads the branch file ``bad``, with its arguments."""
    return {"show": ["show", bad], "export": ["export", bad, "-o", tmp_path / "bad.csv"],
            "snaps": ["snaps", bad], "plot": ["plot", bad, "-o", tmp_path / "bad.png"],
            "view": ["view", bad, "-o", tmp_path / "bad.html"]}


def _each_one_line(cli_exe, commands, *needles):
    """Run ``commands`` (name -> arguments) at once; each gives one line, exit 2, with
    ``needles``."""
    procs = {cmd: subprocess.Popen([cli_exe, *map(str, args)], stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)
             for cmd, args in commands.items()}
    for cmd, proc in procs.items():
        out, err = proc.communicate(timeout=300)
        try:
            one_line_error(subprocess.CompletedProcess(commands[cmd], proc.returncode, out,
                                                       err), *needles)
        except AssertionError as exc:
            raise AssertionError(f"{cmd}: {exc}") from None


def test_damaged_bytes_are_a_checksum_mismatch_everywhere(good_file, tmp_path, cli_exe):
    """Hostile M5 (a): random bytes written over branch 1's stored solutions (the report's 4 kB;
    here as many as the first chunk of its ``y`` holds, to hit data, not metadata). Every
    reader names the dataset (``checksum mismatch in /branches/001/solutions/y``), with one
    line and exit 2 (``show``, ``plot``, ``export`` and ``view`` exited 0 on such a file),
    and a restart from one of its labels is refused the same way."""
    bad = tmp_path / "bad.h5"
    shutil.copy(good_file, bad)
    with h5py.File(bad, "r") as f:
        chunk = f["branches/001/solutions/y"].id.get_chunk_info(0)
        uz, _ = _first_uz(f)
    assert chunk.size > 1000
    with open(bad, "r+b") as fh:
        fh.seek(chunk.byte_offset)
        fh.write(np.random.default_rng(46).bytes(min(4096, chunk.size)))
    commands = _reading_commands(bad, tmp_path)
    commands["restart"] = ["run", tmp_path / "small.toml", "--from", f"{bad}:{uz}",
                           "--out", tmp_path / "out"]
    (tmp_path / "small.toml").write_text(SMALL)
    _each_one_line(cli_exe, commands, str(bad),
                   "damaged branch file: checksum mismatch in /branches/001/solutions/y")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.h5", "small.toml"]


def _no_points(f):
    """Branch 002 emptied: every column and its profiles of 0 rows, its labels gone."""
    g = f["branches/002"]
    for name in list(g["columns"]):
        dtype = g["columns"][name].dtype
        del g["columns"][name]
        g["columns"].create_dataset(name, shape=(0,), dtype=dtype)
    shape = g["profiles"].shape
    del g["profiles"]
    g.create_dataset("profiles", shape=(0, *shape[1:]), dtype=float)
    f.attrs["labels"] = json.dumps({k: v for k, v in json.loads(f.attrs["labels"]).items()
                                    if v[0] != 2})


def test_a_branch_without_points_is_damaged_everywhere(good_file, tmp_path, cli_exe):
    """Hostile L8: a crafted branch of 0 points; ``view`` wrote a blank page (a JavaScript
    error in the browser) and exited 0. Every branch has its start at least, so every
    reader calls such a file damaged: one line, exit 2, nothing written."""
    bad = tmp_path / "bad.h5"
    shutil.copy(good_file, bad)
    with h5py.File(bad, "a") as f:
        _no_points(f)
    _each_one_line(cli_exe, _reading_commands(bad, tmp_path), str(bad),
                   "damaged branch file: branch 002 has no points")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.h5"]


def test_a_file_copied_without_its_branch_folder_says_where_they_are(tmp_path, cli_exe):
    """Hostile L13: the file of a run killed while writing it links its branches from the
    hidden folder ``.<run>.h5.branches`` beside it; copied without it, the readers said
    ``unreadable branch file (... can't open file)``. Now one line says that the branches
    are in that folder, which is missing, and that ``--resume`` in the file's folder makes
    it whole; the file read in its own folder is the same as ever."""
    import elastica_auto as ea
    from elastica_auto.execution.run import number_labels
    from elastica_auto.storage import store
    from helpers import EXAMPLES
    problem = ea.load_problem(str(EXAMPLES / "bratu.py"))
    branches = list(ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), uz=[1],
                                    max_points=30))
    number_labels(branches)
    out, moved = tmp_path / "out", tmp_path / "moved"
    moved.mkdir()
    with store.Writer(out / "b.h5", "b", problem) as writer:
        writer.save(branches)              # linked, as a killed run leaves its file
        shutil.copy(out / "b.h5", moved / "b.h5")
    assert len(BranchFile(out / "b.h5").branches) == len(branches)
    _each_one_line(cli_exe, _reading_commands(moved / "b.h5", tmp_path),
                   str(moved / "b.h5"), "hidden folder .b.h5.branches beside it, which is "
                   "missing", "elastica-auto run b --resume")


# -- 11. a file replaced while it is read; names too long; stale locks ---------------------------

def _invoke(*args):
    """``elastica-auto ARGS`` in this process (CliRunner): (exit status, stdout, stderr)."""
    from click.testing import CliRunner

    from elastica_auto.cli import main
    result = CliRunner().invoke(main, [str(a) for a in args])
    return result.exit_code, result.stdout, result.stderr


def test_show_reads_a_file_replaced_while_it_is_read_consistently(good_file, tmp_path,
                                                                  monkeypatch):
    """Hostile M4: a run replaced the file (an atomic rename) between ``show``'s opening and
    its reads of the columns: a StoreError traceback, exit 1. The file is replaced here right
    after every opening (a hook, not a race): ``show`` and ``export`` read what they print in
    that one opening, and print the file they opened, as they do unreplaced; ``plot`` and
    ``view``, which read more later, say in one line that it changed (exit 2)."""
    from elastica_auto.storage import store
    path, other = tmp_path / "small.h5", tmp_path / "other.h5"
    shutil.copy(good_file, path)
    with h5py.File(good_file, "r") as src, h5py.File(other, "w") as dst:
        for name in src.attrs:                          # the same layout, other numbers
            dst.attrs[name] = src.attrs[name]
        for name in src:
            src.copy(src[name], dst, name)
        cols = dst["branches/001/columns"]
        psi = cols["psi"][()] + 1.0
        del cols["psi"]
        cols["psi"] = psi
    expected = {cmd: _invoke(cmd, path, *extra) for cmd, extra in
                (("show", ["--all"]), ("export", ["-o", tmp_path / "expected.csv"]))}
    opened = store.BranchFile.__init__

    def replaced_after_opening(self, *args, **kwargs):
        opened(self, *args, **kwargs)
        fresh = tmp_path / ".fresh.h5"
        shutil.copy(other, fresh)
        os.replace(fresh, path)                 # as a run renames its new file into place

    monkeypatch.setattr(store.BranchFile, "__init__", replaced_after_opening)
    shutil.copy(good_file, path)
    assert _invoke("show", "--all", path) == expected["show"]
    assert expected["show"][0] == 0 and "Traceback" not in expected["show"][2]
    shutil.copy(good_file, path)
    status, out, err = _invoke("export", path, "-o", tmp_path / "got.csv")
    assert status == 0 and (tmp_path / "got.csv").read_text() == \
        (tmp_path / "expected.csv").read_text()
    for args in (["plot", path, "-o", tmp_path / "x.png"],
                 ["view", path, "-o", tmp_path / "x.html"]):
        shutil.copy(good_file, path)
        status, out, err = _invoke(*args)
        assert status == 2 and len(err.strip().splitlines()) == 1, (args, status, err)
        assert f"{path}: changed since it was opened" in err


LONG = "x" * 300


@pytest.mark.parametrize("args", [
    ["run", LONG], ["show", LONG + ".h5"], ["run", "{toml}", "--from", LONG + ".h5:UZ1"],
    ["path", LONG + ".py", "--to", "P=3"], ["plot", "{good}", "-o", LONG + ".png"],
    ["export", "{good}", "-o", LONG + ".csv"], ["view", "{good}", "-o", LONG + ".html"],
], ids=["run", "show", "from", "path", "plot", "export", "view"])
def test_a_path_longer_than_the_file_system_allows_is_one_line(good_file, tmp_path, cli_exe,
                                                                 args):
    """Hostile L2: a path argument of 300 bytes (over the 255 a name may have) gave an
    ``OSError: [Errno 36] File name too long`` traceback in run, show, --from, path and
    plot -o; now one line, exit 2, as export gave."""
    (tmp_path / "small.toml").write_text(SMALL)
    args = [a.format(toml=tmp_path / "small.toml", good=good_file) for a in args]
    proc = run_cli(cli_exe, *args, cwd=tmp_path)
    one_line_error(proc, "too long")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.toml"]


def test_a_stale_lock_is_cleared_and_a_held_one_names_its_holder(tmp_path, cli_exe):
    """Hostile L10: a run killed (SIGKILL, a crash, a module's os._exit) leaves its lock file.
    A later run writing any file of that folder removes the lock files no process holds, and
    leaves a held one (a run that finds its own lock held names the holder's process and
    host, which the holder wrote into it)."""
    (tmp_path / "small.toml").write_text(SMALL)
    out = tmp_path / "out"
    out.mkdir()
    for name in (".small.h5.lock", ".killed.h5.lock"):     # no process holds them
        (out / name).write_text("12345 elsewhere\n")
    held = out / ".busy.h5.lock"
    with open(held, "w") as fh:                           # a run of busy.h5, alive
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        fh.write(f"{os.getpid()} {socket.gethostname()}\n")
        fh.flush()
        assert run_cli(cli_exe, "run", tmp_path / "small.toml", "--out", out,
                       "-q").returncode == 0
        assert hidden(out) == [".busy.h5.lock"]
        (tmp_path / "busy.toml").write_text(SMALL)
        proc = run_cli(cli_exe, "run", tmp_path / "busy.toml", "--out", out, "-q")
        one_line_error(proc, "another run is writing it",
                       f"process {os.getpid()} on {socket.gethostname()}")
        assert hidden(out) == [".busy.h5.lock"]
    assert run_cli(cli_exe, "run", tmp_path / "busy.toml", "--out", out, "-q").returncode == 0
    assert hidden(out) == [] and sorted(p.name for p in out.iterdir()) == ["busy.h5", "small.h5"]
