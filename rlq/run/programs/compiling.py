"""Compiling a run's programs: per-program XLA options, each program compiled in a worker thread while
the next is traced, and the persistent program cache."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import jax

from rlq.run.programs.build import Programs
from rlq.run.programs.compiler import Option, compile_with, known_to_cpu_xla
from rlq.run.programs.program_cache import FIRST, ProgramCache, compiling, finished, watch_cache_hits

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
    (rlq.run.programs.compiler); ``platform``: where the programs run (None: JAX's default)."""

    def compile_then(lowered: jax.stages.Lowered, name: str) -> Any:
        with compiling(name):
            program = compile_with(lowered, program_options(name, options, platform))
        return then(program)

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
    #: the program of a chunk's last, shorter block, maybe still compiling (None: the blocks divide a chunk)
    rest_soon: Future[tuple[jax.stages.Compiled, Any]] | None = None
    #: the programs JAX's persistent cache supplied so far (XLA did not compile them), in the order it did
    cache_hits: list[str] = field(default_factory=list)

    def from_cache(self) -> list[str]:
        """The programs this run did not compile: loaded whole (``loaded``) or supplied by JAX's cache."""
        return sorted(set(self.loaded) | {name for name in self.cache_hits if name})

    def line(self, seconds: float) -> str:
        """The console's line of the programs ready to train (``seconds``: how long they took): which came from
        the compile cache and which were compiled. A sweep's later jobs say there that they load their programs."""
        ready = sorted(self.programs)
        loaded = [name for name in self.from_cache() if name in ready]
        compiled = [name for name in ready if name not in loaded]

        def listed(names: list[str]) -> str:
            return f"{', '.join(names)} ({len(names)})" if names else "none"

        return (
            f"rlq: programs loaded from the compile cache: {listed(loaded)}; compiled: {listed(compiled)}; "
            f"{seconds:.1f} s"
        )

    def evaluate(self, state: Any, keys: jax.Array) -> Any:
        """The evaluation program's output, waiting for its compile on the first call."""
        return self.evaluate_soon.result()[0](state, keys)

    def store(self) -> str | None:
        """Keep the programs in the program cache; returns why they could not be kept, or None
        (kept, loaded from it, or no cache). Serialising a program holds the GIL and waits for the
        device: call it after training, not between chunks."""
        ready = self.to_keep.result()
        if ready is None or self.cache is None:
            return None
        cache = self.cache
        return cache.store(
            {name: cache.pack(program) if pack is None else pack for name, (program, pack) in ready.items()},
            {name: program for name, (program, _) in ready.items()},
        )


Lowering = Callable[[], jax.stages.Lowered]


def _lowerings(
    programs: Programs,
    keys: jax.Array | jax.ShapeDtypeStruct,
    eval_key: jax.Array | jax.ShapeDtypeStruct,
    with_init: bool,
    defer: bool,
) -> tuple[Any, dict[str, Lowering], dict[str, Lowering]]:
    """The state's shape (``init`` traced here), the programs to lower and compile at once, in their order, and
    those a CPU (``defer``) compiles after them: the evaluation and a chunk's last, shorter block. ``with_init``:
    init is compiled too (a fresh run calls it; a program cache keeps it)."""
    traced_init = programs.init.trace(keys, programs.hyper_shape)
    state_shape = traced_init.out_info
    lowers: dict[str, Lowering] = {
        "init": traced_init.lower,
        "chunk": lambda: programs.chunk.lower(state_shape, programs.hyper_shape),
    }
    # on a CPU init first (a core compiles it while the chunk is traced); elsewhere the slowest compile first
    order = ("init", "chunk") if defer else ("chunk", "init")
    lowerings = {name: lowers[name] for name in order if name != "init" or with_init}
    later: dict[str, Lowering] = {
        "evaluate": lambda: programs.evaluate.lower(state_shape, eval_key),
    }
    if programs.rest is not None:  # a chunk's last, shorter block (rlq.run.stops.slices.block_plan)
        rest = programs.rest
        later["rest"] = lambda: rest.lower(state_shape, programs.hyper_shape)
    if not defer:  # last: init compiles while the evaluation is traced (an MJX trace takes seconds)
        lowerings.update(later)
    return state_shape, lowerings, later


