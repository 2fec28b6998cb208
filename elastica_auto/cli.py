"""The ``elastica-auto`` command line: run, list, show, snaps, export, plot, view, path, derive.

User errors (a bad run file, a missing, foreign or damaged branch file, a path too long for
the file system) print one line and exit with status 2, without a traceback. Every exit status
is in one table, `core.errors.EXIT_STATUSES` (docs/cli.md#exit-status): a branch that ended
MX gives 1, an analysis that could not be made 3, an internal error of the engine 4, a file
that cannot be written once a command is under way 5 (no file half-written), a run whose
cluster had no worker for its worker_timeout 6, an interruption 130 (what was computed is
saved).
"""

from __future__ import annotations

import errno
import json
import os
import signal
import sys
from pathlib import Path

import click

from . import __version__
from .core import labels
from .core.errors import (DEBUG_ENV, EXIT_ANALYSIS_FAILED, EXIT_CLUSTER_LOST, EXIT_INTERNAL,
                          EXIT_INTERRUPTED, EXIT_OK, EXIT_USER, EXIT_WRITE, USER_ERRORS,
                          ClusterLost, RunFileError, StoreError, WriteError, debugging)


def _fail(msg: str, code: int = EXIT_USER):
    click.echo(f"elastica-auto: error: {msg}", err=True)
    sys.exit(code)


def shipped_runs() -> dict[str, Path]:
    """Run files shipped with the package (``runs/*.toml``), by name. (importlib.resources is
    imported here, when a run is looked up among them: a run file given by its path does
    without it.)"""
    from importlib.resources import files
    root = files("elastica_auto.runs")
    return {p.name[:-5]: Path(str(p)) for p in root.iterdir() if p.name.endswith(".toml")}


