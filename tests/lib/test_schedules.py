import jax
import jax.numpy as jnp
import numpy as np
import pytest
from omegaconf import OmegaConf

from rlq.lib.learning.schedules import check_epsilon, epsilon_greedy, epsilon_schedule, exponential, linear


def test_linear_decays_then_stays_at_end():
    values = [float(linear(s, 1.0, 0.1, 100)) for s in (0, 50, 100, 1000)]
    assert values == pytest.approx([1.0, 0.55, 0.1, 0.1])


def test_exponential_multiplies_per_episode_down_to_the_floor():
    assert float(exponential(0, 1.0, 0.5, 0.1)) == pytest.approx(1.0)
    assert float(exponential(2, 1.0, 0.5, 0.1)) == pytest.approx(0.25)
    assert float(exponential(10, 1.0, 0.5, 0.1)) == pytest.approx(0.1)


def test_schedule_from_config_reads_the_right_counter():
    cfg = OmegaConf.create({"schedule": "linear", "start": 1.0, "end": 0.0, "duration": 10, "decay": 0.5})
    assert float(epsilon_schedule(cfg)(5, 100)) == pytest.approx(0.5)
    cfg.schedule = "exponential"
    assert float(epsilon_schedule(cfg)(5, 1)) == pytest.approx(0.5)


def test_bad_schedule_names_the_key():
    cfg = OmegaConf.create({"schedule": "cosine", "start": 1.0, "end": 0.0, "duration": 10, "decay": 0.5})
    assert "algo.epsilon.schedule" in check_epsilon(cfg, "algo.epsilon")


def test_epsilon_greedy_extremes():
    q = jnp.tile(jnp.array([0.0, 2.0, 1.0]), (2000, 1))
    key = jax.random.PRNGKey(0)
    np.testing.assert_array_equal(epsilon_greedy(key, q, 0.0), 1)
    counts = np.bincount(np.asarray(epsilon_greedy(key, q, 1.0)), minlength=3)
    assert counts.min() > 550  # uniform over the 3 actions
