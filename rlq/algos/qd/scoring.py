"""QDax-style black-box evaluation of a batch of flat parameter vectors with full episodes.

    keyed_scoring_fn(params_batch, keys) -> (fitness, descriptors, extras), one key per candidate
    scoring_fn(params_batch, key) -> the same, one key for the batch (``with_one_key``)
    score_with_replicas(keyed_scoring_fn, rows, keys, genotypes, replicas, key) -> Scored: rows and genotypes
        re-scored on fresh episodes (MAP-Elites' champion, ES's mean), in one call

Shared by random search, ES and MAP-Elites: each candidate plays ``num_episodes`` episodes (vmap
over population x episodes, through ``rlq.lib.rollout.evaluate``; the population is split over
the mesh's env devices, rlq.lib.sharding); fitness is the mean over episodes
of a named measure (``rlq.algos.qd.measures``: the return by default), descriptors the mean of an
``info`` entry at each episode's end.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from rlq.algos.qd.measures import FITNESS
from rlq.lib.env_api import Env
from rlq.lib.rollout import evaluate
from rlq.lib.sharding import vmap_envs

#: (params pytree, one obs, key) -> one action
ApplyFn = Callable[[Any, jax.Array, jax.Array], jax.Array]
ScoringFn = Callable[[jax.Array, jax.Array], tuple[jax.Array, jax.Array, dict[str, jax.Array]]]
#: as ``ScoringFn``, given one key per candidate ``(population, ...)``
KeyedScoringFn = ScoringFn


#: extras of a scoring function that total the whole batch rather than give one value per row
BATCH_TOTALS = ("env_steps", "obs_count", "obs_sum", "obs_sq_sum")


def make_keyed_scoring_fn(
    env: Env,
    apply_fn: ApplyFn,
    num_episodes: int,
    unravel: Callable[[jax.Array], Any] | None = None,
    descriptor_key: str | None = "descriptor",
    max_steps: int | None = None,
    fitness: str = "return",
    descriptor_dims: tuple[int, ...] | None = None,
    obs_ref: jax.Array | None = None,
) -> KeyedScoringFn:
    """A scoring function over ``(population, dim)`` parameter vectors, each played on its own key of
    ``(population, ...)`` keys: candidates appended to a batch leave the others' episodes as they were
    (``with_one_key`` takes one key for the batch instead).

    ``unravel`` (from ``jax.flatten_util.ravel_pytree``) turns one vector into the pytree
    ``apply_fn`` takes; without it ``apply_fn`` gets the vector itself. ``env`` must auto-reset
    and carry episode statistics (``make_env`` does both). Descriptors are the per-candidate mean
    of ``info[descriptor_key]`` at each episode's end, shape ``(population, 0)`` when the env has
    no such key (or ``descriptor_key`` is None); ``descriptor_dims`` keeps those components.
    ``fitness`` names a measure of ``rlq.algos.qd.measures.FITNESS``. ``extras["env_steps"]`` counts
    the transitions of the scored episodes; with ``obs_ref`` the extras also hold the count, sum and summed
    squares about ``obs_ref`` of every observation acted on in the batch (``BATCH_TOTALS``: running observation
    statistics, ``rlq.lib.rollout.evaluate``).
    """
    measure = FITNESS[fitness]
    unravel = unravel or (lambda flat: flat)

    def score_one(flat: jax.Array, key: jax.Array) -> dict[str, jax.Array]:
        params = unravel(flat)
        return evaluate(
            env,
            lambda obs, k: apply_fn(params, obs, k),
            key,
            num_episodes,
            max_steps,
            obs_moments=obs_ref is not None,
            obs_ref=obs_ref,
        )

    def scoring_fn(params_batch: jax.Array, keys: jax.Array):
        population = params_batch.shape[0]
        record = vmap_envs(score_one)(params_batch, keys)
        returns = record["episode_return"]
        fitness_ = measure(record).mean(axis=1)
        if descriptor_key is not None and descriptor_key in record:
            descriptors = record[descriptor_key].reshape(population, num_episodes, -1).mean(axis=1)
            if descriptor_dims is not None:
                descriptors = descriptors[:, jnp.asarray(descriptor_dims, jnp.int32)]
        else:
            descriptors = jnp.zeros((population, 0), jnp.float32)
        extras = {
            "episode_return": returns,
            "episode_length": record["episode_length"],
            "finished": record["finished"],
            "env_steps": record["episode_length"].sum(),
        }
        if obs_ref is not None:
            extras.update(
                obs_count=record["obs_count"].sum(),
                obs_sum=record["obs_sum"].sum(axis=(0, 1)),
                obs_sq_sum=record["obs_sq_sum"].sum(axis=(0, 1)),
            )
        return fitness_, descriptors, extras

    return scoring_fn


def with_one_key(score_rows: KeyedScoringFn) -> ScoringFn:
    """``score_rows`` given one key for the whole batch, split into one per candidate."""

    def scoring_fn(params_batch: jax.Array, key: jax.Array) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
        return score_rows(params_batch, jax.random.split(key, params_batch.shape[0]))

    return scoring_fn


def replicated(genotypes: jax.Array, replicas: int) -> jax.Array:
    """Each genotype ``replicas`` times in a row ``(count x replicas, dim)``: the rows scored for them."""
    return jnp.repeat(genotypes, replicas, axis=0)


def replica_means(fitness: jax.Array, replicas: int) -> jax.Array:
    """Each genotype's fitness ``(count,)``: the mean of its ``replicated`` rows' (each a mean of as many episodes,
    so this is the mean over all of them)."""
    return fitness.reshape(-1, replicas).mean(axis=1)


class Scored(NamedTuple):
    """``score_with_replicas``' results: the batch's rows apart from the replicated genotypes appended to them."""

    fitness: jax.Array  # (rows,)
    descriptors: jax.Array  # (rows, descriptors)
    extras: dict[str, jax.Array]  # the rows' episodes; "env_steps" counts every row's, the replicated ones' too
    replica_fitness: jax.Array | None  # (genotypes,) each replicated genotype's mean fitness; None without any


def score_with_replicas(
    score_rows: KeyedScoringFn,
    rows: jax.Array,
    keys: jax.Array,
    genotypes: jax.Array | None,
    replicas: int,
    key: jax.Array,
) -> Scored:
    """``rows`` (each on its key of ``keys``) and ``replicas`` rows of each of ``genotypes`` (their keys split from
    ``key``) scored in one call of ``score_rows``: a genotype re-scored on more episodes than a row plays (a
    champion, a search distribution's mean) costs rows of the batch, not a second rollout program to compile. Each
    row plays on its own key, so ``rows``' episodes are those they play without the genotypes (``genotypes`` None)."""
    if genotypes is None:
        return Scored(*score_rows(rows, keys), None)
    batch, extra = rows.shape[0], genotypes.shape[0] * replicas
    fitness, descriptors, extras = score_rows(
        jnp.concatenate([rows, replicated(genotypes, replicas)]),
        jnp.concatenate([keys, jax.random.split(key, extra)]),
    )
    own = {name: value[:batch] for name, value in extras.items() if name not in BATCH_TOTALS}
    totals = {name: value for name, value in extras.items() if name in BATCH_TOTALS}
    return Scored(
        fitness[:batch],
        descriptors[:batch],
        {**own, **totals},
        replica_means(fitness[batch:], replicas),
    )


class Kept(NamedTuple):
    """``keep_strictly_better``'s result."""

    genotype: jax.Array  # (dim,) the one held, or the fittest candidate where it scored strictly higher
    fitness: jax.Array  # the kept genotype's fitness
    top_fitness: jax.Array  # the fittest candidate's fitness, kept or not


def keep_strictly_better(held: jax.Array, held_fitness: jax.Array, candidates: jax.Array, fitness: jax.Array) -> Kept:
    """``held`` replaced by the fittest of ``candidates`` ``(count, dim)`` only where that scores strictly above
    ``held_fitness``: a tie keeps what is held (of tied candidates, the first is the fittest)."""
    i = jnp.argmax(fitness)
    better = fitness[i] > held_fitness
    return Kept(jnp.where(better, candidates[i], held), jnp.where(better, fitness[i], held_fitness), fitness[i])


def keep_best(
    candidates: jax.Array,
    fitness: jax.Array,
    extras: dict[str, jax.Array],
    best_params: jax.Array,
    best_fitness: jax.Array,
    env_steps: jax.Array,
) -> tuple[jax.Array, jax.Array, jax.Array, dict[str, jax.Array]]:
    """A black-box generation's bookkeeping: the best genotype so far (replaced only by a strictly fitter one,
    ``keep_strictly_better``), the env steps counted on, and the generation's metrics row."""
    kept = keep_strictly_better(best_params, best_fitness, candidates, fitness)
    best_params, best_fitness = kept.genotype, kept.fitness
    env_steps = env_steps + extras["env_steps"]
    metrics = {
        "best_fitness": best_fitness,
        "generation_max_fitness": kept.top_fitness,
        "generation_mean_fitness": fitness.mean(),
        "episode_return": extras["episode_return"].mean(),
        "episode_length": extras["episode_length"].mean(),
        "env_steps": env_steps,
    }
    return best_params, best_fitness, env_steps, metrics
