"""Epochs of shuffled minibatches over an update's data: the learner loop of PPO and PQN."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax

#: (carry, minibatch, key) -> (carry, metrics)
MinibatchStep = Callable[[Any, Any, jax.Array], tuple[Any, Any]]


def minibatch_epochs(
    step: MinibatchStep, carry: Any, data: Any, key: jax.Array, epochs: int, num_minibatches: int
) -> tuple[Any, Any]:
    """``epochs`` passes over ``data`` (a pytree of arrays with one leading item axis), each shuffled
    and cut into ``num_minibatches`` equal minibatches that ``step`` takes in turn with a key of its
    own. Returns the final carry and the metrics stacked as (epochs, num_minibatches)."""
    num_items = len(jax.tree.leaves(data)[0])
    size = num_items // num_minibatches

    def epoch(carry, epoch_key):
        perm = jax.random.permutation(epoch_key, num_items)
        minibatches = jax.tree.map(lambda x: x[perm].reshape((num_minibatches, size) + x.shape[1:]), data)
        keys = jax.random.split(jax.random.fold_in(epoch_key, 1), num_minibatches)
        return jax.lax.scan(lambda c, xs: step(c, *xs), carry, (minibatches, keys))

    return jax.lax.scan(epoch, carry, jax.random.split(key, epochs))
