"""Waiting for another thread's work with a stop seen meanwhile: rlq.run.waiting."""

import threading
from concurrent.futures import Future, ThreadPoolExecutor

import pytest

from rlq.run import waiting


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
