"""Branches as tasks of a Dask cluster (``--scheduler``): a real cluster started here as
subprocesses on 127.0.0.1 (``dask scheduler`` and ``dask worker --nworkers 2``).

The file a cluster writes is the file ``--jobs 1`` writes, number for number (only the
``worker`` attribute and timings differ); both workers are used; a worker killed mid-run
costs nothing; Ctrl-C keeps the finished branches; an unreachable scheduler is one line.
Faults (the last section): a cluster whose workers all die, or whose scheduler goes, ends
the run after worker_timeout with its branches kept and the rest recorded for --resume;
malformed or empty addresses are one line; --jobs is capped at the usable cores; a task
that raises on a worker is said, one whose worker died is computed again quietly.
"""

from __future__ import annotations

import json
import math
import re
import os
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import elastica_auto

from elastica_auto.storage.store import BranchFile
from helpers import ROTATING_ARM, run_cli, signalling_elastica, wait_for

BIN = Path(sys.executable).parent


def _start_cluster(root: Path) -> tuple[str, list]:
    """A scheduler and two single-threaded workers (with their nannies, all in the second
    process's group), on 127.0.0.1: the scheduler's address, once both workers have joined,
    and the two processes (`_stop_cluster`)."""
    root.mkdir(parents=True, exist_ok=True)
    info = root / "scheduler.json"
    common = dict(cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                  start_new_session=True)
    procs = [subprocess.Popen([BIN / "dask", "scheduler", "--scheduler-file", info, "--port",
                               "0", "--host", "127.0.0.1", "--no-dashboard"], **common)]
    wait_for("the scheduler's file", info.is_file, procs[0])
    procs.append(subprocess.Popen([BIN / "dask", "worker", "--scheduler-file", info,
                                   "--nworkers", "2", "--nthreads", "1", "--host", "127.0.0.1",
                                   "--no-dashboard"], **common))
    address = json.loads(info.read_text())["address"]
    from distributed import Client
    with Client(address, timeout=30) as client:
        client.wait_for_workers(2, timeout=60)
    return address, procs


def _stop_cluster(procs):
    """End the scheduler and the workers: SIGTERM to each group, then, for a group still up
    after 30 s (Dask's nannies close their workers gracefully, which on a loaded machine has
    taken longer: CI once), SIGKILL. The processes are Dask's own, not the package's."""
    for p in reversed(procs):
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait(timeout=30)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A scheduler and two single-threaded workers; yields the scheduler's address."""
    address, procs = _start_cluster(tmp_path_factory.mktemp("cluster"))
    yield address
    _stop_cluster(procs)


def _numbers(path) -> dict:
    """Every dataset of a branch file and every attribute but the run's timings, creation
    time and the workers that computed it."""
    out = {}

    def visit(name, obj):
        skip = {"created", "seconds", "worker"}
        for k, v in obj.attrs.items():
            if k not in skip:
                out[f"{name}@{k}"] = v
        if isinstance(obj, h5py.Dataset):
            out[name] = obj[()]

    with h5py.File(path, "r") as f:
        visit("/", f)
        f.visititems(visit)
    return out


@pytest.fixture(scope="module")
def on_cluster(cluster, tmp_path_factory, cli_exe):
    out = tmp_path_factory.mktemp("on_cluster")
    proc = run_cli(cli_exe, "run", "rotating_arm", "--out", out, "--scheduler", cluster)
    assert proc.returncode == 0, proc.stderr
    return out / "rotating_arm.h5"


@pytest.fixture(scope="module")
def in_one_process(tmp_path_factory, cli_exe):
    out = tmp_path_factory.mktemp("one_process")
    proc = run_cli(cli_exe, "run", "rotating_arm", "--out", out, "-j", "1")
    assert proc.returncode == 0, proc.stderr
    return out / "rotating_arm.h5"


def _same_numbers(a_path, b_path):
    here, there = _numbers(a_path), _numbers(b_path)
    assert here.keys() == there.keys()
    for key in here:
        a, b = here[key], there[key]
        if isinstance(a, np.ndarray) and a.dtype.kind == "f":
            np.testing.assert_array_equal(a, b, err_msg=key)
        else:
            assert np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b, key


def test_a_cluster_writes_the_file_one_process_writes(on_cluster, in_one_process):
    _same_numbers(in_one_process, on_cluster)


def test_a_local_cluster_writes_the_file_one_process_writes(rotating_arm, in_one_process):
    """The conftest's rotating_arm is computed with jobs = 2: a local cluster of 2 workers."""
    _same_numbers(in_one_process, rotating_arm.result.path)
    _two_workers([b.attrs["worker"] for b in BranchFile(rotating_arm.result.path).branches])


def _two_workers(workers):
    """Two workers computed the branches; the other direction of each symmetric start is the
    mirror image of the branch before it, taken in this process
    (`elastica_auto.branches.mirror`)."""
    computed, images = workers[::2], workers[1::2]
    assert len(set(computed)) == 2 and all(w.startswith("tcp://127.0.0.1:") for w in computed)
    assert images == [f"mirror of {w}" for w in computed]


def test_both_workers_computed_branches_and_are_named(on_cluster, in_one_process):
    _two_workers([b.attrs["worker"] for b in BranchFile(on_cluster).branches])
    assert [b.attrs["worker"] for b in BranchFile(in_one_process).branches] == \
        ["local", "mirror of local"] * 4


def test_a_cluster_run_reports_its_tasks(tmp_path):
    """on_tasks: tasks done of all, points so far, workers; the last call has every task."""
    from elastica_auto.execution import runfile
    from elastica_auto.execution.jobs import Callbacks
    from elastica_auto.execution.run import execute
    from helpers import elastica_run_file
    calls = []
    plan = runfile.load(elastica_run_file(tmp_path / "small.toml", uz=[0], mirror=False))
    result = execute(plan, tmp_path / "out", Callbacks(on_tasks=lambda *a: calls.append(a)),
                     jobs=2)
    total = len(plan.branches)
    assert calls[-1] == (total, total, sum(len(b.points) for b in result.branches), 2)
    assert all(c[1] == total and c[3] == 2 for c in calls)
    assert [c[0] for c in calls] == sorted(c[0] for c in calls)


def _rotating_arm(tmp_path, **signals) -> Path:
    """The shipped rotating_arm run with a copy of the elastica whose rhs tells the test where
    the run is (`helpers.signalling_elastica`: ``mark``, ``hold``)."""
    signalling_elastica(tmp_path / "mine.py", **signals)
    run = tmp_path / "rotating_arm.toml"
    run.write_text(ROTATING_ARM.read_text().replace('"elastica_lever_arm"', '"mine.py"'))
    return run


