"""Branches as tasks on a Dask cluster: a local one of ``--jobs N`` worker processes, or the
one whose scheduler is at ``--scheduler ADDRESS`` (or a run file's ``[execution]
scheduler``, or ``continuation(..., scheduler=...)``).

Each branch is one task, ``_task(plan, k, job)``, that continues the branch on a worker and
returns it with the worker's address (stored as the branch's ``worker`` attribute). The
plan travels with each task; the equation module goes with it, as its source text, so a
worker needs the elastica-auto package but not the module's file. The client collects
the branches and writes them in the plan's order, so the branch file is the same whatever
computed it.

A worker that dies has its task rescheduled by the scheduler (a task whose workers die four
times is reported as a failed branch, MX). A task that raises is not computed again
quietly: a branch's ends MX with the exception, and any other task is computed in this
process with a warning naming the exception (`TaskFailure`). A cluster with no worker for
the run's ``worker_timeout`` seconds ends the run (`ClusterLost`), its finished branches
saved and the others recorded as not computed. Ctrl-C or SIGTERM cancels the tasks not yet
finished; the finished ones are written (the branches in progress are lost; with ``--jobs
1``, in this process, the branch in progress ends at its next step and is kept).
``distributed`` is imported only here, for a cluster: its import alone costs about a second.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
import traceback
import uuid
from typing import TYPE_CHECKING, Callable

from ..core.errors import ClusterError, ClusterLost, error_text

if TYPE_CHECKING:   # imported where used: a worker imports this module to check its version,
    from .jobs import TaskFailure   # which must not need the rest of the package

#: Seconds to reach the scheduler, and to wait for its first worker.
CONNECT_TIMEOUT = 10.0
#: Seconds a run's cluster may have no worker before the run ends (`ClusterLost`), unless
#: the run sets its own ``worker_timeout``. A worker that dies is replaced at once (its nanny
#: starts it again: 0.35 s here, from the kill to the new worker with the scheduler);
#: workers that reach a batch system's walltime, or are killed with their nannies, are not,
#: and without a limit the run would wait for them for ever. A minute is long past a
#: restart, even on a loaded machine, and short beside a run worth a cluster; where dead
#: workers are replaced by new batch jobs, the limit should exceed the queue's wait.
WORKER_TIMEOUT = 60.0
#: Seconds between looks at a cluster's number of workers (a round trip to its scheduler).
WORKER_POLL = 1.0
#: Seconds to fetch a finished task's result before looking at the cluster again: the
#: worker that holds it may have died since it finished, and then Dask computes the task
#: again, which with no worker left would hold the fetch up for ever (`fetched`). A
#: branch, a few megabytes at most, comes in well under a second.
FETCH_TIMEOUT = 10.0

#: Seconds between looks at the tasks' states.
POLL = 0.05
#: Tasks a local cluster gives each worker thread at a time (Dask's worker-saturation): the
#: one it runs and the next. A worker that dies takes both; the queued one is suspected of
#: the death once, then Dask reruns the suspect on its own, so the innocent branch is well
#: within the three deaths a task is allowed (tests/test_robustness_failures.py).
SATURATION = 2.0
#: ``on_tasks(done, total, points, workers)``: progress of the tasks of a cluster run.
TaskProgress = Callable[[int, int, int, int], None]


def check_address(address: str) -> None:
    """ClusterError (one line) unless ``address`` is one a Dask client here can connect to:
    a scheme with a transport (``tcp://`` by default), a host and a port, and for ``tls://``
    the certificates of Dask's configuration. Checked before a client is made: a client
    made of a bad address raises ValueError or TypeError, and then, collected at the
    interpreter's exit, waits 20 s for an event loop that has ended."""
    from distributed.comm.addressing import get_address_host_port, parse_address
    from distributed.comm.registry import get_backend
    from distributed.security import Security
    why = ""
    try:
        scheme, _ = parse_address(address)
        if scheme == "inproc":
            why = "an in-process address: no other process reaches it"
        else:
            try:
                get_backend(scheme).get_connector()
            except Exception as exc:
                raise ValueError(f"no usable {scheme}:// transport here: "
                                 f"{error_text(exc)}") from None
            get_address_host_port(address)
            if (scheme in ("tls", "wss")
                    and Security().get_connection_args("client").get("ssl_context") is None):
                why = ("TLS needs certificates, and Dask's configuration "
                       "(distributed.comm.tls) gives none")
    except Exception as exc:  # ValueError, TypeError, ImportError: the transport's own words
        why = error_text(exc)[:200]
    if why:
        raise ClusterError(f"{address!r} is not a Dask scheduler's address ({why}); "
                           "expected tcp://HOST:PORT")


def check_answers(address: str) -> None:
    """ClusterError (one line) unless a Dask scheduler answers at ``address`` within
    `CONNECT_TIMEOUT` of the connection: one connection of Dask's own, its handshake
    exchanged, then closed. Checked before a client is made, since Dask's client waits for
    the other end's handshake without a time limit: an address where something else listens
    (the scheduler's dashboard, an HTTP server on 8787, given for the scheduler's 8786) held
    the run for ever, and one that answers with bytes of its own could make Dask read them
    as the length of a frame of exabytes (a MemoryError, reported as an internal error)."""
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    from distributed.comm import connect as dask_connect
    from distributed.security import Security

    async def handshake():
        # the connection within CONNECT_TIMEOUT (Dask's own retries), then as long again
        # for the handshake
        comm = await asyncio.wait_for(
            dask_connect(address, timeout=CONNECT_TIMEOUT,
                         **Security().get_connection_args("client")),
            2 * CONNECT_TIMEOUT)
        await comm.close()

    # in a thread of its own, with its own event loop: the caller may be running one (a
    # notebook calling ea.continuation(..., scheduler=...))
    with ThreadPoolExecutor(1) as pool:
        try:
            pool.submit(asyncio.run, handshake()).result()
        except TimeoutError:    # asyncio's (first: it is an OSError)
            raise ClusterError(
                f"no Dask scheduler answers at {address}: something accepts connections "
                f"there but sent no Dask handshake within {2 * CONNECT_TIMEOUT:g} s (a "
                "dashboard's HTTP port?); give the scheduler's own address, tcp://HOST:PORT "
                "(port 8786 unless it was started with another)") from None
        except OSError as exc:
            raise ClusterError(f"cannot reach the Dask scheduler at {address} "
                               f"({type(exc).__name__}: {error_text(exc)[:200]})") from None
        except Exception as exc:  # bytes Dask cannot read (MemoryError, a decoding error)
            raise ClusterError(
                f"{address} is not a Dask scheduler: what answers there sent what Dask cannot "
                f"read ({type(exc).__name__}: {error_text(exc)[:200]}); give the scheduler's "
                "own address, tcp://HOST:PORT") from None


def connect(address: str):
    """A client of the scheduler at ``address`` with at least one worker that can import
    elastica-auto; ClusterError (one line) otherwise (`check_address`, then
    `check_answers`, first)."""
    from distributed import Client
    check_address(address)
    check_answers(address)
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {address} "
                           f"({type(exc).__name__}: {error_text(exc)[:200]})") from None
    try:
        client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError):
        client.close()
        raise ClusterError(f"the Dask scheduler at {address} has no workers "
                           f"(none joined within {CONNECT_TIMEOUT:g} s)") from None
    try:
        versions = client.run(_version)
    except Exception as exc:  # the workers cannot unpickle a function of this package
        client.close()
        raise ClusterError(f"the workers of {address} cannot run elastica-auto "
                           f"({type(exc).__name__}: {error_text(exc)[:200]}); install it on them"
                           ) from None
    from .. import __version__
    wrong = sorted(w for w, v in versions.items() if v != __version__)
    if wrong:
        client.close()
        raise ClusterError(f"the workers {', '.join(wrong)} of {address} run elastica-auto "
                           f"{versions[wrong[0]]}, this is {__version__}")
    return client


