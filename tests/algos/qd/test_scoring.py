"""The black-box scoring function shared by random search and MAP-Elites."""

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from rlq.algos.qd.scoring import make_scoring_fn
from rlq.config.compose import compose
from rlq.envs.wrappers import AutoReset, EpisodeStats, TimeLimit
from rlq.lib.env_api import Env
from rlq.run.programs.env_stack import make_env
from tests.fakes import Walk


def walk_env(steps: int = 3) -> Env:
    return AutoReset(EpisodeStats(TimeLimit(Walk(), steps)))


def test_fitness_is_mean_return_and_descriptor_from_info():
    params = jnp.array([[0.5], [-1.0], [0.0]])
    scoring_fn = make_scoring_fn(walk_env(3), lambda p, obs, key: p, num_episodes=4)
    fitness, descriptors, extras = jax.jit(scoring_fn)(params, jax.random.PRNGKey(0))
    np.testing.assert_allclose(fitness, [1.5, -3.0, 0.0])
    np.testing.assert_allclose(descriptors, [[1.5, 3.0], [-3.0, -6.0], [0.0, 0.0]])
    assert extras["episode_return"].shape == (3, 4)
    assert int(extras["env_steps"]) == 3 * 4 * 3


def test_unravel_and_shapes_on_cartpole_without_descriptor():
    env = make_env(compose(["env=cartpole"]))
    example = {"w": jnp.zeros(4)}
    _, unravel = ravel_pytree(example)

    def apply_fn(params, obs, key):
        return (obs @ params["w"] >= 0).astype(jnp.int32)

    scoring_fn = make_scoring_fn(env, apply_fn, num_episodes=2, unravel=unravel)
    batch = jax.random.uniform(jax.random.PRNGKey(1), (5, 4), minval=-2, maxval=2)
    fitness, descriptors, extras = jax.jit(scoring_fn)(batch, jax.random.PRNGKey(2))
    assert fitness.shape == (5,)
    assert descriptors.shape == (5, 0)
    np.testing.assert_allclose(fitness, extras["episode_return"].mean(axis=1))
    assert int(extras["env_steps"]) == int(extras["episode_length"].sum())
    assert bool(extras["finished"].all())
