"""REINFORCE: rewards-to-go, Gaussian actions, learning CartPole."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import algo_settings, reinforce
from rlq.config.compose import compose
from rlq.envs.wrappers import AutoReset, EpisodeStats, TimeLimit
from rlq.run.checks.validate import check_run_config
from rlq.run.programs.env_stack import make_env
from rlq.run.train import train
from tests.fakes import Target


def test_rewards_to_go_restart_at_episode_boundaries():
    # one env: episode [r0, r1] ends at t=1, the next [r2, r3, r4] is cut by the array end
    rewards = jnp.array([1.0, 2.0, 1.0, 1.0, 4.0])
    dones = jnp.array([False, True, False, False, False])
    g = reinforce.rewards_to_go(rewards, dones, gamma=0.5)
    np.testing.assert_allclose(g, [1 + 0.5 * 2, 2, 1 + 0.5 * 1 + 0.25 * 4, 1 + 0.5 * 4, 4])
    np.testing.assert_array_equal(reinforce.complete_mask(dones), [True, True, False, False, False])


def test_rewards_to_go_over_time_and_env_axes():
    rewards = jnp.ones((4, 2))
    dones = jnp.array([[False, True], [True, False], [False, False], [True, True]])
    g = reinforce.rewards_to_go(rewards, dones, gamma=1.0)
    np.testing.assert_allclose(g, [[2, 1], [1, 3], [2, 2], [1, 1]])


def test_check_needs_full_episodes():
    env = make_env(compose(["env=cartpole"]))
    cfg = algo_settings(compose(["algo=reinforce", "algo.num_steps=100"]).algo)
    assert "algo.num_steps" in reinforce.check(cfg, env)
    assert "algo.baseline" in reinforce.check(algo_settings(compose(["algo=reinforce", "algo.baseline=foo"]).algo), env)


@pytest.mark.slow
@pytest.mark.parametrize("baseline", ["none", "mean", "value"])
def test_gaussian_policy_updates(baseline):
    env = AutoReset(EpisodeStats(TimeLimit(Target(), 5)))
    cfg = algo_settings(
        compose(["algo=reinforce", "algo.num_envs=4", "algo.num_steps=10", f"algo.baseline={baseline}"]).algo
    )
    algo = reinforce.make(cfg, env, budget_env_steps=400)
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    state, metrics = jax.jit(lambda s: jax.lax.scan(lambda s, _: algo.update(s, algo.hyperparams), s, None, length=3))(
        state
    )
    assert int(metrics["env_steps"][-1]) == 3 * 40
    assert np.all(np.isfinite(np.asarray(metrics["policy_loss"])))
    action = algo.policy(state)(jnp.ones(2), jax.random.PRNGKey(0))
    assert action.shape == (1,) and -1.0 <= float(action[0]) <= 1.0


@pytest.mark.slow
def test_four_seeds_in_one_program(tmp_path):
    cfg = compose(["algo=reinforce", "num_seeds=4", "budget.env_steps=10000", "eval.episodes=2", "logger=quiet"])
    check_run_config(cfg)
    result = train(cfg, tmp_path)
    assert result.eval_return.shape == (4,) and np.all(np.isfinite(result.eval_return))
    assert result.env_steps == 10000


@pytest.mark.slow
def test_preset_learns_cartpole(tmp_path):
    cfg = compose(["experiment=cartpole_reinforce", "num_seeds=3", "eval.every_steps=0", "logger=quiet"])
    check_run_config(cfg)
    result = train(cfg, tmp_path)
    assert result.env_steps <= 1_000_000
    assert np.mean(result.eval_return) >= 400, result.line()
