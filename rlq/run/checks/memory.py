"""Sizes checked before anything is compiled: a run or an evaluation whose arrays could not exist is refused in one
line naming the key to lower, instead of an ``OverflowError`` after the run directory is made or XLA's
``RESOURCE_EXHAUSTED`` traceback.

The estimate counts the arrays whose size the config sets and which the program holds at once: a training
update's observations (every env of every seed, times the unroll's steps), a replay buffer's transitions, an
evaluation's per-step keys and env states; for black-box search (ES, random search, MAP-Elites) a generation's
genotypes (candidates x the genotype's numbers), the evaluation of its candidates' episodes, an archive's genotypes
and a CMA-ES covariance (the genotype's numbers squared). It is a lower bound (activations, the optimiser and XLA's temporaries
come on top), so a refusal is sure and a run that passes can still run out of memory.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
import numpy as np

from rlq.algos import algo_settings, algorithm_spec
from rlq.algos.qd.genotypes import genotype_dim
from rlq.config.spec import RunSpec, as_spec
from rlq.errors import ConfigError
from rlq.lib.env_api import Env

#: the run's step and update counters are 32-bit integers on the device (JAX's default)
INT32_MAX = 2**31 - 1
#: a PRNG key's bytes (two uint32 words): an evaluation splits one per episode and step up front
KEY_BYTES = 8
GIB = 2**30
#: a float32's bytes: a genotype's numbers
FLOAT_BYTES = 4
#: the algorithms that score a population of genotypes over full episodes
SEARCHES = ("es", "random_search", "map_elites")


def free_bytes(device: Any | None = None) -> int | None:
    """The memory free on ``device`` (default: JAX's first): a GPU's from its allocator's figures, the CPU's from
    the host's available memory; None where neither is known."""
    device = device or jax.devices()[0]
    try:
        stats = device.memory_stats()
    except Exception:  # a backend without memory figures
        stats = None
    if stats and "bytes_limit" in stats:
        return int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0))
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def tree_bytes(tree: Any) -> int:
    """Bytes of a pytree of arrays or shapes (``jax.eval_shape``'s output)."""
    return sum(int(np.prod(leaf.shape)) * np.dtype(leaf.dtype).itemsize for leaf in jax.tree.leaves(tree))


def _gib(size: float) -> str:
    return f"{size / GIB:,.1f} GiB"


def check_fits(needed: int, what: str, key: str, free: int | None) -> None:
    """ConfigError naming ``key`` where ``needed`` bytes (at least) exceed ``free``."""
    if free is not None and needed > free:
        raise ConfigError(f"{what} needs at least {_gib(needed)} of device memory, {_gib(free)} is free; lower {key}")


def obs_bytes(env: Env) -> int:
    """Bytes of one observation (float32, whatever the space's dtype: what the networks take)."""
    shape = getattr(env.observation_space, "shape", ()) or ()
    return max(1, math.prod(int(n) for n in shape)) * 4


def check_training_sizes(
    run: RunSpec | Mapping[str, Any], env: Env, env_key: str, env_batch: int, free: int | None
) -> None:
    """One update's env steps fit the 32-bit step counter, and its observations, a replay buffer's transitions and a
    periodic evaluation's keys fit the device's free memory."""
    spec = as_spec(run)
    algo = spec.algorithm
    seeds = int(spec.seeds.count)
    unroll = algorithm_spec(algo).unroll(algo_settings(algo))
    per_update = env_batch * unroll
    if per_update > INT32_MAX:
        times = f" x algo.num_steps={unroll}" if unroll > 1 else ""
        raise ConfigError(
            f"{env_key}={env_batch:,}{times}: one update would take {per_update:,} env steps per seed, beyond the "
            f"32-bit step counter ({INT32_MAX:,}); lower {env_key}"
        )
    check_fits(
        seeds * per_update * obs_bytes(env), f"{env_key}={env_batch:,} (one update's observations)", env_key, free
    )
    buffer = algo.get("buffer_size")
    if isinstance(buffer, int) and buffer > 0:
        check_fits(
            seeds * buffer * 2 * obs_bytes(env),
            f"algo.buffer_size={buffer:,} (the replay buffer)",
            "algo.buffer_size",
            free,
        )
    steps = env.max_episode_steps or 0
    episodes = int(spec.evaluation.episodes)
    check_fits(
        seeds * episodes * steps * KEY_BYTES,
        f"eval.episodes={episodes:,} x {steps:,} steps (the evaluation's keys)",
        "eval.episodes",
        free,
    )


