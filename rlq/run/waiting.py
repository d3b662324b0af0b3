"""Waiting for work in another thread (an evaluation, a program still compiling) in slices of a
fraction of a second, between which a stop (SIGINT/SIGTERM, rlq.run.signals) is seen: a stop
abandons what it waited for instead of waiting for its end."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from typing import TypeVar

T = TypeVar("T")

#: seconds between two looks at the stop flag
POLL_S = 0.2


class Abandoned(Exception):
    """A stop came while waiting: what was waited for is left to its thread (the process ends soon)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def wait(future: Future[T], stopped: Callable[[], int | None]) -> T:
    """``future``'s result, or Abandoned as soon as ``stopped()`` returns a signal number."""
    while True:
        signum = stopped()
        if signum is not None:
            raise Abandoned(signum)
        try:
            return future.result(timeout=POLL_S)
        except FutureTimeout:
            continue
