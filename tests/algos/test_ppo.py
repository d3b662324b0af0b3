import jax.numpy as jnp
import numpy as np
import pytest

from rlq.lib.learning.advantages import gae
from tests.helpers import train_run


def test_gae_matches_hand_computation():
    # one env, three steps; the episode terminates after step 1, step 2 starts a new one
    rewards = jnp.array([[1.0], [2.0], [3.0]])
    values = jnp.array([[0.5], [1.0], [2.0]])
    next_values = jnp.array([[1.0], [9.0], [4.0]])  # V(s1), V(terminal s2, ignored), V(s3)
    terminated = jnp.array([[0.0], [1.0], [0.0]])
    done = terminated
    gamma, lam = 0.9, 0.8
    adv, targets = gae(rewards, values, next_values, terminated, done, gamma, lam)
    d2 = 3.0 + 0.9 * 4.0 - 2.0
    d1 = 2.0 - 1.0
    d0 = 1.0 + 0.9 * 1.0 - 0.5
    expected = np.array([d0 + gamma * lam * d1, d1, d2])
    np.testing.assert_allclose(np.asarray(adv)[:, 0], expected, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(targets)[:, 0], expected + np.array([0.5, 1.0, 2.0]), rtol=1e-6)


def test_gae_bootstraps_on_truncation():
    rewards = jnp.array([[1.0]])
    values = jnp.array([[0.0]])
    next_values = jnp.array([[10.0]])
    adv_trunc, _ = gae(rewards, values, next_values, jnp.array([[0.0]]), jnp.array([[1.0]]), 0.5, 0.9)
    adv_term, _ = gae(rewards, values, next_values, jnp.array([[1.0]]), jnp.array([[1.0]]), 0.5, 0.9)
    assert float(adv_trunc[0, 0]) == pytest.approx(6.0)
    assert float(adv_term[0, 0]) == pytest.approx(1.0)


@pytest.mark.slow
def test_ppo_solves_cartpole_on_every_seed(tmp_path):
    result = train_run(
        tmp_path, "algo=ppo", "env=cartpole", "num_seeds=3", "budget.env_steps=500000", "video.at_end=false"
    )
    assert result.env_steps <= 500_000
    assert np.all(result.eval_return >= 475), result.eval_return
