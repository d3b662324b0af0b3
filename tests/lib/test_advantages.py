"""Q(lambda) returns (PQN's targets) and n-step returns (DQN's) on hand-computed cases."""

import jax.numpy as jnp
import numpy as np

from rlq.lib.learning.advantages import n_step_returns, q_lambda_returns


def test_q_lambda_returns_hand_computed():
    # one env, three steps, no episode end: G2 = r2 + g*q2; G1 = r1 + g*((1-l)*q1 + l*G2); G0 likewise
    rewards = jnp.array([[1.0], [2.0], [3.0]])
    q_max = jnp.array([[10.0], [20.0], [30.0]])
    no = jnp.zeros((3, 1), bool)
    g, lam = 0.5, 0.5
    returns = q_lambda_returns(rewards, q_max, no, no, g, lam)
    g2 = 3.0 + g * 30.0
    g1 = 2.0 + g * ((1 - lam) * 20.0 + lam * g2)
    g0 = 1.0 + g * ((1 - lam) * 10.0 + lam * g1)
    np.testing.assert_allclose(returns[:, 0], [g0, g1, g2], rtol=1e-6)


def test_q_lambda_returns_stop_at_episode_ends():
    # step 0 terminates (no bootstrap, nothing from step 1); step 1 is truncated (bootstraps from its own
    # final observation's q, not from step 2, which belongs to the next episode)
    rewards = jnp.array([[1.0], [2.0], [3.0]])
    q_max = jnp.array([[10.0], [20.0], [30.0]])
    terminated = jnp.array([[True], [False], [False]])
    done = jnp.array([[True], [True], [False]])
    returns = q_lambda_returns(rewards, q_max, terminated, done, 0.9, 0.8)
    np.testing.assert_allclose(returns[:, 0], [1.0, 2.0 + 0.9 * 20.0, 3.0 + 0.9 * 30.0], rtol=1e-6)


def test_q_lambda_extremes():
    rewards = jnp.array([[1.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    q_max = jnp.array([[4.0, 2.0], [6.0, 2.0], [8.0, 2.0]])
    no = jnp.zeros((3, 2), bool)
    one_step = q_lambda_returns(rewards, q_max, no, no, 0.9, 0.0)
    np.testing.assert_allclose(one_step, rewards + 0.9 * q_max, rtol=1e-6)  # lambda 0: one-step TD targets
    full = q_lambda_returns(rewards, q_max, no, no, 0.9, 1.0)
    # lambda 1: discounted rewards to the end of the rollout, then the last bootstrap
    np.testing.assert_allclose(full[0], rewards[0] + 0.9 * rewards[1] + 0.81 * (rewards[2] + 0.9 * q_max[2]), rtol=1e-6)


def _one_env(rewards, terminated, truncated):
    rewards = jnp.array(rewards)[:, None]
    terminated = jnp.array(terminated)[:, None]
    done = terminated | jnp.array(truncated)[:, None]
    next_obs = jnp.arange(1.0, rewards.shape[0] + 1.0)[:, None, None]  # step t's successor is t + 1
    return rewards, terminated, done, next_obs


def test_one_step_is_the_plain_transition():
    rewards, terminated, done, next_obs = _one_env([1.0, 2.0, 3.0], [False, True, False], [False, False, False])
    ret, boot, disc = n_step_returns(rewards, terminated, done, next_obs, 0.9, 1)
    np.testing.assert_array_equal(ret[:, 0], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(boot[:, 0, 0], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(disc[:, 0], [0.9, 0.0, 0.9])


def test_returns_stop_at_the_block_end_and_at_episode_ends():
    # steps 0..4; the episode terminates after step 1 and is truncated after step 3
    rewards, terminated, done, next_obs = _one_env(
        [1.0, 2.0, 4.0, 8.0, 16.0], [False, True, False, False, False], [False, False, False, True, False]
    )
    ret, boot, disc = n_step_returns(rewards, terminated, done, next_obs, 0.5, 3)
    np.testing.assert_allclose(ret[:, 0], [1.0 + 0.5 * 2.0, 2.0, 4.0 + 0.5 * 8.0, 8.0, 16.0])
    np.testing.assert_array_equal(boot[:, 0, 0], [2.0, 2.0, 4.0, 4.0, 5.0])
    # termination: no bootstrap; truncation: the successor's value with γ^k; the block's last step: one step
    np.testing.assert_allclose(disc[:, 0], [0.0, 0.0, 0.25, 0.5, 0.5])
