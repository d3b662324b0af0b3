"""A chunk's wall time, bounded: a chunk of updates runs as calls of one compiled program of a few
updates (its blocks), and the host waits for them in slices of a few seconds, between which a stop
(SIGINT/SIGTERM) is seen. Where the slices fall never changes the numbers: the blocks (and their
programs) follow from the chunk's updates alone.

A chunk is the unit of logging (one train row), evaluations and checkpoints (rlq.run.programs.cadences); a
slice only bounds how long a stop waits for its checkpoint (SLURM kills a job 30 s after its SIGTERM
by default). A process's first slice is one block; each later one is sized from the time per
block measured so far, up to ``TARGET_S`` seconds and at most four times the one before.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rlq.errors import ConfigError

#: the most blocks one chunk is cut into: a block is at least 1/32 of a chunk, so the host calls a
#: program at most 32 times per chunk (a call costs well under a millisecond of the host's time)
MAX_BLOCKS = 32

#: the wall seconds a slice aims at: a stop waits for the slice in flight, then its checkpoint
TARGET_S = 5.0

#: how much a slice may grow over the one before (the time per update can grow during a run,
#: e.g. once DQN's learning starts)
GROWTH = 4


@dataclass(frozen=True)
class BlockPlan:
    """A chunk cut into calls: ``full`` calls of a program of ``size`` updates, then, where ``size``
    does not divide the chunk, one call of a second program of the ``rest`` updates left."""

    size: int
    full: int
    rest: int = 0

    @property
    def calls(self) -> int:
        return self.full + (1 if self.rest else 0)


def block_plan(updates: int) -> BlockPlan:
    """The calls a chunk of ``updates`` updates is cut into, each at most about 1/32 of it: blocks
    of the largest divisor of ``updates`` up to ``MAX_BLOCKS`` where that cuts blocks of at most
    twice that size (one program); otherwise (a prime number of updates above ``MAX_BLOCKS``, or
    one with only small divisors) blocks of ``ceil(updates / MAX_BLOCKS)`` updates and one call of
    the remainder (a second program, compiled only for such chunks)."""
    size = -(-updates // MAX_BLOCKS)
    divisor = max(d for d in range(1, min(updates, MAX_BLOCKS) + 1) if updates % d == 0)
    if updates // divisor <= 2 * size:
        return BlockPlan(updates // divisor, divisor)
    return BlockPlan(size, updates // size, updates % size)


class SliceSizer:
    """How many calls the next slice holds, from the seconds per call measured so far."""

    def __init__(self) -> None:
        self.per_call_s: float | None = None
        self.last = 0

    def next(self, remaining: int) -> int:
        """The calls of the next slice of a chunk with ``remaining`` calls left (at least one)."""
        if self.per_call_s is None:
            calls = 1
        else:
            calls = max(1, min(int(TARGET_S / max(self.per_call_s, 1e-9)), GROWTH * max(1, self.last)))
        self.last = calls
        return min(calls, remaining)

    def record(self, calls: int, seconds: float) -> None:
        """A slice of ``calls`` calls took ``seconds``: the latest rate counts."""
        self.per_call_s = seconds / max(1, calls)


def joined(parts: Sequence[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The metrics of a chunk's calls (on the host), joined along the update axis as one call's would be."""
    return {key: np.concatenate([part[key] for part in parts], axis=1) for key in parts[0]}


@dataclass(frozen=True)
class PartialChunk:
    """The calls of a chunk a stop came in the middle of: how many ran, and their metrics, kept beside
    the checkpoint (``step_<N>.chunk.npz``) so that a resumed run logs the chunk's row as it would have."""

    calls_done: int
    metrics: dict[str, np.ndarray]

    def meta(self, calls_per_chunk: int) -> dict[str, int]:
        return {"chunk_calls_done": self.calls_done, "calls_per_chunk": calls_per_chunk}

    def save(self, checkpoint_path: Path) -> Path:
        path = part_path(checkpoint_path)
        names = sorted(self.metrics)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as f:  # arr_0: the names (an npz's keys cannot hold the metrics' slashes)
            np.savez_compressed(f, np.array(names), *(self.metrics[name] for name in names))
        return path


def part_path(checkpoint_path: Path) -> Path:
    return checkpoint_path.with_name(f"{checkpoint_path.stem}.chunk.npz")


def part_record(parts: Sequence[Mapping[str, np.ndarray]], calls_done: int) -> PartialChunk:
    return PartialChunk(calls_done, joined(parts))


def resumed_part(
    resume: Path | None, meta: Mapping[str, Any], calls_per_chunk: int
) -> tuple[list[dict[str, np.ndarray]], int]:
    """The metrics and the calls done of the chunk a resumed checkpoint was written in the middle of
    (none: ``([], 0)``); a ConfigError where this run cuts its chunks into other calls."""
    done = int(meta.get("chunk_calls_done", 0))
    if resume is None or not done:
        return [], 0
    if int(meta["calls_per_chunk"]) != calls_per_chunk:
        raise ConfigError(
            f"{resume.name} was written after {done} of {meta['calls_per_chunk']} calls of a chunk, and this run "
            f"cuts its chunks into {calls_per_chunk}: resume with the run's own chunk_loop and log_every_steps"
        )
    with np.load(part_path(resume)) as data:
        names = [str(n) for n in data["arr_0"]]
        metrics = {name: data[f"arr_{i + 1}"] for i, name in enumerate(names)}
    return [metrics], done
