"""Variation operators of MAP-Elites over flat genotypes, clipped to the genotype bounds.

- ``gaussian``: parent + sigma * N(0, I) (the brittle star tutorial's mutation, sigma = 0.1);
- ``iso_line``: Vassiliades & Mouret (2018): x + iso_sigma * N(0, I) + line_sigma * N(0, 1) * (y - x)
  for two elites x, y: isotropic noise plus a step along the line joining two elites;
- ``turned`` (``emitter=rotation``): the parent's gait turned by a random whole number of arms (a
  symmetry of the body, given as index permutations of the genotype), then ``gaussian``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

VARIATIONS = ("gaussian", "iso_line")


def gaussian(key: jax.Array, parents: jax.Array, sigma: float, low: jax.Array, high: jax.Array) -> jax.Array:
    return jnp.clip(parents + sigma * jax.random.normal(key, parents.shape), low, high)


def iso_line(
    key: jax.Array,
    parents: jax.Array,
    partners: jax.Array,
    iso_sigma: float,
    line_sigma: float,
    low: jax.Array,
    high: jax.Array,
) -> jax.Array:
    iso_key, line_key = jax.random.split(key)
    iso = iso_sigma * jax.random.normal(iso_key, parents.shape)
    line = line_sigma * jax.random.normal(line_key, parents.shape[:1] + (1,)) * (partners - parents)
    return jnp.clip(parents + iso + line, low, high)


def turned(
    key: jax.Array, parents: jax.Array, rotations: jax.Array, sigma: float, low: jax.Array, high: jax.Array
) -> jax.Array:
    """Each parent permuted by a row of ``rotations`` ``(k, dim)`` other than row 0 (the identity),
    drawn uniformly, then mutated by ``gaussian``."""
    turn_key, noise_key = jax.random.split(key)
    turns = jax.random.randint(turn_key, parents.shape[:1], 1, rotations.shape[0])
    return gaussian(noise_key, jnp.take_along_axis(parents, rotations[turns], axis=1), sigma, low, high)


def uniform(key: jax.Array, count: int, low: jax.Array, high: jax.Array) -> jax.Array:
    """``count`` genotypes uniform in the bounds (the first generation, and random search)."""
    return jax.random.uniform(key, (count,) + low.shape, minval=low, maxval=high)
