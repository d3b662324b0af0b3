"""Sizes checked before anything is compiled: a run or an evaluation whose arrays could not exist is refused in one
line naming the key to lower, instead of an ``OverflowError`` after the run directory is made or XLA's
``RESOURCE_EXHAUSTED`` traceback.

The estimate counts the arrays whose size the config sets and which the program holds at once: a training
update's observations (every env of every seed, times the unroll's steps), a replay buffer's transitions, an
evaluation's per-step keys and env states. It is a lower bound (activations, the optimiser and XLA's temporaries
come on top), so a refusal is sure and a run that passes can still run out of memory.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import jax
import numpy as np
from omegaconf import DictConfig

from rlq.errors import ConfigError
from rlq.lib.env_api import Env

#: the run's step and update counters are 32-bit integers on the device (JAX's default)
INT32_MAX = 2**31 - 1
#: a PRNG key's bytes (two uint32 words): an evaluation splits one per episode and step up front
KEY_BYTES = 8
GIB = 2**30


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


def check_training_sizes(cfg: DictConfig, env: Env, env_key: str, env_batch: int, free: int | None) -> None:
    """One update's env steps fit the 32-bit step counter, and its observations, a replay buffer's transitions and a
    periodic evaluation's keys fit the device's free memory."""
    algo = cfg.algo
    seeds = int(cfg.num_seeds)
    unroll = int(algo.get("num_steps", 1) or 1)
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
    episodes = int(cfg.eval.episodes)
    check_fits(
        seeds * episodes * steps * KEY_BYTES,
        f"eval.episodes={episodes:,} x {steps:,} steps (the evaluation's keys)",
        "eval.episodes",
        free,
    )


def check_evaluation_size(env: Env, episodes: int, free: int | None) -> None:
    """An evaluation of ``episodes`` at once (one seed at a time) fits: its per-step keys and its env states."""
    steps = env.max_episode_steps or 0
    state = tree_bytes(jax.eval_shape(env.reset, jax.random.PRNGKey(0)))
    needed = episodes * (steps * KEY_BYTES + 3 * state)
    check_fits(needed, f"episodes={episodes:,} x {steps:,} steps", "episodes", free)
