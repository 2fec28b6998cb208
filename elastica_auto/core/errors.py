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


def error_text(exc: BaseException) -> str:
    """``exc``'s message on one line (white space collapsed), or its type's name if it has
    none: for a line that says what failed already."""
    return " ".join(str(exc).split()) or type(exc).__name__


def one_line(exc: BaseException) -> str:
    """``exc`` as ``"<type>: <message on one line>"``: for a line that names what failed
    only, as a failed branch or a warning does."""
    return f"{type(exc).__name__}: " + " ".join(str(exc).split())
