"""SIGINT and SIGTERM stop a run at the next chunk boundary instead of killing it mid-chunk.

SLURM sends SIGTERM some time before it kills a job; Ctrl-C sends SIGINT. The handler only
records the signal; the loop sees it after the chunk in flight, writes a resumable ``step_<N>``
checkpoint and raises RunInterrupted (the CLI exits with 128 + the signal's number). A second
signal while waiting acts as it would without rlq (the process ends at once).
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Callable
from types import FrameType
from typing import Any

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopRequest:
    """A context that turns SIGINT/SIGTERM into a flag (``signum``) while it is entered.

    Handlers can only be installed from the main thread; elsewhere (a test's worker thread) the
    context does nothing and signals keep their usual effect."""

    def __init__(self, notify: Callable[[str], None]):
        self.signum: int | None = None
        #: shows the one line that says a stop is coming (a run points it at its console, which
        #: also writes rlq.log, once it has one)
        self.notify = notify
        self._previous: dict[int, Any] = {}

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.signum is not None:  # asked twice: stop now, as the signal would without rlq
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        self.signum = signum
        name = signal.Signals(signum).name
        self.notify(f"{name}: stopping after this chunk with a resumable checkpoint ({name} again stops at once)")

    def __enter__(self) -> StopRequest:
        if threading.current_thread() is threading.main_thread():
            for signum in SIGNALS:
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()
