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
