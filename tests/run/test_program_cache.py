"""Whole compiled programs in the compile cache: keyed by what shapes them, loaded without tracing,
the same training as a fresh compile, and compiled again when a file is unreadable."""

from __future__ import annotations

import json
import pickle
import shutil
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import rlq
from rlq.run.programs import members, program_cache
from rlq.run.programs.compiling import CompiledPrograms
from rlq.run.programs.devices import placement
from rlq.run.programs.program_cache import ProgramCache, finished, program_key
from rlq.store import checkpoint
from tests.helpers import compose_config, run_cli_in_process, run_dirs, train_run

# XLA's CPU runtime reloads these CartPole programs (not every program: see program_cache.CPU_RELOADS)
TINY = (
    "program_cache=always",
    "budget.env_steps=2048",
    "log_every_steps=1024",
    "eval.every_steps=0",
    "eval.episodes=2",
    "video.at_end=false",
)


def run(where, *overrides: str):
    where.mkdir(parents=True)
    return train_run(where, *TINY, *overrides)


def key_of(*overrides: str) -> str:
    return program_key(compose_config(*TINY, *overrides), jax.devices()[:1])


def test_the_key_ignores_host_only_keys_and_follows_everything_else(monkeypatch):
    base = key_of()
    assert key_of("seed=7", "logger=quiet", "checkpoint.every_steps=1024", "stop.when='eval/return>=10'") == base
    assert key_of("algo.num_envs=8") != base
    assert key_of("num_seeds=2") != base
    assert key_of("eval.episodes=3") != base
    monkeypatch.setattr(program_cache, "source_digest", lambda: "other source")
    assert key_of() != base
    monkeypatch.undo()
    monkeypatch.setattr(program_cache, "package_versions", lambda: {"jax": "0.0"})
    assert key_of() != base


def test_the_source_in_the_key_is_the_whole_package():
    """Every module of rlq is in the digest, not only the runner's: an edited algorithm or env must not load the
    programs the old code compiled (the digest once covered rlq/run alone)."""
    root = Path(rlq.__file__).resolve().parent
    assert program_cache.PACKAGE_ROOT == root
    digested = {path.relative_to(root).as_posix() for path in program_cache.source_files()}
    for module in ("algos/ars.py", "lib/rollout.py", "envs/lunar/env.py", "run/programs/program_cache.py"):
        assert module in digested, module


def test_off_without_a_cache_dir_or_when_asked_and_on_the_cpu_only_for_the_envs_xla_reloads():
    for overrides in (("compile_cache=null",), ("program_cache=never",), ("program_cache=auto", "env=humanoid")):
        cfg = compose_config(*TINY, *overrides)
        assert ProgramCache.for_run(cfg, placement(cfg)) is None, overrides
    for overrides in ((), ("program_cache=auto",), ("program_cache=auto", "env=lunar", "algo=dqn")):
        cfg = compose_config(*TINY, *overrides)
        assert ProgramCache.for_run(cfg, placement(cfg)) is not None, overrides


@pytest.mark.slow
def test_a_second_run_loads_its_programs_and_another_seed_trains_as_a_fresh_compile(tmp_path):
    cache = f"compile_cache={tmp_path / 'cache'}"
    first = run(tmp_path / "a", cache)
    assert first.cached_programs == ()
    again = run(tmp_path / "b", cache)
    assert again.cached_programs == ("chunk", "evaluate", "init")
    np.testing.assert_array_equal(again.eval_return, first.eval_return)

    seeded = run(tmp_path / "c", cache, "seed=3")
    assert seeded.cached_programs == ("chunk", "evaluate", "init")
    fresh = run(tmp_path / "d", "compile_cache=null", "seed=3")
    assert fresh.cached_programs == ()
    for got, want in zip(jax.tree.leaves(seeded.state), jax.tree.leaves(fresh.state), strict=True):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
    assert not np.array_equal(np.asarray(jax.tree.leaves(seeded.state)[0]), np.asarray(jax.tree.leaves(first.state)[0]))


@pytest.mark.parametrize("algo", ["ppo", "dqn"])
def test_the_key_leaves_out_the_hyperparameters_the_chunk_takes_as_an_argument(algo):
    """A sweep over a learning rate (or any ``AlgorithmSpec.sweepable`` key) shares its first job's programs;
    a key that shapes them (the envs per seed, the network) does not."""
    base = key_of(f"algo={algo}")
    assert key_of(f"algo={algo}", "algo.lr=3e-3", "algo.gamma=0.9") == base
    assert key_of(f"algo={algo}", "algo.hidden=[32]") != base
    assert key_of(f"algo={algo}", "algo.num_envs=2") != base


