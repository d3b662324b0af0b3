"""The first of the training loop's three steps (prepare, loop, finish: rlq/run/train.py): a run up to its first
chunk. ``prepare`` makes the plan (the programs built, where a resumed run stands, its logger, what the console
says first); ``start`` compiles the programs and makes the first state (fresh, warm-started or resumed) and the
loop's hooks."""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import numpy as np

from rlq.algos.base import budget_note, rounded_note
from rlq.config.spec import RunSpec
from rlq.lib.sharding import is_writer, to_host, to_mesh
from rlq.run.hooks import ChunkEnd, Hook, PeriodicEval
from rlq.run.loop_hooks import loop_hooks
from rlq.run.programs import compile_cache, members
from rlq.run.programs.build import Programs, build, with_hyper, with_hyper_soon
from rlq.run.programs.cadences import Cadences, asked_keys
from rlq.run.programs.compiler import options_from_config
from rlq.run.programs.compiling import CompiledPrograms, compile_programs, program_options
from rlq.run.programs.devices import Placement, shape_note
from rlq.run.programs.distributed import coordination_client
from rlq.run.programs.keys import eval_keys
from rlq.run.programs.program_cache import ProgramCache
from rlq.run.result import early_stop_line, eval_summary, interrupted, resumed_chunks
from rlq.run.stops import slices, waiting
from rlq.run.stops.signals import StopRequest
from rlq.run.videos import Seed0Video, wants_final_video
from rlq.store import checkpoint
from rlq.store.logging import RunLogger
from rlq.store.record import sweep_group


@dataclass(frozen=True)
class Plan:
    """What a run is about to do, before anything compiles: its config and programs, where a resumed run
    stands, its logger, its clocks and the workers its evaluations and videos run in."""

    spec: RunSpec
    where: Placement
    run_dir: Path
    resume: Path | None
    #: the sidecar of ``resume`` ({} for a fresh run)
    resumed_meta: dict[str, Any]
    stop: StopRequest
    #: the run's ``config_hash`` (rlq.store.sidecar), taken before anything read the config
    state_hash: str
    #: ``resume`` is the final checkpoint of a run killed before its summary: the run trains nothing
    finishing: bool
    programs: Programs
    cache: ProgramCache | None
    cached: Future | None
    logger: RunLogger
    #: ``time.perf_counter()`` when this process began the run, and when the run's clock started (a
    #: resumed run's clock goes on from its checkpoint's ``wall_s``)
    began: float
    start: float
    #: the chunk the loop starts at, and the calls of it a stop cut (rlq.run.stops.slices.resumed_part)
    first_chunk: int
    partial: tuple[list[dict[str, np.ndarray]], int]
    num_seeds: int
    #: sweep members in the program (1 without an in-program sweep)
    count: int
    #: evaluations and videos run in ``evaluator``, waited for in slices: a stop abandons one
    #: (rlq.run.stops.waiting); over several processes an evaluation is a collective, whose waits
    #: ``waiter`` ends alike in every process; a video is process 0's alone (``local``)
    evaluator: ThreadPoolExecutor
    waiter: waiting.Waiter
    local: waiting.Waiter


@dataclass(frozen=True)
class Ready:
    """A plan's programs compiled and its first state made: what the loop calls and what it hands to the hooks."""

    compiled: CompiledPrograms
    #: ``compiled.evaluate``, bound when the programs were ready
    evaluate: Callable[[Any, jax.Array], Any]
    state: Any
    start_steps: int
    compile_s: float
    chunk: Callable[[Any], tuple[Any, dict]]
    rest_soon: Future | None
    video: Seed0Video | None
    final_video: bool
    hooks: list[Hook]
    evaluation_keys: Callable[[int], jax.Array]
    #: a chunk's end with the state a stop during its evaluation saves (over several processes, the host
    #: copy the evaluation started from)
    held: Callable[[ChunkEnd], ChunkEnd]
    #: a resumed run a stop cut short at the end of a chunk: that chunk's end (None otherwise), why a hook
    #: ended the run there ('' where none did), and whether the run's final evaluation is all that is left
    end: ChunkEnd | None
    stopped: str
    pending: bool


def append_line(path: Path, line: str) -> None:
    """``line`` at the end of the file at ``path`` (rlq.log before the run's logger has it open)."""
    with open(path, "a") as file:
        file.write(line.rstrip("\n") + "\n")


