"""The project's one replay buffer: a fixed-capacity ring over any pytree of items, pure and jittable.

Items are written at ``position`` and wrap around, so the filled part is always the index range
``[0, size)``; sampling draws uniformly (with replacement) from it.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct


class ReplayState(struct.PyTreeNode):
    """``storage`` has the item structure with a leading ``capacity`` axis on every leaf."""

    storage: Any
    position: jax.Array  # next index written
    size: jax.Array  # number of filled slots (<= capacity)

    @property
    def capacity(self) -> int:
        return jax.tree.leaves(self.storage)[0].shape[0]


def init(capacity: int, example_item: Any) -> ReplayState:
    """An empty buffer of ``capacity`` items shaped and typed like ``example_item`` (no batch axis)."""
    storage = jax.tree.map(lambda x: jnp.zeros((capacity,) + jnp.shape(x), jnp.asarray(x).dtype), example_item)
    return ReplayState(storage, jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32))


def add(state: ReplayState, batch: Any) -> ReplayState:
    """Write a batch of items (leading axis B <= capacity), overwriting the oldest once full."""
    capacity = state.capacity
    count = jax.tree.leaves(batch)[0].shape[0]
    if count > capacity:
        raise ValueError(f"cannot add {count} items at once to a replay buffer of capacity {capacity}")
    index = (state.position + jnp.arange(count)) % capacity
    storage = jax.tree.map(lambda s, b: s.at[index].set(b.astype(s.dtype)), state.storage, batch)
    return ReplayState(storage, (state.position + count) % capacity, jnp.minimum(state.size + count, capacity))


def sample(state: ReplayState, key: jax.Array, batch_size: int) -> Any:
    """``batch_size`` items drawn uniformly with replacement from the filled part.

    An empty buffer yields slot 0 (zeros); callers gate learning on a minimum size.
    """
    index = jax.random.randint(key, (batch_size,), 0, jnp.maximum(state.size, 1))
    return jax.tree.map(lambda s: s[index], state.storage)
