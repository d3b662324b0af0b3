"""The learner loop of PPO and PQN: every item once per epoch, minibatches of equal size, a key each."""

import jax
import jax.numpy as jnp
import numpy as np

from rlq.lib.minibatches import minibatch_epochs


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