def resolve_run(name_or_path: str) -> Path:
    """A run file path: an existing ``.toml`` path, ``runs/<name>.toml`` here, or a shipped run."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.is_file():
        if not p.is_file():
            raise RunFileError(f"{p}: no such run file")
        return p
    local = Path("runs") / f"{name_or_path}.toml"
    if local.is_file():
        return local
    runs = shipped_runs()
    if name_or_path in runs:
        return runs[name_or_path]
    raise RunFileError(f"{name_or_path}: no such run; shipped runs: {', '.join(sorted(runs))}")


def _usage(exc: click.UsageError):
    """A command line click cannot parse: a user error in one line, naming the command and
    where its options are listed (click's own report is three: usage, a hint, the error)."""
    if isinstance(exc, getattr(click.exceptions, "NoArgsIsHelpError", ())):
        raise exc   # `elastica-auto` alone: its help, as click gives it
    name = exc.ctx.command_path if exc.ctx is not None else "elastica-auto"
    _fail(f"{name}: {exc.format_message()} ('{name} --help' lists the options)")


class _StdoutReader:
    """``sys.stdout`` for a command whose reader may stop reading (``elastica-auto show
    FILE.h5 | head``): a write or flush that meets a closed pipe (EPIPE) points the
    standard output at ``os.devnull`` from then on, so that the command goes on and ends as
    it would have (a run computes and saves every branch, its exit status its own), instead
    of dying of an internal error halfway. Any other failure of the stream is raised."""

    def __init__(self, stream):
        self._stream = stream

    def _gone(self):
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:        # the descriptor too: the interpreter's last flush at exit writes there
            os.dup2(devnull, self._stream.fileno())
        except (OSError, ValueError):   # a stream without a descriptor of its own
            pass
        finally:
            os.close(devnull)
        self._stream = open(os.devnull, "w", encoding="utf-8")

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._gone()
            return len(text)

    def flush(self):
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._gone()

    def __getattr__(self, name):    # encoding, errors, isatty, fileno, buffer, ...
        return getattr(self._stream, name)


class _Commands(click.Group):
    """The command group. What any command may meet ends it with one line: a write that
    fails (`WriteError`) with status 5, a standard output whose reader stopped reading
    (``| head``) as nothing at all (`_StdoutReader`), a command line click cannot parse (an
    unknown option, a missing argument, a value of the wrong type) as a user error, a name
    longer than the file system allows (ENAMETOOLONG, from any path argument or option) as a
    user error; and an exception that escapes a command is an internal error (a bug): one
    line saying so and its traceback, exit status 4 (`_internal`), not Python's report with
    status 1, which reads as a failed branch."""

    def parse_args(self, ctx, args):
        try:
            return super().parse_args(ctx, args)
        except click.UsageError as exc:     # before any command: `elastica-auto --nope`
            _usage(exc)

    def invoke(self, ctx):
        if not isinstance(sys.stdout, _StdoutReader):
            sys.stdout = _StdoutReader(sys.stdout)
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            _usage(exc)
        except (click.exceptions.Exit, click.ClickException, click.Abort, KeyboardInterrupt):
            raise
        except WriteError as exc:
            _fail(str(exc), EXIT_WRITE)
        except OSError as exc:
            if exc.errno != errno.ENAMETOOLONG:
                _internal(exc, ctx.invoked_subcommand or "elastica-auto")
            _fail(f"{exc.filename or 'a path'}: {exc.strerror}")
        except Exception as exc:
            _internal(exc, ctx.invoked_subcommand or "elastica-auto")


@click.group(cls=_Commands, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="elastica-auto")
@click.option("--debug", is_flag=True,
              help="Raise an internal error (a bug of the engine) with its traceback, instead "
                   "of recording it and exiting with status 4.")
def main(debug):
    """AUTO-07p-style continuation of boundary value problems, with stability labels."""
    if debug:   # an environment variable: the local workers of a run inherit it
        os.environ[DEBUG_ENV] = "1"
    import warnings
    # An equation module that imports a name from its old place (docs/api.md, "Deprecated
    # paths") gets a DeprecationWarning, which Python shows only for __main__: show the
    # modules' own (each is executed as elastica_auto_eq_<stem>) once per line.
    warnings.filterwarnings("default", category=DeprecationWarning, module="elastica_auto_eq_")


def _internal(exc: BaseException, what: str):
    """An exception that escaped the engine (a bug): the traceback on stderr under one line
    saying so, exit status 4; with --debug, Python's own report."""
    if debugging():
        raise exc
    import traceback
    click.echo(f"elastica-auto: internal error in {what}: {type(exc).__name__}: "
               + " ".join(str(exc).split()) + " (a bug: please report it with the traceback "
               "below; --debug raises it)", err=True)
    click.echo("".join(traceback.format_exception(exc)).rstrip(), err=True)
    sys.exit(EXIT_INTERNAL)


@main.command("list")
def list_runs():
    """List the shipped run files (and the branch files each restarts from)."""
    import tomllib

    from .execution.runfile import restart_files
    for name, path in sorted(shipped_runs().items()):
        try:
            doc = tomllib.loads(path.read_text())
        except (OSError, tomllib.TOMLDecodeError) as exc:
            click.echo(f"{name:<20} (unreadable: {exc})")
            continue
        needs = restart_files(doc)
        after = f" [restarts from {', '.join(needs)}]" if needs else ""
        click.echo(f"{name:<20} {doc.get('description', '')}{after}")


def _fmt_params(params: dict, names) -> str:
    return " ".join(f"{k}={params[k]:.6g}" for k in names)


@main.command()
@click.argument("name_or_path")
@click.option("--out", "out_dir", default="out", show_default=True,
              type=click.Path(file_okay=False), help="Folder for the branch file <run>.h5.")
@click.option("--jobs", "-j", default=0, show_default=True, type=click.IntRange(min=0),
              help="Branches computed at once (0: one per CPU core); at most one per core "
                   "this process may use.")
@click.option("--quiet", "-q", is_flag=True, help="No live progress line (summaries only).")
@click.option("--set", "overrides", multiple=True, metavar="NAME=VALUE",
              help="Override an option, a parameter or a [continuation] key of the run file "
                   "(repeatable): --set ds_max=0.3 --set eps=0.4 --set 'eps=[0.25, 0.5]'.")
@click.option("--from", "restart", metavar="FILE.h5:LABEL",
              help="Start from this label instead of the run file's start.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Compute the branches as tasks of the Dask cluster whose scheduler is at "
                   "ADDRESS (tcp://host:port); default: the run file's [execution] scheduler, "
                   "else this machine (--jobs).")
@click.option("--worker-timeout", "worker_timeout", default=None, type=float,
              metavar="SECONDS",
              help="End the run (exit status 6) once its cluster has had no worker for this "
                   "long, the branches computed so far saved; default: the run file's "
                   "[execution] worker_timeout, else 60.")
@click.option("--resume", is_flag=True,
              help="Continue the run's file: compute only the cells (start, parameter values, "
                   "direction) not in it yet.")
def run(name_or_path, out_dir, jobs, quiet, overrides, restart, scheduler, worker_timeout,
        resume):
    """Run NAME_OR_PATH (a shipped run name or a .toml file) and write OUT/<run>.h5."""
    from .execution.jobs import Callbacks, usable_cores
    from .execution.run import StartError, execute
    from .execution.runfile import load
    out_dir = Path(out_dir)
    if scheduler is not None and not scheduler.strip():
        _fail("--scheduler: an empty address; give tcp://HOST:PORT, or leave the option out "
              "to compute on this machine")
    if worker_timeout is not None and not 0 < worker_timeout < float("inf"):   # nan too
        _fail(f"--worker-timeout: expected a positive number of seconds, got {worker_timeout:g}")
    try:
        plan = load(resolve_run(name_or_path), out_dir=out_dir, overrides=overrides,
                    restart=restart)
    except USER_ERRORS as exc:
        _fail(str(exc))
    nbr = len(plan.branches)
    varying = plan.varying
    cores = usable_cores()
    if jobs > cores and scheduler is None and plan.scheduler is None:
        # more worker processes than cores would only share them, each with its own memory
        click.echo(f"note: --jobs {jobs}: this process may use {cores} cores; at most "
                   f"{cores} worker processes", err=True)
    tty = sys.stderr.isatty() and not quiet
    levels = f", {plan.switch_depth} levels deep" if plan.switch_depth > 1 else ""
    switched = (f", then the other branch at the first {plan.switch_count} BPs of each{levels}"
                if plan.switch_count else "")

    def header():  # once the starts and the output are checked: an error stays one line
        what = {"fold": "fold curves", "bp": "branch-point curves",
                "pitchfork": "pitchfork curves"}.get(plan.curve, "branches")
        solved = f"{plan.problem.free[0]}, " if plan.curve else ""
        click.echo(f"{plan.name}: {nbr} {what} of {plan.problem.source} in {solved}"
                   f"{plan.parameter}{switched} -> {out_dir / plan.output_name}", err=True)

    def of(k):
        return f"{k}/{nbr}" if k <= nbr else f"{k}"

    def on_tasks(done, total, points, workers):
        if tty:
            click.echo(f"\r  tasks {done}/{total} done, {points} points, {workers} workers  ",
                       nl=False, err=True)

    def progress(k, npts, nfolds, lam):
        if tty:
            click.echo(f"\r  branch {of(k)}  {plan.parameter} = {lam:+.6f}  "
                       f"points {npts:5d}  folds {nfolds:3d}", nl=False, err=True)

    def on_branch(k, br):
        if tty:
            click.echo("\r" + " " * 78 + "\r", nl=False, err=True)
        _report_branch(of(k), br, varying)

    def on_landing(done, total, row):
        if tty:
            click.echo(f"\r  damped landing {done}/{total}: {row['lp']} c = "
                       f"{row['damping']:g}" + " " * 20, nl=False, err=True)
            if done == total:
                click.echo("\r" + " " * 78 + "\r", nl=False, err=True)

    signal.signal(signal.SIGTERM, _terminate)
    try:
        callbacks = Callbacks(progress, on_branch, header, on_tasks, on_landing)
        result = execute(plan, out_dir, callbacks, jobs, scheduler, resume, worker_timeout)
    except StartError as exc:
        _fail(str(exc))
    except ClusterLost as exc:     # the branches computed so far are saved: the line says where
        _fail(str(exc), EXIT_CLUSTER_LOST)
    except USER_ERRORS as exc:
        _fail(str(exc))
    except WriteError as exc:      # before the catch-all below: one line, exit 5
        _fail(str(exc), EXIT_WRITE)
    except KeyboardInterrupt:  # execute stops its own interruptions once the output is open
        click.echo("\ninterrupted before the first branch: nothing written", err=True)
        sys.exit(EXIT_INTERRUPTED)
    except (Exception, SystemExit) as exc:  # escaped the engine before its file was opened
        _internal(exc, f"run {plan.name}")
    if resume and result.kept and not result.branches and not result.interrupted:
        click.echo(f"{plan.name}: every cell is in {result.path} already "
                   f"({result.kept} branches); nothing to compute")
        return
    if result.interrupted:
        # what was computed is saved: a further Ctrl-C while the command ends changes nothing
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        out = out_dir / plan.output_name
        saved = (f"{len(result.branches)} branches saved to {result.path}" if result.branches
                 else "no branch saved")
        # a rerun saves beside an earlier result and leaves it alone (see execute)
        kept = f"; the earlier {out} is unchanged" if result.path != out else ""
        click.echo(f"\ninterrupted: {saved}{kept}", err=True)
        sys.exit(EXIT_INTERRUPTED)
    report_run(plan, result)
    if result.failed:
        click.echo(f"failed branches (MX): {', '.join(map(str, result.failed))}", err=True)
    for m in result.missing:
        click.echo(f"missing: {m['what']}: {m['message']}", err=True)
    if result.internal:
        click.echo(f"internal errors (a bug: please report them; the tracebacks are in "
                   f"{result.path}, `elastica-auto show` prints them; --debug raises them): "
                   f"{', '.join(result.internal)}", err=True)
    if result.stopped:
        out = out_dir / plan.output_name
        kept = f"; the earlier {out} is unchanged" if result.path != out else ""
        click.echo(f"stopped: {len(result.branches)} branches saved to {result.path}{kept}",
                   err=True)
    if result.status != EXIT_OK:
        sys.exit(result.status)


def _report_branch(number: str, br, varying):
    """The line of a computed branch (``number``: "k/total"), its warnings and its index
    disagreements."""
    folds = ", ".join(
        f"{p.name}{' (NOT LOCATED)' if p.fold_residual != p.fold_residual else ''}"
        f" {br.transition(p)}".rstrip() for p in br.folds)
    start = f" from {br.start}" if br.start != "trivial" else ""
    bps = ", ".join(f"{p.name} {br.transition(p)}".rstrip()
                    for p in br.points if p.type in labels.SWITCHES)
    cps = ", ".join(p.name for p in br.points if p.type == labels.CP)
    click.echo(f"branch {number} {_fmt_params(br.points[0].params, varying)}{start} "
               f"dir {'+' if br.direction > 0 else '-'}: {len(br.points)} points, "
               f"{len(br.folds)} folds, {br.seconds:.2f} s"
               # the scheme, where it is not the cubic one (ncol = "auto" may choose Gauss)
               + (f", Gauss ncol {ncol}"
                  if isinstance(ncol := br.options.get("ncol"), int) and ncol else "")
               + f"; {br.end}: {br.message}"
               + (f"; folds {folds}" if folds else "") + (f"; {bps}" if bps else "")
               + (f"; cusps {cps}" if cps else ""))
    for w in br.warnings:
        click.echo(f"  warning: {w}")
    if br.disagreements:
        click.echo(f"  index disagreements at {len(br.disagreements)} points: "
                   + ", ".join(f"pt {br.points.index(p) + 1} ({p.note})"
                               for p in br.disagreements[:5]))


def report_run(plan, result):
    """What a finished run found besides its branches (warnings, snap-back targets, damped
    landings, stability maps), then its totals."""
    for w in result.warnings:
        click.echo(f"warning: {w}")
    if result.snaps:
        ends = {(r["branch"], r["lp"]) for r in result.snaps}
        bps = sum(labels.kind_of(lp) in labels.SWITCHES for _, lp in ends)
        where = f"{len(ends) - bps} folds" + (f" and {bps} branch points" if bps else "")
        click.echo(f"snap-back: {len(result.snaps)} stable targets at {where} ending a "
                   f"stable branch (elastica-auto snaps {result.path})")
    if result.landings:
        lps = len({(r["branch"], r["lp"]) for r in result.landings})
        click.echo(f"damped model: {len(result.landings)} landings from {lps} folds "
                   f"(elastica-auto snaps {result.path})")
    for m in result.maps:
        at = ", ".join(f"{k}={v:.6g}" for k, v in m.fixed.items())
        counts = ", ".join(map(str, sorted(set(m.stable.tolist()))))
        click.echo(f"stability map at {at}: {len(m.stable)} regions of ({m.x}, {m.y}), "
                   f"stable equilibria {counts}")
    kept = f"{result.kept} branches kept, " if result.kept else ""
    click.echo(f"{plan.name}: {kept}{len(result.branches)} branches, "
               f"{sum(len(b.points) for b in result.branches)} points, "
               f"{sum(len(b.folds) for b in result.branches)} folds, "
               + (f"{ncp} cusps, " if (ncp := sum(p.type == labels.CP for b in result.branches
                                                  for p in b.points)) else "")
               + f"{result.seconds:.2f} s "
               f"-> {result.path}")


def _terminate(signum, frame):
    """SIGTERM stops a run like Ctrl-C: what was computed is saved."""
    raise KeyboardInterrupt


def _open(path, rows: bool = False):
    from .storage.store import BranchFile
    try:
        return BranchFile(path, rows=rows)
    except StoreError as exc:
        _fail(str(exc))


@main.command()
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--all", "all_points", is_flag=True, help="Every point, not only labelled ones.")
@click.option("--tracebacks", is_flag=True,
              help="Also print the tracebacks of the internal errors stored in the file.")
def show(file, all_points, tracebacks):
    """Print an AUTO-like table of the labelled points of FILE.h5, then the branches that
    ended MX or have warnings, and what the run could not make."""
    from .storage.store import rows
    bf = _open(file, rows=True)   # read in one opening: a run may replace the file meanwhile
    cols = bf.parameters + bf.ordinates
    head = f"{'BR':>3} {'PT':>5} {'TY':>2} {'LAB':>6} " + " ".join(f"{c:>14}" for c in cols) \
        + f" {'index':>5} {'rule':>4} {'direct':>6}"
    try:
        table = list(rows(bf, labelled_only=not all_points))
    except StoreError as exc:   # read on opening already: only a lazy read could fail
        _fail(str(exc))
    click.echo(head)
    for r in table:
        click.echo(f"{r['branch']:>3} {r['pt']:>5} {r['type']:>2} {r['label']:>6} "
                   + " ".join(f"{r[c]:>14.7g}" for c in cols)
                   + f" {r['index']:>5} {r['index_rule']:>4} {r['index_direct']:>6}")
    internal = []
    for b in bf.branches:
        warned = json.loads(b.attrs.get("warnings", "[]") or "[]")
        if b.attrs["end"] in labels.FAILED or warned:
            click.echo(f"branch {b.number}: {b.attrs['end']}: {b.attrs['message']}")
        for w in warned:   # as run printed them: the reason the branch is listed
            click.echo(f"  warning: {w}")
        diagnostics = json.loads(b.attrs.get("diagnostics", "{}") or "{}")
        if diagnostics.get("kind") == "engine":
            internal.append((f"branch {b.number}", diagnostics.get("text", "")))
    for m in bf.missing:
        click.echo(f"missing: {m['what']}: {m.get('message', '')}")
        if m.get("kind") == "engine":
            internal.append((m["what"], m.get("text", "")))
    if internal and not tracebacks:
        click.echo(f"internal errors (a bug): {', '.join(w for w, _ in internal)}; "
                   "--tracebacks prints their tracebacks")
    for what, text in internal if tracebacks else ():
        click.echo(f"traceback of the internal error in {what}:\n{text.rstrip()}")


def _no_snaps(bf) -> str:
    """Why a file has no snap-back targets, from what it holds: no fold ends a stable segment
    (no LP whose transition has index 0 on one side), or some do and the run computed none
    (the equation module has no ``shooting`` hook, or the run did not use it: its warnings,
    `show`, say which), or the run was interrupted before its scan (a branch ended so)."""
    from .branches.stepper import INTERRUPTED
    cut = [b.number for b in bf.branches if b.attrs.get("message") == INTERRUPTED]
    if cut:
        return (f"no snap-back targets: the run was interrupted (branch {cut[0]}) before its "
                f"snap-back scan; elastica-auto run {bf.run} --resume completes it")
    folds = [name for b in bf.branches
             for t, name, tr in zip(b.columns["type"], b.columns["label"], b.columns["transition"])
             if t in labels.FOLDS and "0" in str(tr).split(" -> ")]
    if not folds:
        return ("no snap-back targets: no fold with a known index ends a stable segment "
                "(index 0 on one side)")
    shown = ", ".join(folds[:6]) + (f", ... ({len(folds)} folds)" if len(folds) > 6 else "")
    verb = "ends a stable segment" if len(folds) == 1 else "end stable segments"
    return (f"no snap-back targets: {shown} {verb}, but the run computed none: "
            f"its equation module ({bf.equation}) has no shooting hook, or the run did not "
            "use it (see its warnings: elastica-auto show)")


@main.command()
@click.argument("file", type=click.Path(dir_okay=False))
def snaps(file):
    """Snap-back targets of FILE.h5: at each fold where a stable branch ends, every stable
    equilibrium at the same parameters (all of them, by a shooting scan), the branch, if
    any, that passes through it, and (for modules with dynamics) the one the rod lands on;
    then the damped model's landings, if the run asked for them."""
    bf = _open(file)
    if not bf.snaps:
        click.echo(_no_snaps(bf))
        return
    ords = [c[len("target_"):] for c in bf.snaps[0] if c.startswith("target_")]
    landing = "landed" in bf.snaps[0]
    click.echo(f"{'LP':>6} {'BR':>3} {'param':>6} {'value':>12} {'stable':>7} "
               + " ".join(f"{o:>11}" for o in ords) + f" {'index':>5} {'on branch':>9}"
               + (f" {'landed':>6} {'released':>9} {'transit':>8}" if landing else ""))
    for r in bf.snaps:
        on = int(r["on_branch"])
        line = (f"{r['lp']:>6} {int(r['branch']):>3} {r['parameter']:>6} {r['value']:>12.7g} "
                f"{r['stable_side']:>7} "
                + " ".join(f"{r['target_' + o]:>11.6g}" for o in ords)
                + f" {int(r['index']):>5} {on if on else 'none':>9}")
        if landing and r["landed"]:
            line += f" {'<-':>6} {r['energy_released']:>9.5g} {r['transit_time']:>8.4g}"
        click.echo(line)
    if landing:
        click.echo("landed: where the rod's overdamped dynamics from the fold end; released: "
                   "the energy given up on the way; transit: the time to release 99% of it")
    if bf.landings:
        click.echo("\ndamped model (u_tt + c u_t = -grad E): the equilibrium reached from each "
                   "fold, for each damping")
        click.echo(f"{'LP':>6} {'BR':>3} {'param':>6} {'value':>12} {'damping':>8} "
                   + " ".join(f"{o:>11}" for o in ords) + f" {'released':>9} {'transit':>8}")
        for r in bf.landings:
            head = (f"{r['lp']:>6} {int(r['branch']):>3} {r['parameter']:>6} "
                    f"{r['value']:>12.7g} {r['damping']:>8.4g} ")
            if not r["landed"]:
                click.echo(head + "no stable equilibrium reached")
                continue
            click.echo(head + " ".join(f"{r['target_' + o]:>11.6g}" for o in ords)
                       + f" {r['energy_released']:>9.5g} {r['transit_time']:>8.4g}")


@main.command()
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="CSV file to write.")
def export(file, output):
    """Write every point of every branch of FILE.h5 to a CSV file."""
    from .storage.outputs import check_output
    from .storage.store import export_csv, is_stream
    bf = _open(file, rows=True)
    try:
        path = check_output(output, bf.path, "the CSV", "exported")
        if path.suffix.lower() not in ("", ".csv"):   # x.json would get CSV in it
            _fail(f"-o {output}: export writes CSV only: name the file .csv (or give no "
                  "suffix)")
        path = export_csv(bf, path)
    except StoreError as exc:
        _fail(str(exc))
    n = sum(len(b) for b in bf.branches)
    click.echo(f"{n} points of {len(bf.branches)} branches -> {path}",
               err=is_stream(path))   # not into the CSV on standard output


