"""Waiting for work in another thread (an evaluation, a program still compiling, a video) in slices of a
fraction of a second, between which a stop (SIGINT/SIGTERM, rlq.run.stops.signals) is seen: a stop
abandons what it waited for instead of waiting for its end.

Over several processes an evaluation is a collective: were one process to abandon it while another
took its result, the second would go on to a collective the first never joins. Each wait's outcome
(its result, or a stop) is therefore the first that any process claims in JAX's coordination
service (``Agreed``): every process then goes the same way, and a stop one of them sees ends the
wait of all of them."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from typing import Any, TypeVar

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


class Waiter:
    """The waits of one process: ``stopped`` returns this process's stop (a signal number) or None."""

    def __init__(self, stopped: Callable[[], int | None]):
        self.stopped = stopped

    def wait(self, future: Future[T]) -> T:
        return wait(future, self.stopped)


#: the coordination service's key of a run's ``n``-th wait: ``done`` or ``stop:<signal number>``
WAIT_KEY = "rlq/wait/{}"


class Agreed(Waiter):
    """The waits of one process of a run over several: every process makes the same waits in the same
    order, and the ``n``-th one ends as the first claim of any process says (``client``: JAX's
    ``DistributedRuntimeClient``; a claim is a key set only where it is not set yet).

    A process whose work ended claims ``done``; one that sees its stop claims ``stop:<N>``. Then a
    ``done`` wait gives its result (the others' work has ended, so this one's ends too: a collective),
    and a ``stop`` wait raises Abandoned on every process, the result in hand or not."""

    def __init__(self, stopped: Callable[[], int | None], client: Any):
        super().__init__(stopped)
        self.client, self.count = client, 0

    def _claim(self, key: str, outcome: str) -> str:
        """The wait's outcome: ``outcome`` where this claim came first, else the one that did."""
        try:
            self.client.key_value_set(key, outcome)
            return outcome
        except Exception:  # noqa: BLE001 - the key is set: another process claimed first
            return str(self.client.key_value_try_get(key))

    def _claimed(self, key: str) -> str | None:
        try:
            return str(self.client.key_value_try_get(key))
        except Exception:  # noqa: BLE001 - not claimed yet
            return None

    def wait(self, future: Future[T]) -> T:
        key = WAIT_KEY.format(self.count)
        self.count += 1
        outcome = None
        while outcome is None:
            signum = self.stopped()
            outcome = self._claim(key, f"stop:{signum}") if signum is not None else self._claimed(key)
            if outcome is None:
                try:
                    future.result(timeout=POLL_S)
                except FutureTimeout:
                    continue
                except Exception:  # noqa: BLE001 - the work failed: its error is this wait's result
                    pass
                outcome = self._claim(key, "done")
        if outcome.startswith("stop:"):
            raise Abandoned(int(outcome.split(":", 1)[1]))
        return future.result()


def for_run(stopped: Callable[[], int | None], client: Any | None) -> Waiter:
    """The waits of this process: ``Agreed`` ones where ``client`` (JAX's coordination service) joins it to a
    run's other processes (rlq.run.programs.distributed.coordination_client)."""
    return Waiter(stopped) if client is None else Agreed(stopped, client)
