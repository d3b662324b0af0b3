"""A MAP-Elites archive as a pytree, with a batched insertion and the usual QD metrics.

The cells are a static description: a ``Grid`` (cells per descriptor dimension and the descriptor
bounds) or a ``Cvt`` (centroids of a Voronoi tessellation, rlq/algos/qd/cvt.py). The archive holds
one elite per cell: genotype, fitness (``-inf`` where empty), descriptor and a ``filled`` mask. Grid
cell ``(i, j, ...)`` is stored at the row-major flat index, so for two descriptors ``i`` is the x bin
and ``j`` the y bin; CVT cell ``k`` is centroid ``k``.

Insertion of a batch equals inserting its offspring one by one in batch order with the rule
"an elite is replaced only by a strictly better one": in each cell the best offspring of the
batch competes (the first of equals), and it enters only if it beats the cell's elite.
Descriptors outside the bounds fall into the border cells; offspring with a non-finite fitness
or descriptor are never inserted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from rlq.algos.qd.cvt import Cvt


@dataclass(frozen=True)
class Grid:
    """Cells per descriptor dimension and the descriptor bounds they cover."""

    shape: tuple[int, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]

    def __post_init__(self) -> None:
        if not (len(self.shape) == len(self.low) == len(self.high)) or not self.shape:
            raise ValueError(
                f"archive shape, low and high need one entry per descriptor, got {list(self.shape)}, "
                f"{list(self.low)}, {list(self.high)}"
            )
        if any(int(n) < 1 for n in self.shape):
            raise ValueError(f"archive shape entries must be >= 1, got {list(self.shape)}")
        if any(not lo < hi for lo, hi in zip(self.low, self.high, strict=True)):
            raise ValueError(
                f"archive low must be below high in every dimension, got {list(self.low)}, {list(self.high)}"
            )

    @property
    def num_cells(self) -> int:
        return math.prod(self.shape)

    @property
    def num_descriptors(self) -> int:
        return len(self.shape)

    def cell_index(self, descriptors: jax.Array) -> jax.Array:
        """Row-major flat cell index of each descriptor ``(..., d) -> (...)``."""
        coords = cell_coordinates(self, descriptors)
        strides = np.cumprod((1,) + tuple(self.shape[::-1]))[:-1][::-1]
        return jnp.sum(coords * jnp.asarray(strides, jnp.int32), axis=-1)


#: the cells of an archive: a regular grid or a CVT
Cells = Grid | Cvt


class Archive(struct.PyTreeNode):
    genotypes: jax.Array  # (cells, genotype dim)
    fitness: jax.Array  # (cells,), -inf where empty
    descriptors: jax.Array  # (cells, descriptor dim)
    filled: jax.Array  # (cells,) bool


def empty(grid: Cells, genotype_dim: int) -> Archive:
    cells = grid.num_cells
    return Archive(
        genotypes=jnp.zeros((cells, genotype_dim), jnp.float32),
        fitness=jnp.full((cells,), -jnp.inf, jnp.float32),
        descriptors=jnp.zeros((cells, grid.num_descriptors), jnp.float32),
        filled=jnp.zeros((cells,), bool),
    )


def cell_coordinates(grid: Grid, descriptors: jax.Array) -> jax.Array:
    """Per-dimension bin of each descriptor ``(..., d) -> (..., d)``, clipped into the grid."""
    low, high = jnp.asarray(grid.low, jnp.float32), jnp.asarray(grid.high, jnp.float32)
    bins = jnp.asarray(grid.shape, jnp.int32)
    frac = (jnp.asarray(descriptors, jnp.float32) - low) / (high - low)
    finite = jnp.where(jnp.isfinite(frac), frac, 0.0)
    return jnp.clip(jnp.floor(finite * bins).astype(jnp.int32), 0, bins - 1)


def cell_index(grid: Cells, descriptors: jax.Array) -> jax.Array:
    """Flat cell index of each descriptor ``(..., d) -> (...)``: row-major on a grid, the nearest centroid on a CVT."""
    return grid.cell_index(descriptors)


def insert(archive: Archive, grid: Cells, genotypes: jax.Array, fitness: jax.Array, descriptors: jax.Array) -> Archive:
    """Add a batch of offspring ``(n, dim)``, ``(n,)``, ``(n, d)``; see the module docstring."""
    n, cells = fitness.shape[0], grid.num_cells
    fitness = jnp.asarray(fitness, jnp.float32)
    valid = jnp.isfinite(fitness) & jnp.all(jnp.isfinite(descriptors), axis=-1)
    score = jnp.where(valid, fitness, -jnp.inf)
    idx = cell_index(grid, descriptors)
    best = jax.ops.segment_max(score, idx, num_segments=cells)
    is_best = valid & (score == best[idx])
    winner = jax.ops.segment_min(jnp.where(is_best, jnp.arange(n), n), idx, num_segments=cells)
    has_winner = winner < n
    improves = has_winner & (best > archive.fitness)
    take = jnp.minimum(winner, n - 1)
    return Archive(
        genotypes=jnp.where(improves[:, None], genotypes[take], archive.genotypes),
        fitness=jnp.where(improves, best, archive.fitness),
        descriptors=jnp.where(improves[:, None], jnp.asarray(descriptors, jnp.float32)[take], archive.descriptors),
        filled=archive.filled | improves,
    )


def select(archive: Archive, key: jax.Array, count: int) -> jax.Array:
    """Genotypes of ``count`` elites drawn uniformly (with replacement) from the filled cells.

    One integer draw per parent, mapped through the filled cells' indices (a categorical draw over
    all cells costs ``count`` x cells Gumbel samples). With an empty archive every draw is cell 0
    (zeros): callers replace those."""
    filled = archive.filled.reshape(-1)
    (indices,) = jnp.nonzero(filled, size=filled.shape[0], fill_value=0)
    rank = jax.random.randint(key, (count,), 0, jnp.maximum(jnp.sum(filled), 1))
    return archive.genotypes[indices[rank]]


#: metric names as QD users know them from the tutorial's W&B runs
METRIC_NAMES = (
    "archive-occupancy",
    "qd-score",
    "minimum-fitness",
    "average-fitness",
    "maximum-fitness",
    "furthest-distance-travelled",
)


def metrics(archive: Archive, qd_offset: float = 0.0) -> dict[str, jax.Array]:
    """Occupancy (fraction of cells filled), QD score (sum over elites of fitness + ``qd_offset``),
    min/mean/max elite fitness (NaN while empty) and the largest descriptor norm of an elite."""
    filled = archive.filled
    count = filled.sum()
    nan_if_empty = jnp.where(count > 0, 0.0, jnp.nan)
    fit = archive.fitness
    norms = jnp.linalg.norm(archive.descriptors, axis=-1)
    return {
        "archive-occupancy": count / filled.shape[0],
        "qd-score": jnp.sum(jnp.where(filled, fit + qd_offset, 0.0)),
        "minimum-fitness": jnp.min(jnp.where(filled, fit, jnp.inf)) + nan_if_empty,
        "average-fitness": jnp.sum(jnp.where(filled, fit, 0.0)) / jnp.maximum(count, 1) + nan_if_empty,
        "maximum-fitness": jnp.max(fit) + nan_if_empty,
        "furthest-distance-travelled": jnp.max(jnp.where(filled, norms, 0.0)) + nan_if_empty,
    }


def best_cell(archive: Archive) -> jax.Array:
    """Flat index of the fittest elite."""
    return jnp.argmax(archive.fitness)


def furthest_cell(archive: Archive) -> jax.Array:
    """Flat index of the elite whose descriptor has the largest norm (e.g. travelled furthest)."""
    norms = jnp.linalg.norm(archive.descriptors, axis=-1)
    return jnp.argmax(jnp.where(archive.filled, norms, -1.0))


def chosen_cell(archive: Archive, grid: Cells, spec: str) -> int:
    """The flat index of the elite named by ``spec``: ``best`` (fittest), ``furthest`` (largest
    descriptor norm), grid coordinates ``i,j`` (x bin, y bin) or a CVT cell's index ``k``.
    ValueError for a bad or empty cell."""
    if not bool(np.any(np.asarray(archive.filled))):
        raise ValueError("the archive is empty")
    if spec == "best":
        return int(best_cell(archive))
    if spec == "furthest":
        return int(furthest_cell(archive))
    if isinstance(grid, Cvt):
        return _chosen_centroid(archive, grid, spec)
    try:
        coords = tuple(int(part) for part in spec.split(","))
    except ValueError:
        raise ValueError(f"cell must be best, furthest or grid coordinates like 15,15; got {spec!r}") from None
    if len(coords) != len(grid.shape) or any(not 0 <= c < n for c, n in zip(coords, grid.shape, strict=True)):
        bounds = ", ".join(f"0..{n - 1}" for n in grid.shape)
        raise ValueError(f"cell {spec} is outside the archive's grid ({bounds})")
    index = int(np.ravel_multi_index(coords, grid.shape))
    if not bool(np.asarray(archive.filled)[index]):
        raise ValueError(f"cell {spec} holds no elite")
    return index


def _chosen_centroid(archive: Archive, cvt: Cvt, spec: str) -> int:
    if not spec.isdigit():
        raise ValueError(f"cell must be best, furthest or a CVT cell index like 17; got {spec!r}")
    index = int(spec)
    if index >= cvt.num_cells:
        raise ValueError(f"cell {spec} is outside the archive's CVT cells (0..{cvt.num_cells - 1})")
    if not bool(np.asarray(archive.filled)[index]):
        raise ValueError(f"cell {spec} holds no elite")
    return index
