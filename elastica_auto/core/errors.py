"""User errors: each is reported as one line (the message) with exit status 2.

They live in this module, which imports nothing, so that the command line can catch them
without importing numpy or the engine (``elastica-auto --version`` stays instant).
"""


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
    EXIT_CLUSTER_LOST: "the cluster had no worker for worker_timeout seconds: the branches "
                       "computed so far are saved",
    EXIT_INTERRUPTED: "interrupted (Ctrl-C, SIGTERM): what was computed is saved",
}
EXIT_PRECEDENCE = (EXIT_INTERRUPTED, EXIT_WRITE, EXIT_CLUSTER_LOST, EXIT_INTERNAL,
                   EXIT_ANALYSIS_FAILED, EXIT_BRANCH_FAILED, EXIT_OK)

#: Set (to "1") by ``elastica-auto --debug``: an internal error is raised with its traceback
#: instead of being recorded. An environment variable, so that local workers inherit it.
DEBUG_ENV = "ELASTICA_AUTO_DEBUG"


def debugging() -> bool:
    """Whether ``--debug`` is on (`DEBUG_ENV`)."""
    import os
    return os.environ.get(DEBUG_ENV, "") not in ("", "0")


def error_text(exc: BaseException) -> str:
    """``exc``'s message on one line (white space collapsed), or its type's name if it has
    none: for a line that says what failed already."""
    return " ".join(str(exc).split()) or type(exc).__name__


def one_line(exc: BaseException) -> str:
    """``exc`` as ``"<type>: <message on one line>"``: for a line that names what failed
    only, as a failed branch or a warning does."""
    return f"{type(exc).__name__}: " + " ".join(str(exc).split())