def _programs(
    spec: RunSpec, where: Placement, resumed_meta: dict[str, Any]
) -> tuple[Programs, ProgramCache | None, Future | None]:
    """The run's programs (a resumed run keeps the chunks of its checkpoint), the program cache to use and
    the programs it is loading."""
    compile_cache.enable(spec.compilation.compile_cache)
    cache = ProgramCache.for_run(spec, where)
    cached = cache.load_soon() if cache is not None else None
    chunk_steps = int(resumed_meta.get("chunk_steps", 0))
    done_steps = int(resumed_meta.get("chunks_done", 0)) * chunk_steps
    programs = build(spec, where, done_steps if chunk_steps else int(resumed_meta.get("env_steps", 0)), chunk_steps)
    if programs.replanned:  # its programs are not the ones a fresh run of this config keeps
        cache, cached = None, None
    return programs, cache, cached


def _notes(spec: RunSpec, programs: Programs, resumed: bool, earlier_rows: bool, run_dir: Path) -> list[str | None]:
    """What the console says of the plan before compiling (None: nothing): a run started over, budgets rounded,
    the algorithm's notes, cadences snapped to chunks, a stop rule's granularity, a resumed run's kept chunks."""
    planned = programs.chunk_steps * programs.num_chunks
    cadences = Cadences.from_config(spec)
    asked = asked_keys()
    notes = cadences.snap_notes(programs.chunk_steps, planned, programs.updates_per_chunk == 1, asked)
    small_budget = budget_note(spec.budget.env_steps, programs.algo.steps_per_update, programs.algo.iterations)
    if asked is None or "budget.env_steps" in asked:  # a budget nobody set rounds without a word
        small_budget = small_budget or rounded_note(
            spec.budget.env_steps, planned, programs.algo.steps_per_update, programs.algo.iterations
        )
    over = f"{run_dir} held a run that stopped before its first checkpoint: it starts over" if earlier_rows else None
    stop_note = cadences.stop_note(spec.budget.stop_when, programs.chunk_steps, planned)
    per_chunk = programs.updates_per_chunk
    short = programs.replanned and programs.num_chunks * per_chunk < programs.algo.num_updates and resumed
    kept = (
        f"the run keeps its chunks of {programs.chunk_steps:,} env steps: it ends at {planned:,}, the last whole "
        f"chunk within budget.env_steps={spec.budget.env_steps}"
        if short
        else None
    )
    return [over, small_budget, *programs.algo.notes, *notes, stop_note, kept]


def prepare(
    spec: RunSpec,
    where: Placement,
    run_dir: Path,
    resume: Path | None,
    stop: StopRequest,
    state_hash: str,
    finishing: bool,
) -> Plan:
    """The run's plan: programs built (not compiled), the logger open, the console told what it should know."""
    began = time.perf_counter()
    resumed_meta = checkpoint.meta(resume) if resume is not None else {}
    start = time.perf_counter() - float(resumed_meta.get("wall_s", 0.0))  # the run's clock goes on
    programs, cache, cached = _programs(spec, where, resumed_meta)
    num_seeds = int(spec.seeds.count)
    earlier_rows = resume is None and (run_dir / "metrics.jsonl").exists()
    if earlier_rows:  # a run started over in its directory: the rows of the attempt that died go
        (run_dir / "metrics.jsonl").unlink()
    per_chunk = programs.updates_per_chunk
    # black-box algorithms count true env steps (episodes end early), below the chunks' nominal
    # steps: the checkpoint records how many chunks it follows, and of what size (a run extended
    # with a larger budget may plan other chunks)
    first_chunk = resumed_chunks(resumed_meta, programs.chunk_steps) if resume is not None else 0
    if programs.algo.iterations:  # the bar counts iterations: true env steps fall below the nominal ones
        total, done, unit = programs.num_chunks * per_chunk, first_chunk * per_chunk, "it"
    else:
        total, done, unit = programs.chunk_steps * programs.num_chunks, int(resumed_meta.get("env_steps", 0)), "step"
    stop.early, stop.record = early_stop_line(run_dir, resume), functools.partial(append_line, run_dir / "rlq.log")
    logger = RunLogger(spec.values, run_dir, total, num_seeds, start_steps=done, started=start, unit=unit)
    stop.notify = logger.console.warn
    partial = slices.resumed_part(resume, resumed_meta, programs.calls_per_chunk)
    mismatch = shape_note(spec, where.platform)
    if mismatch:
        logger.console.warn(mismatch)
    for note in [where.note, *_notes(spec, programs, resume is not None, earlier_rows, run_dir)]:
        if note:
            logger.console.message(f"rlq: {note}")
    logger.console.phase("compiling")
    return Plan(
        spec=spec,
        where=where,
        run_dir=run_dir,
        resume=resume,
        resumed_meta=resumed_meta,
        stop=stop,
        state_hash=state_hash,
        finishing=finishing,
        programs=programs,
        cache=cache,
        cached=cached,
        logger=logger,
        began=began,
        start=start,
        first_chunk=first_chunk,
        partial=partial,
        num_seeds=num_seeds,
        count=members.member_count(spec),
        evaluator=ThreadPoolExecutor(max_workers=1, thread_name_prefix="rlq-eval"),
        waiter=waiting.for_run(lambda: stop.signum, coordination_client()),
        local=waiting.Waiter(lambda: stop.signum),
    )


