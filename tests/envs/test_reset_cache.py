"""AutoReset with ``reset_cache``: later episodes start from the env's first state, no fresh reset."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.envs.wrappers import AutoReset, EpisodeStats, TimeLimit
from tests.fakes import RandomStart


def run(reset_cache: bool):
    env = RandomStart(reset_cache)
    wrapped = AutoReset(EpisodeStats(TimeLimit(env, 5)))
    state = wrapped.reset(jax.random.PRNGKey(0))
    traced_at_reset = env.resets_traced
    states = [state]
    for action in (0, 1, 0, 1):
        states.append(wrapped.step(states[-1], jnp.array(action)))
    return env.resets_traced - traced_at_reset, states


def test_cached_reset_restarts_every_episode_from_the_first_state():
    fresh_resets, states = run(reset_cache=True)
    assert fresh_resets == 0
    first = float(states[0].obs[0])
    assert bool(states[2].terminated) and float(states[2].obs[0]) == first
    assert float(states[2].info["final_obs"][0]) == pytest.approx(first + 2.0)
    assert bool(states[4].terminated) and float(states[4].obs[0]) == first
    assert int(states[4].info["episode_length"]) == 2 and int(states[4].extras["t"]) == 0
    np.testing.assert_array_equal(states[4].extras["reset_cache"]["obs"], states[0].obs)


def test_without_cache_each_episode_gets_a_fresh_start():
    fresh_resets, states = run(reset_cache=False)
    assert fresh_resets == 4 and "reset_cache" not in states[0].extras
    assert float(states[2].obs[0]) != float(states[0].obs[0])
