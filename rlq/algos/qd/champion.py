"""A champion kept by re-evaluation: the policy a MAP-Elites run ends with when ``algo.champion.candidates`` > 0.

The fittest elite is the maximum of thousands of noisy means (each offspring's fitness is the mean of its few
episodes), so it is partly the luckiest offspring rather than the best policy. Each iteration the ``candidates``
fittest elites of the archive as the iteration finds it (and the mean the ES emitter's candidates are drawn around,
when it runs: the least noisy candidate) are scored again on fresh episodes, as extra rows of the offspring's batch:
each is ``replicas`` rows of ``algo.episodes`` episodes, its fitness their mean (``scoring.score_with_replicas``, as
``algo=es algo.keep=mean`` scores its mean). The candidate whose re-evaluated mean is the highest so far is kept, as
ES keeps its best-scoring mean. The champion's rows never enter the archive and no emitter is told their scores, so
the search runs exactly as without them.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from rlq.algos.qd.archive import Archive
from rlq.algos.qd.scoring import keep_strictly_better


class Champion(struct.PyTreeNode):
    genotype: jax.Array  # (dim,)
    fitness: jax.Array  # its re-evaluated mean fitness; -inf before any candidate was scored


def empty(dim: int) -> Champion:
    """No champion yet: the policy falls back on the fittest elite (``chosen``)."""
    return Champion(jnp.zeros((dim,), jnp.float32), jnp.asarray(-jnp.inf, jnp.float32))


def fittest(archive: Archive, count: int) -> tuple[jax.Array, jax.Array]:
    """The genotypes of the archive's ``count`` fittest cells ``(count, dim)`` and whether each holds an elite
    (an archive with fewer elites gives empty cells too)."""
    _, index = jax.lax.top_k(archive.fitness, count)
    return archive.genotypes[index], archive.filled[index]


def contenders(archive: Archive, count: int, mean: jax.Array | None) -> tuple[jax.Array, jax.Array]:
    """The candidates to score: the archive's ``count`` fittest cells (``fittest``), then the ES emitter's ``mean``
    when it runs (always valid); their genotypes and whether each may win."""
    genotypes, valid = fittest(archive, count)
    if mean is None:
        return genotypes, valid
    return jnp.concatenate([genotypes, mean[None]]), jnp.concatenate([valid, jnp.ones((1,), bool)])


def kept(champion: Champion, genotypes: jax.Array, valid: jax.Array, fitness: jax.Array) -> Champion:
    """The champion after the candidates ``genotypes`` scored ``fitness`` on fresh episodes: a candidate that is not
    ``valid`` (an empty cell) never wins, and only a strictly higher mean replaces the champion."""
    best = keep_strictly_better(champion.genotype, champion.fitness, genotypes, jnp.where(valid, fitness, -jnp.inf))
    return Champion(best.genotype, best.fitness)


def chosen(champion: Champion, elite: jax.Array) -> jax.Array:
    """The genotype a run's policy plays: the champion once one was scored, else ``elite``."""
    return jnp.where(jnp.isfinite(champion.fitness), champion.genotype, elite)
