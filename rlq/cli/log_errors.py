"""A log handler that cannot write (a full disk under W&B's or Hydra's log file) warns once, at the CLI.

Python's ``logging.Handler.handleError`` prints "--- Logging error ---" and a traceback for every
record it fails to write: on a full disk, hundreds of them around the one line that says so.
"""

from __future__ import annotations

import logging
import sys

_warned: set[int] = set()


def _handle_error(self: logging.Handler, record: logging.LogRecord) -> None:
    if not logging.raiseExceptions or id(self) in _warned:
        return
    _warned.add(id(self))
    err = sys.exc_info()[1]
    where = getattr(self, "baseFilename", None) or type(self).__name__
    print(f"rlq: warning: a log handler cannot write {where} ({err}); its further records are dropped", file=sys.stderr)


def warn_once_on_log_errors() -> None:
    """Every log handler of the process warns once (one line on stderr) where it cannot write, then stays silent."""
    logging.Handler.handleError = _handle_error  # type: ignore[method-assign]