@main.command()
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("-x", "xname", default=None, help="Abscissa (default: the continued parameter).")
@click.option("-y", "yname", default=None,
              help="Ordinate (default: the continued parameter's distinguished ordinate).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Figure file (.png, .pdf, .svg).")
@click.option("--fold/--no-fold", "fold", default=False,
              help="Fold a periodic abscissa into [0, period), e.g. psi into [0, 2 pi).")
def plot(file, xname, yname, output, fold):
    """Plot a bifurcation diagram of FILE.h5, one panel per combination of the values of the
    parameters fixed along its branches (reads the file, computes nothing)."""
    bf = _open(file)
    from .plots import bifurcation_diagram
    from .plots.diagram import period_of
    try:
        period = None
        if fold:
            period = period_of(bf, xname or (bf.branches[0].parameter if bf.branches else ""),
                               "--fold")
        path = bifurcation_diagram(bf, Path(output), xname, yname, period=period)
    except (ValueError, StoreError) as exc:
        _fail(str(exc))
    click.echo(f"wrote {path}")


@main.command()
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("-o", "--output", default=None, type=click.Path(dir_okay=False),
              help="HTML file to write (default: FILE with the suffix .html, beside it).")
@click.option("-x", "xname", default=None,
              help="Abscissa shown first (default: the continued parameter).")
