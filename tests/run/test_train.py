"""The training loop: seeds in one program, chunking, checkpoints."""

import dataclasses
import json
import threading
import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.run.programs.build import build
from rlq.run.programs.cadences import Cadences, chunk_plan
from rlq.run.programs.compiling import compile_pipelined, compile_programs
from rlq.run.programs.keys import eval_keys, seed_keys
from rlq.store import checkpoint
from tests.helpers import compose_config, train_run


def test_chunk_plan_never_exceeds_the_budget():
    for updates, spu, every in [(976, 512, 25_000), (7, 100, 10_000), (1, 512, 100), (1000, 1, 1), (997, 10, 100)]:
        per_chunk, chunks = chunk_plan(updates, spu, Cadences(log=every))
        assert per_chunk * chunks <= updates
        assert updates - per_chunk * chunks < chunks
        assert per_chunk >= 1


def test_chunk_plan_spends_divisible_budgets_exactly():
    assert chunk_plan(250, 4000, Cadences(log=25_000)) == (5, 50)  # REINFORCE with 8 x 500-step rollouts
    per_chunk, chunks = chunk_plan(976, 512, Cadences(log=25_000))
    assert per_chunk * chunks == 976


def test_chunk_plan_lands_on_the_eval_cadence_when_it_can():
    per_chunk, _ = chunk_plan(24, 512, Cadences(log=2000, eval=4096))
    assert 4096 % (per_chunk * 512) == 0


def test_cadences_say_what_they_snap_to():
    notes = Cadences(log=2000, eval=3072, checkpoint=4096).snap_notes(chunk_steps=2048)
    assert notes == [
        "log_every_steps=2000 snaps to 2,048 (one chunk: metrics leave the device once per chunk)",
        "eval.every_steps=3072 snaps to 4,096 (every 2 chunks of 2,048 env steps)",
    ]
    assert Cadences(log=2048, eval=4096).snap_notes(chunk_steps=2048) == []
    assert Cadences(log=1).snap_notes(chunk_steps=2048, single_update=True) == []  # a row per update
    one_chunk = Cadences(log=1000, eval=100_000).snap_notes(chunk_steps=500_000, total_steps=500_000)
    assert one_chunk == []  # a run of one chunk logs and evaluates at its end whatever the cadence
    saved = Cadences(log=40_000, checkpoint=10_000).snap_notes(chunk_steps=40_000, total_steps=40_000)
    assert saved == [  # but a checkpoint cadence asked for is not dropped without a word
        "checkpoint.every_steps=10000: the budget (40,000 env steps) is one chunk, so the only checkpoint is the "
        "final one; a smaller log_every_steps makes more chunks"
    ]
    assert Cadences(log=2048, eval=3000).snap_notes(chunk_steps=2048) == [
        "eval.every_steps=3000 snaps to 2,048 (every 1 chunk of 2,048 env steps)"
    ]


def test_an_eval_stop_rule_without_an_evaluation_before_the_end_is_noted():
    """The final evaluation does not apply stop.when: an eval/ rule needs a periodic evaluation."""
    assert Cadences(log=2048, eval=2048).stop_note("eval/return>=1", 2048, 8192) is None
    assert Cadences(log=2048).stop_note("train/loss<1", 2048, 8192) is None
    assert Cadences(log=2048).stop_note(None, 2048, 8192) is None
    never = Cadences(log=25000).stop_note("eval/return>=1", 4608, 4608)
    assert never is not None and never.startswith(
        "stop.when='eval/return>=1' is never checked: eval.every_steps=0 evaluates only at the end of the run's "
        "4,608 env steps"
    )
    snapped = Cadences(log=25000, eval=1024).stop_note("eval/return>=1", 8192, 8192)
    assert snapped is not None and "eval.every_steps=1024, in whole chunks of 8,192 env steps, evaluates" in snapped


@pytest.mark.slow  # a whole CartPole run with evaluations (~9 s): the quick tier's whole run is the pinned PPO
def test_eval_rows_fall_on_the_configured_steps(tmp_path):
    train_run(
        tmp_path,
        "budget.env_steps=12288",
        "log_every_steps=2000",
        "eval.every_steps=4096",
        "eval.episodes=2",
        "video.at_end=false",
    )
    rows = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    assert sorted({r["env_steps"] for r in rows if r["kind"] == "eval"}) == [4096, 8192, 12288]
    assert "log_every_steps=2000 snaps to" in (tmp_path / "rlq.log").read_text()


