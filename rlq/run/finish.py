"""The last of the training loop's three steps (prepare, loop, finish: rlq/run/train.py): the final greedy
evaluation (in a worker) while this thread writes the final checkpoint and the program cache, then the final
row, figures and video, the RunResult and ``summary.json``."""

from __future__ import annotations

import json
import time
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import numpy as np

from rlq.lib.sharding import to_host, to_mesh
from rlq.run.hooks import Hook, PeriodicEval, seed_figures
from rlq.run.kept import KeepSeedsBest, Kept
from rlq.run.loop import Trained
from rlq.run.prepare import Plan, Ready
from rlq.run.result import RunResult, eval_summary, final_eval_interrupted, finish_interrupted, video_interrupted
from rlq.run.stops import waiting
from rlq.run.videos import cpu_video_skip, video_estimate_s
from rlq.store import checkpoint
from rlq.store.files import write_atomic
from rlq.store.render import DrawsFrames
from rlq.store.sidecar import HASH_KEY


def _flags(plan: Plan, ready: Ready) -> tuple[str, ...]:
    """The run's warnings: those of the run it finishes (a finishing run), then its hooks' (read now)."""
    earlier = tuple(plan.resumed_meta.get("warnings", ())) if ready.pending else ()
    return tuple(dict.fromkeys([*earlier, *(flag for hook in ready.hooks for flag in hook.flags)]))


def outcome(
    plan: Plan, ready: Ready, trained: Trained, final: dict[str, np.ndarray], kept: Kept | None = None
) -> RunResult:
    """The run's result with ``final`` as its final evaluation (and ``kept``, ``eval.keep=best``'s score of each
    seed's best state, as its return), its clocks read now."""
    env_steps, chunk_s, num_seeds = trained.env_steps, trained.chunk_s, plan.num_seeds
    return RunResult(
        env_steps=env_steps,
        num_seeds=num_seeds,
        wall_s=time.perf_counter() - plan.start,
        compile_s=ready.compile_s,
        steady_steps_per_s=(env_steps - ready.start_steps) * num_seeds / max(sum(chunk_s), 1e-9),
        eval_return=(kept.scores if kept is not None else final).get("return", np.zeros(0)),
        run_dir=plan.run_dir,
        state=trained.state,
        start_steps=ready.start_steps,
        chunk_s=chunk_s,
        final_eval=final,
        stopped=trained.stopped,
        cached_programs=tuple(ready.compiled.loaded),
        compile_cache_hits=tuple(ready.compiled.from_cache()),
        process_s=time.perf_counter() - plan.began,
        warnings=_flags(plan, ready),
        kept=kept.record() if kept is not None else None,
    )


#: the evaluation keys' tag of the kept states' score: episodes none of the run's other evaluations play
KEPT_KEYS_TAG = 999_979


def kept_hook(hooks: list[Hook]) -> KeepSeedsBest | None:
    """``eval.keep=best``'s listener of the periodic evaluations, where the run has one."""
    listeners = (hook for periodic in hooks if isinstance(periodic, PeriodicEval) for hook in periodic.listeners)
    return next((hook for hook in listeners if isinstance(hook, KeepSeedsBest)), None)


def chunks_done(plan: Plan, trained: Trained) -> int:
    """The chunks the run has trained at its end (a stop rule may end it before the budget's last)."""
    return trained.end.index + 1 if trained.end is not None else plan.first_chunk


def write_summary(run_dir: Path, recorded: dict[str, Any]) -> None:
    """``summary.json``, whole or not at all."""
    write_atomic(run_dir / "summary.json", json.dumps(recorded, indent=2).encode())


def _save_final(plan: Plan, ready: Ready, trained: Trained, final_state: Any, logged: bool) -> OSError | None:
    """The final checkpoint, with what the end of the run needs if it is killed before its summary (`rlq
    resume` then makes it); a finishing run's is the one it resumed from. A full disk is returned, not raised:
    the run's result is still recorded first."""
    meta = {
        "env_steps": trained.env_steps,
        "num_seeds": plan.num_seeds,
        "wall_s": plan.logger.wall_s(),
        "chunks_done": chunks_done(plan, trained),
        "chunk_steps": plan.programs.chunk_steps,
        HASH_KEY: plan.state_hash,
        "stopped": trained.stopped,
        "final_reused": logged,
        "warnings": list(_flags(plan, ready)),
    }
    try:
        if not plan.finishing:
            checkpoint.save(plan.run_dir / "checkpoints", "final", final_state, meta)
    except OSError as err:
        return err
    return None


def _final_eval(
    plan: Plan, ready: Ready, trained: Trained, final_soon: Future, final_error: OSError | None
) -> tuple[tuple[dict[str, np.ndarray], Kept | None], str | None]:
    """The final evaluation (and ``eval.keep=best``'s kept states, scored) once it is done, and why the programs
    were not kept in the program cache (None where they were). A stop meanwhile ends the run resumably: the final checkpoint goes back to step_<N>,
    or a finishing run keeps it and writes no summary (`rlq resume` finishes it again)."""
    try:
        plan.waiter.wait(ready.compiled.to_keep)  # the evaluation's program may still be compiling
        problem = ready.compiled.store()
        return plan.waiter.wait(final_soon), problem
    except waiting.Abandoned as left:
        env_steps = trained.env_steps
        pending_meta = {"final_pending": True, "stopped": trained.stopped, "num_chunks": plan.programs.num_chunks}
        if plan.finishing:
            raise finish_interrupted(plan.run_dir, left.signum, env_steps) from None
        ended = final_eval_interrupted(plan.run_dir, left.signum, env_steps, None if final_error else pending_meta)
        write_summary(
            plan.run_dir, {**outcome(plan, ready, trained, {}).as_dict(), "final_eval_interrupted": str(ended)}
        )
        raise ended from None


