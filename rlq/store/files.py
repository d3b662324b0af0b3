"""Files that are either whole or absent: what checkpoints and the program cache write."""

from __future__ import annotations

import os
from pathlib import Path

from rlq.store.outputs import check_output_file

#: the temporary files ``write_atomic`` renames into place: ``.<name>.tmp-<pid>``
TEMPORARY = ".*.tmp-*"


def named(err: OSError, path: Path) -> OSError:
    """``err`` with the file it was about (a failed ``write`` names none: ``[Errno 28] No space left on device``)."""
    if err.filename is not None:
        return err
    return type(err)(err.errno, err.strerror or str(err), str(path))


def remove_temporaries(run_dir: Path) -> list[Path]:
    """Remove what writers killed or refused mid-write (a full disk) left of ``write_atomic``'s temporaries in the
    run directory and its ``checkpoints/`` and ``.hydra/``, and in those of an in-program sweep's member runs
    (``members/*``); the caller holds the run lock, so none is in use."""
    runs = [run_dir, *sorted(p for p in (run_dir / "members").glob("*") if p.is_dir())]
    found = [p for r in runs for d in (r, r / "checkpoints", r / ".hydra") for p in d.glob(TEMPORARY)]
    for path in found:
        path.unlink(missing_ok=True)
    return found


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file, fsync and rename: a reader (or a run
    killed mid-write) sees the old file or the new one, never part of one. ``path`` must be absent or a regular
    file (``check_output_file``): the rename would replace a device, a FIFO or a symlink."""
    check_output_file(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as err:  # a full disk: no partial temporary left, and the line names the file
        tmp.unlink(missing_ok=True)
        raise named(err, path) from None
    directory = os.open(path.parent, os.O_RDONLY)
    try:  # the rename itself survives a power cut only once the directory is on disk
        os.fsync(directory)
    finally:
        os.close(directory)