def _first_state(
    plan: Plan, warm: Callable[[Any], Any] | None, hyper: Any
) -> tuple[CompiledPrograms, Any, int, float, Callable[[int], jax.Array]]:
    """The programs compiled and the run's first state: the compiled programs, the state, its env steps,
    the seconds both took, and the evaluations' keys (placed on the mesh) by tag. ``hyper``: the hyperparameters
    (``Programs.hyper`` on the mesh) a fresh run's init starts from, as its chunks train at."""
    spec, where, programs = plan.spec, plan.where, plan.programs
    seeds, num_seeds, count = programs.placement.seeds, plan.num_seeds, plan.count

    def evaluation_keys(tag: int) -> jax.Array:
        return to_mesh(eval_keys(int(spec.seeds.seed), np.int32(tag), num_seeds, count), seeds)

    def first_keys() -> jax.Array:
        with jax.default_device(where.local_device):
            evaluation_keys(0)  # its program compiles now, off the path to the first chunk
            return to_mesh(members.init_keys(spec), seeds)

    t0 = time.perf_counter()
    # the keys' two small programs compile in a worker while the run's programs are traced
    with ThreadPoolExecutor(max_workers=1) as worker:
        keys_soon = worker.submit(first_keys)
        compiled = compile_programs(
            programs,
            jax.eval_shape(functools.partial(members.init_keys, spec)),
            jax.eval_shape(lambda tag: eval_keys(int(spec.seeds.seed), tag, num_seeds, count), np.int32(0)),
            options_from_config(spec),
            plan.cache,
            plan.cached.result() if plan.cached is not None else None,
            need_init=plan.resume is None,
        )
        keys = keys_soon.result()
    if plan.resume is None:
        state, start_steps = compiled.programs["init"](keys, hyper), 0
        if warm is not None:
            state = to_mesh(warm(to_host(state)), seeds)
    else:
        # host arrays, placed on this run's mesh (whatever the device count that wrote them)
        state = to_mesh(members.load_state(plan.resume, compiled.state_shape, spec), seeds)
        start_steps = checkpoint.env_steps(plan.resume)
    return compiled, state, start_steps, time.perf_counter() - t0, evaluation_keys


def _video(plan: Plan, compiled: CompiledPrograms) -> tuple[bool, Seed0Video | None]:
    """Whether the run ends with a video, and the video of seed 0 (None where this process makes none)."""
    spec, where, programs = plan.spec, plan.where, plan.programs
    final_video = wants_final_video(spec.outputs.video.at_end, sweep_group(plan.run_dir) is not None)
    video = (
        Seed0Video(spec, programs.algo, plan.run_dir, plan.logger, programs.env)
        if (final_video or spec.outputs.video.every_steps) and is_writer()  # seed 0 lives on process 0
        else None
    )
    if final_video and video is not None and where.platform != "cpu" and where.mesh.devices.size == 1:
        options = program_options("video", options_from_config(spec), where.platform)
        video.prepare_soon(compiled.state_shape, where.mesh.devices.flat[0], options)  # on a CPU it would slow training
    return final_video, video


