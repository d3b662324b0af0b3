"""Epochs of shuffled minibatches over an update's data: the learner loop of PPO and PQN.

Two samplings of the minibatches (config key ``algo.minibatch_shuffle``), the same on one device:
``global`` shuffles all items with one permutation, so with the env axis split over devices every
minibatch gathers from all of them; ``per_shard`` (brax's: each device shuffles its own share and
the gradients are averaged) shuffles each shard's items within the shard and makes minibatch k of
every shard's k-th slice, so the gather stays on each device.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from jax.sharding import PartitionSpec

from rlq.errors import ConfigError
from rlq.lib.learning.declared import MINIBATCH_SHUFFLES
from rlq.lib.sharding import ENV, env_shards

#: (carry, minibatch, key) -> (carry, metrics)
MinibatchStep = Callable[[Any, Any, jax.Array], tuple[Any, Any]]


def shuffle_shards(shuffle: str) -> int:
    """How many shards the items are shuffled within, under the mesh the caller is traced in: the
    ``env`` devices for ``per_shard``, 1 (one permutation of all items) for ``global``."""
    if shuffle not in MINIBATCH_SHUFFLES:
        raise ConfigError(f"algo.minibatch_shuffle must be one of {', '.join(MINIBATCH_SHUFFLES)}, got {shuffle!r}")
    return env_shards() if shuffle == "per_shard" else 1


def shard_problem(shuffle: str, items: int, shards: int, num_minibatches: int) -> str | None:
    """Why ``items`` learning items cannot be cut per shard over ``shards`` env devices (None: they can)."""
    if shuffle != "per_shard" or shards == 1 or (items % shards == 0 and (items // shards) % num_minibatches == 0):
        return None
    return (
        f"algo.minibatch_shuffle=per_shard cuts each of the {shards} env devices' share of the update's {items} "
        f"learning items into algo.num_minibatches={num_minibatches} parts, which does not divide it; "
        "set algo.minibatch_shuffle=global or another algo.num_minibatches"
    )


def flat_items(x: jax.Array, env_major: bool = False) -> jax.Array:
    """(steps, envs, ...) -> (steps * envs, ...): step-major as a rollout stacks them; ``env_major`` (per-shard
    minibatches): each env's steps together, so every env device's share is one contiguous block."""
    if env_major:
        x = jnp.moveaxis(x, 1, 0)
    return x.reshape((x.shape[0] * x.shape[1],) + x.shape[2:])


def epoch_order(key: jax.Array, num_items: int, shards: int) -> jax.Array:
    """(shards, num_items / shards): one permutation of each shard's own item indices (one key per
    shard); with one shard the permutation of all items."""
    if shards == 1:
        return jax.random.permutation(key, num_items)[None]
    if num_items % shards:
        raise ConfigError(f"{num_items} learning items do not split evenly over {shards} env shards")
    return jax.vmap(lambda k: jax.random.permutation(k, num_items // shards))(jax.random.split(key, shards))


def cut_minibatches(x: jax.Array, order: jax.Array, num_minibatches: int) -> jax.Array:
    """``x`` (items, ...) in ``order`` (``epoch_order``), cut into (num_minibatches, items / num_minibatches, ...).

    With several shards, ``x``'s items are the shards' shares one after another (env-major, as the
    devices hold them) and minibatch k is the concatenation of every shard's k-th slice of its own
    shuffled share."""
    shards, per_shard = order.shape
    if shards == 1:
        return x[order[0]].reshape((num_minibatches, per_shard // num_minibatches) + x.shape[1:])
    if per_shard % num_minibatches:
        raise ConfigError(
            f"per-shard minibatches: num_minibatches={num_minibatches} must divide each env shard's "
            f"{per_shard} learning items; use algo.minibatch_shuffle=global or another num_minibatches"
        )
    size = per_shard // num_minibatches
    shares = _split_axis(x.reshape((shards, per_shard) + x.shape[1:]), 0)
    own = jax.vmap(lambda share, perm: share[perm])(shares, order)
    own = own.reshape((shards, num_minibatches, size) + x.shape[1:]).swapaxes(0, 1)
    own = _split_axis(own, 1)
    return own.reshape((num_minibatches, shards * size) + x.shape[1:])


def _split_axis(x: jax.Array, axis: int) -> jax.Array:
    """Keep ``axis`` split over the ``env`` devices (a no-op outside a mesh with several)."""
    if env_shards() == 1:
        return x
    spec = PartitionSpec(*([None] * axis), ENV)
    return jax.lax.with_sharding_constraint(x, spec)


def minibatch_epochs(
    step: MinibatchStep,
    carry: Any,
    data: Any,
    key: jax.Array,
    epochs: int,
    num_minibatches: int,
    shards: int = 1,
) -> tuple[Any, Any]:
    """``epochs`` passes over ``data`` (a pytree of arrays with one leading item axis), each shuffled
    and cut into ``num_minibatches`` equal minibatches that ``step`` takes in turn with a key of its
    own. With ``shards`` > 1 the items are that many shards' shares one after another, each shuffled
    within itself (``cut_minibatches``). Returns the final carry and the metrics stacked as
    (epochs, num_minibatches)."""
    num_items = len(jax.tree.leaves(data)[0])

    def epoch(carry, epoch_key):
        order = epoch_order(epoch_key, num_items, shards)
        minibatches = jax.tree.map(lambda x: cut_minibatches(x, order, num_minibatches), data)
        keys = jax.random.split(jax.random.fold_in(epoch_key, 1), num_minibatches)
        return jax.lax.scan(lambda c, xs: step(c, *xs), carry, (minibatches, keys))

    return jax.lax.scan(epoch, carry, jax.random.split(key, epochs))
