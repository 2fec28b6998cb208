"""Branches as tasks of a Dask cluster (``--scheduler``): a real cluster started here as
subprocesses on 127.0.0.1 (``dask scheduler`` and ``dask worker --nworkers 2``).

The file a cluster writes is the file ``--jobs 1`` writes, number for number (only the
``worker`` attribute and timings differ); both workers are used; a worker killed mid-run
costs nothing; Ctrl-C keeps the finished branches; an unreachable scheduler is one line.
"""

from __future__ import annotations

import json
import math
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


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A scheduler and two single-threaded workers; yields the scheduler's address."""
    root = tmp_path_factory.mktemp("cluster")
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
    yield address
    for p in reversed(procs):
        os.killpg(p.pid, signal.SIGTERM)
    for p in procs:
        p.wait(timeout=30)


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
    import: `helpers` is on this process's path only) is computed in this process."""
    import importlib

    from distributed import Client

    from elastica_auto.execution.cluster import map_tasks
    with Client(cluster, timeout=30, set_as_default=False) as client:   # as a run's
        reported = []
        pids = map_tasks(client, os.getpid, [()] * 4, lambda i, r: reported.append((i, r)))
        assert sorted(reported) == list(enumerate(pids)) and os.getpid() not in pids
        mods = map_tasks(client, importlib.import_module, [("helpers",)], lambda i, r: None)
        assert mods[0].__name__ == "helpers"


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
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
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
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
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
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
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
    from elastica_auto.execution.run import execute
    from helpers import EXAMPLES

    def refused(*args, **kwargs):
        raise AssertionError("a cluster was started for one branch")

    monkeypatch.setattr(cluster, "Background", refused)
    monkeypatch.setattr(cluster, "local", refused)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    plan = runfile.load(EXAMPLES / "bratu.toml")
    assert len(plan.branches) == 1
    result = execute(plan, tmp_path, jobs=0)
    assert [b.worker for b in result.branches] == ["local"] and result.branches[0].end == "EP"


def test_the_default_run_s_cluster_starts_when_the_work_left_pays_for_it():
    """`_Alongside` starts its cluster once the mean time of what this process finished,
    times what is left of that kind, or the time of the one in hand, exceeds ``pays``."""
    from elastica_auto.execution.run import _Alongside
    started = []

    def make(pays):
        return _Alongside(None, 1, lambda n, on: started.append(n) or _FakeBackground(1, on),
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
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
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
    from elastica_auto.execution.run import RunResult, _Alongside, start_job, execute
    from elastica_auto.analysis.snaps import scans
    from helpers import elastica_run_file
    run = elastica_run_file(tmp_path / "two.toml", uz=[0], mirror=False)
    one = execute(runfile.load(run), tmp_path / "one", jobs=1)
    plan = runfile.load(run)
    pool = _Alongside(plan, 1, lambda n, on: _FakeBackground(workers, on, ends))
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
    """_Alongside.map (the damped model's landings): each task is taken from the front of
    the list by this process or by an idle worker of the cluster, the results come back in
    order and each is reported once; a task whose worker dies, or that a cluster that ends
    took with it, is computed here."""
    import threading
    from elastica_auto.execution.run import _Alongside
    from helpers import WorkingBackground
    background = {"works": lambda n, on: WorkingBackground(n, on),
                  "fails": lambda n, on: WorkingBackground(n, on, fails=True),
                  "ends": lambda n, on: _FakeBackground(1, on, ends=True)}[cluster]
    pool = _Alongside(None, 1, background)
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
    """A worker's branch for a job of an earlier `_Alongside.run` (left out while it computed
    it, and so never waited for) is not taken as the current run's job of the same number;
    the current run's own is."""
    from elastica_auto.execution.run import _Alongside
    pool = _Alongside(None, 1, lambda n, on: _FakeBackground(1, on))
    pool.jobs, pool.level, done = ["job 0 of level 3"], 3, {}
    pool._take((("branch", (2, 0)), True, ("a level-2 branch", "inproc://w")), done)
    assert done == {}

    class Branch:
        worker = None
    pool._take((("branch", (3, 0)), True, (Branch(), "inproc://w")), done)
    assert list(done) == [0] and done[0].worker == "inproc://w"


def test_a_scan_the_cluster_finished_is_taken_not_computed_again():
    """A scan whose result the cluster delivered (in the queue, no longer asked for) while
    this process was busy is taken by `_Alongside.wait_for_scans`, not left for
    `snap_targets` to compute again."""
    import threading
    from elastica_auto.execution.run import _Alongside
    pool = _Alongside(None, 1, lambda n, on: _FakeBackground(1, on))
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
    as each fold is found, before the branch is done, and `_Alongside.wait_for_scans` ends
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
    from elastica_auto.execution.run import RunResult, _Alongside, start_job
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
    pool = _Alongside(plan, 1, lambda n, on: Recording(n, on, fails=fails))
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
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
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
    from elastica_auto.execution.run import _Alongside
    key, wanted = (("psi", 1.0),), {"psi": 1.0}
    guessed = wanted if same else {"psi": 1.0 + 2 * np.pi}
    monkeypatch.setattr(run_module, "scans", lambda problem, br: {key: wanted})
    monkeypatch.setattr(run_module, "copy_key", lambda problem, name, params: key)
    plan = types.SimpleNamespace(problem=None, options=types.SimpleNamespace(mirror=False))
    pool = _Alongside(plan, 1, lambda n, on: _FakeBackground(0, on))
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
    from elastica_auto.execution.run import RunResult, _Alongside, execute, start_job
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
    pool = _Alongside(plan, 1, lambda n, on: Holding(n, on))
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
