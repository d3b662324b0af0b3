"""rlq's typed exceptions: library code raises them, the CLI turns them into one line and an exit code."""

from __future__ import annotations


class RlqError(Exception):
    """Any error rlq reports to the user as one line (the CLI exits with ``exit_code``)."""

    exit_code = 2


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


class OutputError(ConfigError):
    """An output path (``out=``, ``hydra.run.dir``) rlq will not write: a device, a FIFO, a socket or a symlink where a regular file goes, or a
    run directory inside another run (rlq.store.outputs)."""


class PeersMissingError(ConfigError):
    """A run over several processes whose processes did not all join within ``distributed.timeout_s``. The wait
    blocks in JAX's native code, which a Python exception does not stop: the CLI prints the line and ends the
    process at once (``abandons_threads``)."""

    abandons_threads = True


class DamagedFileError(RunDirError):
    """A run's JSON or JSONL file that is not what rlq wrote (garbage, a cut in the middle): rlq.store.jsonfiles."""


class RunLockedError(RunDirError):
    """A run directory another rlq process is training in."""


class DivergedError(RlqError):
    """Training produced NaN or Inf (the CLI exits with code 3; the last good checkpoint is kept)."""

    exit_code = 3


class RunInterrupted(RlqError):
    """SIGINT or SIGTERM stopped training at a chunk boundary after a resumable checkpoint (the CLI
    exits with 128 + the signal's number, as a shell reports a process the signal killed)."""

    def __init__(self, message: str, signum: int):
        super().__init__(message)
        self.exit_code = 128 + signum
