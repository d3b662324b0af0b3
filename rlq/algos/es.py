"""Evolution strategies (evosax): each update is one generation, ask -> score every candidate's full episodes in
one program -> tell.

``strategy`` picks evosax's OpenAI-ES (``open_es``: antithetic Gaussian perturbations, centered-rank gradient,
Adam), CMA-ES (``cma_es``) or separable NES (``snes``). The genotypes are random search's and MAP-Elites'
(rlq/algos/qd/genotypes.py): a deterministic policy's weights or one constant action. evosax's state is a flax
pytree, so it is carried (and checkpointed) inside ``EsState``. evosax minimises: it is told minus the fitness.

``keep`` picks the policy a run ends with. ``candidate``: the best candidate scored so far, on its own
``episodes``; with few episodes on a noisy env (LunarLander's random starts) that is the luckiest
candidate, not the best one. ``mean``: the search distribution's mean, scored every generation on
``mean_episodes`` episodes of its own (not told to the strategy), the best-scoring mean kept. The mean plays them as
``mean_episodes / episodes`` extra rows of the candidates' batch, each on its own key, its fitness the mean of its
rows (``scoring.score_with_replicas``, as MAP-Elites' champion): one rollout program to compile, not two, and the
candidates play the episodes they play without it.

``normalize`` (policy genotypes): candidates act on observations normalised by the running statistics of every
observation acted on in earlier generations (``rlq.lib.learning.normalize``, as augmented random search's V2);
each generation's episodes fold theirs in after the scoring. The kept policy carries the statistics it was scored
with. Off, the state holds no statistics (``None``: a checkpoint's leaves are those of a run without the key).

``reward_shift`` (fitness=return): the strategy is told each candidate's return less the shift per step it played,
as augmented random search ranks its directions; the best candidate or mean is still kept by its return. It is a
constant of the program, present only where it is not 0, so the programs of a run without it are those of the runs
measured before it existed, bit for bit; an in-program sweep cannot vary it (a Hydra sweep compiles each value).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from rlq.algos.base import Algorithm, Hyperparams, updates_for_budget
from rlq.algos.qd.es_emitter import open_es
from rlq.algos.qd.genotypes import check as check_genotype
from rlq.algos.qd.genotypes import make_genotype, search_frame
from rlq.algos.qd.scoring import keep_best, make_keyed_scoring_fn, score_with_replicas
from rlq.algos.spec import AlgorithmSpec
from rlq.declared.es import Config
from rlq.lib.carry import strongly_typed
from rlq.lib.env_api import Env
from rlq.lib.learning import normalize
from rlq.lib.rollout import reference_observation
from rlq.lib.spaces import Box, flat_dim

__all__ = [
    "KEEPS",
    "STRATEGIES",
    "Config",
    "EsState",
    "check",
    "check_env_shards",
    "make",
    "make_strategy",
    "mean_rows",
    "search_frame",
]

STRATEGIES = ("open_es", "cma_es", "snes")
KEEPS = ("candidate", "mean")


class EsState(struct.PyTreeNode):
    es: Any  # evosax's state (a flax pytree): mean, std, ...
    best_params: jax.Array  # flat genotype of the best candidate scored so far
    best_fitness: jax.Array
    key: jax.Array
    env_steps: jax.Array
    generation: jax.Array
    #: ``normalize`` only: the running observation statistics, and those the kept policy was scored with
    obs_stats: normalize.RunningStats | None = None
    kept_stats: normalize.RunningStats | None = None


def check(cfg: Config, env: Env) -> str | None:
    if cfg.strategy not in STRATEGIES:
        return (
            f"algo.strategy must be one of {', '.join(STRATEGIES)}, got {cfg.strategy!r} (e.g. algo.strategy=open_es)"
        )
    if cfg.keep not in KEEPS:
        return f"algo.keep must be one of {', '.join(KEEPS)}, got {cfg.keep!r}"
    if cfg.keep == "mean" and cfg.mean_episodes < 1:
        return f"algo.keep=mean scores the mean on algo.mean_episodes episodes: give 1 or more, got {cfg.mean_episodes}"
    if cfg.keep == "mean" and cfg.mean_episodes % cfg.episodes:
        return (
            f"algo.mean_episodes={cfg.mean_episodes} is not a multiple of algo.episodes={cfg.episodes} (algo.keep=mean "
            f"plays the mean's episodes in groups of algo.episodes, beside the candidates); give a multiple of "
            f"{cfg.episodes}"
        )
    if cfg.strategy == "open_es" and cfg.population % 2:
        return f"algo.population must be even for open_es (antithetic pairs), got {cfg.population}"
    if not env.max_episode_steps:
        return f"es scores full episodes; give env={type(env.unwrapped).__name__} a time limit"
    if cfg.normalize and cfg.genotype != "policy":
        return (
            "algo.normalize=true normalises a policy's observations: use algo.genotype=policy (or algo.normalize=false)"
        )
    if cfg.normalize and not isinstance(env.observation_space, Box):
        return "algo.normalize=true needs a Box observation space (or algo.normalize=false)"
    if cfg.reward_shift and cfg.fitness != "return":
        return (
            f"algo.reward_shift subtracts a bonus per step from returns, and algo.fitness={cfg.fitness} is not a "
            "return: use algo.fitness=return (or algo.reward_shift=0)"
        )
    return check_genotype(cfg, env)


def mean_rows(cfg: Config) -> int:
    """The rows ``algo.keep=mean`` adds to each generation's scored batch: the mean, ``mean_episodes / episodes``
    times (0 with ``keep=candidate``)."""
    return int(cfg.mean_episodes) // int(cfg.episodes) if cfg.keep == "mean" else 0


def check_env_shards(cfg: Config, shards: int) -> str | None:
    """The mean's rows join the candidates' batch, and ``shards`` devices split the two together."""
    extra, population = mean_rows(cfg), int(cfg.population)
    if not extra or (population + extra) % shards == 0:
        return None
    return (
        f"algo.keep=mean's {extra} rows (algo.mean_episodes={cfg.mean_episodes} in groups of algo.episodes="
        f"{cfg.episodes}) join algo.population={population}: the {population + extra} rows scored together split "
        f"over {shards} devices, which does not divide them; set algo.mean_episodes so that {population} + "
        f"mean_episodes / {cfg.episodes} is a multiple of {shards}"
    )


#: the numeric keys that enter init and the update only as arithmetic: program inputs (``Algorithm.init``'s and
#: ``update``'s ``hp``). ``sigma`` is the search's first width (init's); ``lr`` is open_es's alone (cma_es and
#: snes do not read it). ``reward_shift`` is not one: a program without it is the program of a run before it existed,
#: bit for bit (rlq/algos/es.py's module docstring).
SWEEPABLE = ("lr", "sigma")


def make_strategy(
    cfg: Config, dim: int, lr: float | jax.Array | None = None, sigma: float | jax.Array | None = None
) -> tuple[Any, Any]:
    """evosax's strategy object and its params for ``cfg.strategy`` over flat genotypes of ``dim`` numbers (``lr``,
    ``sigma``: values instead of the config's, maybe traced; Adam's state does not depend on ``lr``)."""
    lr = cfg.lr if lr is None else lr
    sigma = cfg.sigma if sigma is None else sigma
    if cfg.strategy == "open_es":
        return open_es(cfg.population, dim, sigma, lr)
    # imported here: evosax's import starts JAX's backend, which a run over several processes joins first
    from evosax.algorithms import CMA_ES, SNES

    es = (CMA_ES if cfg.strategy == "cma_es" else SNES)(cfg.population, jnp.zeros(dim))
    return es, es.default_params.replace(std_init=jnp.asarray(sigma, jnp.float32))


def make(cfg: Config, env: Env, budget_env_steps: int) -> Algorithm:
    genotype = make_genotype(cfg, env)
    low, high = jnp.asarray(genotype.low), jnp.asarray(genotype.high)
    centre, scale = search_frame(cfg, genotype.low, genotype.high)
    defaults = {name: float(getattr(cfg, name)) for name in SWEEPABLE}

    def scoring(stats: normalize.RunningStats | None, ref: jax.Array | None):
        return make_keyed_scoring_fn(
            env,
            genotype.applying(stats),
            cfg.episodes,
            descriptor_key=None,
            fitness=cfg.fitness,
            obs_ref=ref,
        )

    keep_mean = cfg.keep == "mean"
    replicas = mean_rows(cfg)  # the mean plays its mean_episodes as rows of the candidates' batch
    assert env.max_episode_steps, "check() admits only envs with a time limit"
    steps_per_update = (cfg.population * cfg.episodes + keep_mean * cfg.mean_episodes) * env.max_episode_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)

    def init(key: jax.Array, hp: Hyperparams) -> EsState:
        key, sub = jax.random.split(key)
        zero = jnp.zeros((), jnp.int32)
        es, es_params = make_strategy(cfg, genotype.dim, hp["lr"], hp["sigma"])
        es_state = strongly_typed(es.init(sub, jnp.zeros(genotype.dim), es_params))
        start = jnp.clip(centre, low, high)
        stats = normalize.init((flat_dim(env.observation_space),)) if cfg.normalize else None
        return EsState(es_state, start, jnp.asarray(-jnp.inf, jnp.float32), key, zero, zero, stats, stats)

    def update(state: EsState, hp: Hyperparams) -> tuple[EsState, dict]:
        """One update at the numeric hyperparameters ``hp`` (``SWEEPABLE``)."""
        es, es_params = make_strategy(cfg, genotype.dim, hp["lr"], hp["sigma"])
        # JAX's default partitionable threefry: split(k, 5)[:4] == split(k, 4), so keep=mean's first four keys
        # (and the candidates' episodes) are keep=candidate's
        keys = jax.random.split(state.key, 5 if keep_mean else 4)
        key, ask_key, score_key, tell_key = keys[:4]
        candidates, es_state = es.ask(ask_key, state.es, es_params)
        scored = jnp.clip(centre + scale * candidates, low, high)
        mean = jnp.clip(centre + scale * state.es.mean, low, high)[None] if keep_mean else None
        row_keys, mean_key = jax.random.split(score_key, cfg.population), keys[-1]  # keys[4] with keep=mean
        ref = None if state.obs_stats is None else reference_observation(env)
        result = score_with_replicas(scoring(state.obs_stats, ref), scored, row_keys, mean, replicas, mean_key)
        fitness = result.fitness  # the candidates' alone: the mean's rows are neither told nor kept as one
        told = (
            fitness - cfg.reward_shift * result.extras["episode_length"].mean(axis=1) if cfg.reward_shift else fitness
        )
        es_state = strongly_typed(es.tell(tell_key, candidates, -told, es_state, es_params)[0])
        best_params, best_fitness, env_steps, metrics = keep_best(
            scored, fitness, result.extras, state.best_params, state.best_fitness, state.env_steps
        )
        if keep_mean:  # what is kept is the best mean, not the best candidate
            assert mean is not None and result.replica_fitness is not None
            mean_fitness = result.replica_fitness
            best_params, best_fitness, _, _ = keep_best(
                mean, mean_fitness, result.extras, state.best_params, state.best_fitness, state.env_steps
            )
            metrics = {**metrics, "best_fitness": best_fitness, "mean_fitness": mean_fitness[0]}
        stats, kept_stats = state.obs_stats, state.kept_stats
        if stats is not None:  # the kept policy was scored with this generation's statistics where it changed
            kept_stats = jax.tree.map(
                lambda now, held: jnp.where(best_fitness > state.best_fitness, now, held), stats, kept_stats
            )
            stats = normalize.update_from_moments(stats, result.extras, ref)
        new = EsState(es_state, best_params, best_fitness, key, env_steps, state.generation + 1, stats, kept_stats)
        return new, metrics

    def policy(state: EsState):
        return genotype.policy(state.best_params, state.kept_stats)

    return Algorithm(
        init,
        update,
        policy,
        num_updates,
        steps_per_update,
        params=lambda s: s.best_params,
        iterations=True,
        hyperparams=defaults,
    )


SPEC = AlgorithmSpec(
    config=Config,
    make=make,
    check=check,
    env_axis="population",
    check_env_shards=check_env_shards,
    sweepable=SWEEPABLE,
    unroll_axis=None,
)
