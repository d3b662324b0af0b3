"""THE training loop: one compiled program per chunk of updates, for every algorithm.

    state = jit(vmap(algo.init))(seed keys)                 # all seeds in one program
    loop:  state, metrics = jit(vmap(scan(algo.update, K)))(state)
           hooks on the host (rlq/run/hooks.py): log, figures, evaluate, checkpoint

Metrics leave the device once per chunk of K updates; algorithms never do I/O. The programs are
traced one after the other, each compiled in a worker thread while the next is traced
(submit_pipelined); training starts once init and chunk are compiled, and the evaluation program
may still be compiling then (on a CPU it is traced in a worker and compiled last: compile_programs).
Every program runs on the run's mesh (rlq/run/devices.py):
its inputs and outputs are split along the seed axis, and the programs split each seed's envs
over the mesh's env devices where they call rlq.lib.sharding.
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import signal
import sys
import time
from collections.abc import Callable, Collection, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import jax
import jax.numpy as jnp
import numpy as np
from omegaconf import DictConfig

from rlq.algos import make_algo
from rlq.algos.base import Algorithm, budget_note
from rlq.envs import Env
from rlq.envs.wrappers import ReturnWindow, window_return
from rlq.errors import DivergedError, RunInterrupted
from rlq.lib.env_api import EnvState
from rlq.lib.rollout import evaluate
from rlq.lib.sharding import SEED
from rlq.run import checkpoint, compile_cache, guard
from rlq.run.build import evaluation_env, make_env
from rlq.run.compiler import Option, compile_with, known_to_cpu_xla, options_from_config
from rlq.run.devices import Placement, placement, shape_note
from rlq.run.files import write_atomic
from rlq.run.hooks import (
    ChunkEnd,
    DrawFigures,
    Hook,
    KeepBest,
    KeepLast,
    LogTrainRows,
    PeriodicCheckpoint,
    PeriodicEval,
    PeriodicVideo,
    StopWhen,
    save_step_checkpoint,
    seed_figures,
)
from rlq.run.logging import RunLogger
from rlq.run.program_cache import ProgramCache, watch_cache_hits
from rlq.run.render import DrawsFrames
from rlq.run.sidecar import HASH_KEY, config_hash
from rlq.run.signals import StopRequest
from rlq.run.stop import parse_stop
from rlq.run.sweep import sweep_group
from rlq.run.videos import Seed0Video, cpu_video_skip, video_estimate_s, wants_final_video


@functools.partial(jax.jit, static_argnums=(0, 1))
def seed_keys(seed: int, num_seeds: int) -> jax.Array:
    """Key of seed i is fold_in(PRNGKey(seed), i): a seed's run does not depend on num_seeds.

    Jitted, as ``eval_keys``: run eagerly, its PRNG operations compile one small program each
    (0.3-0.4 s on a 2-core CPU before the run's own compile starts)."""
    base = jax.random.PRNGKey(seed)
    return jax.vmap(lambda i: jax.random.fold_in(base, i))(jnp.arange(num_seeds))


@functools.partial(jax.jit, static_argnums=(0, 2))
def eval_keys(seed: int, tag: jax.Array, num_seeds: int) -> jax.Array:
    """The keys of the evaluation tagged ``tag`` (one per seed): every evaluation of a run with the same
    tag draws the same episodes."""
    return jax.random.split(jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(seed), 10_007), tag), num_seeds)


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
    def from_config(cls, cfg: DictConfig) -> Cadences:
        every = (cfg.eval.every_steps, cfg.checkpoint.every_steps, cfg.video.every_steps)
        return cls(int(cfg.log_every_steps), *(int(e) for e in every))

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


