"""Tiny envs shared by the algorithm tests."""

import jax
import jax.numpy as jnp

from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import Box


class Target(Env):
    """Box actions, 5-step episodes; reward = -(action - 0.5)^2 per step, best action 0.5."""

    observation_space = Box((-1.0, -1.0), (1.0, 1.0))
    action_space = Box((-1.0,), (1.0,))

    def reset(self, key: jax.Array) -> EnvState:
        return initial_state(jnp.ones(2), None, key)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        return state.replace(reward=-jnp.sum((action - 0.5) ** 2))
