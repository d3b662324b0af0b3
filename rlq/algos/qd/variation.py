"""Variation operators of MAP-Elites over flat genotypes, clipped to the genotype bounds.

- ``gaussian``: parent + sigma * N(0, I) (the brittle star tutorial's mutation, sigma = 0.1);
- ``iso_line``: Vassiliades & Mouret (2018): x + iso_sigma * N(0, I) + line_sigma * N(0, 1) * (y - x)
  for two elites x, y: isotropic noise plus a step along the line joining two elites.
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


def uniform(key: jax.Array, count: int, low: jax.Array, high: jax.Array) -> jax.Array:
    """``count`` genotypes uniform in the bounds (the first generation, and random search)."""
    return jax.random.uniform(key, (count,) + low.shape, minval=low, maxval=high)
