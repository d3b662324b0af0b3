"""Dependency noise kept off the console, at the CLI only (the libraries stay as they are):
MuJoCo's MJX prints "Failed to import warp" and "Failed to import mujoco_warp" when it is imported
without MuJoCo Warp (rlq's MJX runs use JAX; `env.mjx_impl=warp` says itself what it needs), logs
"Using JAX default device" on the root logger for every model it places (the train and evaluation
envs: twice a run), and brax warns that its System is not maintained each time a humanoid is loaded."""

from __future__ import annotations

import contextlib
import importlib.abc
import importlib.machinery
import io
import logging
import sys
import warnings
from collections.abc import Sequence
from types import ModuleType

#: modules that print on import, and the beginnings of the lines of theirs that are dropped
QUIET_IMPORTS = {"mujoco.mjx.warp": ("Failed to import warp:", "Failed to import mujoco_warp:")}
#: root-logger messages of dependencies that are dropped (beginnings)
QUIET_LOGS = ("Using JAX default device",)
#: loggers of dependencies whose records are dropped: W&B's telemetry exporter logs "Failed to export ... 401" after
#: a run that fell back to offline logging, which the run's own warning has already explained
QUIET_LOGGERS = ("opentelemetry",)
#: dependency warnings that are ignored (regular expressions of their messages' beginnings)
QUIET_WARNINGS = (r"Brax System, piplines and environments are not actively being maintained",)


class _QuietLoader(importlib.abc.Loader):
    def __init__(self, loader: importlib.abc.Loader, dropped: tuple[str, ...]):
        self.loader, self.dropped = loader, dropped

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return self.loader.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        with contextlib.redirect_stdout(io.StringIO()) as out:
            self.loader.exec_module(module)
        kept = [line for line in out.getvalue().splitlines() if not line.startswith(self.dropped)]
        if kept:
            print("\n".join(kept))


class _QuietImports(importlib.abc.MetaPathFinder):
    """Finds the modules of ``QUIET_IMPORTS`` as the other finders do and runs them with their lines dropped."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in QUIET_IMPORTS:
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path, target)
        if spec is not None and spec.loader is not None:
            spec.loader = _QuietLoader(spec.loader, QUIET_IMPORTS[fullname])
        return spec


class _DropMessages(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith(QUIET_LOGS)


def quiet_dependencies() -> None:
    """Install the filters, once per process (before any dependency is imported)."""
    if not any(isinstance(finder, _QuietImports) for finder in sys.meta_path):
        sys.meta_path.insert(0, _QuietImports())
    root = logging.getLogger()
    if not any(isinstance(f, _DropMessages) for f in root.filters):
        root.addFilter(_DropMessages())
    for message in QUIET_WARNINGS:
        warnings.filterwarnings("ignore", message=message, category=UserWarning)
    for name in QUIET_LOGGERS:
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)
