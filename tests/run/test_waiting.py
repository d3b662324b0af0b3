"""Waiting for another thread's work with a stop seen meanwhile: rlq.run.stops.waiting."""

import threading
from concurrent.futures import Future, ThreadPoolExecutor

import pytest

from rlq.run.stops import waiting


def test_a_finished_result_and_an_error_come_back():
    done: Future = Future()
    done.set_result(3)
    assert waiting.wait(done, lambda: None) == 3
    failed: Future = Future()
    failed.set_exception(ValueError("boom"))
    with pytest.raises(ValueError, match="boom"):
        waiting.wait(failed, lambda: None)


def test_a_stop_abandons_work_that_never_ends_on_its_own():
    release, looks = threading.Event(), []

    def stopped() -> int | None:
        looks.append(1)
        return 15 if len(looks) >= 3 else None  # a signal after two looks

    with ThreadPoolExecutor(max_workers=1) as pool:
        pending = pool.submit(release.wait)
        with pytest.raises(waiting.Abandoned) as abandoned:
            waiting.wait(pending, stopped)
        assert abandoned.value.signum == 15 and not pending.done() and len(looks) == 3
        release.set()


class Service:
    """JAX's coordination service's key-value store as ``Agreed`` uses it: a key is set once."""

    def __init__(self):
        self.keys: dict[str, str] = {}

    def key_value_set(self, key: str, value: str) -> None:
        if key in self.keys:
            raise RuntimeError(f"ALREADY_EXISTS: {key}")
        self.keys[key] = value

    def key_value_try_get(self, key: str) -> str:
        if key not in self.keys:
            raise RuntimeError(f"NOT_FOUND: {key}")
        return self.keys[key]


def test_one_process_stop_abandons_the_wait_of_every_process():
    """Over several processes a wait ends alike everywhere: one process's stop abandons the others'
    wait too, whose work never ends on its own (a collective the first process left)."""
    service, release = Service(), threading.Event()
    stopping, other = waiting.Agreed(lambda: 15, service), waiting.Agreed(lambda: None, service)
    with ThreadPoolExecutor(max_workers=1) as pool:
        pending = pool.submit(release.wait)
        for waiter in (stopping, other):
            with pytest.raises(waiting.Abandoned) as abandoned:
                waiter.wait(pending)
            assert abandoned.value.signum == 15
        assert service.keys == {"rlq/wait/0": "stop:15"} and not pending.done()
        release.set()


def test_the_first_claim_of_a_wait_is_every_process_outcome():
    """A stop claimed first abandons a wait whose result another process holds; a result claimed
    first is every process's, a stop seen later notwithstanding (the next wait sees it)."""
    done: Future = Future()
    done.set_result(3)
    service = Service()
    stopping, other = waiting.Agreed(lambda: 2, service), waiting.Agreed(lambda: None, service)
    for waiter in (stopping, other):
        with pytest.raises(waiting.Abandoned):
            waiter.wait(done)
    service = Service()
    first, later = waiting.Agreed(lambda: None, service), waiting.Agreed(lambda: 2, service)
    assert first.wait(done) == 3 and later.wait(done) == 3 and service.keys == {"rlq/wait/0": "done"}
    assert type(waiting.for_run(lambda: None, None)) is waiting.Waiter  # one process: no service
