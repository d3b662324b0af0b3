"""Action distributions shared by the policy-gradient algorithms."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from rlq.lib.learning.declared import ACTION_DISTS
from rlq.lib.spaces import AgentsDiscrete, Box, Discrete, Space


def categorical_sample(key: jax.Array, logits: jax.Array) -> jax.Array:
    return jax.random.categorical(key, logits)


def categorical_log_prob(logits: jax.Array, action: jax.Array) -> jax.Array:
    logp = jax.nn.log_softmax(logits)
    return jnp.take_along_axis(logp, action[..., None].astype(jnp.int32), axis=-1)[..., 0]


def categorical_entropy(logits: jax.Array) -> jax.Array:
    logp = jax.nn.log_softmax(logits)
    return -jnp.sum(jnp.exp(logp) * logp, axis=-1)


def gaussian_sample(key: jax.Array, mean: jax.Array, log_std: jax.Array) -> jax.Array:
    return mean + jnp.exp(log_std) * jax.random.normal(key, mean.shape)


def gaussian_log_prob(mean: jax.Array, log_std: jax.Array, action: jax.Array) -> jax.Array:
    z = (action - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * z**2 - log_std - 0.5 * jnp.log(2 * jnp.pi), axis=-1)


def gaussian_entropy(log_std: jax.Array) -> jax.Array:
    return jnp.sum(log_std + 0.5 * jnp.log(2 * jnp.pi * jnp.e), axis=-1)


def tanh_log_det_jacobian(raw: jax.Array) -> jax.Array:
    """log(1 - tanh(u)^2) per dimension, in a form that stays finite for large |u|."""
    return 2.0 * (jnp.log(2.0) - raw - jax.nn.softplus(-2.0 * raw))


def tanh_normal_log_prob(mean: jax.Array, log_std: jax.Array, raw: jax.Array) -> jax.Array:
    """Log-density of ``tanh(raw)`` for ``raw ~ N(mean, exp(log_std))``, taking the pre-tanh ``raw``.

    Scoring the stored pre-tanh sample avoids ``arctanh`` of actions at the bounds.
    """
    return gaussian_log_prob(mean, log_std, raw) - jnp.sum(tanh_log_det_jacobian(raw), axis=-1)


def tanh_normal_entropy(key: jax.Array, mean: jax.Array, log_std: jax.Array) -> jax.Array:
    """One-sample estimate of the squashed entropy, H[N] + E[log|d tanh/du|] (as brax does)."""
    raw = gaussian_sample(key, mean, log_std)
    return gaussian_entropy(log_std) + jnp.sum(tanh_log_det_jacobian(raw), axis=-1)


@dataclass(frozen=True)
class ActionDist:
    """A policy head's distribution. ``out`` is the network's ``(logits or mean, log_std)``.

    ``sample`` returns the action PPO stores and scores (pre-tanh for tanh_normal); ``to_env``
    maps it into the env's action space; ``mode`` is the greedy env action.
    """

    sample: Callable[[jax.Array, tuple], jax.Array]
    log_prob: Callable[[tuple, jax.Array], jax.Array]
    entropy: Callable[[tuple, jax.Array | None], jax.Array]  # the key: tanh-normal's one-sample estimate needs it
    to_env: Callable[[jax.Array], jax.Array]
    mode: Callable[[tuple], jax.Array]


def _sampled_tanh_entropy(out: tuple, key: jax.Array | None) -> jax.Array:
    if key is None:
        raise ValueError("the tanh-squashed Gaussian's entropy is a one-sample estimate: it needs a key")
    return tanh_normal_entropy(key, *out)


def categorical(joint: bool = False) -> ActionDist:
    """A categorical over logits (..., n); ``joint``: agents that act independently given their own logits
    (..., agents, n), so the joint action's log-probability is the sum of the agents', and so is its entropy."""
    total = (lambda x: x.sum(axis=-1)) if joint else (lambda x: x)
    return ActionDist(
        sample=lambda key, out: categorical_sample(key, out[0]),
        log_prob=lambda out, a: total(categorical_log_prob(out[0], a)),
        entropy=lambda out, key: total(categorical_entropy(out[0])),
        to_env=lambda a: a,
        mode=lambda out: jnp.argmax(out[0], axis=-1),
    )


def make_action_dist(space: Space, kind: str = "clipped_normal") -> ActionDist:
    """Categorical for Discrete, one per agent for AgentsDiscrete (``categorical(joint=True)``); for Box a
    Gaussian clipped to the bounds at the env (``clipped_normal``) or squashed by tanh and rescaled to
    the bounds (``tanh_normal``)."""
    if isinstance(space, Discrete | AgentsDiscrete):
        return categorical(joint=isinstance(space, AgentsDiscrete))
    if kind not in ACTION_DISTS:
        raise ValueError(f"unknown action_dist '{kind}'; choose one of {list(ACTION_DISTS)}")
    assert isinstance(space, Box), "only Discrete, AgentsDiscrete and Box spaces exist"
    low, high = jnp.asarray(space.low, jnp.float32), jnp.asarray(space.high, jnp.float32)
    if kind == "tanh_normal":

        def squash(raw):
            return low + (jnp.tanh(raw) + 1.0) * 0.5 * (high - low)

        return ActionDist(
            sample=lambda key, out: gaussian_sample(key, *out),
            log_prob=lambda out, a: tanh_normal_log_prob(out[0], out[1], a),
            entropy=_sampled_tanh_entropy,
            to_env=squash,
            mode=lambda out: squash(out[0]),
        )
    return ActionDist(
        sample=lambda key, out: gaussian_sample(key, *out),
        log_prob=lambda out, a: gaussian_log_prob(out[0], out[1], a),
        entropy=lambda out, key: gaussian_entropy(out[1]),
        to_env=lambda a: jnp.clip(a, low, high),
        mode=lambda out: jnp.clip(out[0], low, high),
    )
