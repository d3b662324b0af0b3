"""THE training loop: one compiled program per chunk of updates, for every algorithm.

    state = jit(vmap(algo.init))(seed keys)                 # all seeds in one program
    loop:  state, metrics = jit(vmap(scan(algo.update, K)))(state)
           hooks on the host (rlq/run/hooks.py): log, figures, evaluate, checkpoint

Metrics leave the device once per chunk of K updates; algorithms never do I/O. The programs
(rlq/run/programs/build.py) are compiled as rlq/run/programs/compiling.py says; training starts once init and chunk
are compiled. Every program runs on the run's mesh (rlq/run/programs/devices.py): its inputs and outputs are
split along the seed axis, and the programs split each seed's envs over the mesh's env devices.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import sys
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import jax
import numpy as np
from omegaconf import DictConfig

from rlq.algos.base import budget_note, rounded_note
from rlq.errors import DivergedError, RunInterrupted
from rlq.lib.sharding import is_writer, to_host, to_mesh
from rlq.run.hooks import ChunkEnd, Hook, PeriodicEval, seed_figures
from rlq.run.loop_hooks import loop_hooks
from rlq.run.programs import compile_cache, members
from rlq.run.programs.build import Programs, build, call_chunk, with_hyper, with_hyper_soon
from rlq.run.programs.cadences import Cadences, asked_keys
from rlq.run.programs.compiler import options_from_config
from rlq.run.programs.compiling import compile_programs, program_options
from rlq.run.programs.devices import Placement, placement, shape_note
from rlq.run.programs.distributed import agreed_calls, agreed_signal, coordination_client, peer_stops
from rlq.run.programs.keys import eval_keys
from rlq.run.programs.program_cache import ProgramCache
from rlq.run.result import (
    RunResult,
    chunk_summary,
    diverged,
    early_stop_line,
    eval_summary,
    final_eval_interrupted,
    finish_interrupted,
    interrupted,
    resumed_chunks,
    video_interrupted,
)
from rlq.run.stops import guard, slices, waiting
from rlq.run.stops.signals import StopRequest
from rlq.run.videos import Seed0Video, cpu_video_skip, video_estimate_s, wants_final_video
from rlq.store import checkpoint
from rlq.store.files import write_atomic
from rlq.store.logging import RunLogger
from rlq.store.record import sweep_group
from rlq.store.render import DrawsFrames
from rlq.store.sidecar import HASH_KEY, config_hash


def append_line(path: Path, line: str) -> None:
    """``line`` at the end of the file at ``path`` (rlq.log before the run's logger has it open)."""
    with open(path, "a") as file:
        file.write(line.rstrip("\n") + "\n")


def _warn(text: str) -> None:
    print(f"rlq: warning: {text}", file=sys.stderr, flush=True)


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


def redo_evaluation(
    hooks: list[Hook], end: ChunkEnd, run_dir: Path, logger: RunLogger, held: Callable[[ChunkEnd], ChunkEnd]
) -> str:
    """The evaluation after chunk ``end`` that a stop skipped, made by the resumed run as the
    stopped one would have (its row, its listeners); returns why a hook ends the run there, or ''.
    ``held``: ``end`` with the state a stop saves (``evaluated_state``)."""
    try:
        for hook in hooks:
            if isinstance(hook, PeriodicEval):
                hook.on_chunk(end)
    except waiting.Abandoned as left:
        raise interrupted(run_dir, left.signum, held(end), logger.wall_s(), skipped_eval=True) from None
    return next((hook.reason for hook in hooks if hook.stop), "")


def train(
    cfg: DictConfig,
    run_dir: Path,
    resume: Path | None = None,
    warm: Callable[[Any], Any] | None = None,
    finish: bool = False,
) -> RunResult:
    """Train ``cfg.num_seeds`` seeds of one config; write metrics and checkpoints to ``run_dir``.

    ``resume``: a checkpoint of this run written at the end of a chunk; training goes on from it
    to the budget (the state holds every PRNG key, so it continues exactly as the run would have).
    SIGINT/SIGTERM end the run after the slice of a chunk in flight with a resumable checkpoint,
    skipping an evaluation or a video in flight (RunInterrupted); NaN/Inf in parameters, losses or returns end
    it at once (DivergedError).
    ``warm``: maps a fresh run's initial state (on the host) to the one it starts from (``init_from``).
    ``finish``: ``resume`` is the final checkpoint of a run killed before its summary.json; the run makes
    what follows that checkpoint (final evaluation, figures, video, summary, members) and trains nothing."""
    # eager operations (keys, checkpoints) go to the run's kind of device too (config key ``platform``)
    state_hash = config_hash(cfg)  # before anything reads (or sets) the config
    program_cfg = members.program_config(cfg)  # an in-program sweep trains every member's seeds
    where = placement(program_cfg)
    with StopRequest(_warn, peer_stops()) as stop, jax.default_device(where.local_device):
        result = _train(program_cfg, where, Path(run_dir), resume, stop, state_hash, warm, finish)
    if members.sweeping(cfg) and is_writer():
        written = members.write_members(cfg, Path(run_dir))
        print(members.summary_lines(Path(run_dir), written), flush=True)
    return result


def _train(
    cfg: DictConfig,
    where: Placement,
    run_dir: Path,
    resume: Path | None,
    stop: StopRequest,
    state_hash: str,
    warm: Callable[[Any], Any] | None = None,
    finish: bool = False,
) -> RunResult:
    began = time.perf_counter()
    resumed_meta = checkpoint.meta(resume) if resume is not None else {}
    start = time.perf_counter() - float(resumed_meta.get("wall_s", 0.0))  # the run's clock goes on
    compile_cache.enable(cfg.compile_cache)
    cache = ProgramCache.for_run(cfg, where)
    cached = cache.load_soon() if cache is not None else None
    chunk_steps = int(resumed_meta.get("chunk_steps", 0))
    done_steps = int(resumed_meta.get("chunks_done", 0)) * chunk_steps
    programs = build(cfg, where, done_steps if chunk_steps else int(resumed_meta.get("env_steps", 0)), chunk_steps)
    if programs.replanned:  # its programs are not the ones a fresh run of this config keeps
        cache, cached = None, None
    num_seeds = int(cfg.num_seeds)
    planned = programs.chunk_steps * programs.num_chunks
    resumed_steps = int(resumed_meta.get("env_steps", 0))
    earlier_rows = resume is None and (run_dir / "metrics.jsonl").exists()
    if earlier_rows:  # a run started over in its directory: the rows of the attempt that died go
        (run_dir / "metrics.jsonl").unlink()
    per_chunk, steps_per_chunk = programs.updates_per_chunk, programs.chunk_steps
    # black-box algorithms count true env steps (episodes end early), below the chunks' nominal
    # steps: the checkpoint records how many chunks it follows, and of what size (a run extended
    # with a larger budget may plan other chunks)
    first_chunk = resumed_chunks(resumed_meta, steps_per_chunk) if resume is not None else 0
    if programs.algo.iterations:  # the bar counts iterations: true env steps fall below the nominal ones
        total, done, unit = programs.num_chunks * per_chunk, first_chunk * per_chunk, "it"
    else:
        total, done, unit = planned, resumed_steps, "step"
    stop.early, stop.record = early_stop_line(run_dir, resume), functools.partial(append_line, run_dir / "rlq.log")
    logger = RunLogger(cfg, run_dir, total, num_seeds, start_steps=done, started=start, unit=unit)
    stop.notify = logger.console.warn
    partial = slices.resumed_part(resume, resumed_meta, programs.calls_per_chunk)
    mismatch = shape_note(cfg, where.platform)
    if mismatch:
        logger.console.warn(mismatch)
    cadences = Cadences.from_config(cfg)
    asked = asked_keys()
    notes = cadences.snap_notes(programs.chunk_steps, planned, programs.updates_per_chunk == 1, asked)
    small_budget = budget_note(cfg.budget.env_steps, programs.algo.steps_per_update, programs.algo.iterations)
    if asked is None or "budget.env_steps" in asked:  # a budget nobody set rounds without a word
        small_budget = small_budget or rounded_note(
            cfg.budget.env_steps, planned, programs.algo.steps_per_update, programs.algo.iterations
        )
    over = f"{run_dir} held a run that stopped before its first checkpoint: it starts over" if earlier_rows else None
    stop_note = cadences.stop_note(cfg.stop.when, programs.chunk_steps, planned)
    short = programs.replanned and programs.num_chunks * per_chunk < programs.algo.num_updates and resume is not None
    kept = (
        f"the run keeps its chunks of {steps_per_chunk:,} env steps: it ends at {planned:,}, the last whole chunk "
        f"within budget.env_steps={cfg.budget.env_steps}"
        if short
        else None
    )
    for note in [where.note, over, small_budget, *programs.algo.notes, *notes, stop_note, kept]:
        if note:
            logger.console.message(f"rlq: {note}")
    logger.console.phase("compiling")
    seeds = programs.placement.seeds
    count = members.member_count(cfg)

    def evaluation_keys(tag: int) -> jax.Array:
        return to_mesh(eval_keys(int(cfg.seed), np.int32(tag), num_seeds, count), seeds)

    def first_keys() -> jax.Array:
        with jax.default_device(where.local_device):
            evaluation_keys(0)  # its program compiles now, off the path to the first chunk
            return to_mesh(members.init_inputs(cfg), seeds)

    # evaluations and videos run in a worker, waited for in slices: a stop abandons one (rlq.run.stops.waiting);
    # over several processes an evaluation is a collective, whose waits the processes end alike
    evaluator = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rlq-eval")
    waiter = waiting.for_run(lambda: stop.signum, coordination_client())
    local = waiting.Waiter(lambda: stop.signum)  # a video is process 0's alone
    try:
        t0 = time.perf_counter()
        # the keys' two small programs compile in a worker while the run's programs are traced
        with ThreadPoolExecutor(max_workers=1) as worker:
            keys_soon = worker.submit(first_keys)
            compiled = compile_programs(
                programs,
                jax.eval_shape(functools.partial(members.init_inputs, cfg)),
                jax.eval_shape(lambda tag: eval_keys(int(cfg.seed), tag, num_seeds, count), np.int32(0)),
                options_from_config(cfg),
                cache,
                cached.result() if cached is not None else None,
                need_init=resume is None,
            )
            keys = keys_soon.result()
        state_shape = compiled.state_shape
        evaluate_ = compiled.evaluate
        if resume is None:
            state, start_steps = compiled.programs["init"](keys), 0
            if warm is not None:
                state = to_mesh(warm(to_host(state)), seeds)
        else:
            # host arrays, placed on this run's mesh (whatever the device count that wrote them)
            state, start_steps = (
                to_mesh(checkpoint.load(resume, state_shape), seeds),
                checkpoint.env_steps(resume),
            )
        compile_s = time.perf_counter() - t0
        hyper = to_mesh(programs.hyper, seeds)
        chunk, rest_soon = with_hyper(compiled.programs["chunk"], hyper), with_hyper_soon(compiled.rest_soon, hyper)
        # a sweep's later jobs say they load the programs of its first (hyperparameters are the chunk's argument)
        logger.console.message(compiled.line(compile_s))
        chunk_s, env_steps, stopped = [], start_steps, ""
        final_video = wants_final_video(cfg.video.at_end, sweep_group(run_dir) is not None)
        video = (
            Seed0Video(cfg, programs.algo, run_dir, logger, programs.env)
            if (final_video or cfg.video.every_steps) and is_writer()  # seed 0 lives on process 0
            else None
        )
        if final_video and video is not None and where.platform != "cpu" and where.mesh.devices.size == 1:
            options = program_options("video", options_from_config(cfg), where.platform)
            video.prepare_soon(state_shape, where.mesh.devices.flat[0], options)  # on a CPU it would slow training
        logger.console.training()

        # over several processes, the state an evaluation starts from, copied to the host first: a stop during
        # the evaluation saves it (a copy made then would queue on the devices behind the evaluation)
        evaluated_state: list[Any] = []

        def periodic_eval(st: Any, index: int) -> dict[str, np.ndarray]:
            keys = evaluation_keys(index)
            evaluated_state[:] = [to_host(st)] if jax.process_count() > 1 else []
            return waiter.wait(evaluator.submit(lambda: eval_summary(to_host(evaluate_(st, keys)))))

        def held(end: ChunkEnd) -> ChunkEnd:
            return dataclasses.replace(end, state=evaluated_state[0]) if evaluated_state else end

        def stage_video(st: Any, steps: int, name: str) -> Path | None:
            assert video is not None
            try:
                return local.wait(evaluator.submit(video, st, steps, name))
            except waiting.Abandoned:  # the stop is seen after the chunk's hooks: a checkpoint, then the end
                video.forget(name)
                logger.console.warn(f"no video {name}: stopped while it was made")
                return None

        hooks = loop_hooks(cfg, programs, run_dir, logger, periodic_eval, stage_video if video is not None else None)
        end: ChunkEnd | None = None
        # a resumed run a stop cut short at the end of a chunk makes what the stop skipped: the
        # chunk's evaluation, or the run's final one (then it trains nothing)
        pending = finish or (
            bool(resumed_meta.get("final_pending")) and resumed_meta.get("num_chunks") == programs.num_chunks
        )
        if resume is not None and (pending or resumed_meta.get("eval_skipped")):
            end = ChunkEnd(first_chunk - 1, start_steps, state, {}, pending, steps_per_chunk, state_hash)
            stopped = (
                str(resumed_meta.get("stopped", "")) if pending else redo_evaluation(hooks, end, run_dir, logger, held)
            )
        sizer = slices.SliceSizer()
        for i in range(first_chunk, first_chunk if stopped or pending else programs.num_chunks):
            t1 = time.perf_counter()
            parts, called = partial if i == first_chunk else ([], 0)
            while called < programs.calls_per_chunk:  # slices of a few seconds, a stop seen between them
                wanted = sizer.next(programs.calls_per_chunk - called)
                calls, t2 = agreed_calls(ready_calls(wanted, called, programs, rest_soon)), time.perf_counter()
                state, made = call_slice(programs, chunk, rest_soon, state, called, calls, waiter.wait)
                parts += made
                if made:
                    sizer.record(calls, time.perf_counter() - t2)
                    called += calls
                    stop.early = None  # from now on a stop saves what this process trained
                signum = agreed_signal(stop.signum) if called < programs.calls_per_chunk else None
                if signum is not None:
                    metrics, checks = guard.split(slices.joined(parts))
                    failure = guard.first_failure(checks, metrics["env_steps"])
                    if failure is not None:
                        raise diverged(run_dir, *failure, programs.bounds)
                    mid = ChunkEnd(
                        i - 1,
                        int(np.max(metrics["env_steps"][:, -1])),
                        state,
                        {},
                        last=False,
                        chunk_steps=steps_per_chunk,
                        config_sha256=state_hash,
                    )
                    raise interrupted(
                        run_dir,
                        signum,
                        mid,
                        logger.wall_s(),
                        slices.part_record(parts, called),
                        programs.calls_per_chunk,
                    )
            metrics, checks = guard.split(slices.joined(parts))
            failure = guard.first_failure(checks, metrics["env_steps"])
            if failure is not None:
                raise diverged(run_dir, *failure, programs.bounds)
            summary = chunk_summary(metrics)
            chunk_s.append(time.perf_counter() - t1)
            env_steps = int(np.max(summary["env_steps"]))
            end = ChunkEnd(
                i,
                env_steps,
                state,
                summary,
                last=i == programs.num_chunks - 1,
                chunk_steps=steps_per_chunk,
                config_sha256=state_hash,
                updates=metrics,
            )
            try:
                for hook in hooks:
                    hook.on_chunk(end)
            except waiting.Abandoned as left:  # the stop came during the chunk's evaluation
                raise interrupted(run_dir, left.signum, held(end), logger.wall_s(), skipped_eval=True) from None
            signum = agreed_signal(stop.signum)
            if signum is not None:
                raise interrupted(run_dir, signum, end, logger.wall_s())
            if any(hook.stop for hook in hooks):
                stopped = next(hook.reason for hook in hooks if hook.stop)
                break
        logger.console.phase("evaluating")
        stop.early = None  # a stop now leaves a checkpoint to resume from, even where this process trained nothing
        stop.coming = "stopping now, skipping the final evaluation (`rlq resume` makes it)"
        # the final evaluation runs in a worker (a GPU program's loops hold its calling thread until
        # they end) while this thread writes the program cache (after training: serialising between
        # chunks would stall them) and the final checkpoint, copied to the host before the
        # evaluation starts (a copy queued behind it would wait for it)
        # a run a stop rule ended just after an evaluation keeps that one as its final (one eval row, one line)
        evaluated = next((h.last for h in hooks if isinstance(h, PeriodicEval)), None) if stopped else None
        reused = evaluated[1] if evaluated is not None and evaluated[0] == env_steps else None
        # a run stopped after its final checkpoint makes its final evaluation again (the same state and keys: the
        # same numbers); one that reused an evaluation makes that one, whose row and listeners were done then
        again = pending and bool(resumed_meta.get("final_reused"))
        final_state, final_keys = to_host(state), evaluation_keys(first_chunk - 1 if again else 999_983)
        logged = reused is not None or again

        def flags() -> tuple[str, ...]:
            earlier = tuple(resumed_meta.get("warnings", ())) if pending else ()
            return tuple(dict.fromkeys([*earlier, *(flag for hook in hooks for flag in hook.flags)]))

        def outcome(final: dict[str, np.ndarray]) -> RunResult:
            return RunResult(
                env_steps=env_steps,
                num_seeds=num_seeds,
                wall_s=time.perf_counter() - start,
                compile_s=compile_s,
                steady_steps_per_s=(env_steps - start_steps) * num_seeds / max(sum(chunk_s), 1e-9),
                eval_return=final.get("return", np.zeros(0)),
                run_dir=run_dir,
                state=state,
                start_steps=start_steps,
                chunk_s=tuple(chunk_s),
                final_eval=final,
                stopped=stopped,
                cached_programs=tuple(compiled.loaded),
                compile_cache_hits=tuple(compiled.from_cache()),
                process_s=time.perf_counter() - began,
                warnings=flags(),
            )

        final_soon = evaluator.submit(
            lambda: reused if reused is not None else eval_summary(to_host(evaluate_(state, final_keys)))
        )
        meta = {
            "env_steps": env_steps,
            "num_seeds": num_seeds,
            "wall_s": logger.wall_s(),
            "chunks_done": end.index + 1 if end is not None else first_chunk,
            "chunk_steps": steps_per_chunk,
            HASH_KEY: state_hash,
            # what the end of the run needs if it is killed before its summary (`rlq resume` then makes it)
            "stopped": stopped,
            "final_reused": logged,
            "warnings": list(flags()),
        }
        try:
            if not finish:  # a finishing run's final checkpoint is the one it resumed from
                checkpoint.save(run_dir / "checkpoints", "final", final_state, meta)
            final_error = None
        except OSError as err:  # a full disk: the run's result is still recorded, then the error ends it
            final_error = err
        try:
            waiter.wait(compiled.to_keep)  # the evaluation's program may still be compiling
            problem = compiled.store()
            final = waiter.wait(final_soon)
        except waiting.Abandoned as left:  # resumable: the final checkpoint goes back to step_<N>
            pending_meta = {"final_pending": True, "stopped": stopped, "num_chunks": programs.num_chunks}
            if finish:  # its final checkpoint stays and no summary is written: `rlq resume` finishes it again
                raise finish_interrupted(run_dir, left.signum, env_steps) from None
            ended = final_eval_interrupted(run_dir, left.signum, env_steps, None if final_error else pending_meta)
            cut = {**outcome({}).as_dict(), "final_eval_interrupted": str(ended)}
            write_atomic(run_dir / "summary.json", json.dumps(cut, indent=2).encode())
            raise ended from None
        if problem:
            logger.console.message(f"rlq: programs not kept in the compile cache ({problem})")
        if not logged:
            logger.log(env_steps, "eval", final)
        if end is not None and not logged:  # the listeners heard the reused one when it was made
            for hook in hooks:
                hook.on_final_eval(end, final)
        if programs.algo.figures is not None:
            logger.figures(env_steps, seed_figures(programs.algo.figures, state, num_seeds), "final")
        skip = None
        if final_video and video is not None and video.enabled and cfg.video.at_end is None and where.platform == "cpu":
            frames = min(video.max_steps, int(np.max(final["length"][:1], initial=1)))
            estimate = video_estimate_s(compile_s, frames, isinstance(programs.env.unwrapped, DrawsFrames))
            skip = cpu_video_skip(estimate, time.perf_counter() - start, run_dir)
        if skip:
            logger.console.message(f"rlq: {skip}")
        elif final_video and video is not None and video.enabled:
            logger.console.phase("rendering")
            stop.coming = "skipping the final video: the run is complete"
            try:
                local.wait(evaluator.submit(video, state, env_steps, "final_seed0"))
            except waiting.Abandoned as left:  # the run's end is recorded; only the video is missing
                result = outcome(final)
                logger.record(result.line())
                video.forget("final_seed0")
                ended = video_interrupted(run_dir, left.signum, final_error is None)
                cut = {**result.as_dict(), "final_video_interrupted": str(ended)}
                write_atomic(run_dir / "summary.json", json.dumps(cut, indent=2).encode())
                raise ended from None
        result = outcome(final)
        logger.record(result.line())
        if final_error is not None:
            logger.record(
                f"rlq: error: the final checkpoint was not written: {final_error.strerror}: {final_error.filename}"
            )
    except (DivergedError, RunInterrupted) as ended:  # the line the CLI prints ends rlq.log too
        logger.record(f"rlq: {ended}" if isinstance(ended, RunInterrupted) else f"rlq: error: {ended}")
        raise
    finally:
        evaluator.shutdown(wait=False, cancel_futures=True)  # an abandoned evaluation ends with the process
        logger.close()
    recorded: dict[str, Any] = dict(result.as_dict())
    if final_error is not None:
        recorded["final_checkpoint_error"] = f"{final_error.strerror}: {final_error.filename}"
    write_atomic(run_dir / "summary.json", json.dumps(recorded, indent=2).encode())
    if final_error is not None:
        raise final_error
    return result
