"""The learner loop of PPO and PQN: every item once per epoch, minibatches of equal size, a key each."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.errors import ConfigError
from rlq.lib.learning.minibatches import cut_minibatches, epoch_order, minibatch_epochs, shard_problem, shuffle_shards


def test_each_epoch_visits_every_item_once_in_equal_minibatches():
    data = {"x": jnp.arange(12.0), "y": jnp.arange(12.0) * 10}

    def step(carry, minibatch, key):
        np.testing.assert_equal(minibatch["x"].shape, (3,))
        return carry + minibatch["x"].sum(), {"x": minibatch["x"], "pairs": minibatch["y"] - 10 * minibatch["x"]}

    total, metrics = minibatch_epochs(step, jnp.zeros(()), data, jax.random.PRNGKey(0), epochs=2, num_minibatches=4)
    assert float(total) == 2 * sum(range(12))
    assert metrics["x"].shape == (2, 4, 3)
    for epoch in np.asarray(metrics["x"]):
        assert sorted(epoch.reshape(-1).tolist()) == list(range(12))  # a permutation: each item once
    assert not np.array_equal(metrics["x"][0], metrics["x"][1])  # reshuffled per epoch
    np.testing.assert_array_equal(metrics["pairs"], 0.0)  # the leaves of an item stay together


def per_shard_minibatches(items: int, shards: int, num_minibatches: int, seed: int = 0) -> np.ndarray:
    """The item indices of one epoch's minibatches cut per shard: (num_minibatches, items / num_minibatches)."""
    order = epoch_order(jax.random.PRNGKey(seed), items, shards)
    return np.asarray(cut_minibatches(jnp.arange(items), order, num_minibatches))


@pytest.mark.parametrize(("shards", "num_minibatches"), [(2, 4), (4, 2), (4, 3), (3, 1)])
def test_per_shard_minibatches_take_equal_parts_of_every_shard_and_each_item_once(shards, num_minibatches):
    items = 48
    minibatches = per_shard_minibatches(items, shards, num_minibatches)
    share, part = items // shards, items // (shards * num_minibatches)
    assert minibatches.shape == (num_minibatches, items // num_minibatches)
    assert sorted(minibatches.reshape(-1).tolist()) == list(range(items))  # every item once per epoch
    for minibatch in minibatches:
        # the d-th part of a minibatch is batch/(D*M) items of shard d's own contiguous share
        np.testing.assert_array_equal(
            minibatch.reshape(shards, part) // share, np.repeat(np.arange(shards)[:, None], part, 1)
        )
    assert not np.array_equal(per_shard_minibatches(items, shards, num_minibatches, seed=1), minibatches)


def test_per_shard_epochs_visit_every_item_once_with_each_shard_in_every_minibatch():
    def step(carry, minibatch, key):
        return carry, minibatch

    _, seen = minibatch_epochs(step, (), jnp.arange(16), jax.random.PRNGKey(0), 2, num_minibatches=2, shards=4)
    assert seen.shape == (2, 2, 8)
    for epoch in np.asarray(seen):
        assert sorted(epoch.reshape(-1).tolist()) == list(range(16))
        assert all(sorted(set(m // 4)) == [0, 1, 2, 3] for m in epoch)


def test_shards_are_shuffled_with_keys_of_their_own():
    order = np.asarray(epoch_order(jax.random.PRNGKey(0), 64, 4))
    assert order.shape == (4, 16)
    assert len({tuple(row) for row in order}) == 4


def test_one_shard_is_the_global_permutation():
    key, items = jax.random.PRNGKey(3), 24
    expected = np.asarray(jax.random.permutation(key, items)).reshape(4, 6)
    np.testing.assert_array_equal(per_shard_minibatches(items, 1, 4, seed=3), expected)


def test_outside_a_mesh_per_shard_is_one_shard_and_other_values_are_config_errors():
    """One env shard (no mesh, or one env device): per_shard takes the global path, bit for bit."""
    assert shuffle_shards("per_shard") == shuffle_shards("global") == 1
    with pytest.raises(ConfigError, match="minibatch_shuffle"):
        shuffle_shards("local")


def test_shares_that_minibatches_do_not_divide_are_config_errors():
    assert shard_problem("per_shard", 12, 4, 4) is not None and "algo.minibatch_shuffle=global" in shard_problem(
        "per_shard", 12, 4, 4
    )
    assert shard_problem("per_shard", 48, 4, 4) is None
    assert shard_problem("global", 12, 4, 4) is None and shard_problem("per_shard", 12, 1, 5) is None
    with pytest.raises(ConfigError, match="must divide each env shard"):
        cut_minibatches(jnp.arange(12), epoch_order(jax.random.PRNGKey(0), 12, 4), 4)
