"""Orthogonal weight init without LAPACK.

flax's ``orthogonal`` initializer calls ``jnp.linalg.qr``. On CPU, a QR batched by
``vmap(init)`` over seeds runs LAPACK kernels that split the batch over XLA's intra-op thread
pool and block waiting for it; two such kernels running at once on a 2-core machine occupy both
pool threads and wait forever (seen as a hang of ``rlq train num_seeds=8``). This initializer
computes the same matrix with Gram-Schmidt in plain jnp: the Q factor of a Gaussian matrix with
a positive diagonal of R, which is what flax returns after its sign correction (Haar-distributed).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp


def orthonormal_columns(a: jax.Array) -> jax.Array:
    """The Q of a = QR (R with a positive diagonal) for a tall or square ``a`` of shape (n, k).

    Classical Gram-Schmidt with one re-orthogonalisation pass ("twice is enough"), column by
    column; columns not yet processed are masked out of the projections.
    """
    n, k = a.shape
    if n < k:
        raise ValueError(f"orthonormal_columns needs rows >= columns, got {a.shape}")

    def column(i: jax.Array, q: jax.Array) -> jax.Array:
        done = (jnp.arange(k) < i).astype(q.dtype)
        v = q[:, i]
        for _ in range(2):
            v = v - q @ ((q.T @ v) * done)
        return q.at[:, i].set(v / jnp.linalg.norm(v))

    return jax.lax.fori_loop(0, k, column, a)


def orthogonal(scale: float = 1.0):
    """A flax-style kernel initializer: ``scale`` × a random (semi-)orthogonal matrix.

    The last axis holds the outputs; the other axes are flattened into the inputs.
    """

    def init(key: jax.Array, shape: tuple[int, ...], dtype=jnp.float32) -> jax.Array:
        if len(shape) < 2:
            raise ValueError(f"orthogonal init needs at least 2 dimensions, got shape {shape}")
        n_cols = shape[-1]
        n_rows = math.prod(shape) // n_cols
        tall = n_rows >= n_cols
        matrix_shape = (n_rows, n_cols) if tall else (n_cols, n_rows)
        q = orthonormal_columns(jax.random.normal(key, matrix_shape, jnp.float32))
        q = q if tall else q.T
        return (scale * q).reshape(shape).astype(dtype)

    return init