def _candidates(algo: Mapping[str, Any]) -> tuple[str, int]:
    """The key and number of genotypes one generation scores."""
    if algo["name"] == "random_search" and algo.get("variant") == "ars":
        return "algo.ars.directions", 2 * int(algo["ars"]["directions"])
    if algo["name"] == "map_elites":
        return "algo.batch_size", int(algo["batch_size"])
    return "algo.population", int(algo["population"])


def _archive_cells(algo: Mapping[str, Any]) -> int:
    archive = algo.get("archive")
    if archive is None:
        return 0
    if archive.get("kind") == "cvt":
        return int(archive["cells"])
    return math.prod(int(n) for n in archive["shape"])


def _covariances(algo: Mapping[str, Any]) -> tuple[int, str]:
    """How many CMA-ES covariance matrices (each with its eigenvectors: two genotype-squared arrays) the search
    keeps, and what to change instead."""
    if algo["name"] == "es" and algo.get("strategy") == "cma_es":
        return 1, "algo.strategy=snes or open_es (no covariance)"
    if algo["name"] == "map_elites" and algo.get("emitter") in ("improvement", "mixed"):
        return int(algo["cma_emitters"]), "algo.emitter=gaussian (no CMA-ES emitters)"
    return 0, ""


def check_search_sizes(run: RunSpec | Mapping[str, Any], env: Env, free: int | None) -> None:
    """A black-box search's generation fits: its genotypes, the evaluation of its candidates' episodes (every
    episode's per-step keys and env states at once), an archive's genotypes, CMA-ES covariances; and a generation's
    env steps fit the 32-bit step counter. Other algorithms: nothing to check."""
    spec = as_spec(run)
    algo = spec.algorithm
    if algo["name"] not in SEARCHES:
        return
    seeds = int(spec.seeds.count)
    key, candidates = _candidates(algo)
    dim = genotype_dim(algo_settings(algo), env)
    shape = "algo.hidden" if algo.get("genotype") == "policy" and algo.get("hidden") else None
    smaller = f"{key} or {shape}" if shape else key
    of = f"genotypes of {dim:,} numbers" + (f" (algo.hidden={list(algo['hidden'])})" if shape else "")
    check_fits(seeds * candidates * dim * FLOAT_BYTES, f"{key}={candidates:,} {of}", smaller, free)
    episodes = int(algo["episodes"])
    steps = env.max_episode_steps or 0
    mean = int(algo["mean_episodes"]) if algo["name"] == "es" and algo.get("keep") == "mean" else 0
    state = tree_bytes(jax.eval_shape(env.reset, jax.random.PRNGKey(0)))
    scored = candidates * episodes + mean
    check_fits(
        seeds * scored * (steps * KEY_BYTES + 3 * state),
        f"{key}={candidates:,} x algo.episodes={episodes:,} x {steps:,} steps (the candidates' evaluation)",
        f"{key} or algo.episodes",
        free,
    )
    cells = _archive_cells(algo)
    if cells:
        which = "algo.archive.cells" if algo["archive"].get("kind") == "cvt" else "algo.archive.shape"
        check_fits(seeds * cells * dim * FLOAT_BYTES, f"{which}: an archive of {cells:,} {of}", which, free)
    count, instead = _covariances(algo)
    if count:
        check_fits(
            seeds * count * 2 * dim * dim * FLOAT_BYTES,
            f"{count} CMA-ES covariance(s) of {dim:,} x {dim:,} numbers",
            f"{shape or 'the genotype'}, or use {instead}",
            free,
        )
    per_update = scored * steps
    if per_update > INT32_MAX:
        raise ConfigError(
            f"{key}={candidates:,} x algo.episodes={episodes:,} x {steps:,} steps: one generation would take "
            f"{per_update:,} env steps per seed, beyond the 32-bit step counter ({INT32_MAX:,}); lower {key}"
        )


def check_evaluation_size(env: Env, episodes: int, free: int | None) -> None:
    """An evaluation of ``episodes`` at once (one seed at a time) fits: its per-step keys and its env states."""
    steps = env.max_episode_steps or 0
    state = tree_bytes(jax.eval_shape(env.reset, jax.random.PRNGKey(0)))
    needed = episodes * (steps * KEY_BYTES + 3 * state)
    check_fits(needed, f"episodes={episodes:,} x {steps:,} steps", "episodes", free)
