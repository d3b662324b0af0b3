"""Evolution strategies (evosax): OpenAI-ES's step by hand, learning CartPole, the CLI end to end."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import algo_settings, es
from rlq.config.compose import compose
from rlq.run.checks.validate import check_run_config
from rlq.run.programs.env_stack import make_env
from rlq.run.train import train
from tests.helpers import leaf_types, run_cli_in_process, run_dirs, stopped_at


def algo_cfg(**overrides):
    return algo_settings(compose(["algo=es", *[f"algo.{k}={v}" for k, v in overrides.items()]]).algo)


def test_open_es_step_is_adams_first_step_on_the_centered_rank_gradient():
    cfg = algo_cfg(strategy="open_es", population=4, sigma=0.5, lr=0.1)
    strategy, params = es.make_strategy(cfg, 2)
    mean = jnp.array([1.0, -1.0])
    state = strategy.init(jax.random.PRNGKey(0), mean, params)
    x, state = strategy.ask(jax.random.PRNGKey(1), state, params)
    fitness = -np.sum(np.asarray(x) ** 2, axis=1)  # rlq maximises; evosax is told minus the fitness
    state, _ = strategy.tell(jax.random.PRNGKey(2), x, -jnp.asarray(fitness), state, params)
    z = (np.asarray(x) - np.asarray(mean)) / 0.5
    np.testing.assert_allclose(z[:2], -z[2:], atol=1e-6)  # antithetic pairs
    ranks = np.argsort(np.argsort(-fitness))  # rank 0 = best (lowest told value)
    shaped = ranks / 3 - 0.5
    grad = shaped @ z / (4 * 0.5)
    expected = np.asarray(mean) - 0.1 * np.sign(grad)  # Adam's first step: lr * g / |g|
    np.testing.assert_allclose(np.asarray(state.mean), expected, atol=1e-5)
    assert np.all(np.abs(expected - 0.0) <= np.abs(np.asarray(mean)))  # it moved toward the optimum at 0


@pytest.mark.slow
@pytest.mark.parametrize("strategy", es.STRATEGIES)
def test_each_strategy_runs_generations_and_keeps_the_best(strategy):
    env = make_env(compose(["env=cartpole"]))
    algo = es.make(algo_cfg(strategy=strategy, population=6, episodes=1), env, budget_env_steps=10**9)
    state = jax.jit(algo.init)(jax.random.PRNGKey(0))
    state, metrics = jax.jit(lambda s: jax.lax.scan(lambda s, _: algo.update(s), s, None, length=3))(state)
    best = np.asarray(metrics["best_fitness"])
    np.testing.assert_allclose(best, np.maximum.accumulate(np.asarray(metrics["generation_max_fitness"])))
    assert int(state.generation) == 3 and float(state.best_fitness) == best[-1]


@pytest.mark.parametrize("strategy", es.STRATEGIES)
def test_the_state_keeps_its_types_through_a_generation(strategy):
    """A state whose types change after one update makes a jitted update compile twice."""
    env = make_env(compose(["env=cartpole"]))
    algo = es.make(algo_cfg(strategy=strategy, population=6, episodes=1), env, budget_env_steps=10**9)
    state = jax.jit(algo.init)(jax.random.PRNGKey(0))
    updated, _ = jax.jit(algo.update)(state)
    assert leaf_types(updated) == leaf_types(state)


def test_check_names_the_strategies_and_the_even_population():
    env = make_env(compose(["env=cartpole"]))
    assert "algo.strategy must be one of open_es, cma_es, snes" in es.check(algo_cfg(strategy="pso"), env)
    assert "must be even" in es.check(algo_cfg(population=5), env)
    assert es.check(algo_cfg(strategy="snes", population=5), env) is None


@pytest.mark.slow
def test_cli_end_to_end_and_resume_continues_exactly(workdir, tmp_path):
    """evosax's state is checkpointed: a run resumed from an earlier checkpoint ends where the whole run ended."""

    from rlq.store import checkpoint

    args = [
        "algo=es",
        "algo.strategy=cma_es",
        "algo.population=4",
        "algo.episodes=1",
        "budget.env_steps=8000",
        "log_every_steps=2000",
        "checkpoint.every_steps=1",
        "eval.episodes=2",
        "video.at_end=false",
        "logger=quiet",
    ]
    proc = run_cli_in_process("train", *args, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    stopped = stopped_at(run_dir, tmp_path, 0)
    proc = run_cli_in_process("resume", f"run={stopped}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    resumed = checkpoint.leaves(stopped / "checkpoints/final.msgpack")
    original = checkpoint.leaves(run_dir / "checkpoints/final.msgpack")
    for a, b in zip(resumed, original, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow
def test_tuned_open_es_solves_cartpole(tmp_path):
    cfg = compose(["algo=es", "num_seeds=2", "eval.every_steps=0", "logger=quiet"])
    check_run_config(cfg)
    result = train(cfg, tmp_path)
    assert np.mean(result.eval_return) >= 475, result.line()


def test_keep_mean_scores_the_distribution_mean_and_keeps_the_best_one():
    """keep=mean: the kept genotype is a mean the strategy sampled around, and best_fitness is the best of the
    means' own scores (its mean_episodes), never a candidate's."""
    env = make_env(compose(["env=cartpole"]))
    cfg = algo_cfg(strategy="snes", population=6, episodes=1, keep="mean", mean_episodes=3)
    algo = es.make(cfg, env, budget_env_steps=10**9)
    state = jax.jit(algo.init)(jax.random.PRNGKey(0))
    means, rows = [], []
    update = jax.jit(algo.update)
    for _ in range(3):
        means.append(np.asarray(state.es.mean))
        state, metrics = update(state)
        rows.append({k: float(v) for k, v in metrics.items()})
    best = int(np.argmax([row["mean_fitness"] for row in rows]))
    np.testing.assert_allclose(np.asarray(state.best_params), np.clip(means[best], -2.0, 2.0))
    assert float(state.best_fitness) == max(row["mean_fitness"] for row in rows)
    assert algo.steps_per_update == (6 * 1 + 3) * env.max_episode_steps


def test_check_names_the_keep_choices():
    env = make_env(compose(["env=cartpole"]))
    assert "algo.keep must be one of candidate, mean" in es.check(algo_cfg(keep="best"), env)
    assert "algo.mean_episodes" in es.check(algo_cfg(keep="mean", mean_episodes=0), env)


def test_a_constant_action_is_searched_in_its_box_mapped_to_unit_range():
    cfg = algo_cfg(genotype="action")
    low, high = np.array([0.0, -np.pi, 0.0]), np.array([1.0, np.pi, 3 * np.pi])
    centre, scale = es.search_frame(cfg, low, high)
    np.testing.assert_allclose(np.asarray(centre), [0.5, 0.0, 1.5 * np.pi], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(centre - scale), low, atol=1e-6)
    np.testing.assert_allclose(np.asarray(centre + scale), high, rtol=1e-6)
    centre, scale = es.search_frame(algo_cfg(), low, high)  # a policy's weights: as they are
    assert not np.asarray(centre).any() and (np.asarray(scale) == 1).all()