@click.option("-y", "yname", default=None,
              help="Ordinate shown first (default: the continued parameter's distinguished "
                   "ordinate).")
@click.option("--fold/--no-fold", "fold", default=False,
              help="Fold a periodic abscissa into [0, period) at first (the page toggles it).")
@click.option("--equation", "equation", default=None, metavar="PATH",
              help="Draw the configurations with this equation module (a .py file, which is "
                   "run, or a shipped name). Default: the shipped module the file names; a "
                   "file that names a module by a path gets no configurations (docs/trust.md).")
def view(file, output, xname, yname, fold, equation):
    """Write an interactive bifurcation diagram of FILE.h5: one self-contained HTML page (no
    network access) showing the configuration of the point under the mouse beside the
    diagram (reads the file, computes nothing, and runs no code it names)."""
    bf = _open(file)
    from .plots.viewer import check_output, equation_module, page_data, render, write_page
    # SIGTERM (a batch system's, an IDE's, timeout's) ends the drawing like Ctrl-C: the
    # drawing processes are ended with the command, no page is written
    signal.signal(signal.SIGTERM, _terminate)
    try:
        output = check_output(output or Path(file).with_suffix(".html"), bf.path)
        problem = equation_module(equation, bf) if equation is not None else None
        data = page_data(bf, xname, yname, fold, problem=problem)
        text = render(data)
        path = write_page(text, output, bf.path)
    except (ValueError, StoreError) as exc:      # the ProblemErrors of --equation too
        _fail(str(exc))
    except KeyboardInterrupt:
        click.echo("\ninterrupted: no page written", err=True)
        sys.exit(EXIT_INTERRUPTED)
    click.echo(f"wrote {path} ({len(text.encode()) / 1e6:.1f} MB)")
    images = data["images"]
    if images.untrusted:     # as documented: not a failure, the page says so too
        click.echo(f"elastica-auto: configurations not drawn: {images.reason}; pass "
                   "--equation PATH to trust it", err=True)
    if images.failed:        # part of the page could not be made
        click.echo(f"elastica-auto: error: configurations not drawn for "
                   f"{images.failure_line()}", err=True)
        sys.exit(EXIT_ANALYSIS_FAILED)


