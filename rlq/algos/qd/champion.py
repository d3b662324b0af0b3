"""A champion kept by re-evaluation: the policy a MAP-Elites run ends with when ``algo.champion.candidates`` > 0.

The fittest elite is the maximum of thousands of noisy means (each offspring's fitness is the mean of its few
episodes), so it is partly the luckiest offspring rather than the best policy. Each iteration the ``candidates``
fittest elites (and the ES emitter's mean, when it runs: the least noisy candidate) are scored again on
``episodes`` fresh episodes, and the candidate whose re-evaluated mean is the highest so far is kept, as
``algo=es algo.keep=mean`` keeps its best-scoring mean (``keep_best``). The champion never enters the archive and
no emitter is told its scores, so the search runs exactly as without it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from rlq.algos.qd.archive import Archive
from rlq.algos.qd.scoring import ScoringFn, keep_best


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


def rescored(
    champion: Champion,
    genotypes: jax.Array,
    valid: jax.Array,
    score: ScoringFn,
    key: jax.Array,
    env_steps: jax.Array,
) -> tuple[Champion, jax.Array]:
    """The champion after scoring ``genotypes`` on fresh episodes (``score``'s); a candidate that is not ``valid``
    (an empty cell) never wins, and only a strictly higher mean replaces the champion. ``env_steps`` counts on
    every episode played."""
    fitness, _, extras = score(genotypes, key)
    fitness = jnp.where(valid, fitness, -jnp.inf)
    best, best_fitness, env_steps, _ = keep_best(
        genotypes, fitness, extras, champion.genotype, champion.fitness, env_steps
    )
    return Champion(best, best_fitness), env_steps


def chosen(champion: Champion, elite: jax.Array) -> jax.Array:
    """The genotype a run's policy plays: the champion once one was scored, else ``elite``."""
    return jnp.where(jnp.isfinite(champion.fitness), champion.genotype, elite)