def _from_cache(
    programs: Programs,
    loaded: Mapping[str, Future[jax.stages.Compiled]],
    eval_key: jax.Array | jax.ShapeDtypeStruct,
    options: Mapping[str, Option] | None,
) -> CompiledPrograms:
    """The programs ``ProgramCache.load_first`` is loading: ``init`` and ``chunk`` loaded, the evaluation and a
    chunk's last block maybe still loading (a first evaluation comes after at least one chunk). One of those
    that cannot be loaded is compiled instead (its file is gone by then)."""
    first = {name: loaded[name].result() for name in FIRST}
    state_shape = first["init"].out_info
    platform = programs.placement.platform
    names = sorted(loaded)  # ``CompiledPrograms.loaded``: less those compiled instead

    def loaded_or_compiled(name: str, lower: Lowering) -> tuple[jax.stages.Compiled, Any]:
        try:
            return loaded[name].result(), None
        except Exception:  # deserialising failed (XLA raises its runtime error type)
            names.remove(name)
            with jax.default_device(programs.placement.local_device):
                lowered = lower()
            return compile_with(lowered, program_options(name, options, platform)), None

    pool = ThreadPoolExecutor(max_workers=2)
    evaluate_soon = pool.submit(loaded_or_compiled, "evaluate", lambda: programs.evaluate.lower(state_shape, eval_key))
    rest_soon = None
    if "rest" in loaded and programs.rest is not None:
        rest = programs.rest
        rest_soon = pool.submit(loaded_or_compiled, "rest", lambda: rest.lower(state_shape, programs.hyper_shape))
    pool.shutdown(wait=False)
    return CompiledPrograms(first, evaluate_soon, state_shape, names, rest_soon=rest_soon)


def compile_programs(
    programs: Programs,
    keys: jax.Array | jax.ShapeDtypeStruct,
    eval_key: jax.Array | jax.ShapeDtypeStruct,
    options: Mapping[str, Option] | None,
    cache: ProgramCache | None,
    loaded: Mapping[str, Future[jax.stages.Compiled]] | None,
    need_init: bool,
) -> CompiledPrograms:
    """The run's ``init``, ``chunk`` and ``evaluate`` programs: ``loaded`` (from ``cache``, nothing
    traced: ``ProgramCache.load_first``'s) when given, else traced, lowered and compiled, for
    ``CompiledPrograms.store`` to keep in ``cache`` (nothing when JAX's cache supplied them). ``need_init``: a
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
    dependency while they are traced (the humanoid) hold a lock while they do. ``rest``, the program
    of a chunk's last, shorter block (only where blocks do not divide a chunk: rlq.run.stops.slices),
    compiles as ``evaluate`` does; the loop waits for it at the first chunk's last block."""
    if loaded is not None:
        return _from_cache(programs, loaded, eval_key, options)
    platform = programs.placement.platform
    defer = platform == "cpu"
    state_shape, lowerings, later = _lowerings(programs, keys, eval_key, need_init or cache is not None, defer)

    def packed(program: jax.stages.Compiled) -> tuple[jax.stages.Compiled, Any]:
        return program, cache.pack(program) if cache is not None and platform == "cpu" else None

    watching = contextlib.ExitStack()
    hits = watching.enter_context(watch_cache_hits())
    pool = ThreadPoolExecutor(max_workers=len(lowerings) + len(later) + 1)
    try:
        futures = submit_pipelined(pool, lowerings, options, then=packed, platform=platform)
    except BaseException:
        watching.close()
        raise

    def deferred(name: str) -> tuple[jax.stages.Compiled, Any]:
        if not defer:
            return futures[name].result()
        # JAX's default device is per thread: the worker traces for the run's device, as the caller does
        with jax.default_device(programs.placement.local_device):
            lowered = later[name]()
        for first_name in ("init", "chunk"):  # compiled once those are
            if first_name in futures:
                futures[first_name].result()
        with compiling(name):
            program = compile_with(lowered, program_options(name, options, platform))
        return packed(program)

    soon = {name: pool.submit(deferred, name) for name in later}

    def all_compiled() -> dict[str, tuple[jax.stages.Compiled, Any]] | None:
        with watching:
            ready = {name: future.result() for name, future in futures.items() if name not in later}
            ready.update({name: future.result() for name, future in soon.items()})
        return ready if cache is not None and not hits else None

    to_keep = pool.submit(all_compiled)
    pool.shutdown(wait=False)
    first = {name: futures[name].result()[0] for name in lowerings if name not in later}
    rest_soon = soon.get("rest")
    return CompiledPrograms(first, soon["evaluate"], state_shape, [], to_keep, cache, rest_soon, hits)