@pytest.mark.parametrize(
    "algo, values",
    [
        ("algo=es", ("algo.sigma=0.3", "algo.lr=0.05")),
        ("algo=map_elites", ("algo.sigma=0.2", "algo.iso_sigma=0.01", "algo.es_sigma=0.3", "algo.es_lr=0.1")),
        ("algo=random_search", ("algo.sigma=0.3", "algo.ars.step_size=0.05", "algo.ars.noise=0.1")),
    ],
)
def test_the_black_boxes_keys_leave_out_their_widths_and_step_sizes(algo, values):
    assert key_of(algo, *values) == key_of(algo)
    assert key_of(algo, "algo.episodes=2") != key_of(algo)


def sweep_key(*overrides: str) -> str:
    """The key of an in-program sweep's programs, as its run asks for them (``members.program_config``'s spec)."""
    return program_key(members.program_config(compose_config(*TINY, *overrides)), jax.devices()[:1])


def test_the_key_keeps_an_in_program_sweep_s_names_and_counts_not_its_values():
    """The swept values are the programs' argument: a sweep over other values of the same keys loads the first
    sweep's programs; other keys or another number of values do not."""
    swept = sweep_key("+sweep.algo.lr=[1e-3,3e-3]", "+sweep.algo.gamma=[0.9]")
    assert sweep_key("+sweep.algo.lr=[3e-4,1e-2]", "+sweep.algo.gamma=[0.95]") == swept
    assert sweep_key("+sweep.algo.lr=[1e-3,3e-3,1e-2]", "+sweep.algo.gamma=[0.9]") != swept
    assert sweep_key("+sweep.algo.lr=[1e-3,3e-3]", "+sweep.algo.ent_coef=[0.0]") != swept
    assert sweep_key("+sweep.algo.lr=[1e-3,3e-3]") != swept


@pytest.mark.slow
def test_a_sweep_over_other_values_loads_the_first_sweep_s_programs_and_trains_as_a_fresh_compile(tmp_path):
    cache = f"compile_cache={tmp_path / 'cache'}"
    first = sweep_run(tmp_path / "a", cache, "sweep.algo.lr=[1e-3,3e-3]")
    other = sweep_run(tmp_path / "b", cache, "sweep.algo.lr=[3e-4,1e-2]")
    assert json.loads((other / "summary.json").read_text())["cached_programs"] == ["chunk", "evaluate", "init"]
    fresh = sweep_run(tmp_path / "c", "compile_cache=null", "sweep.algo.lr=[3e-4,1e-2]")
    final = [checkpoint.leaves(run_dir / "checkpoints" / "final.msgpack") for run_dir in (first, other, fresh)]
    for got, want in zip(final[1], final[2], strict=True):
        np.testing.assert_array_equal(got, want)
    assert not all(np.array_equal(a, b) for a, b in zip(final[0], final[1], strict=True))


def sweep_run(workdir, *overrides: str):
    """The run directory of `rlq train` of a two-seed in-program sweep in ``workdir``."""
    workdir.mkdir(parents=True)
    proc = run_cli_in_process("train", *TINY, "num_seeds=2", *overrides, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    return run_dir


@pytest.mark.slow
def test_a_run_at_another_learning_rate_loads_the_programs_and_trains_as_a_fresh_compile(tmp_path):
    cache = f"compile_cache={tmp_path / 'cache'}"
    first = run(tmp_path / "a", cache)
    assert first.cached_programs == ()
    swept = run(tmp_path / "b", cache, "algo.lr=1e-3", "algo.ent_coef=0.02")
    assert swept.cached_programs == ("chunk", "evaluate", "init")
    assert (
        "rlq: programs loaded from the compile cache: chunk, init (2); compiled: none"
        in (tmp_path / "b" / "rlq.log").read_text()
    )
    fresh = run(tmp_path / "c", "compile_cache=null", "algo.lr=1e-3", "algo.ent_coef=0.02")
    for got, want in zip(jax.tree.leaves(swept.state), jax.tree.leaves(fresh.state), strict=True):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
    params = [np.asarray(leaf) for leaf in jax.tree.leaves(swept.state.params)]
    assert not all(
        np.array_equal(a, np.asarray(b)) for a, b in zip(params, jax.tree.leaves(first.state.params), strict=True)
    )


@pytest.mark.slow
def test_without_the_program_cache_jax_s_cache_supplies_the_programs_of_another_learning_rate(tmp_path):
    """A CPU run's default (``program_cache=auto``): the chunk is traced again but not compiled."""
    cache = f"compile_cache={tmp_path / 'cache'}"
    before = jax.config.values["jax_persistent_cache_min_compile_time_secs"]
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)
    try:
        first = run(tmp_path / "a", cache, "program_cache=never", "algo=dqn", "algo.learning_starts=512")
        other = run(
            tmp_path / "b", cache, "program_cache=never", "algo=dqn", "algo.learning_starts=512", "algo.lr=3e-3"
        )
    finally:
        jax.config.update("jax_persistent_cache_min_compile_time_secs", before)
    assert "chunk" not in first.compile_cache_hits
    assert other.cached_programs == () and {"chunk", "init"} <= set(other.compile_cache_hits)
    assert "programs loaded from the compile cache: chunk" in (tmp_path / "b" / "rlq.log").read_text()


