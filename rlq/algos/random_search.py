"""Random search: each update samples a population of genotypes, scores each over full episodes
and keeps the best one seen so far (``variant: hill_climb``, T1's search); ``variant: ars`` is augmented
random search instead (rlq/algos/ars.py).

Genotypes (rlq/algos/qd/genotypes.py): the weights of a deterministic policy (``genotype: policy``,
T1's CartPole search) or one constant action such as an open-loop CPG modulation (``genotype:
action``). With ``archive`` set, every scored genotype is also inserted into a MAP-Elites grid
archive, so that random search reports the same QD metrics as MAP-Elites on the same task and
evaluations (the usual baseline of quality-diversity papers).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from rlq.algos import ars, map_elites
from rlq.algos.base import Algorithm, Hyperparams, updates_for_budget
from rlq.algos.qd import archive as qd_archive
from rlq.algos.qd import measures, variation
from rlq.algos.qd.genotypes import decode_action, linear_policy, make_genotype, num_outputs
from rlq.algos.qd.scoring import keep_best, make_keyed_scoring_fn, with_one_key
from rlq.algos.spec import AlgorithmSpec
from rlq.declared.random_search import Config
from rlq.lib.env_api import Env

__all__ = [
    "Config",
    "RandomSearchState",
    "check",
    "decode_action",
    "linear_policy",
    "make",
    "num_outputs",
]


class RandomSearchState(struct.PyTreeNode):
    best_params: jax.Array  # flat genotype
    best_fitness: jax.Array
    key: jax.Array
    env_steps: jax.Array
    generation: jax.Array
    archive: qd_archive.Archive | None = None


VARIANTS = ("hill_climb", "ars")
#: the numeric keys the update reads as arguments (``Algorithm.update``'s ``hp``): ``sigma`` (``sampling: gaussian``'s
#: step) and ARS's (rlq/algos/ars.py). A variant that does not read a key leaves it out of its programs.
SWEEPABLE = ("sigma", *(f"ars.{name}" for name in ars.SWEEPABLE))


def check(cfg: Config, env: Env) -> str | None:
    if cfg.variant not in VARIANTS:
        return f"algo.variant must be one of {', '.join(VARIANTS)}, got {cfg.variant!r} (e.g. algo.variant=ars)"
    if cfg.variant == "ars":
        return ars.check(cfg, env)
    if cfg.sampling not in ("uniform", "gaussian"):
        return f"algo.sampling must be uniform or gaussian, got {cfg.sampling!r} (e.g. algo.sampling=uniform)"
    return map_elites.check_task(cfg, env)


def check_env_shards(cfg: Config, shards: int) -> str | None:
    """``algo.variant=ars`` splits its ``2 x algo.ars.directions`` candidates over the env devices."""
    if cfg.variant != "ars":
        return None
    candidates = 2 * int(cfg.ars.directions)
    if candidates % shards:
        return (
            f"algo.variant=ars splits its {candidates} candidates (2 x algo.ars.directions) over {shards} devices, "
            f"which does not divide them; set algo.ars.directions to a multiple of {shards}"
        )
    return None


def make(cfg: Config, env: Env, budget_env_steps: int) -> Algorithm:
    if cfg.variant == "ars":
        return ars.make(cfg, env, budget_env_steps)
    genotype = make_genotype(cfg, env)
    low, high = jnp.asarray(genotype.low), jnp.asarray(genotype.high)
    grid = map_elites.grid_of(cfg) if cfg.archive is not None else None
    descriptor = cfg.descriptor if grid is not None else None
    dims = None if cfg.descriptor_dims is None else tuple(int(d) for d in cfg.descriptor_dims)
    scoring_fn = with_one_key(
        make_keyed_scoring_fn(
            env,
            genotype.apply,
            cfg.episodes,
            descriptor_key=measures.DESCRIPTOR_KEYS[descriptor] if descriptor else None,
            fitness=cfg.fitness,
            descriptor_dims=dims,
        )
    )
    # Every scored episode runs at most max_episode_steps steps: the budget is never exceeded;
    # metrics report the true count.
    assert env.max_episode_steps, "check() admits only envs with a time limit"
    steps_per_update = cfg.population * cfg.episodes * env.max_episode_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)

    def init(key: jax.Array, hp: Hyperparams) -> RandomSearchState:
        key, sub = jax.random.split(key)
        zero = jnp.zeros((), jnp.int32)
        archive = qd_archive.empty(grid, genotype.dim) if grid is not None else None
        first = variation.uniform(sub, 1, low, high)[0]
        return RandomSearchState(first, jnp.asarray(-jnp.inf, jnp.float32), key, zero, zero, archive)

    defaults = {"sigma": float(cfg.sigma)}

    def ask(state: RandomSearchState, key: jax.Array, sigma: Any) -> jax.Array:
        if cfg.sampling == "uniform":
            return variation.uniform(key, cfg.population, low, high)
        normal_key, uniform_key = jax.random.split(key)
        parents = jnp.broadcast_to(state.best_params, (cfg.population, genotype.dim))
        around = variation.gaussian(normal_key, parents, sigma, low, high)
        return jnp.where(
            jnp.isfinite(state.best_fitness), around, variation.uniform(uniform_key, cfg.population, low, high)
        )

    def update(state: RandomSearchState, hp: Hyperparams) -> tuple[RandomSearchState, dict]:
        """One generation at ``hp``'s ``sigma``."""
        key, ask_key, score_key = jax.random.split(state.key, 3)
        candidates = ask(state, ask_key, hp["sigma"])
        fitness, descriptors, extras = scoring_fn(candidates, score_key)
        best_params, best_fitness, env_steps, metrics = keep_best(
            candidates, fitness, extras, state.best_params, state.best_fitness, state.env_steps
        )
        generation = state.generation + 1
        archive = state.archive
        if grid is not None and archive is not None:
            archive = qd_archive.insert(archive, grid, candidates, fitness, descriptors)
            metrics.update(qd_archive.metrics(archive, cfg.qd_offset))
            metrics["evaluations"] = generation * cfg.population * cfg.episodes
        return RandomSearchState(best_params, best_fitness, key, env_steps, generation, archive), metrics

    def policy(state: RandomSearchState):
        return genotype.policy(state.best_params)

    algo = Algorithm(
        init,
        update,
        policy,
        num_updates,
        steps_per_update,
        params=lambda s: s.best_params,
        iterations=True,
        hyperparams=defaults,
    )
    return algo if grid is None else map_elites.with_archive(algo, cfg, grid)


SPEC = AlgorithmSpec(
    config=Config,
    make=make,
    check=check,
    env_axis="population",
    check_env_shards=check_env_shards,
    eval_metrics=map_elites.eval_metrics,
    sweepable=SWEEPABLE,
    unroll_axis=None,
)