def _final_video(
    plan: Plan,
    ready: Ready,
    trained: Trained,
    final: dict[str, np.ndarray],
    final_error: OSError | None,
    kept: Kept | None = None,
) -> None:
    """Seed 0's final video (of its kept state with ``eval.keep=best``), unless on a CPU it would cost over 10 % of
    the run (then one line says so). A stop while it is made records the run's end without it (RunInterrupted)."""
    spec, video, logger = plan.spec, ready.video, plan.logger
    if not (ready.final_video and video is not None and video.enabled):
        return
    skip = None
    if spec.outputs.video.at_end is None and plan.where.platform == "cpu":
        frames = min(video.max_steps, int(np.max(final["length"][:1], initial=1)))
        estimate = video_estimate_s(ready.compile_s, frames, isinstance(plan.programs.env.unwrapped, DrawsFrames))
        skip = cpu_video_skip(estimate, time.perf_counter() - plan.start, plan.run_dir)
    if skip:
        logger.console.message(f"rlq: {skip}")
        return
    logger.console.phase("rendering")
    plan.stop.coming = "skipping the final video: the run is complete"
    try:
        shown = kept.state if kept is not None else trained.state
        plan.local.wait(plan.evaluator.submit(video, shown, trained.env_steps, "final_seed0"))
    except waiting.Abandoned as left:  # the run's end is recorded; only the video is missing
        result = outcome(plan, ready, trained, final, kept)
        logger.record(result.line())
        video.forget("final_seed0")
        ended = video_interrupted(plan.run_dir, left.signum, final_error is None)
        write_summary(plan.run_dir, {**result.as_dict(), "final_video_interrupted": str(ended)})
        raise ended from None


def finish(plan: Plan, ready: Ready, trained: Trained) -> tuple[RunResult, OSError | None]:
    """The run's end: its final evaluation (reused where a stop rule ended the run just after one), the final
    checkpoint (its OSError returned, to be raised once the summary is written), rows, figures and video."""
    logger, hooks, state, env_steps, stop = plan.logger, ready.hooks, trained.state, trained.env_steps, plan.stop
    logger.console.phase("evaluating")
    stop.early = None  # a stop now leaves a checkpoint to resume from, even where this process trained nothing
    stop.coming = "stopping now, skipping the final evaluation (`rlq resume` makes it)"
    # the final evaluation runs in a worker (a GPU program's loops hold its calling thread until
    # they end) while this thread writes the program cache (after training: serialising between
    # chunks would stall them) and the final checkpoint, copied to the host before the
    # evaluation starts (a copy queued behind it would wait for it)
    # a run a stop rule ended just after an evaluation keeps that one as its final (one eval row, one line)
    evaluated = next((h.last for h in hooks if isinstance(h, PeriodicEval)), None) if trained.stopped else None
    reused = evaluated[1] if evaluated is not None and evaluated[0] == env_steps else None
    # a run stopped after its final checkpoint makes its final evaluation again (the same state and keys: the
    # same numbers); one that reused an evaluation makes that one, whose row and listeners were done then
    again = ready.pending and bool(plan.resumed_meta.get("final_reused"))
    final_state, final_keys = to_host(state), ready.evaluation_keys(plan.first_chunk - 1 if again else 999_983)
    logged = reused is not None or again
    keeper = kept_hook(hooks)

    def final_and_kept() -> tuple[dict[str, np.ndarray], Kept | None]:
        final = reused if reused is not None else eval_summary(to_host(ready.evaluate(state, final_keys)))
        if keeper is None:
            return final, None
        meta = {"env_steps": env_steps, "chunks_done": chunks_done(plan, trained), HASH_KEY: plan.state_hash}
        chosen, from_steps = keeper.with_final(final_state, final["return"], env_steps, meta)
        on_mesh = to_mesh(chosen, plan.programs.placement.seeds)
        scores = eval_summary(to_host(ready.evaluate(on_mesh, ready.evaluation_keys(KEPT_KEYS_TAG))))
        return final, Kept(on_mesh, from_steps, scores)

    final_soon = plan.evaluator.submit(final_and_kept)
    final_error = _save_final(plan, ready, trained, final_state, logged)
    (final, kept), problem = _final_eval(plan, ready, trained, final_soon, final_error)
    if problem:
        logger.console.message(f"rlq: programs not kept in the compile cache ({problem})")
    if not logged:
        logger.log(env_steps, "eval", final)
    if trained.end is not None and not logged:  # the listeners heard the reused one when it was made
        for hook in hooks:
            hook.on_final_eval(trained.end, final)
    if kept is not None:
        logger.log(env_steps, "kept", {**kept.scores, "from_env_steps": np.asarray(kept.from_steps, np.float64)})
    if plan.programs.algo.figures is not None:
        logger.figures(env_steps, seed_figures(plan.programs.algo.figures, state, plan.num_seeds), "final")
    _final_video(plan, ready, trained, final, final_error, kept)
    result = outcome(plan, ready, trained, final, kept)
    logger.record(result.line())
    if final_error is not None:
        logger.record(
            f"rlq: error: the final checkpoint was not written: {final_error.strerror}: {final_error.filename}"
        )
    return result, final_error
