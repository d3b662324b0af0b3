"""What a run ends with: per-chunk and evaluation summaries, the RunResult, and the errors that stop a run
(divergence, a signal) with what to do next."""

from __future__ import annotations

import signal
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax
import numpy as np

from rlq.errors import DivergedError, RunInterrupted
from rlq.run.hooks import (
    ChunkEnd,
    save_step_checkpoint,
)
from rlq.run.stops import guard
from rlq.run.stops.slices import PartialChunk
from rlq.store import checkpoint

#: cumulative metrics and the state at a chunk's end: a chunk reports their last value
COUNTERS = ("env_steps", "evaluations", "return_window")


def chunk_summary(metrics: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Per-seed figures of a chunk: the last value of counters, the NaN-aware mean of the rest."""
    out = {}
    for key, value in jax.device_get(metrics).items():
        value = np.asarray(value, np.float64)
        if key in COUNTERS:
            out[key] = value[:, -1]
        else:
            finite = np.isfinite(value)
            count = finite.sum(axis=1)
            total = np.where(finite, value, 0.0).sum(axis=1)
            out[key] = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return out


def eval_summary(record: dict[str, jax.Array]) -> dict[str, np.ndarray]:
    record = jax.device_get(record)
    out = {
        "return": np.mean(record.pop("episode_return"), axis=1),
        "length": np.mean(record.pop("episode_length"), axis=1),
    }
    for key, raw in record.items():
        value = np.asarray(raw)
        if value.ndim == 2 and np.issubdtype(value.dtype, np.number):
            out[key] = value.mean(axis=1)
        elif value.ndim == 1 and np.issubdtype(value.dtype, np.number):  # per seed (Algorithm.state_metrics)
            out[key] = value
    return out


def per_seed_lists(figures: Mapping[str, Any]) -> dict[str, list[float]]:
    """Per-seed figures (``eval_summary``'s) as JSON lists."""
    return {k: [float(x) for x in np.asarray(v).reshape(-1)] for k, v in figures.items()}


@dataclass
class RunResult:
    env_steps: int
    num_seeds: int
    #: seconds of the run's wall clock; a resumed run's counts on from its checkpoint's
    wall_s: float
    compile_s: float
    steady_steps_per_s: float
    eval_return: np.ndarray
    run_dir: Path
    state: Any = field(repr=False)
    #: env steps per seed of the checkpoint this process resumed from (0: trained from the start)
    start_steps: int = 0
    #: seconds of each training chunk (compiled program call and metrics transfer), in order
    chunk_s: tuple[float, ...] = ()
    #: per-seed figures of the final evaluation (return, length, env metrics, Algorithm.state_metrics)
    final_eval: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    #: why the run ended before its budget (``stop.when``), else empty
    stopped: str = ""
    #: the programs loaded whole from the compile cache (rlq.run.programs.program_cache), not traced
    cached_programs: tuple[str, ...] = ()
    #: the programs this run did not compile: ``cached_programs`` and those JAX's persistent cache supplied
    compile_cache_hits: tuple[str, ...] = ()
    #: seconds of this process's wall clock (a resumed run's ``wall_s`` counts its earlier processes too)
    process_s: float | None = None
    #: what the run warned about and summary.json lists, e.g. ``policy_collapse ...`` (rlq.run.collapse)
    warnings: tuple[str, ...] = ()
    #: ``eval.keep=best``: each seed's kept state's env steps (``from_env_steps``) and its fresh evaluation (``eval``,
    #: per-seed figures; ``eval_return`` is its return, ``final_eval`` stays the last state's), else None
    kept: dict[str, Any] | None = None

    def as_dict(self) -> dict[str, Any]:
        return {
            "env_steps": self.env_steps,
            "num_seeds": self.num_seeds,
            "wall_s": round(self.wall_s, 3),
            "compile_s": round(self.compile_s, 3),
            "steady_env_steps_per_s": round(self.steady_steps_per_s, 1),
            "eval_return": [float(r) for r in self.eval_return],
            "eval_return_mean": float(np.mean(self.eval_return)) if len(self.eval_return) else None,
            "resumed_from_env_steps": self.start_steps,
            "chunk_s": [round(t, 3) for t in self.chunk_s],
            "final_eval": per_seed_lists(self.final_eval),
            "stopped": self.stopped,
            "cached_programs": list(self.cached_programs),
            "compile_cache_hits": list(self.compile_cache_hits),
            "process_wall_s": round(self.wall_s if self.process_s is None else self.process_s, 3),
            "warnings": list(self.warnings),
            **({"kept": {**self.kept, "eval": per_seed_lists(self.kept["eval"])}} if self.kept is not None else {}),
        }

    def duration(self) -> str:
        """This process's seconds, and a resumed run's total beside them."""
        if self.start_steps and self.process_s is not None:
            return f"{self.process_s:.1f} s (run total {self.wall_s:.1f} s)"
        return f"{self.wall_s:.1f} s"

    def line(self) -> str:
        per_seed = ", ".join(f"{r:.1f}" for r in self.eval_return)
        resumed = f" (resumed at {self.start_steps:,})" if self.start_steps else ""
        qd = ""
        if "archive-occupancy" in self.final_eval:
            coverage = 100 * float(np.mean(self.final_eval["archive-occupancy"]))
            qd = f" | archive coverage {coverage:.1f} %, QD score {float(np.mean(self.final_eval['qd-score'])):.4g}"
        stopped = f" | {self.stopped}" if self.stopped else ""
        which = "final greedy eval return"
        if self.kept is not None:
            last = np.mean(self.final_eval.get("return", np.zeros(0)))
            steps = ", ".join(f"{s:,}" for s in self.kept["from_env_steps"])
            which = f"last state's greedy return {last:.1f} | kept states' (from env steps {steps}) greedy eval return"
        return (
            f"rlq: {self.env_steps:,} env steps{resumed} x {self.num_seeds} seed(s) in {self.duration()} "
            f"(compile {self.compile_s:.1f} s, {self.steady_steps_per_s:,.0f} env steps/s) | "
            f"{which} {np.mean(self.eval_return):.1f} (seeds: {per_seed}){qd}{stopped} | {self.run_dir}"
        )


def resumed_chunks(meta: Mapping[str, Any], chunk_steps: int) -> int:
    """The chunks of ``chunk_steps`` env steps a checkpoint with ``meta`` follows: its ``chunks_done`` of its own
    ``chunk_steps`` (a run extended with another budget may plan chunks of another size), else its env steps'."""
    done = int(meta.get("chunks_done", int(meta["env_steps"]) // chunk_steps))
    return done * int(meta.get("chunk_steps", chunk_steps)) // chunk_steps


def diverged(run_dir: Path, name: str, seed: int, env_steps: int, bounds: guard.Bounds | None = None) -> DivergedError:
    """The error of a run stopped by the divergence guard, naming the checkpoint to go back to."""
    good = checkpoint.last_intact(run_dir / "checkpoints")
    kept = (
        f"last good checkpoint: {good}" if good else "no checkpoint was written before it (see checkpoint.every_steps)"
    )
    limit = bounds.limit(name) if bounds else None
    what = f"NaN/Inf or beyond {limit[0]}={limit[1]:g}" if limit else "NaN/Inf"
    return DivergedError(
        f"training diverged: {name} is {what} at env step {env_steps:,} (seed {seed}); stopped, {kept}"
    )


def interrupted(
    run_dir: Path,
    signum: int,
    end: ChunkEnd,
    wall_s: float,
    part: PartialChunk | None = None,
    calls_per_chunk: int = 1,
    skipped_eval: bool = False,
) -> RunInterrupted:
    """Save a resumable checkpoint of the state after chunk ``end`` (unless the periodic hook just
    did), or, with ``part``, in the middle of the chunk after ``end`` (its calls' metrics beside it),
    and the error that ends the run with the signal's exit code. ``skipped_eval``: the stop came
    during the chunk's evaluation, which the resumed run makes first."""
    path = run_dir / "checkpoints" / f"step_{end.env_steps}.msgpack"
    if part is not None:
        part.save(path)  # first: the checkpoint that names it is then never without it
        path = save_step_checkpoint(path.parent, end, wall_s, part.meta(calls_per_chunk))
    elif skipped_eval or not path.exists():
        path = save_step_checkpoint(path.parent, end, wall_s, {"eval_skipped": True} if skipped_eval else None)
    skipped = ", skipping its evaluation (`rlq resume` makes it)" if skipped_eval else ""
    return RunInterrupted(
        f"stopped by {signal.Signals(signum).name} at env step {end.env_steps:,}{skipped}: checkpoint "
        f"{path}; continue with `rlq resume run={run_dir}`",
        signum,
    )


def final_eval_interrupted(run_dir: Path, signum: int, env_steps: int, kept: dict[str, Any] | None) -> RunInterrupted:
    """The error of a run stopped during its final evaluation. ``kept``: what the final checkpoint's
    sidecar gains as it goes back to ``step_<N>`` (``rlq resume`` then makes the final evaluation);
    None where the final checkpoint was not written."""
    name = signal.Signals(signum).name
    if kept is None:
        return RunInterrupted(
            f"stopped by {name} during the final evaluation at env step {env_steps:,}, skipping it; "
            "the final checkpoint was not written",
            signum,
        )
    path = checkpoint.reopen_final(run_dir / "checkpoints", env_steps, kept)
    return RunInterrupted(
        f"stopped by {name} during the final evaluation at env step {env_steps:,}, skipping it: checkpoint "
        f"{path}; `rlq resume run={run_dir}` makes the final evaluation",
        signum,
    )


def finish_interrupted(run_dir: Path, signum: int, env_steps: int) -> RunInterrupted:
    """The error of a run stopped while `rlq resume` made what follows its final checkpoint: the run stays as it
    was (a final checkpoint, no summary), for the next `rlq resume` to finish."""
    return RunInterrupted(
        f"stopped by {signal.Signals(signum).name} during the final evaluation at env step {env_steps:,}, "
        f"skipping it; `rlq resume run={run_dir}` makes it",
        signum,
    )


def video_interrupted(run_dir: Path, signum: int, checkpoint_saved: bool) -> RunInterrupted:
    """The error of a run stopped while its final video was made: the run itself is complete."""
    kept = (
        f"the final checkpoint {run_dir / 'checkpoints' / 'final.msgpack'} is saved"
        if checkpoint_saved
        else "the final checkpoint was not written"
    )
    return RunInterrupted(
        f"stopped by {signal.Signals(signum).name} while rendering the final video, skipping it: the run is "
        f"complete and {kept}; `rlq render run={run_dir}` makes the video",
        signum,
    )


def early_stop_line(run_dir: Path, resume: Path | None) -> Callable[[str], str]:
    """The line of a stop before this process trained anything (``signal name -> line``)."""
    if resume is None:
        return lambda name: f"stopped by {name} before training began: nothing to save (the same command starts over)"
    return lambda name: (
        f"stopped by {name} before this process trained: nothing new to save; `rlq resume run={run_dir}` "
        f"continues from {resume.name}"
    )