@pytest.mark.slow
def test_unreadable_programs_are_compiled_again_and_only_fresh_compiles_are_stored(tmp_path):
    cache = f"compile_cache={tmp_path / 'cache'}"
    run(tmp_path / "a", cache)
    [stored] = (tmp_path / "cache" / "programs").glob("*.bin")
    stored.write_bytes(stored.read_bytes()[:1000])
    assert run(tmp_path / "b", cache).cached_programs == ()
    assert not stored.exists()  # JAX's own cache supplied run b's executables: not stored (see ProgramCache)
    for entry in (tmp_path / "cache").iterdir():
        if entry.name != "programs":
            shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
    assert run(tmp_path / "c", cache).cached_programs == ()
    assert stored.exists()
    assert run(tmp_path / "d", cache).cached_programs == ("chunk", "evaluate", "init")


@pytest.mark.slow
def test_an_evaluation_that_cannot_be_loaded_is_compiled_while_the_run_trains(tmp_path):
    """init and the chunk load before the first chunk, the evaluation after them: one that cannot be read is
    compiled instead, with the same result, and the file goes."""
    cache = f"compile_cache={tmp_path / 'cache'}"
    first = run(tmp_path / "a", cache)
    [stored] = (tmp_path / "cache" / "programs").glob("*.bin")
    programs = pickle.loads(stored.read_bytes())
    serialized, in_tree, out_tree = programs["evaluate"]
    programs["evaluate"] = (serialized[:100], in_tree, out_tree)
    stored.write_bytes(pickle.dumps(programs))
    again = run(tmp_path / "b", cache)
    assert again.cached_programs == ("chunk", "init")
    np.testing.assert_array_equal(again.eval_return, first.eval_return)
    assert not stored.exists()


@pytest.mark.slow
def test_a_resumed_run_loads_the_programs_too(tmp_path):
    cache = f"compile_cache={tmp_path / 'cache'}"
    straight = run(tmp_path / "a", cache, "checkpoint.every_steps=1024")
    from rlq.run.train import train

    cfg = compose_config("logger=quiet", *TINY, cache, "checkpoint.every_steps=1024")
    (tmp_path / "b").mkdir()
    resumed = train(cfg, tmp_path / "b", resume=tmp_path / "a" / "checkpoints" / "step_1024.msgpack")
    assert resumed.cached_programs == ("chunk", "evaluate", "init")
    assert resumed.start_steps == 1024
    np.testing.assert_array_equal(resumed.eval_return, straight.eval_return)


def test_a_program_that_cannot_be_serialised_is_reported_and_nothing_is_written(tmp_path):
    cache = ProgramCache(tmp_path, "key", jax.devices()[:1])
    assert cache.store({"chunk": (b"", None, None), "evaluate": "UNIMPLEMENTED: not serializable"}) == (
        "UNIMPLEMENTED: not serializable"
    )
    assert not cache.path.exists()


def test_programs_left_unserialised_are_serialised_when_stored(tmp_path):
    """Off a CPU, compile_programs leaves the serialising to CompiledPrograms.store (it holds the
    GIL for about a second): store packs what is not packed yet, and the file loads back."""
    double = jax.jit(lambda x: 2 * x).lower(jnp.arange(3.0)).compile()
    square = jax.jit(jnp.square).lower(jnp.arange(3.0)).compile()
    cache = ProgramCache(tmp_path, "key", jax.devices()[:1])
    ready = {"init": (double, None), "chunk": (square, cache.pack(square)), "evaluate": (double, None)}
    compiled = CompiledPrograms({}, finished((double, None)), None, [], finished(ready), cache)
    assert compiled.store() is None
    loaded = cache.load()
    assert loaded is not None and sorted(loaded) == ["chunk", "evaluate", "init"]
    np.testing.assert_allclose(loaded["init"](jnp.arange(3.0)), [0.0, 2.0, 4.0])
    np.testing.assert_allclose(loaded["chunk"](jnp.arange(3.0)), [0.0, 1.0, 4.0])


