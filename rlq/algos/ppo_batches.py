"""PPO's two ways to turn an update's rollout into learning data (its two variants, named).

``fixed_advantages`` is PureJaxRL's: GAE once per update, minibatches of transitions.
``whole_unrolls`` is brax's: minibatches of whole unrolls, GAE recomputed in each minibatch with
the current value net (``algo.recompute_gae=true``).

Both lay the items out step-major (as the rollout stacks them) or, with ``env_major`` (per-shard
minibatches over envs split across devices), env-major: each env's items together, so every
device's share of the items is one contiguous block, as the devices hold the envs.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from rlq.lib.learning.advantages import gae
from rlq.lib.learning.minibatches import flat_items


@dataclass(frozen=True)
class Layout:
    """How an update's rollout of ``unrolls * num_steps`` steps from ``num_envs`` envs is cut up."""

    unrolls: int
    num_steps: int
    num_envs: int

    def by_unroll(self, x: jax.Array) -> jax.Array:
        """(U*T, E) -> (T, U*E): GAE runs within each unroll, as in brax."""
        return x.reshape((self.unrolls, self.num_steps, self.num_envs)).swapaxes(0, 1).reshape((self.num_steps, -1))

    def from_unroll(self, x: jax.Array) -> jax.Array:
        """(T, U*E) -> (U*T, E)."""
        return x.reshape((self.num_steps, self.unrolls, self.num_envs)).swapaxes(0, 1).reshape((-1, self.num_envs))

    def as_unrolls(self, x: jax.Array, env_major: bool = False) -> jax.Array:
        """(U*T, E, ...) -> (U*E, T, ...): one row per unroll; ``env_major``: (E*U, T, ...)."""
        x = x.reshape((self.unrolls, self.num_steps, self.num_envs) + x.shape[2:])
        x = jnp.moveaxis(x, 2, 0) if env_major else jnp.moveaxis(x, 2, 1)
        return x.reshape((self.unrolls * self.num_envs, self.num_steps) + x.shape[3:])


def fixed_advantages(
    data: dict, values, next_values, reward, terminated, done, layout: Layout, gamma, lam, env_major: bool = False
) -> dict:
    """PureJaxRL's PPO: GAE once per update from the rollout's values; minibatches of transitions."""
    r, v, nv, term, d = (layout.by_unroll(x) for x in (reward, values, next_values, terminated, done))
    advantages, targets = gae(r, v, nv, term, d, gamma, lam)
    data = {**data, "advantage": layout.from_unroll(advantages), "target": layout.from_unroll(targets), "value": values}
    return jax.tree.map(lambda x: flat_items(x, env_major), data)


def whole_unrolls(
    data: dict, next_obs, next_values, reward, terminated, truncated, done, layout: Layout, env_major: bool = False
) -> dict:
    """brax's PPO: minibatches of whole unrolls, GAE recomputed in each with the current value net."""
    last = next_obs.reshape((layout.unrolls, layout.num_steps) + next_obs.shape[1:])[:, -1]
    if env_major:
        last = jnp.moveaxis(last, 1, 0)
    extra = {"reward": reward, "terminated": terminated, "truncated": truncated, "done": done}
    data = jax.tree.map(lambda x: layout.as_unrolls(x, env_major), {**data, **extra, "next_value": next_values})
    return {**data, "last_obs": last.reshape((-1,) + last.shape[2:])}
