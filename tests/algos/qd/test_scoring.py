"""The black-box scoring function shared by random search, ES and MAP-Elites; genotypes re-scored as rows of a batch."""

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from rlq.algos.qd.scoring import (
    keep_strictly_better,
    make_keyed_scoring_fn,
    replicated,
    score_with_replicas,
    with_one_key,
)
from rlq.config.compose import compose
from rlq.envs.wrappers import AutoReset, EpisodeStats, TimeLimit
from rlq.lib.env_api import Env
from rlq.run.programs.env_stack import make_env
from tests.fakes import Walk


def walk_env(steps: int = 3) -> Env:
    return AutoReset(EpisodeStats(TimeLimit(Walk(), steps)))


def test_fitness_is_mean_return_and_descriptor_from_info():
    params = jnp.array([[0.5], [-1.0], [0.0]])
    scoring_fn = with_one_key(make_keyed_scoring_fn(walk_env(3), lambda p, obs, key: p, num_episodes=4))
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

    scoring_fn = with_one_key(make_keyed_scoring_fn(env, apply_fn, num_episodes=2, unravel=unravel))
    batch = jax.random.uniform(jax.random.PRNGKey(1), (5, 4), minval=-2, maxval=2)
    fitness, descriptors, extras = jax.jit(scoring_fn)(batch, jax.random.PRNGKey(2))
    assert fitness.shape == (5,)
    assert descriptors.shape == (5, 0)
    np.testing.assert_allclose(fitness, extras["episode_return"].mean(axis=1))
    assert int(extras["env_steps"]) == int(extras["episode_length"].sum())
    assert bool(extras["finished"].all())


def noisy_rows(params: jax.Array, keys: jax.Array):
    """A keyed scoring stub: each row's fitness its first number plus its own key's noise, two episodes a row."""
    noise = jax.vmap(lambda key: jax.random.normal(key, (2,)))(keys)
    returns = params[:, :1] + noise
    extras = {"episode_return": returns, "episode_length": jnp.full((len(params), 2), 3), "env_steps": 6 * len(params)}
    return returns.mean(axis=1), params[:, 1:], extras


def test_with_one_key_splits_the_batch_key_into_one_per_row():
    rows, key = jnp.array([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0]]), jax.random.PRNGKey(0)
    one_key = with_one_key(noisy_rows)(rows, key)
    keyed = noisy_rows(rows, jax.random.split(key, 3))
    for a, b in zip(jax.tree.leaves(one_key), jax.tree.leaves(keyed), strict=True):
        np.testing.assert_array_equal(a, b)


def test_replicated_genotypes_are_the_mean_of_their_rows_and_leave_the_batch_as_it_was():
    rows = jnp.array([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0]])
    keys = jax.random.split(jax.random.PRNGKey(0), 3)
    genotypes, key = jnp.array([[5.0, 50.0], [7.0, 70.0]]), jax.random.PRNGKey(1)
    alone = score_with_replicas(noisy_rows, rows, keys, None, 4, key)
    both = score_with_replicas(noisy_rows, rows, keys, genotypes, 4, key)
    assert alone.replica_fitness is None and both.replica_fitness is not None
    plain_fitness, plain_descriptors, plain_extras = noisy_rows(rows, keys)
    for result in (alone, both):  # the batch's rows: as scored without the genotypes, row by row
        np.testing.assert_array_equal(result.fitness, plain_fitness)
        np.testing.assert_array_equal(result.descriptors, plain_descriptors)
        np.testing.assert_array_equal(result.extras["episode_return"], plain_extras["episode_return"])
    fitness, _, _ = noisy_rows(replicated(genotypes, 4), jax.random.split(key, 8))
    np.testing.assert_allclose(both.replica_fitness, [fitness[:4].mean(), fitness[4:].mean()], rtol=1e-6)
    assert not np.allclose(fitness[:4], fitness[0])  # each row on its own key: four draws, not one
    assert int(alone.extras["env_steps"]) == 3 * 6 and int(both.extras["env_steps"]) == (3 + 8) * 6


def test_only_a_strictly_fitter_candidate_replaces_the_held_one():
    held, candidates = jnp.array([0.0, 0.0]), jnp.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]])
    tie = keep_strictly_better(held, jnp.asarray(5.0), candidates, jnp.array([1.0, 5.0, 5.0]))
    np.testing.assert_array_equal(tie.genotype, held)
    assert float(tie.fitness) == 5.0 and float(tie.top_fitness) == 5.0
    better = keep_strictly_better(held, jnp.asarray(4.0), candidates, jnp.array([1.0, 5.0, 5.0]))
    np.testing.assert_array_equal(better.genotype, candidates[1])  # of tied candidates, the first
    assert float(better.fitness) == 5.0
    worse = keep_strictly_better(held, jnp.asarray(9.0), candidates, jnp.array([1.0, 5.0, 2.0]))
    assert float(worse.fitness) == 9.0 and float(worse.top_fitness) == 5.0  # the generation's best, not kept
