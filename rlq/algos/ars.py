"""Augmented random search (Mania, Guy and Recht 2018, ARS V2-t): ``algo=random_search algo.variant=ars``.

Each update is one iteration: ``directions`` Gaussian directions ``delta``, each scored in both signs
(``w + noise * delta`` and ``w - noise * delta``) over full episodes; the ``top`` directions by their better
sign step the policy ``w += step_size / (top * sigma_R) * sum (r+ - r-) delta``, where ``sigma_R`` is the
standard deviation of the returns used. The policy acts on observations normalised by the running mean and
standard deviation of every observation its candidates saw in earlier iterations (V2), which is what lets a
linear policy learn on bodies such as the humanoid. The statistics are summed about one fixed observation
(``rlq.lib.rollout.reference_observation``): in float32, raw sums of squares cancel, and a component that never
changes (the humanoid's body masses) came out as a tiny spread with a mean a rounding off, so the policy read it as
an input of a few units of noise; summed about the reference it is exact and normalises to 0, as the reference
implementation's float64 statistics (which drop components whose spread is under 1e-7) make it. The search starts
from ``w = 0``; the greedy policy is the current ``w``, not the best candidate scored. Genotypes as random search's
(``genotype: policy``).
``reward_shift`` is subtracted per step from the returns the search ranks by (not from the logged returns).
"""

from __future__ import annotations

from typing import Protocol

import jax
import jax.numpy as jnp
from flax import struct

from rlq.algos.base import Algorithm, Hyperparams, updates_for_budget
from rlq.algos.qd import measures
from rlq.algos.qd.genotypes import GenotypeSettings, make_genotype
from rlq.declared.random_search import ArsConfig as Config
from rlq.lib.env_api import Env
from rlq.lib.learning import normalize
from rlq.lib.rollout import evaluate, reference_observation
from rlq.lib.sharding import vmap_envs
from rlq.lib.spaces import Box, flat_dim

#: the numeric ``algo.ars.`` keys the update reads as arguments (``Algorithm.update``'s ``hp``)
SWEEPABLE = ("step_size", "noise", "reward_shift")


class SearchSettings(GenotypeSettings, Protocol):
    """The keys of random search's config that ARS reads (``algo.variant=ars``)."""

    @property
    def archive(self) -> object | None: ...
    @property
    def ars(self) -> Config: ...
    @property
    def fitness(self) -> str: ...
    @property
    def episodes(self) -> int: ...


class ARSState(struct.PyTreeNode):
    weights: jax.Array  # flat genotype of the current policy
    obs_stats: normalize.RunningStats
    key: jax.Array
    env_steps: jax.Array
    generation: jax.Array


def check(cfg: SearchSettings, env: Env) -> str | None:
    """A one-line problem with ARS's settings on ``env``, or None."""
    if cfg.genotype != "policy":
        return "algo.variant=ars searches a policy's weights: use algo.genotype=policy"
    if cfg.archive is not None:
        return "algo.variant=ars keeps no archive: drop algo.archive (or use algo.variant=hill_climb)"
    if cfg.ars.top > cfg.ars.directions:
        return f"algo.ars.top={cfg.ars.top} must be at most algo.ars.directions={cfg.ars.directions}"
    if cfg.ars.normalize and not isinstance(env.observation_space, Box):
        return "algo.ars.normalize=true needs a Box observation space (or algo.ars.normalize=false)"
    if not cfg.ars.clip_actions and not (isinstance(env.action_space, Box) and env.clamps_actions):
        return (
            "algo.ars.clip_actions=false hands the env actions outside its bounds, which only an env with Box actions "
            "that clamps them itself takes (env=humanoid); drop it"
        )
    return None


