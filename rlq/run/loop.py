"""The second of the training loop's three steps (prepare, loop, finish: rlq/run/train.py): each chunk of updates
in slices of a few seconds (a stop is seen between them), checked by the guard, then handed to the hooks.
Metrics leave the device once per slice; algorithms never do I/O."""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

import numpy as np

from rlq.lib.sharding import to_host
from rlq.run.hooks import ChunkEnd
from rlq.run.prepare import Plan, Ready
from rlq.run.programs.build import Programs, call_chunk
from rlq.run.programs.distributed import agreed_calls, agreed_signal
from rlq.run.result import chunk_summary, diverged, interrupted
from rlq.run.stops import guard, slices, waiting


@dataclass(frozen=True)
class Trained:
    """Where the loop left the run: the state, its env steps per seed, the last chunk's end (None where no
    chunk ended), each chunk's seconds, and why a hook ended the run early ('' where none did)."""

    state: Any
    env_steps: int
    end: ChunkEnd | None
    chunk_s: tuple[float, ...]
    stopped: str


def ready_calls(wanted: int, called: int, programs: Programs, rest_soon: Future | None) -> int:
    """``wanted`` calls of a chunk after ``called``, ending before its last block while that block's
    program still compiles (unless the last block is all that is left)."""
    if called + wanted > programs.full_calls and rest_soon is not None and not rest_soon.done():
        return max(1, programs.full_calls - called)
    return wanted


def call_slice(
    programs: Programs,
    chunk: Callable[[Any], tuple[Any, dict]],
    rest_soon: Future | None,
    state: Any,
    called: int,
    calls: int,
    wait: Callable[[Future], Any],
) -> tuple[Any, list[dict[str, np.ndarray]]]:
    """The next ``calls`` calls of a chunk after ``called``: of ``chunk``'s blocks, then, at the chunk's
    end, of its last, shorter block (``programs.rest``: rlq.run.stops.slices.block_plan), whose compile is
    waited for with a stop seen meanwhile (``wait``: rlq.run.stops.waiting; no call is made then). Returns the
    state and the calls' metrics on the host."""
    full = min(calls, programs.full_calls - called)
    rest = None
    if calls > full and rest_soon is not None:
        try:
            rest = wait(rest_soon)[0]
        except waiting.Abandoned:
            return state, []
    parts = []
    if full:
        state, part = call_chunk(chunk, state, full)
        parts.append(to_host(part))
    if rest is not None:
        state, part = call_chunk(rest, state, 1)
        parts.append(to_host(part))
    return state, parts


def _guarded(plan: Plan, parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The metrics of a chunk's calls, once the divergence guard has passed them (DivergedError if not)."""
    metrics, checks = guard.split(slices.joined(parts))
    failure = guard.first_failure(checks, metrics["env_steps"])
    if failure is not None:
        raise diverged(plan.run_dir, *failure, plan.programs.bounds)
    return metrics


def _chunk_calls(
    plan: Plan, ready: Ready, sizer: slices.SliceSizer, index: int, state: Any, parts: list, called: int
) -> tuple[Any, list[dict[str, np.ndarray]]]:
    """Chunk ``index``'s calls after ``called`` (``parts``: their metrics so far), in slices of a few seconds;
    a stop between two of them ends the run with a checkpoint inside the chunk and its calls' metrics beside
    it (RunInterrupted)."""
    programs, stop = plan.programs, plan.stop
    while called < programs.calls_per_chunk:  # slices of a few seconds, a stop seen between them
        wanted = sizer.next(programs.calls_per_chunk - called)
        calls, t2 = agreed_calls(ready_calls(wanted, called, programs, ready.rest_soon)), time.perf_counter()
        state, made = call_slice(programs, ready.chunk, ready.rest_soon, state, called, calls, plan.waiter.wait)
        parts += made
        if made:
            sizer.record(calls, time.perf_counter() - t2)
            called += calls
            stop.early = None  # from now on a stop saves what this process trained
        signum = agreed_signal(stop.signum) if called < programs.calls_per_chunk else None
        if signum is not None:
            metrics = _guarded(plan, parts)
            steps = int(np.max(metrics["env_steps"][:, -1]))
            mid = ChunkEnd(
                index - 1, steps, state, {}, last=False, chunk_steps=programs.chunk_steps, config_sha256=plan.state_hash
            )
            wall_s = plan.logger.wall_s()
            raise interrupted(
                plan.run_dir, signum, mid, wall_s, slices.part_record(parts, called), programs.calls_per_chunk
            )
    return state, parts


def loop(plan: Plan, ready: Ready) -> Trained:
    """Every chunk of the plan after the first state (a resumed run's from its checkpoint's), each handed
    to the hooks; ends at the budget, where a hook stops the run, or with RunInterrupted/DivergedError."""
    programs, stop, logger, hooks = plan.programs, plan.stop, plan.logger, ready.hooks
    state, env_steps, end, stopped, chunk_s = ready.state, ready.start_steps, ready.end, ready.stopped, []
    sizer = slices.SliceSizer()
    first = plan.first_chunk
    for i in range(first, first if stopped or ready.pending else programs.num_chunks):
        t1 = time.perf_counter()
        parts, called = plan.partial if i == first else ([], 0)
        state, parts = _chunk_calls(plan, ready, sizer, i, state, parts, called)
        metrics = _guarded(plan, parts)
        summary = chunk_summary(metrics)
        chunk_s.append(time.perf_counter() - t1)
        env_steps = int(np.max(summary["env_steps"]))
        end = ChunkEnd(
            i,
            env_steps,
            state,
            summary,
            last=i == programs.num_chunks - 1,
            chunk_steps=programs.chunk_steps,
            config_sha256=plan.state_hash,
            updates=metrics,
        )
        try:
            for hook in hooks:
                hook.on_chunk(end)
        except waiting.Abandoned as left:  # the stop came during the chunk's evaluation
            raise interrupted(plan.run_dir, left.signum, ready.held(end), logger.wall_s(), skipped_eval=True) from None
        signum = agreed_signal(stop.signum)
        if signum is not None:
            raise interrupted(plan.run_dir, signum, end, logger.wall_s())
        if any(hook.stop for hook in hooks):
            stopped = next(hook.reason for hook in hooks if hook.stop)
            break
    return Trained(state, env_steps, end, tuple(chunk_s), stopped)
