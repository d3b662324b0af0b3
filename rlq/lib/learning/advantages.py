"""Advantage and return estimation: GAE for policy gradients, Q(λ) returns for PQN, n-step returns for
DQN's replay (pure, jittable)."""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp

#: recursions this short are traced unrolled: XLA fuses them into a few kernels instead of a loop
UNROLL_STEPS = 32


def gae(
    rewards: jax.Array,
    values: jax.Array,
    next_values: jax.Array,
    terminated: jax.Array,
    done: jax.Array,
    gamma: float,
    lam: float,
) -> tuple[jax.Array, jax.Array]:
    """Generalised advantage estimates and value targets over a (time, ...) batch.

    ``next_values`` is V of the true successor of each step, so truncated episodes bootstrap
    while terminated ones do not; ``done`` stops the recursion at every episode boundary.
    """
    deltas = rewards + gamma * next_values * (1.0 - terminated) - values

    def backwards(adv_next, x):
        delta, d = x
        adv = delta + gamma * lam * (1.0 - d) * adv_next
        return adv, adv

    steps = deltas.shape[0]
    _, advantages = jax.lax.scan(
        backwards,
        jnp.zeros_like(deltas[0]),
        (deltas, done.astype(deltas.dtype)),
        reverse=True,
        unroll=steps if steps <= UNROLL_STEPS else 1,
    )
    return advantages, advantages + values


def unroll_gae(
    values: jax.Array,
    last_value: jax.Array,
    next_value: jax.Array,
    reward: jax.Array,
    terminated: jax.Array,
    truncated: jax.Array,
    done: jax.Array,
    gamma: float,
    lam: float,
) -> tuple[jax.Array, jax.Array]:
    """``gae`` over (unroll, time) rows from the values of their own observations: a step's
    successor value is the next step's, ``last_value`` (V of the last next observation) after the
    last step, and the stored ``next_value`` (V of the final observation) where it was truncated."""
    successors = jnp.concatenate([values[:, 1:], last_value[:, None]], axis=1)
    next_values = jnp.where(truncated, next_value, successors)
    parts = (reward, values, next_values, terminated.astype(values.dtype), done)
    rows = [x.T for x in parts]
    advantages, targets = gae(rows[0], rows[1], rows[2], rows[3], rows[4], gamma, lam)
    return advantages.T, targets.T


def q_lambda_returns(
    rewards: jax.Array,
    next_q_max: jax.Array,
    terminated: jax.Array,
    done: jax.Array,
    gamma: float,
    lam: float,
) -> jax.Array:
    """Peng's Q(λ) returns over a (time, ...) batch, the targets of PQN (Gallici et al. 2024):

        G_t = r_t + γ(1 − terminated_t)·[(1 − m_t)·max_a Q(s′_t, a) + m_t·G_{t+1}],  m_t = λ(1 − done_t)

    ``next_q_max`` is max_a Q of the true successor of each step (the final observation where an
    episode was truncated), so a truncated step bootstraps, a terminated one does not, and no return
    reaches across an episode boundary; the last step bootstraps alone.
    """
    not_terminal = 1.0 - terminated.astype(rewards.dtype)
    mix = lam * (1.0 - done.astype(rewards.dtype))

    def backwards(return_next, x):
        reward, q_max, alive, m = x
        ret = reward + gamma * alive * ((1.0 - m) * q_max + m * return_next)
        return ret, ret

    steps = rewards.shape[0]
    _, returns = jax.lax.scan(
        backwards,
        next_q_max[-1],
        (rewards, next_q_max, not_terminal, mix),
        reverse=True,
        unroll=steps if steps <= UNROLL_STEPS else 1,
    )
    return returns


def n_step_returns(
    rewards: jax.Array,
    terminated: jax.Array,
    done: jax.Array,
    next_obs: Any,
    gamma: float,
    n: int,
) -> tuple[jax.Array, Any, jax.Array]:
    """n-step TD transitions from a (time, ...) batch of consecutive steps, for replay.

    Step t's return sums γ^j·r_{t+j} over k_t = min(n, T − t) steps, fewer where an episode ends
    first (no return reaches across a boundary). It comes with the observation to bootstrap from
    (the true successor of its last step) and that bootstrap's discount γ^k·(1 − terminated), so the
    target is ``return + discount·V(bootstrap)``: 0 after a termination, the value after a
    truncation. With n = 1 these are the one-step (r, s′, γ(1 − terminated)) exactly.
    """
    horizon = rewards.shape[0]
    time = jnp.arange(horizon).reshape((horizon,) + (1,) * (rewards.ndim - 1))
    returns = jnp.zeros_like(rewards)
    discount = jnp.zeros_like(rewards)
    scale = jnp.ones_like(rewards)
    alive = jnp.ones(rewards.shape, bool)
    bootstrap = next_obs
    for j in range(n):
        index = jnp.minimum(jnp.arange(horizon) + j, horizon - 1)
        use = alive & (time + j < horizon)
        returns = jnp.where(use, returns + scale * rewards[index], returns)
        discount = jnp.where(use, scale * gamma * (1.0 - terminated[index].astype(rewards.dtype)), discount)
        bootstrap = jax.tree.map(functools.partial(_take_where, use, index), bootstrap, next_obs)
        scale = scale * gamma
        alive = use & ~done[index]
    return returns, bootstrap, discount


def _take_where(use: jax.Array, index: jax.Array, kept: jax.Array, source: jax.Array) -> jax.Array:
    """``source[index]`` where ``use`` (broadcast over trailing feature axes), else ``kept``."""
    return jnp.where(use.reshape(use.shape + (1,) * (source.ndim - use.ndim)), source[index], kept)