def ars_step(
    weights: jax.Array, deltas: jax.Array, plus: jax.Array, minus: jax.Array, top: int, step_size: float | jax.Array
) -> jax.Array:
    """One ARS step from directions ``(n, dim)`` and their returns in each sign ``(n,)``: the ``top``
    directions by ``max(plus, minus)``, each weighted by ``plus - minus``, scaled by the std of their returns."""
    order = jnp.argsort(-jnp.maximum(plus, minus))[:top]
    used = jnp.concatenate([plus[order], minus[order]])
    sigma = jnp.std(used)
    sigma = jnp.where(sigma > 0, sigma, 1.0)
    step = (plus[order] - minus[order]) @ deltas[order]
    return weights + step_size / (top * sigma) * step


def make(cfg: SearchSettings, env: Env, budget_env_steps: int) -> Algorithm:
    genotype = make_genotype(cfg, env, clip_actions=cfg.ars.clip_actions)
    ars = cfg.ars
    fitness_of = measures.FITNESS[cfg.fitness]
    obs_dim = flat_dim(env.observation_space) if ars.normalize else 0
    candidates_per_update = 2 * ars.directions
    assert env.max_episode_steps, "check() admits only envs with a time limit"
    steps_per_update = candidates_per_update * cfg.episodes * env.max_episode_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)
    defaults = {f"ars.{name}": float(getattr(ars, name)) for name in SWEEPABLE}

    def acting(weights: jax.Array, stats: normalize.RunningStats):
        return genotype.policy(weights, stats if ars.normalize else None)

    def score(
        weights: jax.Array, stats: normalize.RunningStats, key: jax.Array, ref: jax.Array | None
    ) -> dict[str, jax.Array]:
        return evaluate(env, acting(weights, stats), key, cfg.episodes, obs_moments=ref is not None, obs_ref=ref)

    def init(key: jax.Array, hp: Hyperparams) -> ARSState:
        zero = jnp.zeros((), jnp.int32)
        stats = normalize.init((obs_dim,))
        return ARSState(jnp.zeros(genotype.dim, jnp.float32), stats, key, zero, zero)

    def update(state: ARSState, hyperparams: Hyperparams) -> tuple[ARSState, dict]:
        """One generation at ``hyperparams``' ``ars.<SWEEPABLE>`` values."""
        hp = {name.removeprefix("ars."): value for name, value in hyperparams.items()}
        key, delta_key, score_key = jax.random.split(state.key, 3)
        deltas = jax.random.normal(delta_key, (ars.directions, genotype.dim), jnp.float32)
        noise = hp["noise"]
        candidates = jnp.concatenate([state.weights + noise * deltas, state.weights - noise * deltas])
        keys = jax.random.split(score_key, candidates_per_update)
        ref = reference_observation(env) if ars.normalize else None
        record = vmap_envs(lambda w, k: score(w, state.obs_stats, k, ref))(candidates, keys)
        shifted = fitness_of(record) - hp["reward_shift"] * record["episode_length"]
        fitness = shifted.mean(axis=1)
        plus, minus = fitness[: ars.directions], fitness[ars.directions :]
        weights = ars_step(state.weights, deltas, plus, minus, ars.top, hp["step_size"])
        stats = state.obs_stats
        if ars.normalize:
            stats = normalize.update_from_moments(stats, record, ref)
        env_steps = state.env_steps + record["episode_length"].sum().astype(jnp.int32)
        metrics = {
            "generation_max_fitness": fitness.max(),
            "generation_mean_fitness": fitness.mean(),
            "episode_return": record["episode_return"].mean(),
            "episode_length": record["episode_length"].mean(),
            "weights_norm": jnp.linalg.norm(weights),
            "env_steps": env_steps,
        }
        return ARSState(weights, stats, key, env_steps, state.generation + 1), metrics

    def policy(state: ARSState):
        return acting(state.weights, state.obs_stats)

    return Algorithm(
        init,
        update,
        policy,
        num_updates,
        steps_per_update,
        params=lambda s: s.weights,
        iterations=True,
        hyperparams=defaults,
    )
