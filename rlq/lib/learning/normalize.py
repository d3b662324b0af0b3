"""Running observation statistics (parallel Welford) for input normalisation."""

from __future__ import annotations

from collections.abc import Mapping

import jax
import jax.numpy as jnp
from flax import struct


class RunningStats(struct.PyTreeNode):
    """Mean and summed squared deviations of everything seen so far; ``count`` in float32."""

    mean: jax.Array
    m2: jax.Array
    count: jax.Array


def init(shape: tuple[int, ...]) -> RunningStats:
    zeros = jnp.zeros(shape, jnp.float32)
    return RunningStats(mean=zeros, m2=zeros, count=jnp.zeros((), jnp.float32))


def update(stats: RunningStats, batch: jax.Array) -> RunningStats:
    """Fold a batch (any leading axes over ``stats.mean.shape``) in with Chan et al.'s merge."""
    batch = batch.reshape((-1,) + stats.mean.shape).astype(jnp.float32)
    n_b = jnp.float32(batch.shape[0])
    mean_b = batch.mean(axis=0)
    m2_b = jnp.sum(jnp.square(batch - mean_b), axis=0)
    count = stats.count + n_b
    delta = mean_b - stats.mean
    mean = stats.mean + delta * (n_b / count)
    m2 = stats.m2 + m2_b + jnp.square(delta) * (stats.count * n_b / count)
    return RunningStats(mean=mean, m2=m2, count=count)


def update_from_sums(
    stats: RunningStats,
    count: jax.Array,
    total: jax.Array,
    total_sq: jax.Array,
    ref: jax.Array | None = None,
) -> RunningStats:
    """Fold in observations given only by their count, sum and summed squares (a rollout's running
    totals): the same merge as ``update``, whose batch moments these are. With ``ref`` the totals are of
    ``x - ref`` (``rlq.lib.rollout.evaluate(obs_ref=...)``): the batch's spread is then read from well-scaled
    sums, and a component equal to ``ref`` throughout keeps its exact value as mean with no spread."""
    n_b = jnp.asarray(count, jnp.float32)
    shifted_mean = total / jnp.maximum(n_b, 1.0)
    mean_b = shifted_mean if ref is None else ref + shifted_mean
    m2_b = jnp.maximum(total_sq - total * shifted_mean, 0.0)
    count_all = stats.count + n_b
    delta = mean_b - stats.mean
    share = jnp.where(count_all > 0, n_b / jnp.maximum(count_all, 1.0), 0.0)
    mean = stats.mean + delta * share
    m2 = stats.m2 + m2_b + jnp.square(delta) * stats.count * share
    return RunningStats(mean=mean, m2=m2, count=count_all)


def std(stats: RunningStats, eps: float = 0.0) -> jax.Array:
    """Population standard deviation, clipped to [1e-6, 1e6] as in brax; 1 before any data."""
    var = jnp.maximum(stats.m2, 0.0) / jnp.maximum(stats.count, 1.0) + eps
    return jnp.where(stats.count > 0, jnp.clip(jnp.sqrt(var), 1e-6, 1e6), 1.0)


def normalize(stats: RunningStats, x: jax.Array) -> jax.Array:
    return (x - stats.mean) / std(stats)


def normalize_flat(stats: RunningStats, x: jax.Array) -> jax.Array:
    """``x`` of any shape normalised by statistics kept over its flattened components (a linear policy's input)."""
    return normalize(stats, x.reshape(-1)).reshape(x.shape)


def update_from_moments(
    stats: RunningStats, moments: Mapping[str, jax.Array], ref: jax.Array | None = None
) -> RunningStats:
    """Fold in a rollout's observation moments (``rlq.lib.rollout.evaluate(obs_moments=True)``'s ``obs_count``,
    ``obs_sum`` and ``obs_sq_sum``), summed over every axis before the observation's; ``ref``: the ``obs_ref``
    they were summed about."""
    total, total_sq = moments["obs_sum"], moments["obs_sq_sum"]
    leading = tuple(range(total.ndim - 1))
    return update_from_sums(stats, moments["obs_count"].sum(), total.sum(axis=leading), total_sq.sum(axis=leading), ref)
