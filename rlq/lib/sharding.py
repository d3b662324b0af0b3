"""The batch axes a run spreads over devices, and how a program marks its env axis.

The training loop (rlq/run/programs/devices.py) lays the selected devices out as a mesh of two named
axes: ``seed`` (the vmapped seeds; the loop shards it through the programs' input and output
shardings) and ``env`` (within one seed, the batch of independent envs, evaluation episodes or
scored candidates). Programs name their env axis with ``shard_envs`` and ``vmap_envs``; XLA's
partitioner then splits that axis over the ``env`` devices and inserts the collectives the math
needs (a minibatch's gradient is summed across devices), so the numbers are those of one device up
to the order of float sums. Outside a mesh, or with one ``env`` device, both are plain JAX.

Arrays between the mesh and the host, over one process or several (rlq/run/programs/distributed.py): a host
copy of an array that spans processes gathers it from all of them (``to_host``, a collective), and only
process 0 writes the run's files (``is_writer``).
"""

from __future__ import annotations

import contextvars
from collections.abc import Callable
from typing import Any, TypeVar

import jax
import numpy as np
from jax.sharding import PartitionSpec

from rlq.lib.batch import seed_entry

SEED = "seed"
ENV = "env"

F = TypeVar("F", bound=Callable[..., Any])

#: True while tracing the body of ``vmap_envs``: the env axis is taken by the mapped axis
_inside_env_vmap = contextvars.ContextVar("rlq_inside_env_vmap", default=False)


def env_shards() -> int:
    """Devices along the ``env`` axis of the mesh the caller is traced under (1 without one)."""
    mesh = jax.sharding.get_abstract_mesh()
    if mesh.empty or ENV not in mesh.axis_names:
        return 1
    return int(mesh.shape[ENV])


def shard_envs(tree: Any) -> Any:
    """Mark axis 0 of every leaf as a batch of independent envs, to be split over the ``env``
    devices. Leaves whose axis 0 the devices do not divide are left to the partitioner; inside
    ``vmap_envs`` the leaves stay whole and the mapped axis keeps the split."""
    shards = env_shards()
    if shards == 1:
        return tree
    nested = _inside_env_vmap.get()

    def constrain(x: jax.Array) -> jax.Array:
        if nested:
            return jax.lax.with_sharding_constraint(x, PartitionSpec())
        if x.ndim == 0 or x.shape[0] % shards:
            return x
        return jax.lax.with_sharding_constraint(x, PartitionSpec(ENV))

    return jax.tree.map(constrain, tree)


def vmap_envs(fn: F) -> F:
    """``jax.vmap(fn)`` over a batch of independent items (candidates of a population), the
    mapped axis split over the ``env`` devices when they divide it."""

    def body(*args: Any) -> Any:
        token = _inside_env_vmap.set(True)
        try:
            return fn(*args)
        finally:
            _inside_env_vmap.reset(token)

    def batched(*args: Any) -> Any:
        shards = env_shards()
        size = jax.tree.leaves(args)[0].shape[0]
        if shards == 1 or size % shards or _inside_env_vmap.get():
            return jax.vmap(fn)(*args)
        return jax.vmap(body, spmd_axis_name=ENV)(*args)

    return batched  # type: ignore[return-value]


def is_writer() -> bool:
    """Whether this process writes the run's files: process 0 (the only one of a single-process run)."""
    return not jax.distributed.is_initialized() or jax.process_index() == 0


def _global(leaf: Any) -> bool:
    return isinstance(leaf, jax.Array) and not leaf.is_fully_addressable


def gathered(tree: Any) -> Any:
    """``tree`` with every array that spans processes gathered whole onto each host (numpy); the
    others as they are. A collective: every process calls it at the same point of the run."""
    leaves, treedef = jax.tree.flatten(tree)
    spread = [i for i, leaf in enumerate(leaves) if _global(leaf)]
    if not spread:
        return tree
    from jax.experimental import multihost_utils

    whole = multihost_utils.process_allgather([leaves[i] for i in spread], tiled=True)
    for i, value in zip(spread, whole, strict=True):
        leaves[i] = np.asarray(value)
    return jax.tree.unflatten(treedef, leaves)


def to_host(tree: Any) -> Any:
    """``jax.device_get`` for arrays of any process (``gathered`` first: a collective)."""
    return jax.device_get(gathered(tree))


def to_mesh(tree: Any, sharding: jax.sharding.Sharding) -> Any:
    """``jax.device_put(tree, sharding)``; across processes each process places its share of the same host values."""
    if sharding.is_fully_addressable:
        return jax.device_put(tree, sharding)
    return jax.device_put(jax.device_get(tree), sharding)


def first_seed(tree: Any, num_seeds: int) -> Any:
    """``seed_entry(tree, 0, num_seeds)``, read where seed 0 lives: on process 0's devices (the seed
    axis is laid over the processes in order), so process 0 alone takes it, without a collective."""

    def first(leaf: Any) -> Any:
        if not _global(leaf):
            return seed_entry(leaf, 0, num_seeds)
        for shard in leaf.addressable_shards:
            if not shard.index or not shard.index[0].start:
                return shard.data[0]
        raise ValueError("seed 0 lives on another process")

    return jax.tree.map(first, tree)