def _evaluations(
    plan: Plan, evaluate: Callable[[Any, jax.Array], Any], evaluation_keys: Callable[[int], jax.Array]
) -> tuple[Callable[[Any, int], dict[str, np.ndarray]], Callable[[ChunkEnd], ChunkEnd]]:
    """The periodic evaluation the hooks call (in the plan's evaluator, waited for in slices), and a chunk's
    end with the state a stop during that evaluation saves."""
    # over several processes, the state an evaluation starts from, copied to the host first: a stop during
    # the evaluation saves it (a copy made then would queue on the devices behind the evaluation)
    evaluated_state: list[Any] = []

    def periodic_eval(st: Any, index: int) -> dict[str, np.ndarray]:
        keys = evaluation_keys(index)
        evaluated_state[:] = [to_host(st)] if jax.process_count() > 1 else []
        return plan.waiter.wait(plan.evaluator.submit(lambda: eval_summary(to_host(evaluate(st, keys)))))

    def held(end: ChunkEnd) -> ChunkEnd:
        return dataclasses.replace(end, state=evaluated_state[0]) if evaluated_state else end

    return periodic_eval, held


def _stage_video(plan: Plan, video: Seed0Video) -> Callable[[Any, int, str], Path | None]:
    """The hooks' videos during training: made in the plan's evaluator; one a stop abandons is left out."""

    def stage_video(st: Any, steps: int, name: str) -> Path | None:
        try:
            return plan.local.wait(plan.evaluator.submit(video, st, steps, name))
        except waiting.Abandoned:  # the stop is seen after the chunk's hooks: a checkpoint, then the end
            video.forget(name)
            plan.logger.console.warn(f"no video {name}: stopped while it was made")
            return None

    return stage_video


def redo_evaluation(
    hooks: list[Hook], end: ChunkEnd, run_dir: Path, logger: RunLogger, held: Callable[[ChunkEnd], ChunkEnd]
) -> str:
    """The evaluation after chunk ``end`` that a stop skipped, made by the resumed run as the
    stopped one would have (its row, its listeners); returns why a hook ends the run there, or ''.
    ``held``: ``end`` with the state a stop saves (``Ready.held``)."""
    try:
        for hook in hooks:
            if isinstance(hook, PeriodicEval):
                hook.on_chunk(end)
    except waiting.Abandoned as left:
        raise interrupted(run_dir, left.signum, held(end), logger.wall_s(), skipped_eval=True) from None
    return next((hook.reason for hook in hooks if hook.stop), "")


def start(plan: Plan, warm: Callable[[Any], Any] | None = None) -> Ready:
    """The plan's programs compiled, its first state made and its hooks ready. ``warm``: maps a fresh run's
    initial state (on the host) to the one it starts from. A resumed run a stop cut short at the end of a
    chunk makes first what the stop skipped: the chunk's evaluation, or the run's final one (then it trains
    nothing)."""
    programs, logger = plan.programs, plan.logger
    hyper = to_mesh(programs.hyper, programs.placement.seeds)
    compiled, state, start_steps, compile_s, evaluation_keys = _first_state(plan, warm, hyper)
    evaluate = compiled.evaluate
    chunk, rest_soon = with_hyper(compiled.programs["chunk"], hyper), with_hyper_soon(compiled.rest_soon, hyper)
    # a sweep's later jobs say they load the programs of its first (hyperparameters are the chunk's argument)
    logger.console.message(compiled.line(compile_s))
    final_video, video = _video(plan, compiled)
    logger.console.training()
    periodic_eval, held = _evaluations(plan, evaluate, evaluation_keys)
    stage_video = _stage_video(plan, video) if video is not None else None
    hooks = loop_hooks(plan.spec, programs, plan.run_dir, logger, periodic_eval, stage_video)
    meta, end, stopped = plan.resumed_meta, None, ""
    pending = plan.finishing or (bool(meta.get("final_pending")) and meta.get("num_chunks") == programs.num_chunks)
    if plan.resume is not None and (pending or meta.get("eval_skipped")):
        end = ChunkEnd(plan.first_chunk - 1, start_steps, state, {}, pending, programs.chunk_steps, plan.state_hash)
        stopped = str(meta.get("stopped", "")) if pending else redo_evaluation(hooks, end, plan.run_dir, logger, held)
    return Ready(
        compiled=compiled,
        evaluate=evaluate,
        state=state,
        start_steps=start_steps,
        compile_s=compile_s,
        chunk=chunk,
        rest_soon=rest_soon,
        video=video,
        final_video=final_video,
        hooks=hooks,
        evaluation_keys=evaluation_keys,
        held=held,
        end=end,
        stopped=stopped,
        pending=pending,
    )
