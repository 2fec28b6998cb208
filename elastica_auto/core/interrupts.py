"""Ctrl-C and SIGTERM held off where raising would lose work.

Python raises KeyboardInterrupt wherever the main thread happens to be when the signal
arrives. Inside a continuation step that is what we want (the stepper catches it and ends
the branch at its last point), but after a branch is computed it would lose the branch: in
its stability labelling, or half way through the save that writes it. `Interruptions`
records the signal instead, for the caller to act on once the work is safe.
"""

from __future__ import annotations

import signal
import threading


class Interruptions:
    """While active, Ctrl-C and SIGTERM set ``stop`` instead of raising KeyboardInterrupt
    (which, raised at an arbitrary point, inside the Dask client's own callbacks say, would
    be reported as an "exception ignored" traceback or stop a save half way); the handlers
    before are restored on exit. In the main thread only (elsewhere, signals are not ours,
    and ``stop`` stays clear).

    ``raising``: while it is true, the next signal raises KeyboardInterrupt as usual (inside
    a continuation, which ends its branch at its last point) and clears it, so that a second
    signal cannot break into the branch's own ending; the owner clears it once that work is
    over. One context over the whole of a branch's work, with ``raising`` switched off, leaves
    no moment between the two behaviours where a signal would meet neither."""

    def __init__(self, raising: bool = False):
        self.stop = threading.Event()
        self.raising = raising
        self._before = {}

    def _handle(self, signum, frame):
        self.stop.set()
        if self.raising:
            self.raising = False
            raise KeyboardInterrupt

    def __enter__(self) -> Interruptions:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._before[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc_info):
        for sig, handler in self._before.items():
            signal.signal(sig, handler)