def chunk_plan(num_updates: int, steps_per_update: int, cadences: Cadences) -> tuple[int, int]:
    """(updates per chunk, number of chunks): equal chunks, so one compiled program.

    The chunk length is chosen between half and twice the logging cadence to waste the fewest
    updates (a run never exceeds ``num_updates``; most budgets are hit exactly), then to land on
    the most cadences (a chunk of exactly ``log_every_steps``, evaluations and checkpoints on
    whole numbers of chunks), then closest to the logging cadence.
    """
    target = max(1, cadences.log // max(1, steps_per_update))
    if target >= num_updates:
        return num_updates, 1
    candidates = range(max(1, target // 2), min(num_updates, 2 * target) + 1)
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


#: how a chunk's updates run (config key ``chunk_loop``): ``scan``, one compiled program loops over
#: them; ``calls``, the host calls the one-update program back to back without waiting for it
CHUNK_LOOPS = ("scan", "calls")


def env_windows(state: Any) -> list[dict[str, jax.Array]]:
    """The return windows (``ReturnWindow``) of the env batches an algorithm's state holds: every
    algorithm that steps envs itself keeps them in its state; black-box algorithms hold none."""
    nodes = jax.tree.leaves(state, is_leaf=lambda node: isinstance(node, EnvState))
    return [
        cast(dict[str, jax.Array], node.extras[ReturnWindow.KEY])
        for node in nodes
        if isinstance(node, EnvState) and ReturnWindow.KEY in node.extras
    ]


@dataclass
class Programs:
    """The compiled pieces of a run, built once from a config. A chunk is ``calls_per_chunk`` calls
    of ``chunk`` (see ``call_chunk``), ``updates_per_chunk`` updates in all."""

    env: Env
    algo: Algorithm
    init: jax.stages.Wrapped
    chunk: jax.stages.Wrapped
    evaluate: jax.stages.Wrapped
    updates_per_chunk: int
    num_chunks: int
    placement: Placement
    calls_per_chunk: int = 1
    #: the divergence guard's bounds the chunk checks (``guard:``), for the line that names the one passed
    bounds: guard.Bounds = guard.NO_BOUNDS

    @property
    def chunk_steps(self) -> int:
        """Env steps per seed of one chunk."""
        return self.updates_per_chunk * self.algo.steps_per_update


def on_mesh(fn: Callable, where: Placement, name: str) -> jax.stages.Wrapped:
    """``jit(vmap(fn))`` over seeds on the run's mesh: every input and output split along its
    leading (seed) axis, and ``fn`` traced under the mesh, so that its env axis is split where it
    says so (rlq.lib.sharding).

    One seed is traced without ``vmap`` (its axis taken off the inputs and put back on the
    outputs): the same numbers, but batching a program of nested loops re-traces every loop body
    at each level, which more than doubles the trace (LunarLander's chunk: 3.2 s -> 1.7 s)."""
    batched = jax.vmap(fn, spmd_axis_name=SEED)

    def one_seed(*args):
        out = fn(*jax.tree.map(lambda x: x[0], args))
        return jax.tree.map(lambda x: jnp.expand_dims(x, 0), out)

    def traced(*args):
        with jax.sharding.use_abstract_mesh(where.mesh.abstract_mesh):
            if jax.tree.leaves(args)[0].shape[0] == 1:
                return one_seed(*args)
            return batched(*args)

    traced.__name__ = traced.__qualname__ = name  # JAX's logs and profiles then say jit(chunk), not jit(traced)
    return jax.jit(traced, in_shardings=where.seeds, out_shardings=where.seeds)


def build(cfg: DictConfig, where: Placement | None = None) -> Programs:
    """The run's env, algorithm and programs on ``where`` (default: the config's placement)."""
    where = where or placement(cfg)
    env = make_env(cfg)
    algo = make_algo(cfg.algo, env, cfg.budget.env_steps)
    per_chunk, num_chunks = chunk_plan(algo.num_updates, algo.steps_per_update, Cadences.from_config(cfg))
    calls = per_chunk if cfg.chunk_loop == "calls" else 1

    window = int(cfg.return_window)

    bounds = guard.Bounds.from_config(cfg.get("guard"))
    update = guard.with_flags(algo.update, algo.params, bounds)

    def run_chunk(state):
        state, metrics = jax.lax.scan(lambda s, _: update(s), state, None, length=per_chunk // calls)
        windows = env_windows(state)
        if window and windows:
            metrics = {**metrics, "return_window": window_return(windows, window)[None]}
        return state, metrics

    @functools.cache
    def eval_env() -> Env:
        """Built when the evaluation program is traced, off the path to the first chunk; its
        construction (an MJX model's upload) runs eagerly inside that trace."""
        with jax.ensure_compile_time_eval():
            return evaluation_env(cfg, env)

    def eval_one(state, key):
        record = evaluate(eval_env(), algo.policy(state), key, cfg.eval.episodes)
        if algo.state_metrics is not None:
            record.update(algo.state_metrics(state))
        return record

    return Programs(
        env=env,
        algo=algo,
        init=on_mesh(algo.init, where, "init"),
        chunk=on_mesh(run_chunk, where, "chunk"),
        evaluate=on_mesh(eval_one, where, "evaluate"),
        updates_per_chunk=per_chunk,
        num_chunks=num_chunks,
        placement=where,
        calls_per_chunk=calls,
        bounds=bounds,
    )


def call_chunk(chunk: Callable[[Any], tuple[Any, dict]], state: Any, calls: int) -> tuple[Any, dict]:
    """``calls`` calls of the compiled ``chunk``, queued without waiting (jax dispatches them
    asynchronously), and their metrics joined along the update axis as one call's would be. The
    join runs in numpy on the host: a jax concatenate would compile a small program per metric on
    the first chunk (0.5 s on a GPU).

    With ``chunk_loop=calls`` the program holds a single update and no loop around it: the MJX
    humanoid's update, compiled that way, runs 2-3 % faster than inside a loop of updates
    (docs/humanoid.md), and the host's dispatch hides behind updates that take a tenth of a second
    or more."""
    parts = []
    for _ in range(calls):
        state, metrics = chunk(state)
        parts.append(metrics)
    if calls == 1:
        return state, parts[0]
    return state, jax.tree.map(lambda *xs: np.concatenate(xs, axis=1), *jax.device_get(parts))


#: XLA options per program on a CPU, where the two or so cores that compile also train, so compile time
#: counts as much as run time (figures: CartPole PPO on 2 cores, docs/history/benchmarks.md).
#: - init runs once: without LLVM's optimisations and with XLA's older (non-MLIR) fusion emitters it
#:   compiles in 0.5 s instead of 1.5 s and still runs in milliseconds.
#: - chunk at LLVM's level 1 instead of XLA's default 2: 2.1-2.3 s instead of 3.1-3.5 s to compile, as
#:   fast to run (level 0 runs 3x slower).
#: - evaluate at level 1 with the older fusion emitters: 0.4-0.5 s instead of 1.2 s (LunarLander's
#:   7.7 s instead of 12.3 s), no slower to run. The chunk keeps the MLIR emitters: without them
#:   CartPole's trains 15 % slower, and LunarLander's (`lunar_ppo`) compiles in 9.8 s instead of 12.8 s but
#:   trains 16-20 % slower (2026-11-28).
#: Options the installed XLA does not know are left out (``known_to_cpu_xla``).
CPU_OPTIONS: dict[str, dict[str, Option]] = {
    "init": {"xla_backend_optimization_level": 0, "xla_cpu_use_fusion_emitters": False},
    "chunk": {"xla_backend_optimization_level": 1},
    "evaluate": {"xla_backend_optimization_level": 1, "xla_cpu_use_fusion_emitters": False},
}


#: XLA options per program on a GPU. The evaluation program compiles beside the chunk's and then
#: while the chunks train, and XLA's autotuner times its candidate kernels on that busy GPU: the
#: humanoid's took 34-45 s to compile and was ready 8-13 s after training ended; without autotuning
#: 24-28 s, ready before it (H100, docs/humanoid.md). An evaluation steps a hundred-odd envs
#: and waits on kernel launches, not on the matrix products autotuning picks; the final video's
#: episode (rlq.run.videos), compiled while the chunks train, steps one.
GPU_OPTIONS: dict[str, dict[str, Option]] = {
    "evaluate": {"xla_gpu_autotune_level": 0},
    "video": {"xla_gpu_autotune_level": 0},
}


def program_options(
    name: str, options: Mapping[str, Option] | None, platform: str | None = None
) -> Mapping[str, Option] | None:
    """The XLA options program ``name`` compiles with on ``platform`` (None: JAX's default): the
    run's, over ``CPU_OPTIONS`` on a CPU (those the installed XLA knows) and ``GPU_OPTIONS`` on a
    GPU; the run's own options win."""
    platform = platform or jax.default_backend()
    ours = {"cpu": CPU_OPTIONS, "gpu": GPU_OPTIONS}.get(platform, {}).get(name)
    if ours is None:
        return options
    return {**(known_to_cpu_xla(ours) if platform == "cpu" else ours), **(options or {})}


def submit_pipelined(
    pool: ThreadPoolExecutor,
    lowerings: Mapping[str, Callable[[], jax.stages.Lowered]],
    options: Mapping[str, Option] | None = None,
    then: Callable[[jax.stages.Compiled], Any] = lambda program: program,
    platform: str | None = None,
) -> dict[str, Future]:
    """Lower each program on the caller's thread and hand its compile, followed by ``then``, to
    ``pool`` as soon as it is lowered: XLA's compiler releases the GIL, so the next program is
    traced while the previous one compiles. ``options``: XLA compiler options for every program
    (rlq.run.compiler); ``platform``: where the programs run (None: JAX's default)."""

    def compile_then(lowered: jax.stages.Lowered, name: str) -> Any:
        return then(compile_with(lowered, program_options(name, options, platform)))

    return {name: pool.submit(compile_then, lower(), name) for name, lower in lowerings.items()}


def compile_pipelined(
    lowerings: Mapping[str, Callable[[], jax.stages.Lowered]], options: Mapping[str, Option] | None = None
) -> dict[str, jax.stages.Compiled]:
    """``submit_pipelined``, waited for: the caller waits for the slowest compile rather than for
    the sum (MJX programs take tens of seconds each to trace and to compile). Pass the slowest
    compile first."""
    with ThreadPoolExecutor(max_workers=max(1, len(lowerings))) as pool:
        futures = submit_pipelined(pool, lowerings, options)
        return {name: future.result() for name, future in futures.items()}


@dataclass
class CompiledPrograms:
    """A run's compiled programs: ``init`` (when needed) and ``chunk`` ready, ``evaluate`` maybe
    still compiling; the shape of the state; which programs came whole from the program cache;
    and, once all are compiled, the programs to keep in ``cache`` with their serialised form (None
    where not yet serialised; ``to_keep`` is None when there is nothing to keep)."""

    programs: dict[str, jax.stages.Compiled]
    evaluate_soon: Future[tuple[jax.stages.Compiled, Any]]
    state_shape: Any
    loaded: list[str]
    to_keep: Future[dict[str, tuple[jax.stages.Compiled, Any]] | None] = field(default_factory=lambda: finished(None))
    cache: ProgramCache | None = None

    def evaluate(self, state: Any, keys: jax.Array) -> Any:
        """The evaluation program's output, waiting for its compile on the first call."""
        return self.evaluate_soon.result()[0](state, keys)

    def store(self) -> str | None:
        """Keep the programs in the program cache; returns why they could not be kept, or None
        (kept, loaded from it, or no cache). Serialising a program holds the GIL and waits for the
        device (0.5-1 s for a LunarLander chunk on a GPU): call it after training, not between chunks."""
        ready = self.to_keep.result()
        if ready is None or self.cache is None:
            return None
        cache = self.cache
        return cache.store(
            {name: cache.pack(program) if pack is None else pack for name, (program, pack) in ready.items()}
        )


def finished(value: Any) -> Future:
    """A future that already holds ``value``."""
    future: Future = Future()
    future.set_result(value)
    return future


def compile_programs(
    programs: Programs,
    keys: jax.Array | jax.ShapeDtypeStruct,
    eval_key: jax.Array | jax.ShapeDtypeStruct,
    options: Mapping[str, Option] | None,
    cache: ProgramCache | None,
    loaded: dict[str, jax.stages.Compiled] | None,
    need_init: bool,
) -> CompiledPrograms:
    """The run's ``init``, ``chunk`` and ``evaluate`` programs: ``loaded`` (from ``cache``, nothing
    traced) when given, else traced, lowered and compiled, for ``CompiledPrograms.store`` to keep in
    ``cache`` (nothing when JAX's cache supplied them). ``need_init``: a
    fresh run calls init; a resumed one needs only its output shape (init is compiled for the cache).

    ``keys`` and ``eval_key`` may be shapes: the programs are traced, not called, here.

    Returns once ``init`` and ``chunk`` are compiled; ``evaluate`` may still be compiling (a run's
    first evaluation comes after at least one chunk). Programs are serialised for ``cache`` as they
    compile on a CPU (XLA's CPU runtime needs it before a program first runs), elsewhere only when
    ``CompiledPrograms.store`` is called. On a CPU, where the cores that compile also
    train, ``evaluate`` is traced in a worker thread and compiled after the others, while the first
    chunks train: its compile is then off the path to the first training row rather than sharing
    the cores with the chunk's. On an accelerator the host's cores compile all three side by side.
    Tracing in two threads is safe: JAX keeps its trace state per thread, and the envs that patch a
    dependency while they are traced (the humanoid) hold a lock while they do."""
    if loaded is not None:
        return CompiledPrograms(loaded, finished((loaded["evaluate"], None)), loaded["init"].out_info, sorted(loaded))
    traced_init = programs.init.trace(keys)
    state_shape = traced_init.out_info
    platform = programs.placement.platform
    defer = platform == "cpu"
    lowers: dict[str, Callable[[], jax.stages.Lowered]] = {
        "init": traced_init.lower,
        "chunk": lambda: programs.chunk.lower(state_shape),
    }
    # on a CPU init first (a core compiles it while the chunk is traced); elsewhere the slowest compile first
    order = ("init", "chunk") if defer else ("chunk", "init")
    lowerings = {name: lowers[name] for name in order if name != "init" or need_init or cache is not None}
    if not defer:  # last: init compiles while the evaluation is traced (an MJX trace takes seconds)
        lowerings["evaluate"] = lambda: programs.evaluate.lower(state_shape, eval_key)

    def packed(program: jax.stages.Compiled) -> tuple[jax.stages.Compiled, Any]:
        return program, cache.pack(program) if cache is not None and platform == "cpu" else None

    watching = contextlib.ExitStack()
    hits = watching.enter_context(watch_cache_hits())
    pool = ThreadPoolExecutor(max_workers=len(lowerings) + 2)
    try:
        futures = submit_pipelined(pool, lowerings, options, then=packed, platform=platform)
    except BaseException:
        watching.close()
        raise

    def evaluate_program() -> tuple[jax.stages.Compiled, Any]:
        if not defer:
            return futures["evaluate"].result()
        # JAX's default device is per thread: the worker traces for the run's device, as the caller does
        with jax.default_device(programs.placement.mesh.devices.flat[0]):
            lowered = programs.evaluate.lower(state_shape, eval_key)
        for future in futures.values():  # compiled once the others are
            future.result()
        return packed(compile_with(lowered, program_options("evaluate", options, platform)))

    evaluate_soon = pool.submit(evaluate_program)

    def all_compiled() -> dict[str, tuple[jax.stages.Compiled, Any]] | None:
        with watching:
            ready = {name: future.result() for name, future in futures.items() if name != "evaluate"}
            ready["evaluate"] = evaluate_soon.result()
        return ready if cache is not None and not hits else None

    to_keep = pool.submit(all_compiled)
    pool.shutdown(wait=False)
    first = {name: futures[name].result()[0] for name in lowerings if name != "evaluate"}
    return CompiledPrograms(first, evaluate_soon, state_shape, [], to_keep, cache)


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
    #: the programs loaded whole from the compile cache (rlq.run.program_cache), not traced
    cached_programs: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return {
            "env_steps": self.env_steps,
            "num_seeds": self.num_seeds,
            "wall_s": round(self.wall_s, 3),
            "compile_s": round(self.compile_s, 3),
            "steady_env_steps_per_s": round(self.steady_steps_per_s, 1),
            "eval_return": [float(r) for r in self.eval_return],
            "eval_return_mean": float(np.mean(self.eval_return)),
            "resumed_from_env_steps": self.start_steps,
            "chunk_s": [round(t, 3) for t in self.chunk_s],
            "final_eval": {k: [float(x) for x in np.asarray(v).reshape(-1)] for k, v in self.final_eval.items()},
            "stopped": self.stopped,
            "cached_programs": list(self.cached_programs),
        }

    def line(self) -> str:
        per_seed = ", ".join(f"{r:.1f}" for r in self.eval_return)
        resumed = f" (resumed at {self.start_steps:,})" if self.start_steps else ""
        qd = ""
        if "archive-occupancy" in self.final_eval:
            coverage = 100 * float(np.mean(self.final_eval["archive-occupancy"]))
            qd = f" | archive coverage {coverage:.1f} %, QD score {float(np.mean(self.final_eval['qd-score'])):.4g}"
        stopped = f" | {self.stopped}" if self.stopped else ""
        return (
            f"rlq: {self.env_steps:,} env steps{resumed} x {self.num_seeds} seed(s) in {self.wall_s:.1f} s "
            f"(compile {self.compile_s:.1f} s, {self.steady_steps_per_s:,.0f} env steps/s) | "
            f"final greedy eval return {np.mean(self.eval_return):.1f} (seeds: {per_seed}){qd}{stopped} | {self.run_dir}"
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


def loop_hooks(
    cfg: DictConfig,
    programs: Programs,
    run_dir: Path,
    logger: RunLogger,
    evaluate: Callable[[Any, int], dict[str, np.ndarray]],
    video: Seed0Video | None,
) -> list[Hook]:
    """The host's work after each chunk, in order: log, figures, evaluation (its listeners: figures,
    the stop rule, and with ``checkpoint.keep_best`` the best state), checkpoint (its listener keeps
    the last ``checkpoint.keep_last``), video, stop rule."""
    hooks: list[Hook] = [LogTrainRows(logger, programs.updates_per_chunk)]
    algo = programs.algo
    at_eval: list[Hook] = []
    if algo.figures is not None:
        figures = DrawFigures(algo.figures, algo.figures_every, programs.updates_per_chunk, int(cfg.num_seeds), logger)
        hooks.append(figures)
        at_eval += [figures] if algo.figures_at_eval else []
    stop: list[Hook] = [StopWhen(parse_stop(cfg.stop.when), logger)] if cfg.stop.when else []
    cadences, chunk_steps = Cadences.from_config(cfg), programs.chunk_steps
    directory = run_dir / "checkpoints"
    best: list[Hook] = [KeepBest(directory)] if cfg.checkpoint.keep_best else []

    def every_chunks(every_steps: int) -> int:
        return cadences.snapped(every_steps, chunk_steps) // chunk_steps

    hooks.append(PeriodicEval(evaluate, every_chunks(cadences.eval), logger, listeners=at_eval + stop + best))
    keep = [KeepLast(int(cfg.checkpoint.keep_last))]
    hooks.append(PeriodicCheckpoint(directory, every_chunks(cadences.checkpoint), keep, logger.wall_s))
    if video is not None and cadences.video:
        hooks.append(PeriodicVideo(video, every_chunks(cadences.video)))
    return hooks + stop


def interrupted(run_dir: Path, signum: int, end: ChunkEnd, wall_s: float) -> RunInterrupted:
    """Save a resumable checkpoint of the state after chunk ``end`` (unless the periodic hook just
    did) and the error that ends the run with the signal's exit code."""
    path = run_dir / "checkpoints" / f"step_{end.env_steps}.msgpack"
    if not path.exists():
        path = save_step_checkpoint(path.parent, end, wall_s)
    return RunInterrupted(
        f"stopped by {signal.Signals(signum).name} at env step {end.env_steps:,}: checkpoint "
        f"{path}; continue with `rlq resume run={run_dir}`",
        signum,
    )


def _warn(text: str) -> None:
    print(f"rlq: warning: {text}", file=sys.stderr, flush=True)


def train(
    cfg: DictConfig, run_dir: Path, resume: Path | None = None, warm: Callable[[Any], Any] | None = None
) -> RunResult:
    """Train ``cfg.num_seeds`` seeds of one config; write metrics and checkpoints to ``run_dir``.

    ``resume``: a checkpoint of this run written at the end of a chunk; training goes on from it
    to the budget (the state holds every PRNG key, so it continues exactly as the run would have).
    SIGINT/SIGTERM end the run after the chunk in flight with a resumable checkpoint
    (RunInterrupted); NaN/Inf in parameters, losses or returns end it at once (DivergedError).
    ``warm``: maps a fresh run's initial state (on the host) to the one it starts from (``init_from``)."""
    # eager operations (keys, checkpoints) go to the run's kind of device too (config key ``platform``)
    where = placement(cfg)
    with StopRequest(_warn) as stop, jax.default_device(where.mesh.devices.flat[0]):
        return _train(cfg, where, Path(run_dir), resume, stop, warm)


def _train(
    cfg: DictConfig,
    where: Placement,
    run_dir: Path,
    resume: Path | None,
    stop: StopRequest,
    warm: Callable[[Any], Any] | None = None,
) -> RunResult:
    resumed_meta = checkpoint.meta(resume) if resume is not None else {}
    state_hash = config_hash(cfg)  # before anything reads (or sets) the config
    start = time.perf_counter() - float(resumed_meta.get("wall_s", 0.0))  # the run's clock goes on
    compile_cache.enable(cfg.compile_cache)
    cache = ProgramCache.for_run(cfg, where)
    cached = cache.load_soon() if cache is not None else None
    programs = build(cfg, where)
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
    logger = RunLogger(cfg, run_dir, total, num_seeds, start_steps=done, started=start, unit=unit)
    stop.notify = logger.console.warn
    mismatch = shape_note(cfg, where.platform)
    if mismatch:
        logger.console.warn(mismatch)
    cadences = Cadences.from_config(cfg)
    notes = cadences.snap_notes(programs.chunk_steps, planned, programs.updates_per_chunk == 1, asked_keys())
    small_budget = budget_note(cfg.budget.env_steps, programs.algo.steps_per_update, programs.algo.iterations)
    over = f"{run_dir} held a run that stopped before its first checkpoint: it starts over" if earlier_rows else None
    stop_note = cadences.stop_note(cfg.stop.when, programs.chunk_steps, planned)
    for note in [over, small_budget, *programs.algo.notes, *notes, stop_note]:
        if note:
            logger.console.message(f"rlq: {note}")
    logger.console.phase("compiling")
    seeds = programs.placement.seeds

    def evaluation_keys(tag: int) -> jax.Array:
        return jax.device_put(eval_keys(int(cfg.seed), np.int32(tag), num_seeds), seeds)

    def first_keys() -> jax.Array:
        with jax.default_device(where.mesh.devices.flat[0]):
            evaluation_keys(0)  # its program compiles now, off the path to the first chunk
            return jax.device_put(seed_keys(cfg.seed, num_seeds), seeds)

    try:
        t0 = time.perf_counter()
        # the keys' two small programs compile in a worker while the run's programs are traced
        with ThreadPoolExecutor(max_workers=1) as worker:
            keys_soon = worker.submit(first_keys)
            compiled = compile_programs(
                programs,
                jax.eval_shape(functools.partial(seed_keys, cfg.seed, num_seeds)),
                jax.eval_shape(lambda tag: eval_keys(int(cfg.seed), tag, num_seeds), np.int32(0)),
                options_from_config(cfg),
                cache,
                cached.result() if cached is not None else None,
                need_init=resume is None,
            )
            keys = keys_soon.result()
        state_shape = compiled.state_shape
        chunk, evaluate_ = compiled.programs["chunk"], compiled.evaluate
        if resume is None:
            state, start_steps = compiled.programs["init"](keys), 0
            if warm is not None:
                state = jax.device_put(warm(jax.device_get(state)), seeds)
        else:
            # host arrays, placed on this run's mesh (whatever the device count that wrote them)
            state, start_steps = (
                jax.device_put(checkpoint.load(resume, state_shape), seeds),
                checkpoint.env_steps(resume),
            )
        compile_s = time.perf_counter() - t0
        chunk_s, env_steps, stopped = [], start_steps, ""
        final_video = wants_final_video(cfg.video.at_end, sweep_group(run_dir) is not None)
        video = (
            Seed0Video(cfg, programs.algo, run_dir, logger, programs.env)
            if final_video or cfg.video.every_steps
            else None
        )
        if final_video and video is not None and where.platform != "cpu" and where.mesh.devices.size == 1:
            options = program_options("video", options_from_config(cfg), where.platform)
            video.prepare_soon(state_shape, where.mesh.devices.flat[0], options)  # on a CPU it would slow training
        logger.console.training()
        hooks = loop_hooks(
            cfg,
            programs,
            run_dir,
            logger,
            lambda st, i: eval_summary(evaluate_(st, evaluation_keys(i))),
            video,
        )
        end: ChunkEnd | None = None
        for i in range(first_chunk, programs.num_chunks):
            t1 = time.perf_counter()
            state, metrics = call_chunk(chunk, state, programs.calls_per_chunk)
            metrics, checks = guard.split(jax.device_get(metrics))
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
            )
            for hook in hooks:
                hook.on_chunk(end)
            if stop.signum is not None:
                raise interrupted(run_dir, stop.signum, end, logger.wall_s())
            if any(hook.stop for hook in hooks):
                stopped = next(hook.reason for hook in hooks if hook.stop)
                break
        logger.console.phase("evaluating")
        # the final evaluation runs in a worker (a GPU program's loops hold its calling thread until
        # they end) while this thread writes the program cache (after training: serialising between
        # chunks would stall them) and the final checkpoint, copied to the host before the
        # evaluation starts (a copy queued behind it would wait for it)
        final_state, final_keys = jax.device_get(state), evaluation_keys(999_983)
        # a run a stop rule ended just after an evaluation keeps that one as its final (one eval row, one line)
        evaluated = next((h.last for h in hooks if isinstance(h, PeriodicEval)), None) if stopped else None
        reused = evaluated[1] if evaluated is not None and evaluated[0] == env_steps else None
        with ThreadPoolExecutor(max_workers=1) as worker:
            final_soon = worker.submit(
                lambda: reused if reused is not None else eval_summary(evaluate_(state, final_keys))
            )
            problem = compiled.store()
            meta = {
                "env_steps": env_steps,
                "num_seeds": num_seeds,
                "wall_s": logger.wall_s(),
                "chunks_done": end.index + 1 if end is not None else first_chunk,
                "chunk_steps": steps_per_chunk,
                HASH_KEY: state_hash,
            }
            try:
                checkpoint.save(run_dir / "checkpoints", "final", final_state, meta)
                final_error = None
            except OSError as err:  # a full disk: the run's result is still recorded, then the error ends it
                final_error = err
            final = final_soon.result()
        if problem:
            logger.console.message(f"rlq: programs not kept in the compile cache ({problem})")
        if reused is None:
            logger.log(env_steps, "eval", final)
        if end is not None and reused is None:  # the listeners heard the reused one when it was made
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
            video(state, env_steps, "final_seed0")
        steady_steps = (env_steps - start_steps) * num_seeds
        result = RunResult(
            env_steps=env_steps,
            num_seeds=num_seeds,
            wall_s=time.perf_counter() - start,
            compile_s=compile_s,
            steady_steps_per_s=steady_steps / max(sum(chunk_s), 1e-9),
            eval_return=final["return"],
            run_dir=run_dir,
            state=state,
            start_steps=start_steps,
            chunk_s=tuple(chunk_s),
            final_eval=final,
            stopped=stopped,
            cached_programs=tuple(compiled.loaded),
        )
        logger.record(result.line())
        if final_error is not None:
            logger.record(
                f"rlq: error: the final checkpoint was not written: {final_error.strerror}: {final_error.filename}"
            )
    except (DivergedError, RunInterrupted) as ended:  # the line the CLI prints ends rlq.log too
        logger.record(f"rlq: {ended}" if isinstance(ended, RunInterrupted) else f"rlq: error: {ended}")
        raise
    finally:
        logger.close()
    recorded: dict[str, Any] = dict(result.as_dict())
    if final_error is not None:
        recorded["final_checkpoint_error"] = f"{final_error.strerror}: {final_error.filename}"
    write_atomic(run_dir / "summary.json", json.dumps(recorded, indent=2).encode())
    if final_error is not None:
        raise final_error
    return result
