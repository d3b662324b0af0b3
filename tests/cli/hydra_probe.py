"""A Hydra callback that appends the events it sees to a file (tests/cli/test_single_run.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback


class Probe(Callback):
    def __init__(self, path: str) -> None:
        self.path = Path(path)

    def _log(self, event: str) -> None:
        with self.path.open("a") as file:
            file.write(event + "\n")

    def on_run_start(self, config: Any, **kwargs: Any) -> None:
        self._log("run_start")

    def on_job_start(self, config: Any, **kwargs: Any) -> None:
        self._log("job_start")

    def on_job_end(self, config: Any, job_return: Any, **kwargs: Any) -> None:
        self._log(f"job_end {job_return.status.name}")

    def on_run_end(self, config: Any, **kwargs: Any) -> None:
        self._log("run_end")
