"""How a run's cadences (logging, evaluation, checkpoints, videos) become chunks of updates."""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Any

from rlq.config.spec import RunSpec, as_spec
from rlq.run.stops.stop import parse_stop


@dataclass(frozen=True)
class Cadences:
    """The env-step cadences a run asks for: train rows (``log_every_steps``: one chunk), greedy
    evaluations, checkpoints and videos (0: never). Those run at chunk ends, so each snaps to the
    nearest whole number of chunks unless the chunk's env steps divide it."""

    log: int
    eval: int = 0
    checkpoint: int = 0
    video: int = 0

    @classmethod
    def from_config(cls, run: RunSpec | Mapping[str, Any]) -> Cadences:
        spec = as_spec(run)
        every = (spec.evaluation.every_steps, spec.checkpoints.every_steps, spec.outputs.video.every_steps)
        return cls(int(spec.budget.log_every_steps), *(int(e) for e in every))

    def periodic(self) -> tuple[tuple[str, int], ...]:
        return (
            ("eval.every_steps", self.eval),
            ("checkpoint.every_steps", self.checkpoint),
            ("video.every_steps", self.video),
        )

    def misses(self, chunk_steps: int) -> int:
        """How many of the cadences the chunk's env steps miss (rows would not fall on them)."""
        periodic = [every for _, every in self.periodic() if every]
        return int(self.log != chunk_steps) + sum(every % chunk_steps != 0 for every in periodic)

    @staticmethod
    def snapped(every: int, chunk_steps: int) -> int:
        """``every`` rounded to a whole number (at least one) of chunks; 0 stays 0 (never)."""
        return max(1, math.floor(every / chunk_steps + 0.5)) * chunk_steps if every else 0

    def snap_notes(
        self,
        chunk_steps: int,
        total_steps: int | None = None,
        single_update: bool = False,
        asked: Collection[str] | None = None,
    ) -> list[str]:
        """One line per cadence the chunks cannot hit, saying what it snaps to (cadences beyond
        ``total_steps``, which only the end of the run reaches, need none; nor a log cadence below
        a chunk of one update, ``single_update``, the finest there is: e.g. ``log_every_steps=1``,
        a row per MAP-Elites iteration). ``asked``: the cadence keys the user set (None: all); a
        default nobody set snaps without a word."""
        notes: list[tuple[str, str]] = []
        if total_steps is not None and total_steps <= chunk_steps:  # one chunk: everything comes at its end
            if self.checkpoint and self.checkpoint < total_steps:  # a checkpoint cadence asked for resumability
                notes.append(
                    (
                        "checkpoint.every_steps",
                        f"checkpoint.every_steps={self.checkpoint}: the budget ({total_steps:,} env steps) is one "
                        "chunk, so the only checkpoint is the final one; a smaller log_every_steps makes more chunks",
                    )
                )
            return [text for key, text in notes if asked is None or key in asked]
        finest = single_update and self.log < chunk_steps
        if self.log != chunk_steps and not finest and (total_steps is None or self.log < total_steps):
            notes.append(
                (
                    "log_every_steps",
                    f"log_every_steps={self.log} snaps to {chunk_steps:,} (one chunk: metrics leave the device once "
                    "per chunk)",
                )
            )
        for key, every in self.periodic():
            if every and every % chunk_steps and (total_steps is None or every < total_steps):
                snapped = self.snapped(every, chunk_steps)
                notes.append(
                    (
                        key,
                        f"{key}={every} snaps to {snapped:,} (every {snapped // chunk_steps} chunk"
                        f"{'s' if snapped // chunk_steps > 1 else ''} of {chunk_steps:,} env steps)",
                    )
                )
        return [text for key, text in notes if asked is None or key in asked]

    def stop_note(self, when: str | None, chunk_steps: int, total_steps: int) -> str | None:
        """The note of an ``eval/`` rule of ``stop.when`` that no evaluation checks: no periodic
        evaluation falls before the run's last chunk (the final evaluation does not apply it)."""
        if not when or parse_stop(when).kind != "eval":
            return None
        if self.eval and self.snapped(self.eval, chunk_steps) < total_steps:
            return None
        chunks = f", in whole chunks of {chunk_steps:,} env steps," if self.eval else ""
        return (
            f"stop.when={when!r} is never checked: eval.every_steps={self.eval}{chunks} evaluates only at the end "
            f"of the run's {total_steps:,} env steps; give eval.every_steps (and log_every_steps, the chunk "
            "evaluations fall between) below that"
        )


def asked_keys() -> set[str] | None:
    """The config keys the command line set (Hydra's task overrides of the job); None outside a Hydra job."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return None
    return {str(item).split("=", 1)[0].lstrip("+~") for item in HydraConfig.get().overrides.task}


def chunk_plan(num_updates: int, steps_per_update: int, cadences: Cadences, done: int = 0) -> tuple[int, int]:
    """(updates per chunk, number of chunks): equal chunks, so one compiled program.

    The chunk length is chosen between half and twice the logging cadence to waste the fewest
    updates (a run never exceeds ``num_updates``; most budgets are hit exactly), then to land on
    the most cadences (a chunk of exactly ``log_every_steps``, evaluations and checkpoints on
    whole numbers of chunks), then closest to the logging cadence.

    ``done``: updates a resumed run has already taken, which its chunks must divide (a run extended
    to a larger budget goes on from a whole chunk); the chunk is then at most twice the cadence.
    """
    target = max(1, cadences.log // max(1, steps_per_update))
    if done:
        candidates = [k for k in range(1, min(num_updates, 2 * target) + 1) if done % k == 0]
    elif target >= num_updates:
        return num_updates, 1
    else:
        candidates = list(range(max(1, target // 2), min(num_updates, 2 * target) + 1))
    best = min(
        candidates,
        key=lambda k: (
            num_updates - k * (num_updates // k),
            cadences.misses(k * steps_per_update),
            abs(k - target),
            -k,
        ),
    )
    return best, num_updates // best
