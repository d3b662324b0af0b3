"""ε-greedy exploration: schedules (pure functions of counters kept in the algorithm state) and
action selection.

Both ε-greedy algorithms read an ``epsilon`` config group::

    schedule: linear | exponential
    start, end        # initial value; final value (linear) or floor (exponential)
    duration          # linear: env steps from start to end
    decay             # exponential: factor applied per completed episode
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import jax
import jax.numpy as jnp

from rlq.lib.learning.declared import Epsilon

SCHEDULES = ("linear", "exponential")


def linear(step: jax.Array, start: float | jax.Array, end: float | jax.Array, duration: int) -> jax.Array:
    """``start`` to ``end`` linearly over ``duration`` steps, then ``end``."""
    frac = jnp.clip(jnp.asarray(step, jnp.float32) / max(int(duration), 1), 0.0, 1.0)
    return start + frac * (end - start)


def exponential(
    episodes: jax.Array, start: float | jax.Array, decay: float | jax.Array, floor: float | jax.Array
) -> jax.Array:
    """``start * decay**episodes``, never below ``floor``."""
    return jnp.maximum(start * jnp.power(decay, jnp.asarray(episodes, jnp.float32)), floor)


def check_epsilon(cfg: Epsilon, prefix: str) -> str | None:
    """An error message for a bad ``epsilon`` group, else None."""
    if cfg.schedule not in SCHEDULES:
        return f"{prefix}.schedule must be one of {', '.join(SCHEDULES)}, got '{cfg.schedule}'"
    if not (0.0 <= cfg.end <= 1.0 and 0.0 <= cfg.start <= 1.0):
        return f"{prefix}.start and {prefix}.end must lie in [0, 1]"
    if cfg.schedule == "exponential" and not 0.0 < cfg.decay <= 1.0:
        return f"{prefix}.decay must lie in (0, 1], got {cfg.decay}"
    return None


def epsilon_schedule(
    cfg: Epsilon, values: Mapping[str, float | jax.Array] | None = None
) -> Callable[[jax.Array, jax.Array], jax.Array]:
    """``(env_steps, completed_episodes) -> epsilon`` for an ``epsilon`` config group. ``values``: ``start``,
    ``end`` and ``decay`` to use instead of the group's (traced hyperparameters); ``schedule`` and ``duration``
    shape the program and always come from ``cfg``."""
    given = {"start": float(cfg.start), "end": float(cfg.end), "decay": float(cfg.decay), **(values or {})}
    start, end = given["start"], given["end"]
    if cfg.schedule == "linear":
        duration = int(cfg.duration)
        return lambda steps, episodes: linear(steps, start, end, duration)
    decay = given["decay"]
    return lambda steps, episodes: exponential(episodes, start, decay, end)


#: the keys of an ``epsilon`` group that enter its schedule only as arithmetic (``epsilon_schedule``'s ``values``)
EPSILON_VALUES = ("start", "end", "decay")


def epsilon_values(hyperparams: Mapping[str, float | jax.Array], prefix: str = "epsilon.") -> dict[str, Any]:
    """The ``epsilon.*`` entries of an algorithm's hyperparameters, without the prefix (``epsilon_schedule``'s ``values``)."""
    return {name.removeprefix(prefix): value for name, value in hyperparams.items() if name.startswith(prefix)}


def epsilon_greedy(key: jax.Array, q_values: jax.Array, epsilon: jax.Array) -> jax.Array:
    """Per row of ``q_values`` (..., actions): a uniform random action with probability ε, else argmax."""
    explore_key, action_key = jax.random.split(key)
    shape, num_actions = q_values.shape[:-1], q_values.shape[-1]
    random_action = jax.random.randint(action_key, shape, 0, num_actions)
    explore = jax.random.uniform(explore_key, shape) < epsilon
    return jnp.where(explore, random_action, jnp.argmax(q_values, axis=-1))
