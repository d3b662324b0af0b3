"""The one network module: MLPs and the heads built from them."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from rlq.lib.agents import with_agent_id
from rlq.lib.learning.declared import ACTIVATION_NAMES
from rlq.lib.learning.initializers import orthogonal
from rlq.lib.spaces import AgentsDiscrete, Box, Discrete, Space

#: the activations by name (their names: rlq.lib.learning.declared, which the declarations read without JAX)
ACTIVATIONS: dict[str, Callable[[jax.Array], jax.Array]] = {name: getattr(nn, name) for name in ACTIVATION_NAMES}


#: names accepted for a network's compute dtype (``algo.compute_dtype``)
COMPUTE_DTYPES: dict[str, Any] = {"float32": jnp.float32, "bfloat16": jnp.bfloat16}


def compute_dtype(name: str) -> Any:
    if name not in COMPUTE_DTYPES:
        raise ValueError(f"unknown compute dtype '{name}'; choose one of {sorted(COMPUTE_DTYPES)}")
    return COMPUTE_DTYPES[name]


def activation(name: str) -> Callable[[jax.Array], jax.Array]:
    if name not in ACTIVATIONS:
        raise ValueError(f"unknown activation '{name}'; choose one of {sorted(ACTIVATIONS)}")
    return ACTIVATIONS[name]


class MLP(nn.Module):
    """Dense layers with orthogonal init; the last layer has no activation.

    ``dtype`` is the hidden layers' compute dtype. With bfloat16 the hidden activations (and their
    gradients) are stored at half the size, which is what bounds a wide MLP's minibatch step on a
    GPU; parameters stay float32 and the output layer computes in float32. ``layer_norm`` puts a
    LayerNorm between each hidden layer and its activation (PQN's Q-network)."""

    hidden: Sequence[int]
    out: int
    activation: str = "tanh"
    out_scale: float = 1.0
    dtype: Any = jnp.float32
    layer_norm: bool = False

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        act = activation(self.activation)
        for width in self.hidden:
            x = nn.Dense(width, kernel_init=orthogonal(np.sqrt(2)), dtype=self.dtype)(x)
            if self.layer_norm:
                x = nn.LayerNorm(dtype=self.dtype)(x)
            x = act(x)
        return nn.Dense(self.out, kernel_init=orthogonal(self.out_scale), dtype=jnp.float32)(x)


def encode_obs(obs: jax.Array, space: Space, agent_id: bool = False) -> jax.Array:
    """Network input for an observation: one-hot for Discrete, float vector for Box; for AgentsDiscrete
    each agent's one-hot, (..., agents, n), with ``agent_id`` followed by its index's (rlq.lib.agents)."""
    if isinstance(space, AgentsDiscrete):
        x = jax.nn.one_hot(obs, space.n)
        return with_agent_id(x, space.agents) if agent_id else x
    if isinstance(space, Discrete):
        return jax.nn.one_hot(obs, space.n)
    return obs.astype(jnp.float32)


class ActorCritic(nn.Module):
    """Separate policy and value MLPs. Discrete: logits; Box: Gaussian mean and log-std.

    The log-std is a state-free parameter, or with ``state_std`` a second actor output mapped
    through softplus + 1e-3 (brax's parametrisation). ``value_hidden`` defaults to ``hidden``.
    """

    action_space: Space
    hidden: Sequence[int] = (64, 64)
    activation: str = "tanh"
    value_hidden: Sequence[int] | None = None
    state_std: bool = False
    dtype: Any = jnp.float32

    @nn.compact
    def __call__(self, x: jax.Array) -> tuple[jax.Array, jax.Array | None, jax.Array]:
        value_hidden = self.hidden if self.value_hidden is None else self.value_hidden
        value = MLP(value_hidden, 1, self.activation, out_scale=1.0, dtype=self.dtype, name="critic")(x)[..., 0]
        if isinstance(self.action_space, Discrete):
            logits = MLP(
                self.hidden, self.action_space.n, self.activation, out_scale=0.01, dtype=self.dtype, name="actor"
            )(x)
            return logits, None, value
        assert isinstance(self.action_space, Box)
        dim = self.action_space.shape[0]
        if self.state_std:
            out = MLP(self.hidden, 2 * dim, self.activation, out_scale=0.01, dtype=self.dtype, name="actor")(x)
            mean, raw_scale = out[..., :dim], out[..., dim:]
            return mean, jnp.log(jax.nn.softplus(raw_scale) + 1e-3), value
        mean = MLP(self.hidden, dim, self.activation, out_scale=0.01, dtype=self.dtype, name="actor")(x)
        log_std = self.param("log_std", nn.initializers.zeros, (dim,))
        return mean, jnp.broadcast_to(log_std, mean.shape), value
