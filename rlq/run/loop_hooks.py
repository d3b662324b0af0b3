"""The host's work after each chunk, assembled from a run's config: the hooks the loop calls in order."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rlq.config.spec import RunSpec
from rlq.lib.spaces import Discrete
from rlq.run.collapse import CollapseWatch
from rlq.run.hooks import (
    DrawFigures,
    Hook,
    KeepBest,
    KeepLast,
    LogTrainRows,
    PeriodicCheckpoint,
    PeriodicEval,
    PeriodicVideo,
    StopWhen,
)
from rlq.run.kept import KeepSeedsBest
from rlq.run.programs.build import Programs
from rlq.run.programs.cadences import Cadences
from rlq.run.stops.stop import parse_stop
from rlq.store.logging import RunLogger


def loop_hooks(
    spec: RunSpec,
    programs: Programs,
    run_dir: Path,
    logger: RunLogger,
    evaluate: Callable[[Any, int], dict[str, np.ndarray]],
    video: Callable[[Any, int, str], Path | None] | None,
) -> list[Hook]:
    """The host's work after each chunk, in order: log, the collapse watch (Discrete actions), figures, evaluation
    (its listeners: figures, the stop rule, with ``checkpoint.keep_best`` the best state, with ``eval.keep=best``
    each seed's best), checkpoint (its listener keeps the last ``checkpoint.keep_last``), video (``video``:
    rlq.run.videos.Seed0Video's call), stop rule."""
    hooks: list[Hook] = [LogTrainRows(logger, programs.updates_per_chunk)]
    if isinstance(programs.env.action_space, Discrete):  # a Gaussian's entropy has no zero to fall to
        hooks.append(CollapseWatch(logger, run_dir / "metrics.jsonl", spec.algorithm.get("lr")))
    algo = programs.algo
    at_eval: list[Hook] = []
    if algo.figures is not None:
        figures = DrawFigures(
            algo.figures, algo.figures_every, programs.updates_per_chunk, int(spec.seeds.count), logger
        )
        hooks.append(figures)
        at_eval += [figures] if algo.figures_at_eval else []
    stop_when = spec.budget.stop_when
    stop: list[Hook] = [StopWhen(parse_stop(stop_when), logger)] if stop_when else []
    cadences, chunk_steps = Cadences.from_config(spec), programs.chunk_steps
    directory = run_dir / "checkpoints"
    best: list[Hook] = [KeepBest(directory)] if spec.checkpoints.keep_best else []
    if spec.evaluation.keep == "best":
        best.append(KeepSeedsBest(directory, int(spec.seeds.count)))

    def every_chunks(every_steps: int) -> int:
        return cadences.snapped(every_steps, chunk_steps) // chunk_steps

    hooks.append(PeriodicEval(evaluate, every_chunks(cadences.eval), logger, listeners=at_eval + stop + best))
    keep = [KeepLast(int(spec.checkpoints.keep_last))]
    hooks.append(PeriodicCheckpoint(directory, every_chunks(cadences.checkpoint), keep, logger.wall_s))
    if video is not None and cadences.video:
        hooks.append(PeriodicVideo(video, every_chunks(cadences.video)))
    return hooks + stop
