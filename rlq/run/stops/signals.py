"""SIGINT and SIGTERM: before a run has anything to save they end it at once; after, they stop it
at the next slice of a chunk with a resumable checkpoint instead of killing it mid-chunk.

SLURM sends SIGTERM some time before it kills a job (30 s by default); Ctrl-C sends SIGINT. While
a run compiles or trains its first slice there is nothing new to save: the process ends within a
moment, with one line that says so and the exit code 128 + the signal's number. Once a slice has
trained, the signal is recorded; the loop sees it after the slice in flight (slices are kept to a
few seconds, rlq.run.stops.slices), writes a resumable ``step_<N>`` checkpoint and raises RunInterrupted
(the CLI exits with the same code). A second signal while waiting ends the process at once (exit code 128 + its
number); one that arrives within ``SAME_STOP_S`` of the first is the same stop delivered twice.

Over several processes (rlq/run/programs/distributed.py) one process's signal is every process's (``Peers``): it is
published in JAX's coordination service, which the others read every fraction of a second, and a process that
ends before training leaves the service with the others first (JAX aborts a process whose coordinator ended).

Python runs a signal handler only between bytecodes of the main thread, and the main thread spends
a compile or a chunk inside XLA: the handler is a no-op, and a watcher thread reads the signal from
``signal.set_wakeup_fd``'s pipe, written by the interpreter's C handler the moment it arrives. The main thread
leaves the context only once those threads are out of JAX's native code (an interpreter that ends while a daemon
thread is inside it aborts the process).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from types import FrameType
from typing import Any, Protocol

SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: seconds between two looks at the other processes' stop
PEER_POLL_S = 0.2
#: seconds after a stop in which the same signal again is that stop, not a second one: timeout(1) and a shell's
#: kill of a process group deliver one SIGTERM twice within microseconds; a person's second Ctrl-C comes later
SAME_STOP_S = 1.0
#: seconds the main thread, leaving the context, waits for its watchers: an early stop in flight that ends the process,
#: the other processes' watcher's last look at their stops
ENDING_WAIT_S = 30.0


class Peers(Protocol):
    """The run's other processes, as a stop sees them (rlq.run.programs.distributed.PeerStops)."""

    def publish(self, signum: int) -> None: ...

    def seen(self) -> int | None: ...

    def leave(self) -> None: ...


class StopRequest:
    """A context that turns SIGINT/SIGTERM into a flag (``signum``) while it is entered, or, while
    ``early`` holds (nothing to save yet), into the end of the process.

    Handlers can only be installed from the main thread; elsewhere (a test's worker thread) the
    context does nothing and signals keep their usual effect."""

    def __init__(self, notify: Callable[[str], None], peers: Peers | None = None):
        self.signum: int | None = None
        self.peers = peers
        #: shows the one line that says a stop is coming (a run points it at its console, which
        #: also writes rlq.log, once it has one)
        self.notify = notify
        #: the line that says why a stop now saves nothing (``signal name -> line``); None once a
        #: slice has trained and a stop saves a checkpoint
        self.early: Callable[[str], str] | None = lambda name: (
            f"stopped by {name} before training began: nothing to save"
        )
        #: writes the early line to the run's log too (a run points it at rlq.log once it has one)
        self.record: Callable[[str], None] | None = None
        #: what a stop does now, said in the line that acknowledges it (a run's end changes it)
        self.coming = "stopping after this slice with a resumable checkpoint"
        self._previous: dict[int, Any] = {}
        self._wakeup: tuple[int, int] | None = None
        self._old_fd = -1
        self._lock = threading.Lock()
        self._closed = threading.Event()
        self._first_at = 0.0  # time.monotonic() of the first stop
        self._peer_first = False  # the stop came from another process: this one's own signal is the same stop
        self._peer_watcher: threading.Thread | None = None

    def _ignore(self, signum: int, frame: FrameType | None) -> None:
        """The Python-level handler: the watcher thread acts on the signal."""

    def _on_signal(self, signum: int, from_peer: bool = False) -> None:
        with self._lock:
            if from_peer and (self.signum is not None or self._closed.is_set()):
                return  # a stop of this process's own came first
            if self.peers is not None and not from_peer:
                self.peers.publish(signum)
            name = signal.Signals(signum).name
            if self.early is not None:
                line = f"rlq: {self.early(name)}"
                print(line, file=sys.stderr, flush=True)
                if self.record is not None:
                    try:
                        self.record(line)
                    except Exception:  # noqa: BLE001 - the process ends now whatever the log says
                        pass
                if self.peers is not None:
                    self.peers.leave()
                os._exit(128 + signum)
            if self.signum is not None and self._peer_first:  # SLURM signals every task: one stop, not two
                self._peer_first = False
                return
            if self.signum is not None and time.monotonic() - self._first_at < SAME_STOP_S:
                return  # the same stop delivered twice (timeout(1) and kill(0, ...) signal the process and its group)
            if self.signum is not None:  # asked twice: stop now, as the signal would without rlq
                print(f"rlq: {name} again: stopped at once, without a checkpoint", file=sys.stderr, flush=True)
                os._exit(128 + signum)  # from the watcher thread: signal.signal works only in the main thread
            self.signum, self._peer_first, self._first_at = signum, from_peer, time.monotonic()
            self.notify(f"{name}: {self.coming} ({name} again stops at once)")

    def _watch(self, read_fd: int) -> None:
        try:
            while data := os.read(read_fd, 64):
                for signum in data:
                    if signum in SIGNALS:
                        self._on_signal(signum)
        finally:
            os.close(read_fd)

    def _watch_peers(self, peers: Peers) -> None:
        while not self._closed.wait(PEER_POLL_S):
            signum = peers.seen()
            if signum is not None:
                self._on_signal(signum, from_peer=True)
                return

    def __enter__(self) -> StopRequest:
        if threading.current_thread() is threading.main_thread():
            read_fd, write_fd = os.pipe()
            os.set_blocking(write_fd, False)
            self._wakeup = (read_fd, write_fd)
            self._old_fd = signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
            threading.Thread(target=self._watch, args=(read_fd,), name="rlq-signals", daemon=True).start()
            for signum in SIGNALS:
                self._previous[signum] = signal.signal(signum, self._ignore)
            if self.peers is not None:
                self._peer_watcher = threading.Thread(
                    target=self._watch_peers, args=(self.peers,), name="rlq-peer-stops", daemon=True
                )
                self._peer_watcher.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._lock.acquire(timeout=ENDING_WAIT_S):
            # A stop in flight holds the lock; an early one until its os._exit. Its leaving the other processes fails
            # the main thread's collective in flight; were the main thread to end the interpreter then, finalisation
            # would unwind the watcher thread out of JAX's native code, which aborts the process (SIGABRT) instead of
            # the early stop's exit code.
            self._lock.release()
        self._closed.set()
        if self._peer_watcher is not None:
            # its look at the coordination service runs in JAX's native code, which an interpreter's end must not
            # unwind (the process would abort)
            self._peer_watcher.join(timeout=ENDING_WAIT_S)
            self._peer_watcher = None
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()
        if self._wakeup is not None:
            signal.set_wakeup_fd(self._old_fd)
            os.close(self._wakeup[1])  # the watcher reads the end of the pipe and stops
            self._wakeup = None
