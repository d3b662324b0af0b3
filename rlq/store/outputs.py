"""The guard every writer asks first: rlq writes regular files and directories of its own, never over a device, a
FIFO, a socket or a symlink, and never a run directory inside another run's tree.

``write_atomic`` renames a temporary file over its target, which replaces whatever the target was: as root,
``out=/dev/full`` would have swapped the device for a regular file. The commands call ``check_output_file`` on each
file they will write before doing any work, so a refusal leaves nothing behind; ``write_atomic`` calls it again.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from rlq.errors import OutputError

#: what a run directory holds once `rlq train` started in it (a run stopped before its first checkpoint included)
RUN_MARKERS = (".hydra/config.yaml", "rlq.lock", "metrics.jsonl", "rlq.log")

_KINDS = (
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISLNK, "a symlink"),
    (stat.S_ISREG, "a file"),
)


def kind_of(mode: int) -> str:
    """What a non-regular file is, in words (``a FIFO``)."""
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def _named(path: Path, key: str | None) -> str:
    return f"{key}={path}" if key else str(path)


def check_output_file(path: Path, key: str | None = None) -> None:
    """``path`` is absent or a regular file rlq may replace; OutputError naming it (``key=path``) otherwise: a
    directory, a device, a FIFO, a socket, or a symlink (replacing it would not write where it points, and writing
    through it would write outside what rlq owns)."""
    path = Path(path)
    try:
        mode = os.lstat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):  # absent (a path through a file: the caller's check says so)
        return
    except OSError as err:  # a path that cannot be looked at
        raise OutputError(f"{_named(path, key)} cannot be written: {err.strerror}") from None
    if stat.S_ISREG(mode):
        return
    if stat.S_ISLNK(mode):
        raise OutputError(
            f"{_named(path, key)} is a symlink (to {os.readlink(path)}); rlq writes only regular files: "
            "give the file's own path or another name"
        )
    if stat.S_ISDIR(mode):
        raise OutputError(f"{_named(path, key)} is a directory; give a file name, e.g. {path / 'out'}")
    raise OutputError(
        f"{_named(path, key)} is {kind_of(mode)}, not a regular file; rlq writes only regular files: give another path"
    )


def enclosing_run(path: Path) -> Path | None:
    """The run directory ``path`` lies inside (a parent of it holding a run's record or lock), if any."""
    resolved = Path(os.path.abspath(path))
    for parent in resolved.parents:
        if any((parent / marker).exists() for marker in RUN_MARKERS):
            return parent
    return None


def is_run_dir(path: Path) -> bool:
    """Whether ``path`` holds what `rlq train` writes first (its record, lock, metrics or log)."""
    return any((Path(path) / marker).exists() for marker in RUN_MARKERS)


def check_not_nested(path: Path, key: str) -> None:
    """``path`` is not inside another run's tree (``hydra.run.dir=<finished run>/checkpoints``)."""
    outer = enclosing_run(path)
    if outer is not None:
        raise OutputError(f"{key}={path} is inside the run {outer}; runs do not nest: give a directory outside it")


def check_run_dir(path: Path, key: str) -> None:
    """``path`` may become a run directory: not inside another run's tree, and absent or a directory (not a symlink
    to one elsewhere) that is empty or an rlq run's."""
    path = Path(path)
    check_not_nested(path, key)
    try:
        mode = os.lstat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):  # absent (a path through a file: the caller's check says so)
        return
    except OSError as err:
        raise OutputError(f"{key}={path} cannot be used: {err.strerror}") from None
    if stat.S_ISLNK(mode):
        raise OutputError(
            f"{key}={path} is a symlink (to {os.readlink(path)}); give the directory's own path or a new directory"
        )
    if not stat.S_ISDIR(mode):
        raise OutputError(f"{key}={path} is {kind_of(mode)}; give a directory")
    if not is_run_dir(path) and any(path.iterdir()):
        raise OutputError(f"{key}={path} holds files rlq did not write; give a new or empty directory")
