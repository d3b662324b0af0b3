"""What the loop does on the host between chunks, as hooks: the loop itself only trains.

After every chunk the loop calls ``on_chunk`` of each hook in order; the evaluation hook calls
``on_eval`` of the hooks listening to evaluations, and the checkpoint hook ``on_checkpoint`` of
those listening to checkpoints. A hook ends a run early by setting ``stop`` (the loop then writes
the final evaluation and checkpoint as at the end of the budget).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rlq.lib.batch import seed_entry
from rlq.lib.sharding import to_host
from rlq.run.stops.stop import StopRule
from rlq.store import checkpoint
from rlq.store.jsonfiles import read_json_object
from rlq.store.logging import RunLogger
from rlq.store.sidecar import HASH_KEY


@dataclass(frozen=True)
class ChunkEnd:
    """Where the run stands after a chunk: its 0-based index, the env steps per seed, the state of
    all seeds (on the device), the chunk's metrics summary, and whether it is the budget's last."""

    index: int
    env_steps: int
    state: Any
    summary: dict[str, np.ndarray]
    last: bool
    #: env steps per seed of one chunk (nominal), for a run extended with another budget, whose chunks may differ
    chunk_steps: int = 0
    #: the run's ``config_hash`` (rlq.store.sidecar), recorded in its checkpoints' sidecars
    config_sha256: str | None = None
    #: the chunk's metrics per update (seeds x updates, on the host), of which ``summary`` is the mean
    updates: Mapping[str, np.ndarray] | None = None


class Hook:
    """A no-op hook; subclasses override what they need."""

    #: set to end the run after this chunk; ``reason`` says why (summary line and summary.json)
    stop: bool = False
    reason: str = ""
    #: a listener of PeriodicEval that is also told of the run's final evaluation
    at_final: bool = False
    #: warnings the run's summary.json lists (``warnings``), e.g. a collapsed policy (rlq.run.collapse)
    flags: tuple[str, ...] = ()

    def on_chunk(self, end: ChunkEnd) -> None:
        pass

    def on_eval(self, end: ChunkEnd, result: dict[str, np.ndarray]) -> None:
        pass

    def on_checkpoint(self, end: ChunkEnd, path: Path) -> None:
        pass

    def on_final_eval(self, end: ChunkEnd, result: dict[str, np.ndarray]) -> None:
        """The run's final evaluation, after its last chunk (the loop has logged it)."""


def save_step_checkpoint(
    directory: Path, end: ChunkEnd, wall_s: float | None, extra: dict[str, Any] | None = None
) -> Path:
    """The whole state after chunk ``end`` as ``step_<N>.msgpack``, with what resume needs: the env
    steps, the chunks done (black-box algorithms' true env steps fall below the chunks' nominal
    ones) and the run's wall clock; ``extra``: more of it (a stop in the middle of a chunk)."""
    meta: dict[str, Any] = {"env_steps": end.env_steps, "chunks_done": end.index + 1, **(extra or {})}
    if end.chunk_steps:
        meta["chunk_steps"] = end.chunk_steps
    if wall_s is not None:
        meta["wall_s"] = wall_s
    if end.config_sha256:
        meta[HASH_KEY] = end.config_sha256
    return checkpoint.save(directory, f"step_{end.env_steps}", end.state, meta)


def fires(end: ChunkEnd, every_chunks: int) -> bool:
    """Whether a periodic hook fires after this chunk: every ``every_chunks``-th chunk (0: never),
    the budget's last chunk excepted (the run's end has its own evaluation, checkpoint and video).

    Cadences are counted in chunks, not env steps (rlq.run.programs.cadences.Cadences snaps each to whole
    chunks): a resumed run goes on with the same chunk indices, and black-box algorithms, whose true
    env steps fall below the chunks' nominal steps, keep the schedule too."""
    return every_chunks > 0 and not end.last and (end.index + 1) % every_chunks == 0


class LogTrainRows(Hook):
    """The chunk's training metrics to the console, metrics.jsonl and W&B (``updates_per_chunk``: the
    iterations a chunk adds to a progress bar that counts them)."""

    def __init__(self, logger: RunLogger, updates_per_chunk: int = 1):
        self.logger, self.per_chunk = logger, updates_per_chunk

    def on_chunk(self, end: ChunkEnd) -> None:
        self.logger.log(end.env_steps, "train", end.summary, iterations=(end.index + 1) * self.per_chunk)


def seed_figures(figures: Callable[[Any], dict[str, np.ndarray]], state: Any, num_seeds: int) -> list[dict]:
    """The algorithm's pictures of each seed's state, drawn on the host."""
    host = to_host(state)
    return [figures(seed_entry(host, i, num_seeds)) for i in range(num_seeds)]


class DrawFigures(Hook):
    """The algorithm's figures (e.g. MAP-Elites heatmaps) every ``every_updates`` updates, and at
    each evaluation where it listens to ``PeriodicEval``."""

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

    def draw(self, end: ChunkEnd) -> None:
        pictures = seed_figures(self.figures, end.state, self.num_seeds)
        self.logger.figures(end.env_steps, pictures, f"step_{end.env_steps}")

    def on_chunk(self, end: ChunkEnd) -> None:
        if self.due(end.index) and not end.last:
            self.draw(end)

    def on_eval(self, end: ChunkEnd, result: dict[str, np.ndarray]) -> None:
        """Listening to ``PeriodicEval`` (``Algorithm.figures_at_eval``): figures at each evaluation."""
        if not self.due(end.index):  # not drawn for this chunk already
            self.draw(end)


