"""What the loop does on the host between chunks, as hooks: the loop itself only trains.

After every chunk the loop calls ``on_chunk`` of each hook in order; the evaluation hook calls
``on_eval`` of the hooks listening to evaluations, and the checkpoint hook ``on_checkpoint`` of
those listening to checkpoints. A hook ends a run early by setting ``stop`` (the loop then writes
the final evaluation and checkpoint as at the end of the budget).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import numpy as np

from rlq.run import checkpoint
from rlq.run.logging import RunLogger


@dataclass(frozen=True)
class ChunkEnd:
    """Where the run stands after a chunk: its 0-based index, the env steps per seed, the state of
    all seeds (on the device), the chunk's metrics summary, and whether it is the budget's last."""

    index: int
    env_steps: int
    state: Any
    summary: dict[str, np.ndarray]
    last: bool


class Hook:
    """A no-op hook; subclasses override what they need."""

    stop: bool = False

    def on_chunk(self, end: ChunkEnd) -> None:
        pass

    def on_eval(self, end: ChunkEnd, result: dict[str, np.ndarray]) -> None:
        pass

    def on_checkpoint(self, end: ChunkEnd, path: Path) -> None:
        pass


def next_multiple(steps: int, every: int) -> int | None:
    """The first multiple of ``every`` after ``steps`` (None when ``every`` is 0: never)."""
    return (steps // every + 1) * every if every else None


class LogTrainRows(Hook):
    """The chunk's training metrics to the console, metrics.jsonl and W&B."""

    def __init__(self, logger: RunLogger):
        self.logger = logger

    def on_chunk(self, end: ChunkEnd) -> None:
        self.logger.log(end.env_steps, "train", end.summary)


def seed_figures(figures: Callable[[Any], dict[str, np.ndarray]], state: Any, num_seeds: int) -> list[dict]:
    """The algorithm's pictures of each seed's state, drawn on the host."""
    host = jax.device_get(state)
    return [figures(jax.tree.map(lambda x, i=i: x[i], host)) for i in range(num_seeds)]


class DrawFigures(Hook):
    """The algorithm's figures (e.g. MAP-Elites heatmaps) every ``every_updates`` updates."""

    def __init__(
        self,
        figures: Callable[[Any], dict[str, np.ndarray]],
        every_updates: int,
        updates_per_chunk: int,
        num_seeds: int,
        logger: RunLogger,
    ):
        self.figures, self.every, self.per_chunk = figures, every_updates, updates_per_chunk
        self.num_seeds, self.logger = num_seeds, logger

    def due(self, chunk: int) -> bool:
        """Whether chunk ``chunk`` (0-based) crossed a multiple of the figure cadence."""
        if self.every <= 0:
            return False
        return (chunk + 1) * self.per_chunk // self.every > chunk * self.per_chunk // self.every

    def on_chunk(self, end: ChunkEnd) -> None:
        if self.due(end.index) and not end.last:
            pictures = seed_figures(self.figures, end.state, self.num_seeds)
            self.logger.figures(end.env_steps, pictures, f"step_{end.env_steps}")


class PeriodicEval(Hook):
    """A greedy evaluation of every seed once ``every_steps`` more env steps have passed."""

    def __init__(
        self,
        evaluate: Callable[[Any, int], dict[str, np.ndarray]],
        every_steps: int,
        start_steps: int,
        logger: RunLogger,
        listeners: Sequence[Hook] = (),
    ):
        self.evaluate, self.every, self.logger = evaluate, every_steps, logger
        self.next = next_multiple(start_steps, every_steps)
        self.listeners = list(listeners)

    def on_chunk(self, end: ChunkEnd) -> None:
        if self.next is None or end.env_steps < self.next or end.last:
            return
        result = self.evaluate(end.state, end.index)
        self.logger.log(end.env_steps, "eval", result)
        self.next = next_multiple(end.env_steps, self.every)
        for hook in self.listeners:
            hook.on_eval(end, result)


class PeriodicCheckpoint(Hook):
    """The whole state of all seeds to ``checkpoints/step_<N>.msgpack`` every ``every_steps`` env steps."""

    def __init__(self, directory: Path, every_steps: int, start_steps: int, listeners: Sequence[Hook] = ()):
        self.directory, self.every = directory, every_steps
        self.next = next_multiple(start_steps, every_steps)
        self.listeners = list(listeners)

    def on_chunk(self, end: ChunkEnd) -> None:
        if self.next is None or end.env_steps < self.next or end.last:
            return
        meta = {"env_steps": end.env_steps, "chunks_done": end.index + 1}
        path = checkpoint.save(self.directory, f"step_{end.env_steps}", end.state, meta)
        self.next = next_multiple(end.env_steps, self.every)
        for hook in self.listeners:
            hook.on_checkpoint(end, path)
