"""One process per run directory: an advisory lock on ``<run dir>/rlq.lock``.

``flock`` is released by the kernel when its process ends, however it ends (a SLURM kill, a
crash), so a stale lock file never blocks `rlq resume`; the file itself stays.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rlq.errors import RunLockedError
from rlq.store.files import remove_temporaries

LOCK_NAME = "rlq.lock"


def _holder(fd: int) -> str:
    os.lseek(fd, 0, os.SEEK_SET)
    pid = os.read(fd, 32).decode(errors="replace").strip()
    return f"pid {pid}" if pid else "another process"


def locked_by(run_dir: Path) -> str | None:
    """Who holds the run directory's lock now (e.g. ``pid 1234``), or None."""
    path = Path(run_dir) / LOCK_NAME
    if not path.exists():
        return None
    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return _holder(fd)
    finally:
        os.close(fd)
    return None


@contextmanager
def run_lock(run_dir: Path) -> Iterator[None]:
    """Hold the run directory's lock; RunLockedError when another rlq process holds it."""
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    fd = os.open(run_dir / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise RunLockedError(
                f"{run_dir} is in use by another rlq process ({_holder(fd)}); wait for it or use another directory"
            ) from None
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        yield
    finally:
        os.close(fd)


def remove_leftovers(run_dir: Path) -> list[Path]:
    """``remove_temporaries`` of a run no process trains in now (its lock is free; taken for the moment it takes):
    what a writer killed mid-write left, removed by the next command that reads the run. Nothing where the run is
    in use, was never trained here (no lock file), or cannot be changed (a read-only copy)."""
    path = Path(run_dir) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return []
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return remove_temporaries(Path(run_dir))
    except OSError:  # held by a training process (BlockingIOError), or a file that cannot be removed
        return []
    finally:
        os.close(fd)
