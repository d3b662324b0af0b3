"""Continuous PPO: tanh-normal log-probs, the running observation normaliser, brax batching, and
learning on a cheap continuous task (a contextual bandit with far-from-unit observations)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from omegaconf import OmegaConf
from scipy.stats import norm

from rlq.algos import algo_settings, ppo
from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.envs.wrappers import AutoReset, EpisodeStats
from rlq.lib.learning import distributions as dist
from rlq.lib.learning import normalize
from rlq.lib.learning.advantages import gae, unroll_gae
from rlq.lib.rollout import evaluate
from rlq.lib.spaces import Box
from tests.fakes import Bandit
from tests.helpers import train_run


def test_tanh_normal_density_matches_numerical_derivative_of_cdf():
    mean, log_std = jnp.array([0.3]), jnp.array([np.log(0.8)])
    y = np.linspace(-0.98, 0.98, 41)
    raw = np.arctanh(y)
    logp = jax.vmap(lambda u: dist.tanh_normal_log_prob(mean, log_std, u[None]))(jnp.asarray(raw, jnp.float32))

    def cdf(v):  # P(tanh(U) <= v)
        return norm.cdf((np.arctanh(v) - 0.3) / 0.8)

    h = 1e-5
    density = (cdf(y + h) - cdf(y - h)) / (2 * h)
    np.testing.assert_allclose(np.exp(np.asarray(logp)), density, rtol=1e-3)


def test_tanh_normal_sums_over_dimensions_and_stays_finite_at_the_bounds():
    mean, log_std = jnp.array([0.1, -0.5]), jnp.array([0.0, -1.0])
    raw = jnp.array([0.4, 30.0])  # tanh(30) rounds to 1.0 in float32: scoring raw stays finite
    per_dim = [dist.tanh_normal_log_prob(mean[i : i + 1], log_std[i : i + 1], raw[i : i + 1]) for i in range(2)]
    total = dist.tanh_normal_log_prob(mean, log_std, raw)
    assert np.isfinite(float(total))
    np.testing.assert_allclose(float(total), float(per_dim[0] + per_dim[1]), rtol=1e-6)


def test_action_dists_map_into_the_bounds():
    space = Box((-2.0, 0.0), (2.0, 1.0))
    raw = jnp.array([[-50.0, 50.0], [0.0, 0.0]])
    squashed = dist.make_action_dist(space, "tanh_normal").to_env(raw)
    np.testing.assert_allclose(squashed, [[-2.0, 1.0], [0.0, 0.5]], atol=1e-6)
    clipped = dist.make_action_dist(space, "clipped_normal").to_env(raw)
    np.testing.assert_allclose(clipped, [[-2.0, 1.0], [0.0, 0.0]])


def test_running_normaliser_matches_numpy_on_hand_data():
    rng = np.random.default_rng(0)
    a = rng.normal(3.0, 2.0, (7, 3)).astype(np.float32)
    b = rng.normal(-1.0, 0.5, (2, 5, 3)).astype(np.float32)  # leading axes (time, env)
    stats = normalize.update(normalize.update(normalize.init((3,)), a), b)
    both = np.concatenate([a, b.reshape(-1, 3)])
    assert float(stats.count) == 17
    np.testing.assert_allclose(stats.mean, both.mean(0), rtol=1e-5)
    np.testing.assert_allclose(normalize.std(stats), both.std(0), rtol=1e-5)
    np.testing.assert_allclose(normalize.normalize(stats, both), (both - both.mean(0)) / both.std(0), atol=1e-5)


def test_normaliser_is_identity_before_data_and_guards_constant_inputs():
    stats = normalize.init((2,))
    np.testing.assert_array_equal(normalize.normalize(stats, jnp.array([4.0, -1.0])), [4.0, -1.0])
    stats = normalize.update(stats, jnp.ones((10, 2)))
    assert np.all(np.isfinite(normalize.normalize(stats, jnp.ones(2))))


def test_unroll_gae_uses_successor_values_and_stored_values_at_truncation():
    # 2 unrolls x 4 steps; unroll 0 terminates at t=1, unroll 1 is truncated at t=2
    rng = np.random.default_rng(1)
    values, last_value, stored = rng.normal(size=(2, 4)), rng.normal(size=2), rng.normal(size=(2, 4))
    reward = rng.normal(size=(2, 4))
    terminated = np.array([[0, 1, 0, 0], [0, 0, 0, 0]], bool)
    truncated = np.array([[0, 0, 0, 0], [0, 0, 1, 0]], bool)
    done = terminated | truncated
    true_next = np.concatenate([values[:, 1:], last_value[:, None]], axis=1)
    true_next[1, 2] = stored[1, 2]  # V(final obs) of the truncated episode
    args = [jnp.asarray(x, jnp.float32) for x in (values, last_value, stored, reward)]
    adv, targets = unroll_gae(*args[:3], args[3], terminated, truncated, done, 0.9, 0.8)
    parts = (reward, values, true_next, terminated.astype(np.float32), done)
    expected_adv, expected_targets = gae(*(jnp.asarray(x.T, jnp.float32) for x in parts), 0.9, 0.8)
    np.testing.assert_allclose(adv, np.asarray(expected_adv).T, rtol=1e-5)
    np.testing.assert_allclose(targets, np.asarray(expected_targets).T, rtol=1e-5)


@pytest.mark.slow
def test_recomputed_gae_ppo_learns_cartpole(tmp_path):
    result = train_run(
        tmp_path, "env=cartpole", "algo.recompute_gae=true", "algo.clip_value=false", "budget.env_steps=150000",
        "eval.episodes=8", "log_every_steps=50000",
    )  # fmt: skip
    assert float(np.mean(result.eval_return)) > 150, result.eval_return


def algo_cfg(**overrides):
    return algo_settings(OmegaConf.merge(compose(["algo=ppo", *WITHOUT_TUNED]).algo, overrides))


def test_check_names_the_compute_dtypes():
    env = AutoReset(EpisodeStats(Bandit()))
    assert ppo.check(algo_cfg(compute_dtype="bfloat16"), env) is None
    assert "float32, bfloat16" in ppo.check(algo_cfg(compute_dtype="float16"), env)


def test_brax_batch_size_semantics():
    env = AutoReset(EpisodeStats(Bandit()))
    cfg = algo_cfg(num_envs=16, num_steps=10, batch_size=8, num_minibatches=4)
    assert ppo.check(cfg, env) is None
    algo = ppo.make(cfg, env, 10_000)
    assert algo.steps_per_update == 8 * 4 * 10  # two unrolls of 10 steps per env
    assert ppo.steps_per_update(cfg) == algo.steps_per_update
    assert "multiple of algo.num_envs" in ppo.check(algo_cfg(num_envs=16, batch_size=6, num_minibatches=4), env)


@pytest.mark.slow
@pytest.mark.parametrize(
    "action_dist,recompute,dtype",
    [("tanh_normal", True, "float32"), ("clipped_normal", False, "float32"), ("tanh_normal", True, "bfloat16")],
)
def test_continuous_ppo_learns_a_contextual_bandit(action_dist, recompute, dtype):
    env = AutoReset(EpisodeStats(Bandit()))
    cfg = algo_cfg(
        num_envs=16, num_steps=8, batch_size=16, num_minibatches=4, update_epochs=4, lr=1e-3,
        anneal_lr=False, ent_coef=1e-3, normalize_obs=True, reward_scaling=10.0, action_dist=action_dist,
        hidden=[32, 32], activation="swish", clip_value=False, max_grad_norm=0.5, recompute_gae=recompute,
        compute_dtype=dtype,
    )  # fmt: skip
    assert ppo.check(cfg, env) is None
    algo = ppo.make(cfg, env, 40 * 512)

    def run(key):
        state = algo.init(key, algo.hyperparams)
        state, metrics = jax.lax.scan(
            lambda s, _: algo.update(s, algo.hyperparams), state, None, length=algo.num_updates
        )
        record = evaluate(env, algo.policy(state), jax.random.PRNGKey(7), 256)
        return state, metrics, record

    state, metrics, record = jax.jit(run)(jax.random.PRNGKey(0))
    assert int(state.env_steps) == algo.num_updates * 512
    assert float(state.obs_stats.count) == algo.num_updates * 512
    np.testing.assert_allclose(state.obs_stats.mean, [10.0, 10.0], atol=0.5)
    assert np.all(np.isfinite(np.asarray(metrics["value_loss"])))
    random_return = -(1 / 3 + 1 / 12)  # E[(a - u/2)^2] for a, u ~ U(-1, 1)
    assert float(record["episode_return"].mean()) > 0.02 * random_return, float(record["episode_return"].mean())
