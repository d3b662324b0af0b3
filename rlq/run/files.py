"""Files that are either whole or absent: what checkpoints and the program cache write."""

from __future__ import annotations

import os
from pathlib import Path


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file, fsync and rename: a reader (or a run
    killed mid-write) sees the old file or the new one, never part of one."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    directory = os.open(path.parent, os.O_RDONLY)
    try:  # the rename itself survives a power cut only once the directory is on disk
        os.fsync(directory)
    finally:
        os.close(directory)