def test_the_process_keeps_the_programs_it_stored_while_their_file_stands(tmp_path, monkeypatch):
    """A sweep's later jobs in one process take the programs from memory, without deserialising them; a file
    written anew (another process's programs) is read again."""
    double = jax.jit(lambda x: 2 * x).lower(jnp.arange(3.0)).compile()
    cache = ProgramCache(tmp_path, "kept", jax.devices()[:1])
    assert cache.store({"chunk": cache.pack(double)}, {"chunk": double}) is None
    deserialised = []
    monkeypatch.setattr(ProgramCache, "_deserialize", lambda self, parts: deserialised.append(parts) or double)
    loaded = ProgramCache(tmp_path, "kept", jax.devices()[:1]).load()
    assert loaded is not None and loaded["chunk"] is double and deserialised == []
    assert cache.store({"chunk": cache.pack(double)}) is None  # rewritten without the programs: not kept
    assert cache.load() is not None and len(deserialised) == 1
    assert cache.load() is not None and len(deserialised) == 1  # the loaded set is kept in turn
    cache.path.unlink()
    assert cache.load() is None


@pytest.mark.slow  # a whole run (9 s)
def test_the_final_checkpoint_and_the_programs_are_kept_before_the_final_evaluation_is_read(tmp_path, monkeypatch):
    """The main thread writes them while a worker runs the final evaluation: a run whose final
    evaluation fails keeps both."""
    from rlq.run import finish as finish_module

    calls = []

    def failing_summary(record):
        calls.append(record)
        raise RuntimeError("final evaluation failed")

    monkeypatch.setattr(finish_module, "eval_summary", failing_summary)
    cache = tmp_path / "cache"
    with pytest.raises(RuntimeError, match="final evaluation failed"):
        run(tmp_path / "a", f"compile_cache={cache}")
    assert len(calls) == 1
    assert (tmp_path / "a" / "checkpoints" / "final.msgpack").is_file()
    assert len(list((cache / "programs").glob("*.bin"))) == 1


def test_the_console_line_says_which_programs_were_loaded_and_which_compiled():
    first = CompiledPrograms({"chunk": None, "init": None}, finished(None), None, [])
    assert first.line(5.93) == "rlq: programs loaded from the compile cache: none; compiled: chunk, init (2); 5.9 s"
    later = CompiledPrograms({"chunk": None, "init": None}, finished(None), None, [], cache_hits=["chunk", ""])
    assert later.line(1.3) == "rlq: programs loaded from the compile cache: chunk (1); compiled: init (1); 1.3 s"


def test_on_a_cpu_auto_declines_a_program_with_a_custom_call_and_writes_nothing(tmp_path):
    """XLA's CPU runtime crashes running such a program reloaded (CMA-ES's eigendecomposition, LAPACK's)."""
    eigh = jax.jit(jnp.linalg.eigh).lower(jnp.eye(3)).compile()
    square = jax.jit(jnp.square).lower(jnp.arange(3.0)).compile()
    cache = ProgramCache(tmp_path, "key", jax.devices()[:1], custom_calls=False)
    declined = cache.pack(eigh)
    assert isinstance(declined, program_cache.Declined)
    assert cache.store({"chunk": declined, "init": cache.pack(square)}) is None
    assert not cache.path.exists()
    assert not isinstance(cache.pack(square), str)
    cfg = compose_config(*TINY[1:], "program_cache=auto")
    auto = ProgramCache.for_run(cfg, placement(cfg))
    assert auto is not None and not auto.custom_calls


@pytest.mark.slow
@pytest.mark.parametrize(("strategy", "loaded"), [("open_es", ("chunk", "evaluate", "init")), ("cma_es", ())])
def test_by_default_a_cpu_run_of_cartpole_loads_its_programs_unless_they_call_a_custom_call(tmp_path, strategy, loaded):
    """``program_cache=auto``: a CMA-ES program (LAPACK's eigendecomposition) is compiled again, not reloaded."""
    tiny = ("log_every_steps=2000", "eval.every_steps=0", "eval.episodes=2", "video.at_end=false", "algo=es")
    tiny = (*tiny, f"algo.strategy={strategy}", "algo.population=4", "algo.episodes=1", "budget.env_steps=4000")
    cache = f"compile_cache={tmp_path / 'cache'}"
    for name in "abc":
        (tmp_path / name).mkdir()
    assert train_run(tmp_path / "a", *tiny, cache).cached_programs == ()
    again = train_run(tmp_path / "b", *tiny, cache, "algo.sigma=0.3")
    assert again.cached_programs == loaded
    fresh = train_run(tmp_path / "c", *tiny, "compile_cache=null", "algo.sigma=0.3")
    for got, want in zip(jax.tree.leaves(again.state), jax.tree.leaves(fresh.state), strict=True):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