def test_a_worker_killed_mid_run_costs_nothing(cluster, tmp_path, cli_exe):
    """SIGKILL to the worker computing a branch, in one of its steps (held there until the
    kill): its task is rescheduled, the run completes with every branch, number for number
    the branches one process computes."""
    held, out = tmp_path / "held", tmp_path / "out"
    run = _rotating_arm(tmp_path, hold=('abs(p["psi"]) > 1', held))
    proc = subprocess.Popen([cli_exe, "run", run, "--out", out, "--scheduler", cluster],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    from distributed import Client
    try:
        pid = int(wait_for("a branch in a step on a worker", lambda: held.is_file()
                           and held.read_text(), proc))
        with Client(cluster, timeout=30) as client:
            assert pid in client.run(os.getpid).values()      # one of the cluster's workers
        os.kill(pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=300)
    finally:  # a step still held (the test failed before the kill) fails: its worker is free
        (tmp_path / "held.release").touch()
    assert proc.returncode == 0, err
    bf = BranchFile(out / "rotating_arm.h5")
    assert len(bf.branches) == 8 and all(b.attrs["end"] == "EP" for b in bf.branches)
    # the same module (the copy of the elastica written by hand) in one process
    one = tmp_path / "one"
    (tmp_path / "plain").mkdir()
    plain = _rotating_arm(tmp_path / "plain")
    assert run_cli(cli_exe, "run", plain, "--out", one, "-j", "1").returncode == 0
    for a, b in zip(BranchFile(one / "rotating_arm.h5").branches, bf.branches, strict=True):
        for name, col in a.columns.items():
            np.testing.assert_array_equal(col, b.columns[name], err_msg=name)
        np.testing.assert_array_equal(a.profiles, b.profiles)
    with Client(cluster, timeout=30) as client:
        client.wait_for_workers(2, timeout=60)       # the nanny restarted it


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_cluster_run_keeps_its_finished_branches(cluster, tmp_path, cli_exe,
                                                                sig):
    """Branches slowed by smaller steps (ds_max = 0.1, seconds each), and one of the last two
    (eps = 0.5, P = 9 pi^2 / 4) held in a step until the run is over: the signal comes once
    the first is saved (the file appears), while the others run."""
    held, out = tmp_path / "held", tmp_path / "out"
    run = _rotating_arm(tmp_path, hold=('p["eps"] == 0.5 and p["P"] > 20 and abs(p["psi"]) > 1',
                                        held))
    proc = subprocess.Popen([cli_exe, "run", run, "--out", out, "--scheduler", cluster,
                             "--set", "ds_max=0.1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for("the first branch saved", (out / "rotating_arm.h5").exists, proc)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:  # the held step, if it was reached, fails: its worker is free again
        (tmp_path / "held.release").touch()
    assert proc.returncode == 130 and "Traceback" not in err, err
    saved = BranchFile(out / "rotating_arm.h5").branches
    assert f"interrupted: {len(saved)} branches saved to" in err
    assert all(b.attrs["end"] == "EP" for b in saved) and 1 <= len(saved) < 8


def test_tasks_on_a_cluster_come_back_in_order_or_are_computed_here(cluster):
    """cluster.map_tasks (the damped landings of a --jobs N or scheduler run): the results
    in order, each reported once; a task the workers cannot compute (a module they cannot
    import: `helpers` is on this process's path only) is computed in this process, and a
    warning says why."""
    import importlib

    from distributed import Client

    from elastica_auto.execution.cluster import map_tasks
    with Client(cluster, timeout=30, set_as_default=False) as client:   # as a run's
        reported = []
        warnings = []
        pids = map_tasks(client, os.getpid, [()] * 4, lambda i, r: reported.append((i, r)),
                         warnings)
        assert sorted(reported) == list(enumerate(pids)) and os.getpid() not in pids
        assert warnings == []
        mods = map_tasks(client, importlib.import_module, [("helpers",)], lambda i, r: None,
                         warnings)
        assert mods[0].__name__ == "helpers"
    # said, with the worker's exception (issue 45 item 3)
    (line,) = warnings
    assert line.startswith("task 1 of 1 (import_module) raised on a worker: "
                           "ModuleNotFoundError: No module named 'helpers' (")
    assert line.endswith("); computed here instead")


def test_an_unreachable_scheduler_is_one_line(tmp_path, cli_exe):
    proc = run_cli(cli_exe, "run", "rotating_arm", "--out", tmp_path / "out", "--scheduler",
                   "tcp://127.0.0.1:1")
    assert proc.returncode == 2 and not (tmp_path / "out").exists()
    assert proc.stderr.strip().splitlines() == [
        "elastica-auto: error: cannot reach the Dask scheduler at tcp://127.0.0.1:1 (OSError: "
        "Timed out trying to connect to tcp://127.0.0.1:1 after 10 s)"]


def test_a_run_file_names_its_scheduler(cluster, tmp_path):
    from elastica_auto.execution import runfile
    from helpers import elastica_run_file
    path = elastica_run_file(tmp_path / "small.toml", uz=[0])
    path.write_text(path.read_text() + f'\n[execution]\nscheduler = "{cluster}"\n')
    plan = runfile.load(path)
    assert plan.scheduler == cluster
    path.write_text(path.read_text() + 'jobs = 3\n')
    with pytest.raises(runfile.RunFileError, match=r"\[execution\] jobs: unknown key"):
        runfile.load(path)


def test_distributed_is_imported_only_for_a_cluster(tmp_path):
    """--version, a one-process run and the read-only commands never import distributed."""
    code = ("import sys\nfrom click.testing import CliRunner\nfrom elastica_auto.cli import main\n"
            "r = CliRunner()\n"
            "assert r.invoke(main, ['--version']).exit_code == 0\n"
            f"assert r.invoke(main, ['run', 'rotating_arm', '--out', {str(tmp_path)!r}, '-j', '1',"
            " '--set', 'max_points=20', '--set', 'eps=0.25', '--set', 'P=pi^2/4']).exit_code == 0\n"
            f"assert r.invoke(main, ['show', {str(tmp_path / 'rotating_arm.h5')!r}])"
            ".exit_code == 0\n"
            "print('distributed' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


def test_workers_without_the_package_are_one_line(tmp_path, cli_exe):
    """A cluster whose worker finds another elastica_auto first on its path (here one that
    says it is version 0.0.0): exit 2, one line naming the worker, nothing written."""
    fake = tmp_path / "fake" / "elastica_auto"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text('__version__ = "0.0.0"\n')
    info = tmp_path / "scheduler.json"
    common = dict(cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                  start_new_session=True)
    procs = [subprocess.Popen([BIN / "dask", "scheduler", "--scheduler-file", info, "--port",
                               "0", "--host", "127.0.0.1", "--no-dashboard"], **common)]
    try:
        wait_for("the scheduler's file", info.is_file, procs[0])
        procs.append(subprocess.Popen(
            [BIN / "dask", "worker", "--scheduler-file", info, "--nworkers", "1", "--nthreads",
             "1", "--host", "127.0.0.1", "--no-dashboard"],
            env={**os.environ, "PYTHONPATH": str(tmp_path / "fake")}, **common))
        address = json.loads(info.read_text())["address"]
        proc = run_cli(cli_exe, "run", "rotating_arm", "--out", tmp_path / "out",
                       "--scheduler", address)
        assert proc.returncode == 2 and not (tmp_path / "out").exists()
        (line,) = proc.stderr.strip().splitlines()
        assert line.startswith("elastica-auto: error: the workers tcp://127.0.0.1:")
        assert line.endswith(f" of {address} run elastica-auto 0.0.0, this is "
                             f"{elastica_auto.__version__}")
    finally:
        for p in procs:
            os.killpg(p.pid, signal.SIGTERM)
        for p in procs:
            p.wait(timeout=30)


# -- the default run: this process at once, a local cluster joining in the background ----------

_WAITING = '''

import os as _os
import time as _time


def _wait_for_a_worker(p):
    """In the test's own process, with the flag file there: the first call in a branch
    waits until a worker of the background cluster has called rhs (so that it computes a
    branch); in a worker: say so. The numbers are the shipped module's."""
    if _os.getpid() != {main}:
        open({started!r}, "a").close()
    elif _os.path.exists({flag!r}) and not globals().get("_waited") and _in_a_branch():
        globals()["_waited"] = True
        deadline = _time.monotonic() + 120
        while not _os.path.exists({started!r}) and _time.monotonic() < deadline:
            _time.sleep(0.01)


def _in_a_branch():
    import sys
    frame = sys._getframe()
    while frame is not None and frame.f_code.co_name != "compute_branch":
        frame = frame.f_back
    return frame is not None
'''


def _waiting_elastica(path: Path, flag: Path, started: Path) -> Path:
    from helpers import ELASTICA
    head = "def rhs(s, y, p):\n"
    path.write_text(ELASTICA.replace(head, head + "    _wait_for_a_worker(p)\n")
                    + _WAITING.format(main=os.getpid(), flag=str(flag), started=str(started)))
    return path


def test_the_default_run_computes_here_and_on_a_background_cluster(tmp_path, monkeypatch):
    """jobs = 0 on two cores: this process starts on the first branch at once and a local
    cluster of one worker, started meanwhile (at once: `run.CLUSTER_PAYS` 0), computes the
    other (this process waits, in its first step, for the worker to start: else it could
    finish both first). The file is the one jobs = 1 writes, number for number, snap-back
    table (scanned on the worker) too."""
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution import runfile
    from elastica_auto.execution.run import execute
    monkeypatch.setattr(run_module, "CLUSTER_PAYS", 0.0)
    from helpers import elastica_run_file
    flag, started = tmp_path / "wait", tmp_path / "started"
    _waiting_elastica(tmp_path / "mine.py", flag, started)
    run = elastica_run_file(tmp_path / "two.toml", uz=[0], mirror=False)
    run.write_text(run.read_text().replace('"elastica_lever_arm"', '"mine.py"'))
    one = execute(runfile.load(run), tmp_path / "one", jobs=1)
    assert not started.exists()
    flag.touch()
    monkeypatch.setattr(run_module, "usable_cores", lambda: 2)
    both = execute(runfile.load(run), tmp_path / "both", jobs=0)
    assert [len(b.points) for b in both.branches] == [len(b.points) for b in one.branches]
    assert both.snaps and len(both.snaps) == len(one.snaps)
    _same_numbers(one.path, both.path)
    workers = [b.attrs["worker"] for b in BranchFile(both.path).branches]
    assert workers[0] == "local" and workers[1].startswith("inproc://")


def test_a_default_run_hands_fold_curves_to_its_background_cluster(tmp_path, monkeypatch):
    """A fold curve's problem is made of closures (`branches.codim2`), which pickle refuses;
    the background cluster is sent its tasks by value, as Dask sends them. Fold curves from
    the two folds of a waiting elastica (this process waits in its first branch until a
    worker has called rhs), jobs = 0 on two cores, the cluster started at once: a worker
    computes branches, and the file is the one jobs = 1 writes, number for number."""
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution import runfile
    from elastica_auto.execution.run import execute
    from helpers import elastica_run_file, fold_curves_file
    monkeypatch.setattr(run_module, "CLUSTER_PAYS", 0.0)
    flag, started = tmp_path / "wait", tmp_path / "started"
    _waiting_elastica(tmp_path / "mine.py", flag, started)
    arm = elastica_run_file(tmp_path / "arm.toml")
    arm.write_text(arm.read_text().replace('"elastica_lever_arm"', '"mine.py"'))
    folds = execute(runfile.load(arm), tmp_path, jobs=1).path
    curves = fold_curves_file(tmp_path / "curves.toml", "mine.py", folds)
    one = execute(runfile.load(curves), tmp_path / "one", jobs=1)
    flag.touch()
    monkeypatch.setattr(run_module, "usable_cores", lambda: 2)
    both = execute(runfile.load(curves), tmp_path / "both", jobs=0)
    assert started.exists() and len(both.branches) == len(one.branches) == 4
    _same_numbers(one.path, both.path)
    workers = [b.attrs["worker"] for b in BranchFile(both.path).branches]
    assert workers[0] == "local" and any(w.startswith("inproc://") for w in workers)


def test_a_default_run_shares_its_maps_enumerations_with_its_cluster(tmp_path, monkeypatch,
                                                                      rotating_arm):
    """A fold-curve run with ``map = true``, jobs = 0 on two cores, a stand-in worker up at
    once: the map's enumerations (one per region, `analysis.maps.region_counts`) are tasks
    shared with it, and the file, maps included, is the one jobs = 1 writes."""
    from elastica_auto.execution import cluster, runfile
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution.run import execute
    from helpers import WorkingBackground, fold_curves_file
    handed = []

    class Recording(WorkingBackground):
        def submit(self, tag, function, args):
            handed.append((tag[0], function.__name__))
            return super().submit(tag, function, args)

    curves = fold_curves_file(tmp_path / "curves.toml", "elastica_lever_arm",
                              rotating_arm.result.path, "map = true\n")
    one = execute(runfile.load(curves), tmp_path / "one", jobs=1)
    monkeypatch.setattr(run_module, "CLUSTER_PAYS", 0.0)
    monkeypatch.setattr(cluster, "Background", Recording)
    monkeypatch.setattr(run_module, "usable_cores", lambda: 2)
    both = execute(runfile.load(curves), tmp_path / "both", jobs=0)
    regions = sum(len(m.stable) for m in both.maps)
    assert regions >= 2 and ("task", "region_counts") in handed
    _same_numbers(one.path, both.path)


def test_a_task_that_does_not_pickle_stays_here_and_sends_nothing():
    """`Background.submit` of a task with an argument no pickler takes (a lock) answers
    False (the command computes it) and writes nothing to the helper, whose input stays a
    sequence of whole requests; a closure is sent, by value."""
    import io
    import pickle
    import threading
    import types

    import cloudpickle
    from elastica_auto.execution.cluster import Background
    pipe = io.BytesIO()
    bg = Background.__new__(Background)
    bg._pickle, bg._dumps, bg._lock = pickle, cloudpickle.dumps, threading.Lock()
    bg.proc = types.SimpleNamespace(stdin=pipe)
    assert not bg.submit(("task", 0), print, (threading.Lock(),))
    assert pipe.getvalue() == b""
    offset = 2.0
    assert bg.submit(("task", 1), lambda x: x + offset, (1.0,))
    tag, call, (function, *args) = pickle.loads(pipe.getvalue())
    assert tag == ("task", 1) and function(*args) == 3.0


def test_a_default_run_of_one_branch_starts_no_cluster(tmp_path, monkeypatch):
    """One branch (examples/bratu.toml) on two cores: computed here, no cluster started."""
    from elastica_auto.execution import cluster, runfile
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution.run import execute
    from helpers import EXAMPLES

    def refused(*args, **kwargs):
        raise AssertionError("a cluster was started for one branch")

    monkeypatch.setattr(cluster, "Background", refused)
    monkeypatch.setattr(cluster, "local", refused)
    monkeypatch.setattr(run_module, "usable_cores", lambda: 2)
    plan = runfile.load(EXAMPLES / "bratu.toml")
    assert len(plan.branches) == 1
    result = execute(plan, tmp_path, jobs=0)
    assert [b.worker for b in result.branches] == ["local"] and result.branches[0].end == "EP"


def test_the_default_run_s_cluster_starts_when_the_work_left_pays_for_it():
    """`Alongside` starts its cluster once the mean time of what this process finished,
    times what is left of that kind, or the time of the one in hand, exceeds ``pays``."""
    from elastica_auto.execution.run import Alongside
    started = []

    def make(pays):
        return Alongside(None, 1, lambda n, on: started.append(n) or _FakeBackground(1, on),
                          pays=pays)
    pool = make(3.0)
    assert not pool.started and not pool.background.ready.is_set() and started == []
    pool.spent["branch"] = [1.0, 2]                # 0.5 s each
    pool._consider("branch", 5)                    # 2.5 s left
    pool._consider("scan", 100)                    # none finished: nothing known
    pool._consider("branch", 1, running=2.9)       # the one in hand: 2.9 s so far
    pool._consider("branch", 1, running=1.6)
    assert not pool.started and started == []
    pool._consider("branch", 7)                    # 3.5 s left
    assert pool.started and pool.background.ready.is_set() and started == [1]
    pool._consider("branch", 7)
    assert started == [1]
    pool = make(3.0)
    pool._consider("task", 0, running=10.0)        # nothing left: no use
    assert not pool.started
    pool._consider("task", 1, running=3.1)
    assert pool.started
    make(0.0)
    assert started == [1, 1, 1]


@pytest.mark.parametrize("pays", [1e-9, math.inf])
def test_a_default_run_starts_its_cluster_only_if_it_pays(tmp_path, monkeypatch, pays):
    """Two branches on two cores (examples of the elastica): with `run.CLUSTER_PAYS` 1e-9
    the first branch, computed here, outlasts it at its first step with the other left: the
    cluster (a stand-in worker) is started before that branch is done, and computes the
    second; with inf it is never started. The branches are those jobs = 1 computes."""
    from elastica_auto.execution import cluster, runfile
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution.run import execute
    from helpers import WorkingBackground, elastica_run_file
    finished, at_start = [], []
    compute_here = run_module.compute_branch

    def computed(*args, **kwargs):
        out = compute_here(*args, **kwargs)
        finished.append(args[1])
        return out

    def background(n, on):
        if math.isinf(pays):
            raise AssertionError("a cluster was started that does not pay")
        at_start.append(list(finished))
        return WorkingBackground(n, on)

    monkeypatch.setattr(run_module, "CLUSTER_PAYS", pays)
    monkeypatch.setattr(cluster, "Background", background)
    monkeypatch.setattr(run_module, "usable_cores", lambda: 2)
    run = elastica_run_file(tmp_path / "two.toml", uz=[0], mirror=False)
    one = execute(runfile.load(run), tmp_path / "one", jobs=1)
    monkeypatch.setattr(run_module, "compute_branch", computed)
    both = execute(runfile.load(run), tmp_path / "both", jobs=0)
    assert [b.worker for b in both.branches] == (["local", "local"] if math.isinf(pays)
                                                 else ["local", "stand-in"])
    assert at_start == ([] if math.isinf(pays) else [[]])
    for a, b in zip(both.branches, one.branches):
        np.testing.assert_array_equal(a.column("psi"), b.column("psi"))


def test_a_one_branch_run_imports_only_what_it_uses(tmp_path):
    """`elastica-auto run examples/bratu.toml` with the default jobs: no cluster (nor its
    module), no distributed, no scipy.integrate (Bratu has no snap-back scan), no plotting."""
    from helpers import EXAMPLES, imported_by
    assert imported_by([(["run", EXAMPLES / "bratu.toml", "--out", tmp_path], 0)],
                       ["distributed", "dask", "elastica_auto.execution.cluster",
                        "scipy.integrate", "matplotlib", "plotly"]) == []
    assert (tmp_path / "bratu.h5").is_file()


class _FakeBackground:
    """A background cluster that is up at once with ``workers`` workers and computes
    nothing: with ``ends``, it ends as soon as it is handed a task (the task lost)."""

    def __init__(self, workers, on_result, ends=False):
        import threading
        self.workers, self.on_result, self.ends = workers, on_result, ends
        self.ready = threading.Event()
        self.ready.set()
        self.tasks = []

    def submit(self, tag, function, args):
        import threading
        self.tasks.append(tag)
        if self.ends:       # as the real one: from its own thread
            self.ready.clear()
            threading.Thread(target=self.on_result,
                             args=(None, False, "the local cluster ended")).start()
        return True

    def finish(self):
        self.ready.clear()

    def close(self, wait=0.0):
        self.ready.clear()


@pytest.mark.parametrize("workers, ends", [(0, False), (1, True)])
def test_the_default_run_computes_here_what_its_cluster_does_not(tmp_path, workers, ends):
    """A cluster that tells of no worker, or that ends with a branch and then never takes
    anything: this process computes every branch and every snap-back scan, and the run ends
    with the branches that jobs = 1 computes."""
    from elastica_auto.execution import runfile
    from elastica_auto.core.interrupts import Interruptions
    from elastica_auto.execution.run import RunResult, Alongside, start_job, execute
    from elastica_auto.analysis.snaps import scans
    from helpers import elastica_run_file
    run = elastica_run_file(tmp_path / "two.toml", uz=[0], mirror=False)
    one = execute(runfile.load(run), tmp_path / "one", jobs=1)
    plan = runfile.load(run)
    pool = Alongside(plan, 1, lambda n, on: _FakeBackground(workers, on, ends))
    first = [start_job(plan, spec) for spec in plan.branches]
    result = RunResult(None, [], 0.0)
    with Interruptions() as signals:
        assert not pool.run(first, result.branches, lambda: None, None, None, signals.stop)
        assert pool.wait_for_scans(signals.stop)
    assert [b.worker for b in result.branches] == ["local", "local"]
    # a cluster up from the start is handed the plan's first branch (the next in plan order)
    assert pool.background.tasks == ([("branch", (1, 0))] if ends else [])
    assert len(pool.scans) == len({k for b in result.branches
                                   for k in scans(plan.problem, b)}) > 0
    for a, b in zip(result.branches, one.branches):
        np.testing.assert_array_equal(a.column("psi"), b.column("psi"))


@pytest.mark.parametrize("cluster", ["works", "fails", "ends"])
def test_a_default_run_shares_its_other_tasks_with_its_cluster(cluster):
    """Alongside.map (the damped model's landings): each task is taken from the front of
    the list by this process or by an idle worker of the cluster, the results come back in
    order and each is reported once; a task whose worker dies, or that a cluster that ends
    took with it, is computed here."""
    import threading
    from elastica_auto.execution.run import Alongside
    from helpers import WorkingBackground
    background = {"works": lambda n, on: WorkingBackground(n, on),
                  "fails": lambda n, on: WorkingBackground(n, on, fails=True),
                  "ends": lambda n, on: _FakeBackground(1, on, ends=True)}[cluster]
    pool = Alongside(None, 1, background)
    reported = []
    got = pool.map(threading.get_ident, [()] * 5, lambda i, r: reported.append((i, r)))
    assert sorted(i for i, _ in reported) == list(range(5))
    assert dict(reported) == dict(enumerate(got))
    here = threading.get_ident()
    assert pool.background.tasks[0] == ("task", 0)     # the idle worker takes the first
    assert here in got
    if cluster == "works":
        assert got[0] != here
    else:
        assert got == [here] * 5


def test_a_branch_of_an_earlier_level_is_dropped_when_it_comes_back():
    """A worker's branch for a job of an earlier `Alongside.run` (left out while it computed
    it, and so never waited for) is not taken as the current run's job of the same number;
    the current run's own is."""
    from elastica_auto.execution.run import Alongside
    pool = Alongside(None, 1, lambda n, on: _FakeBackground(1, on))
    pool.jobs, pool.level, done = ["job 0 of level 3"], 3, {}
    pool._take((("branch", (2, 0)), True, ("a level-2 branch", "inproc://w")), done)
    assert done == {}

    class Branch:
        worker = None
    pool._take((("branch", (3, 0)), True, (Branch(), "inproc://w")), done)
    assert list(done) == [0] and done[0].worker == "inproc://w"


def test_a_scan_the_cluster_finished_is_taken_not_computed_again():
    """A scan whose result the cluster delivered (in the queue, no longer asked for) while
    this process was busy is taken by `Alongside.wait_for_scans`, not left for
    `snap_targets` to compute again."""
    import threading
    from elastica_auto.execution.run import Alongside
    pool = Alongside(None, 1, lambda n, on: _FakeBackground(1, on))
    key, params = (("P", 2.0),), {"P": 2.0}
    pool.pending_params[key] = params
    pool.asked.add(key)
    pool._on_result(("scan", key), True, (["an equilibrium"], "inproc://w"))
    assert not pool.asked
    assert pool.wait_for_scans(threading.Event())
    assert pool.scans == {key: (params, ["an equilibrium"])}


@pytest.mark.parametrize("wanted, fails, mirror", [("all", False, False), ("first", False, False),
                                                   ("all", True, False), ("all", False, True)])
def test_the_scans_of_a_branch_computed_here_go_to_an_idle_worker_while_it_is_computed(
        tmp_path, monkeypatch, wanted, fails, mirror):
    """A branch continued in this process, a stand-in worker idle from the start: the scans
    at the folds that end a stable segment (by the direct count) are handed to the worker
    as each fold is found, before the branch is done, and `Alongside.wait_for_scans` ends
    with each scan the labelled branch wants (`analysis.snaps.scans`, at its parameters)
    as `enumerate_equilibria` gives it, none computed here; guesses the branch does not
    want (``first``: it wants only its first) are not kept, nor computed here. A worker that
    dies with each task (``fails``): the run goes on, and the scans this process keeps are
    the right ones (`snap_targets` computes the others). With ``mirror`` (the images of
    scans sent are made from them): no guess is made at such an image, each guess is kept."""
    import threading

    from elastica_auto.analysis import snaps
    from elastica_auto.core.interrupts import Interruptions
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution import runfile
    from elastica_auto.execution.run import RunResult, Alongside, start_job
    from helpers import WorkingBackground, elastica_run_file
    computing, handed, where = threading.Event(), [], []
    compute, enumerate_ = run_module.compute_branch, run_module.enumerate_equilibria

    def computed(*args):
        computing.set()
        try:
            return compute(*args)
        finally:
            computing.clear()

    def enumerated(problem, params):
        where.append(threading.current_thread() is threading.main_thread())
        return enumerate_(problem, params)

    class Recording(WorkingBackground):
        def submit(self, tag, function, args):
            if tag[0] == "branch":      # refused (as a task that does not pickle): the
                return False            # branch is computed here
            handed.append((tag[0], computing.is_set()))
            return super().submit(tag, function, args)

    def wanted_scans(problem, br):
        out = snaps.scans(problem, br)
        return out if wanted == "all" else dict(list(out.items())[:1])

    monkeypatch.setattr(run_module, "compute_branch", computed)
    monkeypatch.setattr(run_module, "enumerate_equilibria", enumerated)
    monkeypatch.setattr(run_module, "scans", wanted_scans)
    plan = runfile.load(elastica_run_file(tmp_path / "one.toml", eps="0.5", P="9*pi^2/4",
                                          directions="forward", bounds=("-6*pi", "6*pi"),
                                          mirror=mirror))
    pool = Alongside(plan, 1, lambda n, on: Recording(n, on, fails=fails))
    result = RunResult(None, [], 0.0)
    with Interruptions() as signals:
        assert not pool.run([start_job(plan, spec) for spec in plan.branches],
                            result.branches, lambda: None, None, None, signals.stop)
        assert pool.wait_for_scans(signals.stop)
    (br,) = result.branches
    want = wanted_scans(plan.problem, br)
    guessed = [t for t in handed if t[0] == "guess"]
    assert len(snaps.scans(plan.problem, br)) >= 2 and len(guessed) >= len(want) // (1 + mirror)
    assert all(during for _, during in guessed)
    assert fails or ("scan", False) not in handed     # (failed guesses are sent again)
    if fails:
        assert pool.scans.keys() <= want.keys()
    elif mirror:
        assert len(pool.scans) == len(guessed) < len(want) and not any(where)
    else:
        assert pool.scans.keys() == want.keys() and not any(where)
    for key in pool.scans:
        params = want[key]
        assert pool.scans[key][0] == params
        got, here = pool.scans[key][1], enumerate_(plan.problem, params)
        assert [(e.k, e.index, e.ordinates) for e in got] == [
            (e.k, e.index, e.ordinates) for e in here]
        for a, b in zip(got, here):
            np.testing.assert_array_equal(a.state.y, b.state.y)


def test_a_default_run_whose_scans_were_guessed_writes_the_file_one_process_writes(
        tmp_path, monkeypatch):
    """The rotating arm at eps = 0.5, P = 9 pi^2/4 both ways (the second branch the first's
    mirror image, whose scans `snap_targets` makes from the first's), jobs = 0, a stand-in
    worker that takes no branch: every scan it computes was guessed, and the file, snap-back
    table included, is the one jobs = 1 writes."""
    from elastica_auto.execution import cluster, runfile
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution.run import execute
    from helpers import WorkingBackground, elastica_run_file
    handed = []

    class Guessing(WorkingBackground):
        def submit(self, tag, function, args):
            if tag[0] == "branch":
                return False
            handed.append(tag[0])
            return super().submit(tag, function, args)

    path = elastica_run_file(tmp_path / "arm.toml", eps="0.5", P="9*pi^2/4",
                             bounds=("-6*pi", "6*pi"))
    one = execute(runfile.load(path), tmp_path / "one", jobs=1)
    monkeypatch.setattr(run_module, "CLUSTER_PAYS", 0.0)
    monkeypatch.setattr(cluster, "Background", Guessing)
    monkeypatch.setattr(run_module, "usable_cores", lambda: 2)
    both = execute(runfile.load(path), tmp_path / "both", jobs=0)
    assert len(one.snaps) > 0 and "guess" in handed and "scan" not in handed
    _same_numbers(one.path, both.path)


@pytest.mark.parametrize("same", [True, False])
def test_a_guessed_scan_is_kept_only_at_the_parameters_the_branch_wants(monkeypatch, same):
    """A scan guessed at parameters of the same key (a periodic copy) but not those the
    saved branch wants is not given as its scan: that one is sent; at the same parameters
    the guess's result is kept."""
    import types

    from elastica_auto.execution import run as run_module
    from elastica_auto.execution.run import Alongside
    key, wanted = (("psi", 1.0),), {"psi": 1.0}
    guessed = wanted if same else {"psi": 1.0 + 2 * np.pi}
    monkeypatch.setattr(run_module, "scans", lambda problem, br: {key: wanted})
    monkeypatch.setattr(run_module, "copy_key", lambda problem, name, params: key)
    plan = types.SimpleNamespace(problem=None, options=types.SimpleNamespace(mirror=False))
    pool = Alongside(plan, 1, lambda n, on: _FakeBackground(0, on))
    br = types.SimpleNamespace(parameter="psi")
    pool.guesses[key] = (br, guessed, key)
    pool.spare[key] = ["the guess's equilibria"]
    pool._scan(br)
    if same:
        assert pool.scans == {key: (wanted, ["the guess's equilibria"])} and not pool.unsent
    else:
        assert pool.scans == {} and pool.unsent == [(key, wanted)]
    assert not pool.guesses and not pool.spare


@pytest.mark.parametrize("held", [0, 1])
def test_scans_waiting_for_a_busy_worker_are_computed_here_meanwhile(tmp_path, monkeypatch,
                                                                      held):
    """Two branches, one worker that holds the branch it took (``held``: the plan's first,
    or its second) until this process has computed every scan of the other, here, while
    it waits: the guesses of a branch computed here that cannot be saved yet (``held =
    0``: the branch before it is out), or the wanted scans of one saved (``held = 1``).
    Without that this process waits and the worker is released only by its time-out. The
    scans kept are those `enumerate_equilibria` gives (at the parameters of the first
    branch to want each key), each computed once, and the branches those of jobs = 1."""
    import threading

    from elastica_auto.analysis import snaps
    from elastica_auto.core.interrupts import Interruptions
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution import runfile
    from elastica_auto.execution.run import RunResult, Alongside, execute, start_job
    from helpers import WorkingBackground, elastica_run_file
    # two arm lengths: no scan key of one branch is the other's (as both directions' are,
    # by the mirror image), so each guess computed here is the scan its branch keeps
    path = elastica_run_file(tmp_path / "two.toml", eps="0.5", P="9*pi^2/4",
                             directions="forward", bounds=("-6*pi", "6*pi"), mirror=False)
    path.write_text(path.read_text().replace("eps = '0.5'", "eps = [0.5, 0.45]"))
    one = execute(runfile.load(path), tmp_path / "one", jobs=1)
    plan = runfile.load(path)
    mine = snaps.scans(plan.problem, one.branches[1 - held])
    here, released, timed_out, computed = [], threading.Event(), [], []
    enumerate_ = run_module.enumerate_equilibria

    def enumerated(problem, params):
        out = enumerate_(problem, params)
        computed.append(scan_key(params))
        if threading.current_thread() is threading.main_thread() and not released.is_set():
            here.append(scan_key(params))
            if set(here) >= mine.keys():
                released.set()
        return out

    def scan_key(params):
        return snaps.scan_key(plan.problem, "psi", params)

    def holding(*args):
        timed_out.append(not released.wait(60))
        return run_module.compute_branch(*args)

    class Holding(WorkingBackground):
        refused = held == 1          # the first branch refused: this process takes it

        def submit(self, tag, function, args):
            if tag[0] == "branch":
                if self.refused or tag[1][1] != held:
                    self.refused = False
                    return False
                return super().submit(tag, holding, args)
            return super().submit(tag, function, args)

    monkeypatch.setattr(run_module, "enumerate_equilibria", enumerated)
    pool = Alongside(plan, 1, lambda n, on: Holding(n, on))
    result = RunResult(None, [], 0.0)
    with Interruptions() as signals:
        assert not pool.run([start_job(plan, spec) for spec in plan.branches],
                            result.branches, lambda: None, None, None, signals.stop)
        assert pool.wait_for_scans(signals.stop)
    assert len(mine) >= 2 and timed_out == [False]
    assert [b.worker for b in result.branches][held] == "stand-in"
    for a, b in zip(result.branches, one.branches):
        np.testing.assert_array_equal(a.column("psi"), b.column("psi"))
    assert mine.keys() <= pool.scans.keys()
    # each computed once, by whoever: a guess computed here is kept, not computed again
    assert not mine.keys() & snaps.scans(plan.problem, one.branches[held]).keys()
    assert all(computed.count(key) == 1 for key in mine)
    for key in mine:    # at the parameters of the first branch to want the key
        params, got = pool.scans[key]
        again = enumerate_(plan.problem, params)
        assert [(e.k, e.index, e.ordinates) for e in got] == [
            (e.k, e.index, e.ordinates) for e in again]


# -- faults: a cluster that loses its workers, tasks that raise, addresses that are none -------

def _cells(path) -> dict:
    """The branches of a branch file by their cell (start, parameter values, direction)."""
    return {b.attrs["cell"]: b for b in BranchFile(path).branches}


@pytest.fixture(scope="module")
def plain_in_one_process(tmp_path_factory, cli_exe):
    """rotating_arm with the module `_rotating_arm` writes (the hand-written elastica, whose
    numbers are the shipped energy-first module's to rounding only), in one process."""
    here = tmp_path_factory.mktemp("plain_one_process")
    assert run_cli(cli_exe, "run", _rotating_arm(here), "--out", here / "out",
                   "-j", "1").returncode == 0
    return here / "out" / "rotating_arm.h5"


@pytest.mark.parametrize("killed", ["workers", "scheduler"])
def test_a_run_whose_workers_all_die_ends_and_resume_completes_it(tmp_path, cli_exe,
                                                                  plain_in_one_process, killed):
    """hostile H5: every worker of the run's scheduler killed (with their nannies, as a batch
    system's walltime ends them), or the scheduler, once a branch is saved and another is
    held in a step on a worker. With --worker-timeout 1 the run ends with one line and exit
    status EXIT_CLUSTER_LOST (at once for a scheduler gone); its file has the finished
    branches, value for value those one process computes (a later one that finished first
    before the earlier ones), and after them every other cell of the plan, ending MX as not
    computed. ``--resume`` (here in one process)
    computes those, and the file is then the one-process run's, cell for cell."""
    from elastica_auto.core.errors import EXIT_CLUSTER_LOST
    from elastica_auto.execution.jobs import NOT_COMPUTED
    address, procs = _start_cluster(tmp_path / "cluster")
    held, out = tmp_path / "held", tmp_path / "out"
    run = _rotating_arm(tmp_path, hold=('p["eps"] == 0.5 and p["P"] > 20 and abs(p["psi"]) > 1',
                                        held))
    proc = subprocess.Popen([cli_exe, "run", run, "--out", out, "--scheduler", address,
                             "--worker-timeout", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for("the first branch saved", (out / "rotating_arm.h5").exists, proc)
        wait_for("a branch held in a step on a worker",
                 lambda: held.is_file() and held.read_text(), proc)
        victim = procs[1] if killed == "workers" else procs[0]  # workers: with their nannies
        os.killpg(victim.pid, signal.SIGKILL)
        victim.wait(timeout=30)
        _, err = proc.communicate(timeout=300)
    finally:   # a run that did not end (the defect) is not left behind
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        _stop_cluster(procs)
    assert proc.returncode == EXIT_CLUSTER_LOST and "Traceback" not in err, err
    line = err.strip().splitlines()[-1]
    saved = BranchFile(out / "rotating_arm.h5").branches
    missing = [b for b in saved if b.attrs["message"] == NOT_COMPUTED]
    why = ("has had no worker for 1 s (worker_timeout)" if killed == "workers" else
           "went away (the connection to it closed)")
    assert line == (f"elastica-auto: error: the Dask scheduler at {address} {why}: "
                    f"{len(saved) - len(missing)} branches saved to "
                    f"{out / 'rotating_arm.h5'}, {len(missing)} not computed (run it again "
                    "with --resume to compute them)")
    one = _cells(plain_in_one_process)      # the same module in one process
    assert {b.attrs["cell"] for b in saved} == one.keys() and len(saved) == len(one)
    assert saved[-len(missing):] == missing and 1 <= len(missing) < len(saved)
    assert all(b.attrs["end"] == "MX" for b in missing)
    for b in saved[:-len(missing)]:
        _same_cell(one[b.attrs["cell"]], b, saved)
    resumed = run_cli(cli_exe, "run", run, "--out", out, "-j", "1", "--resume")
    assert resumed.returncode == 0, resumed.stderr
    again = _cells(out / "rotating_arm.h5")
    assert again.keys() == one.keys() and len(BranchFile(out / "rotating_arm.h5").branches) == 8
    branches = BranchFile(out / "rotating_arm.h5").branches
    for cell, a in one.items():
        b = again[cell]
        assert b.attrs["end"] == a.attrs["end"] == "EP"
        _same_cell(a, b, branches)


def _same_cell(a, b, file_branches):
    """Branch ``b`` (of a file whose branches are ``file_branches``) is the one-process run's
    ``a``, column for column, but for where it stands in its file: ``branch`` is its place
    there, and ``label`` numbers the labels through the file. A later cell that finished on
    the other worker before the cluster was lost is saved before the earlier ones not
    computed (nothing finished is lost), and a resume keeps the branches saved and adds the
    others after them, so the place and the labels' numbers can differ from one process's;
    the labels' kinds (``type``) are compared, and the place is the file's own. A branch
    that one run mirrored from its pair (``worker`` "mirror of ...") and the other computed
    (its pair not computed in the same run: a resume after the loss) is the same to rounding
    only (1e-15 seen): its numbers and profiles are compared to 1e-12 of each one's size
    there, every other column exactly."""
    rounding = len({x.attrs["worker"].startswith("mirror of") for x in (a, b)}) == 2
    pairs = [(name, col, b.columns[name]) for name, col in a.columns.items()
             if name not in ("branch", "label")]
    for name, mine, theirs in pairs + [("profiles", a.profiles, b.profiles)]:
        if rounding and np.asarray(mine).dtype.kind == "f":
            scale = np.nanmax(np.abs(mine), initial=1.0)   # NaN: a row without a value
            np.testing.assert_allclose(theirs, mine, rtol=0, atol=1e-12 * scale, err_msg=name)
        else:
            np.testing.assert_array_equal(mine, theirs, err_msg=name)
    place = next(k for k, x in enumerate(file_branches) if x.attrs["cell"] == b.attrs["cell"])
    assert set(b.columns["branch"]) == {place + 1}
    assert [bool(x) for x in b.columns["label"]] == [bool(x) for x in a.columns["label"]]


def test_a_result_lost_with_its_worker_does_not_hold_the_run(tmp_path, monkeypatch):
    """hostile H5 (as reproduced: "Couldn't gather 1 keys, rescheduling", then no end): a
    branch that finished on a worker, whose workers all die as the command fetches it (here
    killed just before its fetch). Dask computes it again, with no worker to do it: the
    fetch no longer waits for ever, and the run ends after worker_timeout with the branches
    it had (the first fetched at least; which branch finishes first is the cluster's
    choice, and a mirror image whose turn comes after the cluster was lost is not made), the
    others not computed."""
    import threading

    from elastica_auto.core.errors import ClusterLost
    from elastica_auto.execution import cluster, runfile
    from elastica_auto.execution.jobs import NOT_COMPUTED
    from elastica_auto.execution.run import execute
    address, procs = _start_cluster(tmp_path / "cluster")
    fetch, fetches, ended = cluster.fetched, [], []

    def fetched(future):
        fetches.append(future.key)
        if len(fetches) == 2:       # a second branch finished: its workers die first
            os.killpg(procs[1].pid, signal.SIGKILL)
            procs[1].wait(timeout=30)
        return fetch(future)

    def run():
        try:
            execute(runfile.load(ROTATING_ARM), tmp_path / "out", scheduler=address,
                    worker_timeout=1.0)
        except ClusterLost as exc:
            ended.append(exc)

    monkeypatch.setattr(cluster, "fetched", fetched)
    thread = threading.Thread(target=run, daemon=True)   # a hung run fails the test
    try:
        thread.start()
        thread.join(300)
    finally:
        _stop_cluster(procs)
    assert not thread.is_alive() and len(ended) == 1
    assert "has had no worker for 1 s (worker_timeout)" in str(ended[0])
    saved = BranchFile(tmp_path / "out" / "rotating_arm.h5").branches
    # the branch fetched first (before the kill: its key elastica-branch-K-...) and any
    # other that finished before the workers died are whole; the rest, one at least, not
    # computed
    ends = [b.attrs["end"] for b in saved]
    first = int(str(fetches[0]).split("-")[2])
    assert len(saved) == 8 and ends[first - 1] == "EP" and "MX" in ends
    assert all((b.attrs["end"], b.attrs["message"]) == ("MX", NOT_COMPUTED)
               for b in saved if b.attrs["end"] != "EP")


@pytest.mark.parametrize("address", ["notanaddress", "tls://127.0.0.1:1", "inproc://x"])
@pytest.mark.parametrize("where", ["option", "run file"])
def test_a_malformed_scheduler_address_is_one_line(tmp_path, cli_exe, address, where):
    """hostile M3: a scheduler address no Dask client can use (no port; TLS without
    certificates in Dask's configuration; an in-process address), given by --scheduler or
    by the run file's [execution] scheduler: exit 2, one line naming it, nothing written
    (it was a traceback, then a 20 s wait at exit)."""
    from helpers import elastica_run_file
    run = elastica_run_file(tmp_path / "small.toml", uz=[0])
    args = ["--scheduler", address]
    if where == "run file":
        run.write_text(run.read_text() + f'\n[execution]\nscheduler = "{address}"\n')
        args = []
    proc = run_cli(cli_exe, "run", run, "--out", tmp_path / "out", *args)
    assert proc.returncode == 2 and not (tmp_path / "out").exists()
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith(f"elastica-auto: error: {address!r} is not a Dask scheduler's "
                           "address (")
    assert line.endswith("); expected tcp://HOST:PORT")


def test_an_empty_scheduler_address_is_refused(tmp_path, cli_exe):
    """hostile L16: ``--scheduler ""`` (and ``scheduler = ""`` in the run file) is refused
    with one line, exit 2, nothing written: it ran on this machine without a word."""
    from helpers import elastica_run_file
    run = elastica_run_file(tmp_path / "small.toml", uz=[0])
    proc = run_cli(cli_exe, "run", run, "--out", tmp_path / "out", "--scheduler", "")
    assert proc.returncode == 2 and not (tmp_path / "out").exists()
    assert proc.stderr.strip().splitlines() == [
        "elastica-auto: error: --scheduler: an empty address; give tcp://HOST:PORT, or leave "
        "the option out to compute on this machine"]
    run.write_text(run.read_text() + '\n[execution]\nscheduler = " "\n')
    proc = run_cli(cli_exe, "run", run, "--out", tmp_path / "out")
    assert proc.returncode == 2 and not (tmp_path / "out").exists()
    assert proc.stderr.strip().splitlines() == [
        f"elastica-auto: error: {run}: [execution] scheduler: an empty address; give "
        "tcp://HOST:PORT, or leave the key out to compute on this machine"]


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", '"abc"'])
def test_worker_timeout_is_a_positive_number_of_seconds(tmp_path, cli_exe, value):
    """--worker-timeout and [execution] worker_timeout: a positive (finite) number of
    seconds, else one line and exit 2."""
    from elastica_auto.execution import runfile
    from helpers import elastica_run_file
    run = elastica_run_file(tmp_path / "small.toml", uz=[0])
    text = run.read_text()
    run.write_text(text + "\n[execution]\nworker_timeout = 30\n")
    assert runfile.load(run).worker_timeout == 30.0
    run.write_text(text + f"\n[execution]\nworker_timeout = {value}\n")
    with pytest.raises(runfile.RunFileError, match=r"\[execution\] worker_timeout: "):
        runfile.load(run)
    if value == '"abc"':
        return
    run.write_text(text)
    proc = run_cli(cli_exe, "run", run, "--out", tmp_path / "out", "--worker-timeout", value)
    assert proc.returncode == 2 and not (tmp_path / "out").exists()
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_jobs_are_capped_at_the_usable_cores(tmp_path, monkeypatch):
    """hostile L6: ``jobs = 12`` on a run with switch (examples/nonlinear_eigenvalue.toml,
    whose branches are not known in advance) started 12 worker processes whatever the
    cores; with two usable cores the local cluster has two workers (threads here)."""
    from elastica_auto.execution import cluster, runfile
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution.run import execute
    from helpers import EXAMPLES
    started, local = [], cluster.local

    def recorded(workers, threads=False):
        started.append(workers)
        return local(workers, threads=True)

    monkeypatch.setattr(cluster, "local", recorded)
    monkeypatch.setattr(run_module, "usable_cores", lambda: 2)
    plan = runfile.load(EXAMPLES / "nonlinear_eigenvalue.toml")
    assert plan.switch_count
    result = execute(plan, tmp_path, jobs=12)
    assert started == [2] and len(result.branches) > 2


def test_jobs_above_the_usable_cores_are_said_to_be_capped(tmp_path, cli_exe):
    """hostile L6: the command says so when --jobs asks for more workers than the cores this
    process may run on (its CPU affinity, read here independently)."""
    from helpers import elastica_run_file
    cores = len(os.sched_getaffinity(0))
    run = elastica_run_file(tmp_path / "small.toml", uz=[0], mirror=False)
    proc = run_cli(cli_exe, "run", run, "--out", tmp_path / "out", "-j", cores + 1)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines()[0] == (
        f"note: --jobs {cores + 1}: this process may use {cores} cores; at most {cores} worker "
        "processes")
    workers = {b.attrs["worker"] for b in BranchFile(tmp_path / "out" / "small.h5").branches}
    assert len(workers) <= cores


_ON_WORKERS_ONLY = '''

_shooting = shooting


def shooting(p):
    """The shipped hook in the command's process; elsewhere (a worker) it raises."""
    import os
    if os.environ.get("ELASTICA_TEST_COMMAND") != "1":
        raise RuntimeError("shooting is refused on this worker")
    return _shooting(p)
'''


def test_a_task_that_raises_on_a_worker_is_said_and_computed_here(cluster, tmp_path, cli_exe):
    """issue 45 item 3: the enumerations of a fold-curve run's stability map (``map =
    true``) are tasks of the --scheduler run's workers, and the module's shooting hook
    raises there (not in the command's process: an environment variable only the command
    has). Each is computed in the command's process, and the run says so, with the
    exception and where it was raised; the file, maps included, is the one-process run's."""
    from helpers import ELASTICA, elastica_run_file, fold_curves_file
    (tmp_path / "mine.py").write_text(ELASTICA + _ON_WORKERS_ONLY)
    env = {**os.environ, "ELASTICA_TEST_COMMAND": "1"}

    def cli(run, *args):
        return subprocess.run([cli_exe, "run", run, *map(str, args)], capture_output=True,
                              text=True, timeout=300, env=env)
    arm = elastica_run_file(tmp_path / "arm.toml")
    arm.write_text(arm.read_text().replace('"elastica_lever_arm"', '"mine.py"'))
    assert cli(arm, "--out", tmp_path, "-j", "1").returncode == 0
    curves = fold_curves_file(tmp_path / "curves.toml", "mine.py", tmp_path / "arm.h5",
                              "map = true\n")
    one = cli(curves, "--out", tmp_path / "one", "-j", "1")
    assert one.returncode == 0 and "warning" not in one.stdout, one.stdout + one.stderr
    there = cli(curves, "--out", tmp_path / "there", "--scheduler", cluster)
    assert there.returncode == 0, there.stderr
    said = [w for w in there.stdout.splitlines() if w.startswith("warning: ")]
    assert said and all(re.fullmatch(
        r"warning: task \d+ of \d+ \(region_counts\) raised on a worker: RuntimeError: "
        r"shooting is refused on this worker \(mine\.py:\d+ in shooting\); computed here "
        r"instead", w) for w in said), said
    assert BranchFile(tmp_path / "one" / "curves.h5").maps
    _same_numbers(tmp_path / "one" / "curves.h5", tmp_path / "there" / "curves.h5")


def test_tasks_whose_worker_died_are_computed_here_quietly_and_raising_ones_are_said(tmp_path):
    """issue 45 item 3, `cluster.map_tasks` on a local cluster that gives a task up at its
    worker's first death (allowed-failures 0): a task that kills its worker (and only a
    worker: not this process) is computed here without a word; one that raises on a worker
    only is computed here, and a warning gives the exception and the worker's frame."""
    import dask
    import distributed  # noqa: F401  (its configuration read before a value of it is set)

    from elastica_auto.execution import cluster
    here = os.getpid()

    def dies(pid):
        if os.getpid() != pid:
            os.kill(os.getpid(), signal.SIGKILL)
        return "here"

    def raises(pid):
        if os.getpid() != pid:
            raise ValueError("refused on a worker")
        return "here"

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        client = cluster.local(1)
    try:
        warnings = []
        assert cluster.map_tasks(client, dies, [(here,)], lambda i, r: None, warnings) == ["here"]
        assert warnings == []
        client.wait_for_workers(1, timeout=60)          # the nanny's new worker
        assert cluster.map_tasks(client, raises, [(here,), (here,)], lambda i, r: None,
                                 warnings) == ["here", "here"]
    finally:
        cluster.close(client)
    assert len(warnings) == 2 and all(re.fullmatch(
        r"task \d of 2 \(raises\) raised on a worker: ValueError: refused on a worker "
        r"\(\S+:\d+ in raises\); computed here instead", w) for w in warnings)


def test_a_branch_task_that_raises_ends_its_branch_with_the_exception(tmp_path, monkeypatch):
    """issue 45 item 3: a branch task that raises on a worker (here `compute_branch` raising
    outside the continuation, in the worker threads of a local cluster only) ends its
    branch MX with the exception in its message and its diagnostics, the worker's frames
    among them; the other branches are computed."""
    import threading

    from elastica_auto.execution import cluster, jobs, runfile
    from elastica_auto.execution import run as run_module
    from elastica_auto.execution.run import execute
    from helpers import elastica_run_file
    compute, local = jobs.compute_branch, cluster.local

    def computed(plan, k, job, *args):
        if threading.current_thread() is not threading.main_thread() and job.spec.direction < 0:
            raise TypeError("an engine bug on a worker")
        return compute(plan, k, job, *args)

    monkeypatch.setattr(jobs, "compute_branch", computed)
    monkeypatch.setattr(cluster, "local", lambda workers, threads=False: local(workers, True))
    monkeypatch.setattr(run_module, "usable_cores", lambda: 2)
    plan = runfile.load(elastica_run_file(tmp_path / "two.toml", uz=[0], mirror=False))
    result = execute(plan, tmp_path / "out", jobs=2)
    (good, bad) = BranchFile(result.path).branches
    assert good.attrs["end"] == "EP"
    assert bad.attrs["end"] == "MX" and re.fullmatch(
        r"raised on a worker: TypeError: an engine bug on a worker \(test_cluster\.py:\d+ in "
        r"computed\)", bad.attrs["message"])
    diagnostics = json.loads(bad.attrs["diagnostics"])
    assert diagnostics["exception"] == "TypeError"
    assert diagnostics["error"] == "an engine bug on a worker"
    assert diagnostics["traceback"][-1] == diagnostics["where"]
    assert any(f.endswith(" in _task") for f in diagnostics["traceback"])


def test_a_default_run_s_task_that_raises_on_its_cluster_is_said_and_computed_here(tmp_path):
    """issue 45 item 3, the default run's background cluster (`cluster.Background`, its
    worker a thread of the helper process): of two tasks of `Alongside.map`, this process
    takes one and waits until the worker has taken the other, which raises there (only
    outside this process). Both results are this process's, and a warning names the
    worker's exception."""
    from elastica_auto.execution.cluster import Background
    from elastica_auto.execution.run import Alongside
    here, tried = os.getpid(), tmp_path / "tried"

    def work(i):
        import os
        import time
        if os.getpid() != here:
            open(tried, "a").close()
            raise RuntimeError("refused outside the command")
        deadline = time.monotonic() + 120
        while not os.path.exists(tried) and time.monotonic() < deadline:
            time.sleep(0.01)
        return i, os.getpid()

    pool = Alongside(None, 1, Background)
    try:
        got = pool.map(work, [(0,), (1,)], lambda i, r: None)
    finally:
        pool.background.close()
    assert tried.exists() and got == [(0, here), (1, here)]
    (line,) = pool.warnings
    assert re.fullmatch(r"task [12] of 2 \(work\) raised on a worker: RuntimeError: refused "
                        r"outside the command \(\S+:\d+ in work\); computed "
                        r"here instead", line), line


@pytest.mark.parametrize("kind", ["scan", "guess"])
def test_a_scan_that_raises_on_the_default_run_s_cluster_is_said_and_not_sent_again(
        monkeypatch, kind):
    """issue 45 item 3: a snap-back scan (wanted, or guessed) that raised on the default
    run's cluster is a warning naming the exception, and is not sent to the cluster again
    when a branch wants it (`snap_targets` computes it here); one lost with its worker is
    said nothing of."""
    import types

    from elastica_auto.execution import run as run_module
    from elastica_auto.execution.jobs import TaskFailure
    from elastica_auto.execution.run import Alongside
    key, params = (("psi", 1.0),), {"psi": 1.0}
    monkeypatch.setattr(run_module, "scans", lambda problem, br: {key: params})
    monkeypatch.setattr(run_module, "copy_key", lambda problem, name, params: key)
    plan = types.SimpleNamespace(problem=None, options=types.SimpleNamespace(mirror=False))
    raised = TaskFailure("RuntimeError", "no shooting here", traceback=("mine.py:3 in shooting",))
    lost = TaskFailure("KilledWorker", "the worker died", lost=True)
    pools = {}
    for failure in (lost, raised):
        pool = pools[failure.lost] = Alongside(plan, 1, lambda n, on: _FakeBackground(0, on))
        if kind == "scan":
            pool.pending_params[key] = params
        else:
            pool.guesses[key] = (None, params, key)
        pool._take(((kind, key), False, failure), {})
        pool._scan(types.SimpleNamespace(parameter="psi"))       # a branch that wants it
    assert pools[True].warnings == [] and pools[True].unsent == [(key, params)]
    assert pools[False].warnings == [
        "the snap-back scan at psi=1 raised on a worker: RuntimeError: no shooting here "
        "(mine.py:3 in shooting); computed here where the run needs it"]
    assert pools[False].unsent == [] and key not in pools[False].scans


def test_a_task_ended_by_a_closing_client_is_not_reported_at_exit():
    """A client closed while it gathers ends its waits with Dask's AllExit, and asyncio reports
    each such task whose exception nobody read ("Task exception was never retrieved", with a
    traceback) when it is collected, which can be after a run's last line (a lost cluster's
    exit status 6 came with that traceback once in the suite). Made here as asyncio makes it:
    a task that raised AllExit, collected unread. After `cluster.quiet_all_exit` (which
    `cluster.close` calls) no report reaches stderr; a task that raised anything else is
    still reported."""
    import textwrap
    code = textwrap.dedent("""
        import asyncio, gc, sys
        from distributed.client import AllExit
        from elastica_auto.execution import cluster
        if sys.argv[1] == "quiet":
            cluster.quiet_all_exit()

        async def gather(exc):
            raise exc

        async def main():
            for exc in (AllExit(), ValueError("other")):
                task = asyncio.ensure_future(gather(exc))
                await asyncio.sleep(0)
                await asyncio.sleep(0)
                assert task.done()
                del task
                gc.collect()
        asyncio.run(main())
        """)
    out = {how: subprocess.run([sys.executable, "-c", code, how], capture_output=True,
                               text=True, timeout=120) for how in ("quiet", "loud")}
    for how, proc in out.items():
        assert proc.returncode == 0, proc.stderr
    assert out["loud"].stderr.count("Task exception was never retrieved") == 2
    assert "AllExit" in out["loud"].stderr
    assert out["quiet"].stderr.count("Task exception was never retrieved") == 1
    assert "AllExit" not in out["quiet"].stderr and "ValueError: other" in out["quiet"].stderr


def test_an_address_where_no_scheduler_answers_is_one_line(monkeypatch):
    """hostile2: --scheduler at a port where something other than a Dask scheduler listens.
    An HTTP server (the dashboard's port 8787 given for the scheduler's 8786) sends no
    handshake: the run waited for ever (Dask's client reads the handshake without a time
    limit). A server that answers with bytes of its own (eight 0xff: read by Dask as a frame
    length of 2^64 - 1 bytes) was an internal error (MemoryError). Each is now a
    ClusterError naming the address, after the timeout at most. (The junk server first: it
    fails at once without the check, where the HTTP server would hang.)"""
    import http.server
    import socketserver
    import threading

    from elastica_auto.core.errors import ClusterError
    from elastica_auto.execution import cluster as cluster_mod

    class Junk(socketserver.BaseRequestHandler):
        def handle(self):
            self.request.sendall(b"\xff" * 8)

    monkeypatch.setattr(cluster_mod, "CONNECT_TIMEOUT", 1.0)
    http_server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                                  http.server.SimpleHTTPRequestHandler)
    junk_server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), Junk)
    for server in (http_server, junk_server):
        threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        junk_address = f"tcp://127.0.0.1:{junk_server.server_address[1]}"
        with pytest.raises(ClusterError, match=re.escape(
                f"{junk_address} is not a Dask scheduler: what answers there sent what Dask "
                "cannot read (")):
            cluster_mod.connect(junk_address)
        http_address = f"tcp://127.0.0.1:{http_server.server_address[1]}"
        with pytest.raises(ClusterError, match=re.escape(
                f"no Dask scheduler answers at {http_address}: something accepts connections "
                "there but sent no Dask handshake within 2 s")):
            cluster_mod.connect(http_address)
    finally:
        for server in (http_server, junk_server):
            server.shutdown()
            server.server_close()