def _values(option: str, items) -> dict[str, float]:
    """``NAME=VALUE`` items (VALUE an expression such as ``2*pi``) as a dict."""
    from .core.expressions import evaluate
    out = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name.strip():
            _fail(f"{option} {item!r}: expected NAME=VALUE")
        try:
            out[name.strip()] = evaluate(text)
        except ValueError as exc:
            _fail(f"{option} {item}: {exc}")
    return out


@main.command()
@click.argument("equation")
@click.option("--at", "at", multiple=True, metavar="NAME=VALUE",
              help="Parameter values at the start of the path (repeatable; others: defaults).")
@click.option("--to", "to", multiple=True, metavar="NAME=VALUE",
              help="Values at the end of the path of the parameters that move (repeatable).")
@click.option("--ds-max", "ds_max", default=None, type=float,
              help="Largest step in the path parameter t (of [0, 1]).")
def path(equation, at, to, ds_max):
    """Snap-backs along a straight path in parameter space: every fold where a stable
    equilibrium ends as the parameters move from --at to --to, and the stable equilibria
    there (EQUATION: a shipped module name or a .py file with the shooting hook)."""
    from .api import snaps_along
    from .model.problem import load_problem
    a, b = _values("--at", at), _values("--to", to)
    if not b:
        _fail("--to: give at least one NAME=VALUE, the end of the path")
    try:
        problem = load_problem(equation)
    except USER_ERRORS as exc:
        _fail(str(exc))
    try:
        options = {} if ds_max is None else {"ds_max": ds_max}
        snaps, branches = snaps_along(problem, a, b, **options)
    except USER_ERRORS as exc:
        _fail(str(exc))
    except (Exception, SystemExit) as exc:   # the module failing on the path: one line
        from .core.errors import ENGINE, failure_record, module_files
        record = failure_record(exc, module_files(problem.module))
        if record["kind"] == ENGINE:
            _internal(exc, "path")
        _fail(f"{problem.source}: the path failed: {record['exception']}: "
              + " ".join(record["error"].split()) + f" ({record['where']})")
    start = {**problem.defaults(), **a}
    moving = ", ".join(f"{k} {start[k]:.6g} -> {v:.6g}" for k, v in b.items())
    fixed = ", ".join(f"{k}={v:.6g}" for k, v in start.items() if k not in b)
    ords = problem.ordinate_names
    click.echo(f"path of {problem.source}: {moving} ({fixed}); {len(branches)} branches "
               f"from the equilibria at the start")
    if not snaps:
        click.echo("no snap: no stable equilibrium ends on the path")
    for n, s in enumerate(snaps, 1):
        where = ", ".join(f"{k}={s.params[k]:.8g}" for k in b)
        state = ", ".join(f"{o}={s.ordinates[o]:.6g}" for o in ords[:2])
        click.echo(f"snap {n} at t={s.t:.6f} ({where}) from {state} to "
                   f"{len(s.targets)} stable equilibri{'um' if len(s.targets) == 1 else 'a'}:")
        for r in s.targets:
            on = f"on branch {r['on_branch']}" if r["on_branch"] else "on no branch followed"
            click.echo("    " + ", ".join(f"{o}={r['target_' + o]:.6g}" for o in ords[:2])
                       + f" ({on})")


