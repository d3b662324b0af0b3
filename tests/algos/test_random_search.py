"""Random policy search: the linear rule, keeping the best, learning CartPole."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import algo_settings, random_search
from rlq.config.compose import compose
from rlq.envs.wrappers import AutoReset, EpisodeStats, TimeLimit
from rlq.lib.spaces import Box, Discrete
from rlq.run.checks.validate import check_run_config
from rlq.run.programs.env_stack import make_env
from rlq.run.train import train
from tests.fakes import Target


def algo_cfg(**overrides):
    return algo_settings(compose(["algo=random_search", *[f"algo.{k}={v}" for k, v in overrides.items()]]).algo)


def test_linear_sign_rule_for_two_actions():
    w = {"w": jnp.array([[1.0], [-2.0], [0.5], [0.0]])}
    obs = jnp.array([[1.0, 0.5, 0.0, 9.0], [1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 2.0, 0.0]])
    y = random_search.linear_policy(w, obs)
    actions = random_search.decode_action(y, Discrete(2))
    np.testing.assert_array_equal(actions, [1, 0, 1])  # w·obs = 0 -> 1, as in T1


def test_argmax_and_clip_rules():
    y = jnp.array([[0.1, 0.7, -0.2]])
    assert int(random_search.decode_action(y, Discrete(3))[0]) == 1
    clipped = random_search.decode_action(jnp.array([3.0, -0.2]), Box((-1.0, -1.0), (1.0, 1.0)))
    np.testing.assert_allclose(clipped, [1.0, -0.2])
    raw = random_search.decode_action(jnp.array([3.0, -0.2]), Box((-1.0, -1.0), (1.0, 1.0)), clip=False)
    np.testing.assert_allclose(raw, [3.0, -0.2])
    assert random_search.num_outputs(Discrete(2)) == 1 and random_search.num_outputs(Discrete(5)) == 5


def run_generations(cfg, env, n):
    algo = random_search.make(cfg, env, budget_env_steps=10**9)
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    return algo, *jax.jit(lambda s: jax.lax.scan(lambda s, _: algo.update(s, algo.hyperparams), s, None, length=n))(
        state
    )


def test_keeps_the_best_candidate():
    env = make_env(compose(["env=cartpole"]))
    algo, state, metrics = run_generations(algo_cfg(population=4, episodes=2), env, 6)
    best = np.asarray(metrics["best_fitness"])
    np.testing.assert_allclose(best, np.maximum.accumulate(np.asarray(metrics["generation_max_fitness"])))
    assert np.all(np.diff(best) >= 0)
    assert float(state.best_fitness) == best[-1]
    steps = np.asarray(metrics["env_steps"])
    assert np.all(np.diff(steps) > 0) and steps[-1] <= 6 * algo.steps_per_update


@pytest.mark.parametrize("sampling", ["uniform", "gaussian"])
def test_box_actions_with_an_mlp(sampling):
    env = AutoReset(EpisodeStats(TimeLimit(Target(), 5)))
    cfg = algo_cfg(population=16, episodes=1, sampling=sampling, hidden="[4]")
    algo, state, metrics = run_generations(cfg, env, 5)
    assert np.isfinite(float(state.best_fitness)) and float(state.best_fitness) <= 0
    action = algo.policy(state)(jnp.ones(2), jax.random.PRNGKey(0))
    assert action.shape == (1,) and -1.0 <= float(action[0]) <= 1.0


def test_four_seeds_in_one_program(tmp_path):
    cfg = compose(
        [
            "algo=random_search",
            "num_seeds=4",
            "algo.population=4",
            "algo.episodes=2",
            "budget.env_steps=8000",
            "eval.episodes=2",
            "logger=quiet",
        ]
    )
    check_run_config(cfg)
    result = train(cfg, tmp_path)
    assert result.eval_return.shape == (4,) and np.all(np.isfinite(result.eval_return))


@pytest.mark.slow
def test_preset_solves_cartpole(tmp_path):
    cfg = compose(["experiment=cartpole_random_search", "num_seeds=3", "eval.every_steps=0", "logger=quiet"])
    check_run_config(cfg)
    result = train(cfg, tmp_path)
    assert np.mean(result.eval_return) >= 475, result.line()