def local(workers: int, threads: bool = False):
    """A client of a new Dask cluster of ``workers`` single-threaded worker processes on this
    machine (`close` ends both). Its workers are this process's children and watch it: they
    end at once if it is killed outright (SIGKILL), even in the middle of a task
    (tests/test_robustness_failures.py checks it). ``threads``: the workers are threads of
    this process instead, and there is no dashboard (`serve`: up in a third of the time)."""
    import logging

    import dask
    from distributed import Client, LocalCluster
    # Two tasks per single-threaded worker (SATURATION): the next branch waits on the worker,
    # not behind a round trip to the scheduler (4-5 ms a task here, 5% of a short branch).
    # The scheduler's HTTP server on any free port: its default, 8787, may be taken (by
    # another run), and taking another would print a warning. Dask's own logs are silenced up
    # to CRITICAL, in the workers too: a failure reaches the user as the branch's MX line, and
    # a worker closing after its scheduler logs a heartbeat traceback at ERROR (seen in CI).
    with dask.config.set({"distributed.scheduler.worker-saturation": SATURATION}):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=not threads,
                               dashboard_address=None if threads else ":0",
                               silence_logs=logging.CRITICAL, memory_limit=0)
    return Client(cluster, set_as_default=False)


def close(client, interrupted: bool = False):
    """Close ``client`` and, if it made one, its local cluster; after an interruption, its
    workers are ended first, at once (a task in a slow step would hold up a graceful close).
    A client still trying to reach a scheduler that is gone stops trying without a word: Dask
    would log the stop as an error, with a traceback, after the run's own line."""
    import logging
    cluster = client.cluster
    if cluster is not None and interrupted:
        for nanny in list(cluster.workers.values()):
            process = getattr(getattr(nanny, "process", None), "process", None)
            if process is not None and process.pid:
                try:
                    os.kill(process.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
    logger = logging.getLogger("distributed.client")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    quiet_all_exit()
    try:
        client.close()
    finally:
        logger.setLevel(level)
    if cluster is not None:
        cluster.close(timeout=10)


class _NoAllExit:
    """A filter of the ``asyncio`` logger that drops the report of a task ended by Dask's
    ``AllExit``: a client closed while it still gathers results ends those waits by raising
    it, and asyncio reports each such task whose exception nobody read ("Task exception was
    never retrieved", with a traceback) whenever it is collected, which may be after the
    run's own last line, at exit (seen once in the suite, after a lost cluster's exit status
    6). Any other report passes."""

    def filter(self, record) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        return not (exc is not None and type(exc).__name__ == "AllExit"
                    and type(exc).__module__.startswith("distributed"))


_ALL_EXIT = _NoAllExit()


def quiet_all_exit():
    """Install `_NoAllExit` on the ``asyncio`` logger (once; it stays: the tasks it is about
    are collected at any later time)."""
    import logging
    logger = logging.getLogger("asyncio")
    if _ALL_EXIT not in logger.filters:
        logger.addFilter(_ALL_EXIT)


def _version() -> str:
    from .. import __version__
    return __version__


def _task(plan, k: int, job):
    """Branch number ``k`` of ``plan`` from ``job``, on a worker: (branch, worker address)."""
    from distributed import get_worker

    from .jobs import compute_branch
    branch = compute_branch(plan, k, job)
    return branch, get_worker().address


def task_failure(future) -> TaskFailure:
    """Why ``future`` (done, not finished) has no result: lost (`TaskFailure.lost`) if its
    workers died, that is the scheduler gave up on it (KilledWorker: they died with it more
    than its ``allowed-failures`` times), its connection closed, or it was cancelled or lost;
    else the exception it raised on its worker, with the worker's traceback."""
    from distributed import KilledWorker
    from distributed.comm import CommClosedError

    from .jobs import TaskFailure
    exc = future.exception() if future.status == "error" else None
    if exc is None:
        return TaskFailure("RuntimeError", f"the task was {future.status} (its workers died)",
                           lost=True)
    try:
        frames = tuple(f"{os.path.basename(f.filename)}:{f.lineno} in {f.name}"
                       for f in traceback.extract_tb(future.traceback()))
    except Exception:  # a traceback that did not travel
        frames = ()
    return TaskFailure(type(exc).__name__, error_text(exc)[:500],
                       lost=isinstance(exc, (KilledWorker, CommClosedError)), traceback=frames)


def _address(client) -> str:
    return getattr(client.scheduler, "address", None) or "?"


def _unanswered(client) -> ClusterLost:
    """The run's end when ``client`` lost its connection to its scheduler: Dask cancels
    every task of the client at once (and a run cancels none but those it leaves out, so
    a cancelled task of the run says so), and the tasks it had are gone with it."""
    return ClusterLost(f"the Dask scheduler at {_address(client)} went away (the connection "
                       "to it closed)")


def fetched(future) -> tuple[bool, object]:
    """(True, the result) of the finished ``future``, or (False, None) if it did not come
    within `FETCH_TIMEOUT` or was cancelled meanwhile: its worker died with it (the task is
    computed again, and the future is no longer done) or the scheduler went away."""
    from concurrent.futures import CancelledError
    try:
        return True, future.result(timeout=FETCH_TIMEOUT)
    except (TimeoutError, CancelledError, OSError):
        # OSError: distributed's CommClosedError, a connection closed as the result came (the
        # scheduler or the worker gone; the run's watch tells which, `_Watch`): it was an
        # internal error that ended a run whose scheduler was killed
        return False, None


class _Watch:
    """Whether ``client``'s cluster has had a worker in the last ``timeout`` seconds:
    `check` raises ClusterLost once it has had none for longer, nor a scheduler that
    answers (``timeout`` None: `WORKER_TIMEOUT`). It asks the scheduler at most every
    `WORKER_POLL` seconds; a scheduler that is gone ends the run sooner (`_unanswered`)."""

    def __init__(self, client, timeout: float | None):
        self.client = client
        self.timeout = WORKER_TIMEOUT if timeout is None else timeout
        self.since: float | None = None      # when the workers were first seen gone
        self.asked = -WORKER_POLL

    def check(self):
        now = time.monotonic()
        if now - self.asked < WORKER_POLL:
            return
        self.asked = now
        client = self.client
        answers = client.status == "running"
        try:
            workers = answers and client.scheduler_info(n_workers=0).get("n_workers", 0)
        except OSError:          # CommClosedError too: the scheduler is going away
            answers = workers = False
        if workers:
            self.since = None
            return
        if self.since is None:
            self.since = now
        elif now - self.since > self.timeout:
            what = "has had no worker" if answers else "has not answered"
            raise ClusterLost(f"the Dask scheduler at {_address(client)} {what} for "
                              f"{self.timeout:g} s (worker_timeout)")


def map_tasks(client, function, args_list, on_done, warnings: list[str],
              worker_timeout: float | None = None) -> list:
    """``function(*args)`` for each of ``args_list`` as tasks of ``client``'s cluster; their
    results in order, ``on_done(i, result)`` called as each arrives. A task whose workers
    died is computed in this process; so is one that raised there, with a line in
    ``warnings`` naming the exception (computed here, it raises here as it would in a run
    without a cluster). A cluster without a worker for ``worker_timeout`` seconds (None:
    `WORKER_TIMEOUT`) leaves the tasks it has not done to this process, with a line in
    ``warnings``. (The landings and the maps' enumerations of a ``--jobs N`` or scheduler
    run: `execution.run._analyse`.)"""
    futures = {client.submit(function, *args, pure=False): i
               for i, args in enumerate(args_list)}
    out = [None] * len(args_list)
    pending, watch = set(futures), _Watch(client, worker_timeout)
    name = getattr(function, "__name__", "task")

    def here(i):
        out[i] = function(*args_list[i])
        on_done(i, out[i])

    while pending:
        ready = sorted((f for f in pending if f.done() and f.status != "cancelled"),
                       key=futures.get)
        gone = not ready and any(f.status == "cancelled" for f in pending)
        if not ready:
            try:
                if gone:
                    raise _unanswered(client)
                watch.check()
            except ClusterLost as exc:
                if client.status == "running":
                    client.cancel(list(pending))
                warnings.append(f"{exc}: its {len(pending)} tasks left ({name}) were "
                                "computed here")
                for i in sorted(futures[f] for f in pending):
                    here(i)
                break
            time.sleep(POLL)
            continue
        pending.difference_update(ready)
        for future in ready:
            i = futures[future]
            if future.status == "finished":
                got, out[i] = fetched(future)
                if got:
                    on_done(i, out[i])
                else:     # looked at again, as it stands now
                    pending.add(future)
                continue
            failure = task_failure(future)
            if not failure.lost:
                warnings.append(f"task {i + 1} of {len(out)} ({name}) raised on a worker: "
                                f"{failure}; computed here instead")
            here(i)
    return out


def run_on_cluster(client, plan, jobs_list, branches, save, on_branch=None,
                   on_tasks: TaskProgress | None = None, stop=None, skip=None,
                   worker_timeout: float | None = None) -> bool:
    """Compute ``jobs_list`` as tasks of ``client``'s cluster, appending the branches to
    ``branches`` in plan order and calling ``save()`` after each, but those for which
    ``skip(i, branches)`` is true when their turn comes (their tasks cancelled then, done
    or not: see `elastica_auto.execution.run.switch_levels`); True if interrupted
    (``stop``, a `threading.Event`, set: see `elastica_auto.core.interrupts.Interruptions`).
    A task that failed gives its job's branch ending MX, with the exception (`task_failure`,
    `failed_branch`). A cluster without a worker for ``worker_timeout`` seconds (None:
    `WORKER_TIMEOUT`) raises ClusterLost once ``branches`` has the finished branches (saved)
    and, after them, one for each job not done, ending MX with the message `NOT_COMPUTED`."""
    from .jobs import NOT_COMPUTED, TaskFailure, failed_branch
    from .schedule import Schedule
    schedule = Schedule(plan, jobs_list, branches, save, on_branch, skip)
    token = uuid.uuid4().hex[:8]
    # The plan goes with every task (tens of kilobytes): scattered once instead, it would be
    # data the scheduler cannot recompute, and a worker that dies would take it, and every
    # task waiting for it, down with it. One `map` is one message to the scheduler: a
    # `submit` a task would keep the first worker waiting 0.1 s for a sweep of 64. A mirror
    # job is no task: it is made here at its turn, from the branch before it.
    computed = [i for i, job in enumerate(jobs_list) if not job.mirror]
    numbers = [schedule.number(i) for i in computed]
    futures_list = client.map(_task, [plan] * len(computed), numbers,
                              [jobs_list[i] for i in computed], pure=False,
                              key=[f"elastica-branch-{k}-{token}" for k in numbers])
    tasks = dict(zip(computed, futures_list))
    futures = {f: i for i, f in tasks.items()}
    pending, done, points, finished = set(futures), {}, 0, 0
    last = 0.0
    watch = _Watch(client, worker_timeout)

    def report(force=False):
        nonlocal last
        now = time.monotonic()
        if on_tasks is not None and (force or now - last > 0.5):
            last = now
            # a scheduler gone answers without "workers" (the run's watch ends the run)
            workers = client.scheduler_info().get("workers", {})
            on_tasks(finished, len(futures), points, len(workers))

    def lost(exc: ClusterLost):
        if client.status == "running":
            client.cancel(list(pending))
        # the finished branches, beyond a gap in the plan's order too, then the jobs not
        # done (mirror images included): the file records what is missing
        missing = [failed_branch(plan, jobs_list[i], TaskFailure(
            "ClusterLost", "the cluster had no worker", lost=True))
            for i in range(schedule.taken, len(jobs_list)) if i not in done]
        for br in missing:
            br.message = NOT_COMPUTED
        schedule.rest(done, missing)
        raise exc

    def cancel(i):
        if i in tasks:
            client.cancel(tasks[i])
            pending.discard(tasks[i])

    stop = stop if stop is not None else threading.Event()
    while pending and not stop.is_set():
        ready = {f for f in pending if f.done() and f.status != "cancelled"}
        if not ready and any(f.status == "cancelled" for f in pending):   # scheduler gone
            lost(_unanswered(client))
        if not ready:
            try:
                watch.check()
            except ClusterLost as exc:
                lost(exc)
            time.sleep(POLL)
            report()
            continue
        pending -= ready
        for f in ready:
            i = futures[f]
            if f.status == "finished":
                got, value = fetched(f)
                if not got:       # looked at again, as it stands now
                    pending.add(f)
                    continue
                br, worker = value
                br.worker = worker
            elif f.status == "lost":
                # its data went with the workers as the cluster ended (no KilledWorker: not
                # the task's fault): submitted again, for workers that come back; with none,
                # the watch ends the run and the branch is recorded as not computed
                again = client.submit(_task, plan, schedule.number(i), jobs_list[i],
                                      pure=False, key=f"elastica-branch-{schedule.number(i)}-"
                                                      f"{uuid.uuid4().hex[:8]}")
                tasks[i] = again
                futures[again] = i
                pending.add(again)
                continue
            else:  # the task raised, or its workers died beyond the scheduler's retries
                br = failed_branch(plan, jobs_list[i], task_failure(f))
            done[i] = br
            finished += 1
            points += len(br.points)
        # in order (`Schedule`): a job left out at its turn has its task cancelled, done or
        # not; a mirror image is made here at its turn, and a signal meanwhile ends the run
        # with the branches the cluster finished (not the image)
        if schedule.take(done, on_skip=cancel, keep_interrupted=False):
            stop.set()
        report()
    if stop.is_set():
        client.cancel(list(pending))
        schedule.rest(done)     # finished beyond a gap in the plan's order
        return True
    report(force=True)
    return False


# -- the default run: this process computes at once, a local cluster joins in the background --

def serve(results_fd: int):
    """The background helper of a default run (`Background`), in its own process: reads
    ``workers`` then ``(tag, function, args)`` requests as pickles from stdin, computes each
    as a task of a local cluster of ``workers`` (`local`) that it starts, and writes
    ``("ready", workers)`` once the cluster is up, then ``("done", tag, value)`` or
    ``("error", tag, failure)`` (a `TaskFailure`) per task, as pickles on the file
    descriptor ``results_fd``.
    It is the Dask client and the scheduler's host, so that the command's own process, busy
    with branches, imports nothing of ``distributed`` and runs no scheduler. At the end of
    its input (the command closed it, or ended, even killed outright) it ends its workers at
    once and exits. One worker is a thread of this process, which is then a worker too: a
    task that ends the process ends the helper, and the command computes what it had handed
    it."""
    import pickle
    import sys

    out = os.fdopen(results_fd, "wb")
    lock = threading.Lock()

    def send(message):
        with lock:
            pickle.dump(message, out, protocol=pickle.HIGHEST_PROTOCOL)
            out.flush()

    def report(tag, future):
        if future.status == "finished":
            send(("done", tag, future.result()))
        else:
            send(("error", tag, task_failure(future)))

    inp = sys.stdin.buffer
    workers = pickle.load(inp)
    # one worker: a thread of this process (no worker process to start: the cluster is up
    # in about a third of the time); more: worker processes, each with a core of its own
    client = local(workers, threads=workers == 1)
    # the client's view of the workers may be older than the cluster's: wait until it has
    # all of them (the command hands out one task per worker it is told of)
    client.wait_for_workers(workers)
    send(("ready", workers))
    try:
        while True:
            try:
                tag, function, args = pickle.load(inp)
            except EOFError:
                break
            future = client.submit(function, *args, pure=False,
                                   key=f"elastica-{tag[0]}-{uuid.uuid4().hex[:12]}")
            future.add_done_callback(lambda f, tag=tag: report(tag, f))
    finally:
        if workers > 1:
            close(client, interrupted=True)
        os._exit(0)


def _call(function, *args):
    """A task of the helper's cluster: ``function(*args)`` and the worker's address."""
    from distributed import get_worker
    return function(*args), get_worker().address


class Background:
    """The local cluster of a default run, started in a helper process (`serve`) while this
    process computes: `submit` hands it a task once it is ``ready``; each result reaches
    ``on_result(tag, ok, value)`` (``value``: the result and the worker's address, or why
    there is none, a `TaskFailure`), called from a reading thread. `close` ends it at once."""

    def __init__(self, workers: int, on_result):
        import pickle
        import subprocess
        import sys

        import cloudpickle
        self._pickle = pickle
        # by value, as Dask sends a task: a plan's problem may be made of closures (the fold
        # curves' extended system), which pickle refuses
        self._dumps = cloudpickle.dumps
        read, write = os.pipe()
        self.proc = subprocess.Popen(
            [sys.executable, "-c", f"from elastica_auto.execution.cluster import serve; "
             f"serve({write})"],
            stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            pass_fds=(write,), start_new_session=True)
        os.close(write)
        self._results = os.fdopen(read, "rb")
        self.workers = 0                     # set once ready
        self.ready = threading.Event()
        self.on_result = on_result
        self._lock = threading.Lock()
        self._send(workers)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _send(self, message) -> bool:
        """Write one request to the helper; False if it has ended, or if the request does
        not pickle (then it is computed here, and nothing of it reaches the helper)."""
        try:
            data = self._dumps(message, protocol=self._pickle.HIGHEST_PROTOCOL)
        except Exception:
            return False
        try:
            with self._lock:
                self.proc.stdin.write(data)
                self.proc.stdin.flush()
            return True
        except (OSError, ValueError):        # the helper has ended
            return False

    def _read(self):
        while True:
            try:
                message = self._pickle.load(self._results)
            except Exception:  # the helper ended (or failed to start): the run goes on here
                self.ready.clear()
                self.on_result(None, False, "the local cluster ended")
                return
            if message[0] == "ready":
                self.workers = message[1]
                self.ready.set()
                self.on_result(None, True, None)
            else:
                self.on_result(message[1], message[0] == "done", message[2])

    def submit(self, tag, function, args) -> bool:
        """Hand ``function(*args)`` to the cluster; False if it has ended."""
        return self._send((tag, _call, (function, *args)))

    def finish(self):
        """No more tasks: the helper ends its cluster and exits, while this process goes on."""
        self.ready.clear()
        with contextlib.suppress(OSError):
            self.proc.stdin.close()

    def close(self, wait: float = 0.0):
        """End the helper and its cluster: after ``wait`` seconds for it to end by itself
        (after `finish`), at once (its workers hold nothing of value)."""
        self.finish()
        with contextlib.suppress(Exception):
            self.proc.wait(timeout=wait)
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