def test_compile_pipelined_traces_on_the_caller_thread_in_order():
    traced_on, order = [], []

    def program(name, fn):
        def lower():
            def traced(x):
                traced_on.append(threading.current_thread())
                return fn(x)

            order.append(name)
            return jax.jit(traced).lower(jnp.arange(3.0))

        return lower

    compiled = compile_pipelined(
        {"double": program("double", lambda x: 2 * x), "square": program("square", jnp.square)}
    )
    assert order == ["double", "square"]
    assert traced_on == [threading.current_thread()] * 2
    np.testing.assert_allclose(compiled["double"](jnp.arange(3.0)), [0.0, 2.0, 4.0])
    np.testing.assert_allclose(compiled["square"](jnp.arange(3.0)), [0.0, 1.0, 4.0])


@pytest.mark.slow  # builds and compiles a run's programs (~7 s); the pipelining itself: the test above
def test_training_starts_while_the_evaluation_program_is_still_being_traced_in_a_worker():
    programs = build(compose_config("budget.env_steps=2048", "log_every_steps=1024", "eval.episodes=2"))
    traced_on, release = [], threading.Event()
    original = programs.evaluate

    def held_evaluate(state, keys):
        traced_on.append(threading.current_thread())
        release.wait(timeout=30)  # the evaluation's trace waits until the first chunk has run
        return original(state, keys)

    programs = dataclasses.replace(programs, evaluate=jax.jit(held_evaluate))
    keys = seed_keys(0, 1)
    eval_keys = jax.random.split(jax.random.PRNGKey(5), 1)
    compiled = compile_programs(programs, keys, eval_keys, None, None, None, need_init=True)
    state, _ = compiled.programs["chunk"](compiled.programs["init"](keys, programs.hyper), programs.hyper)
    jax.block_until_ready(state)
    assert not compiled.evaluate_soon.done()
    release.set()
    record = compiled.evaluate(state, eval_keys)
    assert traced_on and all(thread is not threading.current_thread() for thread in traced_on)
    assert compiled.store() is None  # no program cache
    np.testing.assert_array_equal(record["episode_return"], original(state, eval_keys)["episode_return"])


def test_the_evaluation_is_traced_in_its_worker_under_the_runs_device():
    """JAX's config contexts are per thread: the worker that traces the evaluation on a CPU enters
    the run's device with ``jax.default_device``, as the caller does (LunarLander's
    ``sweep_layout=auto`` reads it)."""
    programs = build(compose_config("budget.env_steps=2048", "log_every_steps=1024", "eval.episodes=2"))
    seen = []
    original = programs.evaluate

    def recording_evaluate(state, keys):
        seen.append((threading.current_thread(), jax.config.values["jax_default_device"]))
        return original(state, keys)

    programs = dataclasses.replace(programs, evaluate=jax.jit(recording_evaluate))
    keys, eval_keys = seed_keys(0, 1), jax.random.split(jax.random.PRNGKey(5), 1)
    cpu = jax.devices("cpu")[0]
    with jax.default_device(cpu):
        compiled = compile_programs(programs, keys, eval_keys, None, None, None, need_init=True)
        compiled.evaluate_soon.result()
    assert seen and all(thread is not threading.current_thread() and device == cpu for thread, device in seen)


def test_seed_keys_do_not_depend_on_num_seeds():
    np.testing.assert_array_equal(seed_keys(3, 2), seed_keys(3, 8)[:2])


def test_a_sweep_over_seeds_compiles_the_keys_once():
    """The seed's key is the keys' programs' argument, not a constant baked into them."""
    from rlq.run.programs import keys

    seed_keys(11, 2), eval_keys(11, np.int32(0), 2)
    sizes = keys._seed_keys._cache_size(), keys._eval_keys._cache_size()
    seed_keys(12, 2), eval_keys(12, np.int32(0), 2)
    assert (keys._seed_keys._cache_size(), keys._eval_keys._cache_size()) == sizes


@pytest.mark.parametrize("seed", [0, 7, -1, 2**31 - 1])
def test_the_jitted_keys_are_those_of_the_eager_derivation(seed):
    base = jax.random.PRNGKey(seed)
    eager = jax.vmap(lambda i: jax.random.fold_in(base, i))(jnp.arange(3))
    np.testing.assert_array_equal(seed_keys(seed, 3), eager)
    for tag in (0, 999_983):
        expected = jax.random.split(jax.random.fold_in(jax.random.fold_in(base, 10_007), tag), 3)
        np.testing.assert_array_equal(eval_keys(seed, np.int32(tag), 3), expected)


