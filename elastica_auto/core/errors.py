"""Errors and how a failure is told: user errors (each reported as one line, the message,
with exit status 2), the other exit statuses, and who failed (`failure_kind`).

They live in this module, which imports nothing but ``os``, so that the command line can
catch them without importing numpy or the engine (``elastica-auto --version`` stays
instant).
"""

import os


class ProblemError(ValueError):
    """An equation module does not follow the protocol (missing name, wrong shape, ...)."""


class RunFileError(ValueError):
    """A run file that cannot be used; the message is one line naming the file and key."""


class StoreError(ValueError):
    """A branch file that cannot be read (missing, truncated, foreign, newer format)."""


class PlanError(ValueError):
    """An argument of ``continuation()`` that cannot be used. ``key`` names the argument
    (``bounds``, ``params.eps``, ...); the message starts with it."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key, self.detail = key, message


class ClusterError(RuntimeError):
    """A Dask scheduler that cannot be used: unreachable, without workers, or with workers
    that cannot run this package."""


class NumericalFailure(RuntimeError):
    """A computation that did not succeed for numerical reasons (a corrector that did not
    converge, say): the problem is hard there, the engine is not at fault. The correctors'
    failures derive from it (`failure_kind`)."""


class StartError(RuntimeError):
    """A start point that cannot be built (no exact solution, corrector failure)."""


USER_ERRORS = (RunFileError, StoreError, ProblemError, PlanError, ClusterError)


class WriteError(RuntimeError):
    """A file that could not be written once a command was under way: the disk full, a
    read-only file system, a file-size limit. One line and its own exit status
    (`EXIT_WRITE`); no file is left half-written (an earlier file stands, a run's branches
    so far are kept where they could be written)."""


class ClusterLost(RuntimeError):
    """The Dask cluster of a run had no worker for longer than the run's ``worker_timeout``:
    the run ends with the branches computed so far saved (`EXIT_CLUSTER_LOST`)."""


#: The command line's exit statuses (docs/cli.md#exit-status; a test keeps the two in step).
#: Where several apply, the first of `EXIT_PRECEDENCE` is the one given.
EXIT_OK = 0
EXIT_BRANCH_FAILED = 1
EXIT_USER = 2
EXIT_ANALYSIS_FAILED = 3
EXIT_INTERNAL = 4
EXIT_WRITE = 5
EXIT_CLUSTER_LOST = 6
EXIT_INTERRUPTED = 130
EXIT_STATUSES = {
    EXIT_OK: "success",
    EXIT_BRANCH_FAILED: "a branch failed (MX): the corrector, or the equation module raising "
                        "or exiting inside it",
    EXIT_USER: "user error: one line, nothing computed",
    EXIT_ANALYSIS_FAILED: "an analysis after the branches failed (snap-back scan, landings, "
                          "stability maps): the file is written and says what is missing",
    EXIT_INTERNAL: "internal error: an exception from the engine itself (a bug), its "
                   "traceback kept in the file; --debug re-raises it",
    EXIT_WRITE: "a file could not be written (disk full, read-only, too large): one line",
    EXIT_CLUSTER_LOST: "the cluster was lost (no worker for worker_timeout seconds, or its "
                       "scheduler gone): the branches computed so far are saved",
    EXIT_INTERRUPTED: "interrupted (Ctrl-C, SIGTERM): what was computed is saved",
}
EXIT_PRECEDENCE = (EXIT_INTERRUPTED, EXIT_WRITE, EXIT_CLUSTER_LOST, EXIT_INTERNAL,
                   EXIT_ANALYSIS_FAILED, EXIT_BRANCH_FAILED, EXIT_OK)

#: Set (to "1") by ``elastica-auto --debug``: an internal error is raised with its traceback
#: instead of being recorded. An environment variable, so that local workers inherit it.
DEBUG_ENV = "ELASTICA_AUTO_DEBUG"


def debugging() -> bool:
    """Whether ``--debug`` is on (`DEBUG_ENV`)."""
    return os.environ.get(DEBUG_ENV, "") not in ("", "0")


def error_text(exc: BaseException) -> str:
    """``exc``'s message on one line (white space collapsed), or its type's name if it has
    none: for a line that says what failed already."""
    return " ".join(str(exc).split()) or type(exc).__name__


#: Who failed, as `failure_kind` tells it: what a branch's diagnostics and a run's ``missing``
#: record under "kind" (CALLER: a function the Python API's caller passed, `CallbackError`).
MODULE, NUMERICAL, ENGINE, CALLER = "module", "numerical", "engine", "caller"


class CallbackError(Exception):
    """A function the caller passed (``ea.continuation``'s ``progress``) raised: its own
    error, not the engine's (``__cause__`` is what it raised). The branch ends there as any
    failing branch does (MX, the points so far kept), its diagnostics of kind CALLER naming
    the callback's line."""

    def __init__(self, name: str):
        super().__init__(name)
        self.name = name


def module_files(module) -> tuple[str, ...]:
    """The files whose code is the equation module's: its own, and for an energy module the
    code derived from its energy (``__derived_file__``: a division by a parameter set to 0
    there is the module's, not the engine's)."""
    return tuple(f for f in (getattr(module, "__file__", None),
                             getattr(module, "__derived_file__", None)) if f)


def _files(module_file) -> tuple[str, ...]:
    if module_file is None:
        return ()
    return (module_file,) if isinstance(module_file, str) else tuple(module_file)


def failure_kind(exc: BaseException, module_file: str | tuple[str, ...] | None) -> str:
    """Who raised ``exc``: `MODULE`, the equation module (a frame of ``module_file``, one
    file or several: `module_files`, is on the traceback, or the engine refused what the
    module returned: ProblemError, or the module called ``sys.exit``); `NUMERICAL`, a
    computation that failed for numerical reasons (`NumericalFailure`, LAPACK's LinAlgError,
    a floating-point trap, memory exhausted by the size of the problem); else `ENGINE`, the
    engine's own code raising, which is a bug: the command reports it apart
    (`EXIT_INTERNAL`) rather than as a hard problem."""
    import traceback
    if isinstance(exc, CallbackError):
        return CALLER
    if isinstance(exc, (ProblemError, SystemExit)):
        return MODULE
    files = _files(module_file)
    for frame in traceback.extract_tb(exc.__traceback__):
        if frame.filename in files:
            return MODULE
    if isinstance(exc, (NumericalFailure, FloatingPointError, MemoryError)):
        return NUMERICAL
    if type(exc).__name__ == "LinAlgError":        # numpy's or scipy's: no import here
        return NUMERICAL
    return ENGINE


def failure_record(exc: BaseException, module_file: str | tuple[str, ...] | None) -> dict:
    """What is kept of a failure (a branch's ``diagnostics``, a run's ``missing``): the
    exception's type and message, ``kind`` (`failure_kind`), ``where`` (the module's line
    if it raised, named with the hook the engine called, else the innermost frame),
    ``traceback`` (the frames, one line each) and, for an internal error, ``text``: the
    whole traceback as Python prints it."""
    import traceback
    kind = failure_kind(exc, module_file)
    if kind == CALLER and exc.__cause__ is not None:
        # what the callback raised, where it raised it (its innermost line)
        frames = traceback.extract_tb(exc.__cause__.__traceback__)
        at = frames[-1] if frames else None
        place = f"{os.path.basename(at.filename)}:{at.lineno} in {at.name}, " if at else ""
        return {"exception": type(exc.__cause__).__name__, "error": error_text(exc.__cause__),
                "where": f"{place}the {exc.name} callback", "kind": kind,
                "traceback": [f"{f.filename}:{f.lineno} in {f.name}" for f in frames]}
    frames = traceback.extract_tb(exc.__traceback__)
    files = _files(module_file)
    own = [f for f in frames if f.filename in files]
    if own:   # the innermost line of the module, and the hook the engine called
        at = own[-1]
        hook = "" if own[0].name == at.name else f", called from {own[0].name}"
        where = f"{os.path.basename(at.filename)}:{at.lineno} in {at.name}{hook}"
    elif frames:
        at = frames[-1]
        where = f"{os.path.basename(at.filename)}:{at.lineno} in {at.name}"
    else:
        where = "?"
    if isinstance(exc, SystemExit):
        error = f"the equation module called sys.exit({exc.code!r})"
    else:
        error = str(exc)
    out = {"exception": type(exc).__name__, "error": error, "where": where, "kind": kind,
           "traceback": [f"{f.filename}:{f.lineno} in {f.name}" for f in frames]}
    if kind == ENGINE:
        out["text"] = "".join(traceback.format_exception(exc))
    return out


def one_line(exc: BaseException) -> str:
    """``exc`` as ``"<type>: <message on one line>"``: for a line that names what failed
    only, as a failed branch or a warning does."""
    return f"{type(exc).__name__}: " + " ".join(str(exc).split())
