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


USER_ERRORS = (RunFileError, StoreError, ProblemError)
