import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.lib.learning import replay


def _items(values):
    values = jnp.asarray(values, jnp.float32)
    return {"x": values, "pair": jnp.stack([values, -values], axis=-1)}


def test_add_fills_in_order_and_wraps_around():
    state = replay.init(5, {"x": jnp.zeros(()), "pair": jnp.zeros(2)})
    state = replay.add(state, _items([1, 2, 3]))
    assert int(state.position) == 3 and int(state.size) == 3
    state = jax.jit(replay.add)(state, _items([4, 5, 6, 7]))
    # 6 and 7 overwrote the two oldest items (1 and 2)
    np.testing.assert_array_equal(state.storage["x"], [6, 7, 3, 4, 5])
    np.testing.assert_array_equal(state.storage["pair"][:, 1], [-6, -7, -3, -4, -5])
    assert int(state.position) == 2 and int(state.size) == 5


def test_add_rejects_a_batch_larger_than_the_buffer():
    state = replay.init(2, {"x": jnp.zeros(()), "pair": jnp.zeros(2)})
    with pytest.raises(ValueError, match="capacity 2"):
        replay.add(state, _items([1, 2, 3]))


def test_samples_come_only_from_the_filled_part():
    state = replay.init(100, {"x": jnp.zeros(()), "pair": jnp.zeros(2)})
    state = replay.add(state, _items([1, 2, 3]))
    batch = jax.jit(replay.sample, static_argnums=2)(state, jax.random.PRNGKey(0), 3000)
    assert batch["x"].shape == (3000,) and batch["pair"].shape == (3000, 2)
    values, counts = np.unique(np.asarray(batch["x"]), return_counts=True)
    np.testing.assert_array_equal(values, [1, 2, 3])  # never an empty (zero) slot
    assert counts.min() > 800  # roughly uniform
    np.testing.assert_array_equal(batch["pair"][:, 0], batch["x"])  # leaves stay aligned


def test_keeps_item_dtypes():
    state = replay.init(4, {"obs": jnp.zeros((), jnp.int32), "done": jnp.zeros((), bool)})
    state = replay.add(state, {"obs": jnp.array([3, 1]), "done": jnp.array([True, False])})
    assert state.storage["obs"].dtype == jnp.int32 and state.storage["done"].dtype == jnp.bool_
