"""CartPole-v1 from gymnax behind the rlq Env protocol."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from gymnax.environments.classic_control.cartpole import CartPole as GymnaxCartPole
from omegaconf import DictConfig

from rlq.envs.base import Env, EnvState, initial_state
from rlq.envs.spaces import Box, Discrete


class CartPole(Env):
    """gymnax's CartPole physics; termination from the pole/cart limits only.

    gymnax's own ``step`` auto-resets and folds the time limit in; rlq calls ``step_env`` and
    ``reset_env`` directly and leaves truncation to the TimeLimit wrapper.
    """

    max_episode_steps = 500

    def __init__(self, max_episode_steps: int = 500):
        self._env = GymnaxCartPole()
        self._params = self._env.default_params.replace(max_steps_in_episode=max_episode_steps)
        self.max_episode_steps = int(max_episode_steps)
        high = self._env.observation_space(self._params).high
        self.observation_space = Box(tuple(float(-h) for h in high), tuple(float(h) for h in high))
        self.action_space = Discrete(2)

    def reset(self, key: jax.Array) -> EnvState:
        key, sub = jax.random.split(key)
        obs, inner = self._env.reset_env(sub, self._params)
        return initial_state(obs.astype(jnp.float32), inner, key)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        key, sub = jax.random.split(state.key)
        obs, inner, reward, terminated, _ = self._env.step_env(sub, state.inner, action, self._params)
        return state.replace(
            obs=obs.astype(jnp.float32),
            reward=jnp.asarray(reward, jnp.float32),
            terminated=jnp.asarray(terminated, bool),
            truncated=jnp.zeros((), bool),
            inner=inner,
            key=key,
        )


def make(cfg: DictConfig) -> Env:
    return CartPole(max_episode_steps=cfg.get("max_episode_steps", 500))