@pytest.mark.slow
def test_a_one_seed_run_matches_its_seed_in_a_batch():
    """A one-seed run's programs skip the seed vmap (rlq.run.programs.build.on_mesh); their numbers are
    seed 0's of a two-seed run."""
    overrides = ("algo.num_envs=4", "algo.num_steps=16", "budget.env_steps=256", "log_every_steps=128")
    one, two = build(compose_config(*overrides, "num_seeds=1")), build(compose_config(*overrides, "num_seeds=2"))
    key_one, key_two = seed_keys(0, 1), seed_keys(0, 2)
    state_one, metrics_one = one.chunk(one.init(key_one, one.hyper), one.hyper)
    state_two, metrics_two = two.chunk(two.init(key_two, two.hyper), two.hyper)
    for a, b in zip(jax.tree.leaves(state_one), jax.tree.leaves(state_two), strict=True):
        assert a.shape == (1, *b.shape[1:])
        np.testing.assert_allclose(np.asarray(a[0], np.float64), np.asarray(b[0], np.float64), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(metrics_one["value_loss"][0], metrics_two["value_loss"][0], rtol=1e-5)


@pytest.fixture(scope="module")
def eight_seeds(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("eight")
    return train_run(
        run_dir, "num_seeds=8", "budget.env_steps=8192", "log_every_steps=4096", "eval.episodes=4"
    ), run_dir


@pytest.mark.slow
def test_eight_seeds_train_in_one_program_and_differ(eight_seeds):
    result, run_dir = eight_seeds
    rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    train_rows = [r for r in rows if r["kind"] == "train" and r["seed"] != "mean"]
    assert {r["seed"] for r in train_rows} == set(range(8))
    last_step = max(r["env_steps"] for r in train_rows)
    losses = [r["value_loss"] for r in train_rows if r["env_steps"] == last_step]
    assert len(set(losses)) == 8, "seeds produced identical metrics"
    params = jax.tree.leaves(result.state.params)[0]
    assert params.shape[0] == 8
    assert not np.allclose(params[0], params[1])


@pytest.mark.slow  # its eight-seed run compiles for 15-20 s: the full suite runs it (with the test beside it)
def test_checkpoint_round_trip(eight_seeds):
    result, run_dir = eight_seeds
    cfg = compose_config("num_seeds=8", "budget.env_steps=8192")
    programs = build(cfg)
    template = jax.eval_shape(programs.init, seed_keys(cfg.seed, 8), programs.hyper)  # as `rlq resume`, `rlq eval` load
    restored = checkpoint.load(checkpoint.latest(run_dir), template)
    for a, b in zip(jax.tree.leaves(restored), jax.tree.leaves(result.state), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.slow
def test_chunk_loop_calls_matches_scan(tmp_path):
    """``chunk_loop=calls`` queues one-update programs instead of looping inside one program (with
    ``scan``, over a block of a chunk's updates: rlq.run.stops.slices): the same updates, metrics and final
    parameters (to float rounding: two different programs)."""
    overrides = (
        "num_seeds=2",
        "budget.env_steps=65536",
        "log_every_steps=32768",
        "eval.episodes=2",
        "video.at_end=false",
    )
    results, rows = {}, {}
    for loop in ("scan", "calls"):
        run_dir = tmp_path / loop
        run_dir.mkdir()
        results[loop] = train_run(run_dir, *overrides, f"chunk_loop={loop}")
        lines = (run_dir / "metrics.jsonl").read_text().splitlines()
        rows[loop] = [r for r in map(json.loads, lines) if r["kind"] == "train"]
    assert build(compose_config(*overrides, "chunk_loop=calls")).calls_per_chunk == 64  # 512 env steps per update
    assert build(compose_config(*overrides)).calls_per_chunk == 32  # blocks of 2 updates
    assert len(rows["calls"]) == len(rows["scan"]) == 2 * 3  # 2 chunks x (2 seeds + mean)
    for calls_row, scan_row in zip(rows["calls"], rows["scan"], strict=True):
        assert calls_row.keys() == scan_row.keys()
        for key, value in scan_row.items():
            if key == "wall_s":
                continue
            assert calls_row[key] == (value if isinstance(value, str) else pytest.approx(value, rel=1e-4, abs=1e-6)), (
                key
            )
    for a, b in zip(jax.tree.leaves(results["calls"].state), jax.tree.leaves(results["scan"].state), strict=True):
        np.testing.assert_allclose(np.asarray(a, np.float64), np.asarray(b, np.float64), rtol=1e-4, atol=1e-6)


@pytest.mark.slow
def test_a_prime_chunk_runs_as_bounded_blocks_and_a_remainder_with_the_numbers_of_one_call(tmp_path, monkeypatch):
    """A chunk of 37 updates (a prime) is 18 calls of 2 updates and one of 1 (a second program),
    never one call of 37: the same parameters and rows, to the bit, as the chunk in one call."""
    from rlq.run import loop as loop_module
    from rlq.run.stops import slices

    # the patched plan below gives the config other programs: none of the first run's from the program cache
    overrides = ("budget.env_steps=37888", "log_every_steps=18944", "eval.episodes=2", "video.at_end=false")
    overrides = (*overrides, "program_cache=never")
    assert build(compose_config(*overrides)).updates_per_chunk == 37  # 512 env steps per update
    real_call, programs_called = loop_module.call_chunk, []

    def counting(chunk, state, count):
        programs_called.extend([chunk] * count)
        return real_call(chunk, state, count)

    monkeypatch.setattr(loop_module, "call_chunk", counting)
    results, rows = {}, {}
    for split in ("blocks", "one call"):
        if split == "one call":
            monkeypatch.setattr(slices, "block_plan", lambda updates: slices.BlockPlan(updates, 1))
        programs_called.clear()
        run_dir = tmp_path / split.replace(" ", "_")
        run_dir.mkdir()
        results[split] = train_run(run_dir, *overrides)
        lines = (run_dir / "metrics.jsonl").read_text().splitlines()
        rows[split] = [{k: v for k, v in r.items() if k != "wall_s"} for r in map(json.loads, lines)]
        per_program = [programs_called.count(program) for program in dict.fromkeys(programs_called)]
        assert per_program == ([2 * 18, 2 * 1] if split == "blocks" else [2]), split  # 2 chunks
    assert rows["blocks"] == rows["one call"] and [r["kind"] for r in rows["blocks"]].count("train") >= 2
    for a, b in zip(jax.tree.leaves(results["blocks"].state), jax.tree.leaves(results["one call"].state), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_a_slice_waits_for_the_remainder_program_only_when_it_is_all_that_is_left(monkeypatch):
    """18 blocks and a remainder: while the remainder's program compiles, a slice ends before it; a stop
    while the loop waits for that program makes no call (the mid-chunk checkpoint keeps the 18)."""
    from concurrent.futures import Future

    from rlq.run import loop as loop_module
    from rlq.run.stops.waiting import Waiter

    programs = types.SimpleNamespace(full_calls=18, calls_per_chunk=19)
    compiling: Future = Future()
    assert loop_module.ready_calls(8, 16, programs, compiling) == 2  # the 2 blocks left, not the remainder
    assert loop_module.ready_calls(8, 18, programs, compiling) == 1  # the remainder is all that is left
    assert loop_module.ready_calls(8, 16, programs, None) == 8
    made = []
    monkeypatch.setattr(loop_module, "call_chunk", lambda chunk, state, count: made.append(count))
    state, parts = loop_module.call_slice(programs, "block", compiling, "state", 18, 1, Waiter(lambda: 15).wait)
    assert (state, parts, made) == ("state", [], [])
    compiling.set_result(("rest", None))
    calls = []

    def call_chunk(chunk, state, count):
        calls.append((chunk, count))
        return state, {"loss": np.zeros((1, count))}

    monkeypatch.setattr(loop_module, "call_chunk", call_chunk)
    _, parts = loop_module.call_slice(programs, "block", compiling, "state", 16, 3, Waiter(lambda: None).wait)
    assert calls == [("block", 2), ("rest", 1)] and len(parts) == 2


def test_unknown_chunk_loop_is_a_config_error():
    from rlq.errors import ConfigError
    from rlq.run.checks.validate import check_run_config

    with pytest.raises(ConfigError, match="chunk_loop must be one of scan, calls"):
        check_run_config(compose_config("chunk_loop=loop"))