class PeriodicEval(Hook):
    """A greedy evaluation of every seed every ``every_chunks`` chunks."""

    def __init__(
        self,
        evaluate: Callable[[Any, int], dict[str, np.ndarray]],
        every_chunks: int,
        logger: RunLogger,
        listeners: Sequence[Hook] = (),
    ):
        self.evaluate, self.every, self.logger = evaluate, every_chunks, logger
        self.listeners = list(listeners)
        #: the latest evaluation's env steps and result (a run that a stop rule ends there is not evaluated again)
        self.last: tuple[int, dict[str, np.ndarray]] | None = None

    def on_chunk(self, end: ChunkEnd) -> None:
        if not fires(end, self.every):
            return
        result = self.evaluate(end.state, end.index)
        self.last = (end.env_steps, result)
        self.logger.log(end.env_steps, "eval", result)
        for hook in self.listeners:
            hook.on_eval(end, result)

    def on_final_eval(self, end: ChunkEnd, result: dict[str, np.ndarray]) -> None:
        """Passed on to the listeners with ``at_final``."""
        for hook in self.listeners:
            if hook.at_final:
                hook.on_eval(end, result)


class PeriodicCheckpoint(Hook):
    """The whole state of all seeds to ``checkpoints/step_<N>.msgpack`` every ``every_chunks`` chunks;
    ``clock``: the run's wall seconds, recorded so that a resumed run's clock goes on from them."""

    def __init__(
        self,
        directory: Path,
        every_chunks: int,
        listeners: Sequence[Hook] = (),
        clock: Callable[[], float] | None = None,
    ):
        self.directory, self.every, self.clock = directory, every_chunks, clock
        self.listeners = list(listeners)

    def on_chunk(self, end: ChunkEnd) -> None:
        if not fires(end, self.every):
            return
        path = save_step_checkpoint(self.directory, end, self.clock() if self.clock is not None else None)
        for hook in self.listeners:
            hook.on_checkpoint(end, path)


class PeriodicVideo(Hook):
    """Seed 0's greedy episode as ``videos/step_<N>_seed0.mp4`` every ``every_chunks`` chunks
    (``write``: rlq.run.videos.Seed0Video; the run's end has its own video, ``video.at_end``)."""

    def __init__(self, write: Callable[[Any, int, str], Path | None], every_chunks: int):
        self.write, self.every = write, every_chunks

    def on_chunk(self, end: ChunkEnd) -> None:
        if fires(end, self.every):
            self.write(end.state, end.env_steps, f"step_{end.env_steps}_seed0")


class StopWhen(Hook):
    """Ends the run once ``rule`` (``stop.when``) holds for the mean over seeds of a training
    chunk's metric (``train/``, on every chunk) or an evaluation's (``eval/``, as a listener of
    ``PeriodicEval``). A metric the rows do not have is reported once and never stops the run."""

    def __init__(self, rule: StopRule, logger: RunLogger):
        self.rule, self.logger = rule, logger
        self._missing_told = False

    def _check(self, env_steps: int, row: dict[str, np.ndarray]) -> None:
        if self.rule.metric not in row:
            if not self._missing_told:
                names = ", ".join(sorted(row))
                self.logger.console.warn(
                    f"stop.when: {self.rule.kind} rows have no '{self.rule.metric}' (they have: {names})"
                )
                self._missing_told = True
            return
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            value = float(np.nanmean(np.asarray(row[self.rule.metric], np.float64)))
        if self.rule.met(value):
            self.stop = True
            self.reason = f"stop.when {self.rule} met at {env_steps:,} env steps (mean over seeds {value:.4g})"
            self.logger.console.message(f"rlq: {self.reason}")

    def on_chunk(self, end: ChunkEnd) -> None:
        if self.rule.kind == "train":
            self._check(end.env_steps, end.summary)

    def on_eval(self, end: ChunkEnd, result: dict[str, np.ndarray]) -> None:
        if self.rule.kind == "eval":
            self._check(end.env_steps, result)


class KeepLast(Hook):
    """Listens to PeriodicCheckpoint: keeps the newest ``keep`` ``step_*`` checkpoints, deletes the
    older ones (0: keeps all)."""

    def __init__(self, keep: int):
        self.keep = keep

    def on_checkpoint(self, end: ChunkEnd, path: Path) -> None:
        if self.keep <= 0:
            return
        periodic = checkpoint.intermediate(path.parent)
        for old in periodic[: -self.keep]:
            for part in old.parent.glob(f"{old.stem}.*"):
                part.unlink(missing_ok=True)


class KeepBest(Hook):
    """Listens to PeriodicEval: the state of the best greedy return so far (mean over seeds) goes to
    ``checkpoints/best.msgpack``, its sidecar records the env steps and the return. A resumed run
    reads the best so far from the sidecar. The run's final evaluation counts too."""

    at_final = True

    def __init__(self, directory: Path):
        self.directory = directory
        sidecar = directory / "best.json"
        self.best = float(read_json_object(sidecar).get("eval_return", -math.inf)) if sidecar.exists() else -math.inf

    def on_eval(self, end: ChunkEnd, result: dict[str, np.ndarray]) -> None:
        value = float(np.nanmean(np.asarray(result["return"], np.float64)))
        if not value > self.best:
            return
        self.best = value
        meta: dict[str, Any] = {"env_steps": end.env_steps, "chunks_done": end.index + 1, "eval_return": value}
        if end.config_sha256:
            meta[HASH_KEY] = end.config_sha256
        checkpoint.save(self.directory, "best", end.state, meta)