@main.command()
@click.argument("module", type=click.Path(dir_okay=False))
@click.option("-o", "--output", default=None, type=click.Path(dir_okay=False),
              help="Write the module to this file (atomically) instead of printing it.")
@click.option("--no-cache", "no_cache", is_flag=True,
              help="Derive afresh: neither read nor write the cache of generated code.")
def derive(module, output, no_cache):
    """Print the equation module derived from MODULE.py's ENERGY(): the module with its
    ENERGY replaced by the derived definitions it does not define itself, a plain module
    that loads without sympy and gives the same results (docs/energy.md)."""
    from .energy.loader import printed
    from .model.problem import load_problem
    try:
        problem = load_problem(module, cache=not no_cache)
        if problem.generated is None:
            _fail(f"{module}: defines no ENERGY(); there is nothing to derive")
        # the file load_problem read: a path, or a shipped module's name
        text = printed(Path(problem.module.__file__).read_text(encoding="utf-8"),
                       problem.generated)
    except USER_ERRORS as exc:
        _fail(str(exc))
    if output is None:
        click.echo(text, nl=False)
        return
    from .energy.cache import write_text
    if not write_text(Path(output), text):
        from .core.errors import EXIT_WRITE
        _fail(f"{output}: cannot write", EXIT_WRITE)
    click.echo(f"wrote {output}", err=True)
