"""rlq's typed exceptions: library code raises them, the CLI turns them into one line and exit 2."""

from __future__ import annotations


class RlqError(Exception):
    """Any error rlq reports to the user as one line (the CLI exits with code 2)."""


class ConfigError(RlqError, ValueError):
    """A config value, override or combination rlq cannot run."""


class UsageError(RlqError):
    """A malformed command line (an argument that is not key=value, an unknown option)."""


class RunDirError(RlqError):
    """A run directory that is missing or was not written by `rlq train`."""


class CheckpointError(RlqError):
    """A checkpoint that is missing, unreadable, or cannot continue this run."""


class ExportError(RlqError):
    """A run whose policy `rlq export` cannot write as network parameters (e.g. a Q-table)."""
