"""A centroidal Voronoi tessellation (CVT) of the descriptor space: the cells of a CVT-MAP-Elites
archive (Vassiliades et al. 2018), an alternative to the regular grid when the number of cells
should not grow as (bins per dimension) ** dimensions.

The centroids are k-means centroids of ``samples`` points drawn uniformly in the bounds. They are
computed on the host with numpy from ``seed`` alone (float64, a fixed number of Lloyd iterations
at most), so every run seed, ``rlq resume``, ``eval`` and ``render`` see the same cells and
archives of different seeds compare cell by cell. A descriptor's cell is its nearest centroid.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

#: Lloyd iterations at most (they stop earlier once no sample changes cell); the cells are even enough for
#: QD long before k-means converges fully, which takes tens of seconds on a CPU for 50,000 samples
MAX_ITERATIONS = 20
#: samples assigned at a time (bounds the host memory of the distance matrix)
CHUNK = 4096


@dataclass(frozen=True)
class Cvt:
    """``cells`` centroids over the box ``[low, high]``, from ``samples`` uniform points drawn with ``seed``."""

    cells: int
    low: tuple[float, ...]
    high: tuple[float, ...]
    samples: int
    seed: int = 0

    def __post_init__(self) -> None:
        if len(self.low) != len(self.high) or not self.low:
            raise ValueError(
                f"archive low and high need one entry per descriptor, got {list(self.low)}, {list(self.high)}"
            )
        if any(not lo < hi for lo, hi in zip(self.low, self.high, strict=True)):
            raise ValueError(
                f"archive low must be below high in every dimension, got {list(self.low)}, {list(self.high)}"
            )
        if self.cells < 1:
            raise ValueError(f"algo.archive.cells must be >= 1, got {self.cells}")
        if self.samples < self.cells:
            raise ValueError(
                f"algo.archive.cvt_samples={self.samples} is below algo.archive.cells={self.cells}: k-means needs "
                f"at least one sample per cell (e.g. algo.archive.cvt_samples={50 * self.cells})"
            )

    @property
    def num_cells(self) -> int:
        return self.cells

    @property
    def num_descriptors(self) -> int:
        return len(self.low)

    @functools.cached_property
    def centroids(self) -> np.ndarray:
        """``(cells, descriptors)`` float32, computed once per ``Cvt`` (the first use)."""
        return kmeans_centroids(self.cells, np.asarray(self.low), np.asarray(self.high), self.samples, self.seed)

    def cell_index(self, descriptors: jax.Array) -> jax.Array:
        """Index of the nearest centroid of each descriptor ``(..., d) -> (...)`` (cell 0 for non-finite ones)."""
        return nearest(jnp.asarray(self.centroids), descriptors)


def nearest(centroids: jax.Array, descriptors: jax.Array) -> jax.Array:
    """Index of the nearest of ``centroids (c, d)`` to each descriptor ``(..., d)``; 0 where not finite."""
    points = jnp.asarray(descriptors, jnp.float32)
    finite = jnp.all(jnp.isfinite(points), axis=-1, keepdims=True)
    points = jnp.where(finite, points, centroids[0])
    distances = jnp.sum(jnp.square(points[..., None, :] - centroids), axis=-1)
    return jnp.argmin(distances, axis=-1).astype(jnp.int32)


def _assign(points: np.ndarray, centroids: np.ndarray) -> np.ndarray:
    squared = np.sum(centroids**2, axis=1)
    parts = [
        np.argmin(squared - 2.0 * points[i : i + CHUNK] @ centroids.T, axis=1) for i in range(0, len(points), CHUNK)
    ]
    return np.concatenate(parts)


def kmeans_centroids(cells: int, low: np.ndarray, high: np.ndarray, samples: int, seed: int) -> np.ndarray:
    """Lloyd's k-means on ``samples`` uniform points in ``[low, high]``, started from the first ``cells``
    of them; a cell that loses all its points keeps its centroid."""
    rng = np.random.default_rng(seed)
    points = rng.uniform(low, high, size=(samples, len(low)))
    centroids = points[:cells].copy()
    labels = _assign(points, centroids)
    for _ in range(MAX_ITERATIONS):
        counts = np.bincount(labels, minlength=cells)
        sums = np.stack([np.bincount(labels, points[:, k], cells) for k in range(points.shape[1])], axis=1)
        centroids = np.where(counts[:, None] > 0, sums / np.maximum(counts, 1)[:, None], centroids)
        new = _assign(points, centroids)
        if np.array_equal(new, labels):
            break
        labels = new
    return centroids.astype(np.float32)
