"""seed_entry: one seed's entry of a run's state, with batch-shared leaves kept whole."""

import jax.numpy as jnp
import numpy as np

from rlq.lib.batch import seed_entry


def test_leaves_with_the_seed_axis_are_sliced_and_shared_ones_kept():
    state = {"params": jnp.arange(6.0).reshape(3, 2), "step": jnp.array([4, 5, 6]), "shared": jnp.zeros((7, 2))}
    entry = seed_entry(state, 1, num_seeds=3)
    np.testing.assert_array_equal(entry["params"], [2.0, 3.0])
    assert int(entry["step"]) == 5
    assert entry["shared"].shape == (7, 2)


def test_host_arrays_and_scalars():
    entry = seed_entry({"a": np.array([1, 2]), "b": 3.0}, 0, num_seeds=2)
    assert entry == {"a": 1, "b": 3.0}
