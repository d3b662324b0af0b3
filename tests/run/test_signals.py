"""SIGINT/SIGTERM over several processes (rlq.run.stops.signals with ``Peers``): one process's stop is every process's."""

import signal
import time

from rlq.run.stops import signals
from rlq.run.stops.signals import StopRequest


class Peers:
    """The run's other processes: ``stopped`` is the signal one of them published."""

    def __init__(self, stopped: int | None = None):
        self.stopped, self.published, self.left = stopped, [], 0

    def publish(self, signum: int) -> None:
        self.published.append(signum)

    def seen(self) -> int | None:
        return self.stopped

    def leave(self) -> None:
        self.left += 1


def test_a_signal_is_published_to_the_other_processes():
    peers, lines = Peers(), []
    with StopRequest(lines.append, peers) as stop:
        stop.early = None  # training: a stop saves a checkpoint
        stop._on_signal(signal.SIGTERM)
        assert stop.signum == signal.SIGTERM and peers.published == [signal.SIGTERM]
    assert lines == ["SIGTERM: stopping after this slice with a resumable checkpoint (SIGTERM again stops at once)"]


def test_another_process_stop_is_this_one_s_and_its_own_signal_then_is_the_same_stop(monkeypatch):
    """SLURM signals every task: a task that saw another's stop first takes its own signal as that stop, not as
    a second signal (which would end it at once, without its part of the checkpoint)."""
    killed = []
    monkeypatch.setattr(signals.os, "_exit", lambda code: killed.append(code - 128))
    monkeypatch.setattr(signals, "SAME_STOP_S", 0.0)
    peers, lines = Peers(stopped=signal.SIGTERM), []
    with StopRequest(lines.append, peers) as stop:
        stop.early = None
        deadline = time.monotonic() + 30
        while stop.signum is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert stop.signum == signal.SIGTERM and peers.published == []
        stop._on_signal(signal.SIGTERM)  # this process's own
        assert killed == [] and len(lines) == 1
        stop._on_signal(signal.SIGTERM)  # a second one: at once
        assert killed == [signal.SIGTERM]


def test_a_second_signal_from_the_watcher_thread_ends_the_process_and_a_twin_within_a_second_does_not(monkeypatch):
    """timeout(1) signals the process and its group: one SIGTERM arrives twice, and the watcher thread (where
    signal.signal cannot be called) must take it as one stop; a later second signal ends the process at once."""
    import threading

    exits = []
    monkeypatch.setattr(signals.os, "_exit", exits.append)
    lines = []
    with StopRequest(lines.append) as stop:
        stop.early = None

        def twice() -> None:
            stop._on_signal(signal.SIGTERM)
            stop._on_signal(signal.SIGTERM)

        worker = threading.Thread(target=twice)
        worker.start()
        worker.join()
        assert stop.signum == signal.SIGTERM and exits == [] and len(lines) == 1
        stop._first_at -= signals.SAME_STOP_S
        worker = threading.Thread(target=stop._on_signal, args=(signal.SIGTERM,))
        worker.start()
        worker.join()
        assert exits == [128 + signal.SIGTERM]


def test_an_error_of_the_main_thread_during_an_early_stop_waits_for_the_stop_to_end_the_process(monkeypatch):
    """Process 0 leaves the run at an early stop, which fails its main thread's collective in flight: the main
    thread must not end the interpreter before the watcher's exit (finalisation would abort the process)."""
    import threading

    events = []
    monkeypatch.setattr(signals.os, "_exit", lambda code: events.append(("exit", code)))
    left = threading.Event()

    class Leaving(Peers):
        def leave(self) -> None:
            left.set()
            time.sleep(0.5)
            events.append("left")

    try:
        with StopRequest(lambda line: None, Leaving()) as stop:
            threading.Thread(target=stop._on_signal, args=(signal.SIGTERM,)).start()
            assert left.wait(30)
            raise RuntimeError("the collective failed: the coordinator left")
    except RuntimeError:
        events.append("main")
    assert events == ["left", ("exit", 128 + signal.SIGTERM), "main"]
