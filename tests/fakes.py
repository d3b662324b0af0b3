"""The fake envs every test shares: tiny, deterministic where it matters, no physics."""

import jax
import jax.numpy as jnp

from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import AgentsDiscrete, Box, Discrete, Space


class Target(Env):
    """Box actions, 5-step episodes; reward = -(action - 0.5)^2 per step, best action 0.5."""

    observation_space = Box((-1.0, -1.0), (1.0, 1.0))
    action_space = Box((-1.0,), (1.0,))

    def reset(self, key: jax.Array) -> EnvState:
        return initial_state(jnp.ones(2), None, key)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        return state.replace(reward=-jnp.sum((action - 0.5) ** 2))


class SpacesOnly(Env):
    """Only the spaces, for the checks an algorithm or controller makes before building anything."""

    def __init__(self, observation_space: Space, action_space: Space):
        self.observation_space, self.action_space = observation_space, action_space


class Counter(Env):
    """obs = steps taken; reward 1 per step; terminates when the action is 1."""

    observation_space = Box((0.0,), (100.0,))
    action_space = Discrete(2)

    def reset(self, key):
        return initial_state(jnp.zeros(1), jnp.zeros((), jnp.int32), key)

    def step(self, state: EnvState, action):
        t = state.inner + 1
        return state.replace(obs=t[None].astype(jnp.float32), reward=jnp.ones(()), terminated=action == 1, inner=t)


class RandomStart(Env):
    """obs = a random start value plus the steps taken; terminates when the action is 1."""

    observation_space = Box((0.0,), (100.0,))
    action_space = Discrete(2)

    def __init__(self, reset_cache: bool):
        self.reset_cache = reset_cache
        self.resets_traced = 0

    def reset(self, key):
        self.resets_traced += 1
        start = jax.random.uniform(key, (1,))
        return initial_state(start, start, key)

    def step(self, state: EnvState, action):
        inner = state.inner + 1.0
        return state.replace(obs=inner, reward=jnp.ones(()), terminated=action == 1, inner=inner)


class Bandit(Env):
    """One-step episodes: obs = 10 + 20*u (u ~ U(-1, 1)^2), reward = -(a - u0/2)^2, a in [-1, 1]."""

    observation_space = Box((-10.0, -10.0), (30.0, 30.0))
    action_space = Box((-1.0,), (1.0,))
    max_episode_steps = 1

    def reset(self, key):
        key, sub = jax.random.split(key)
        u = jax.random.uniform(sub, (2,), minval=-1.0, maxval=1.0)
        return initial_state(10.0 + 20.0 * u, u, key)

    def step(self, state: EnvState, action):
        reward = -jnp.square(action[0] - 0.5 * state.inner[0])
        return state.replace(reward=reward, terminated=jnp.ones((), bool))


class Walk(Env):
    """Deterministic 1-d walk: position += action, reward = action, descriptor = (pos, 2 pos)."""

    observation_space = Box((-10.0,), (10.0,))
    action_space = Box((-1.0,), (1.0,))

    def reset(self, key: jax.Array) -> EnvState:
        return initial_state(jnp.zeros(1), None, key, {"descriptor": jnp.zeros(2)})

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        pos = state.obs + action
        return state.replace(obs=pos, reward=action[0], info={"descriptor": jnp.concatenate([pos, 2 * pos])})


class Arms(Env):
    """Decentralised one-step episodes: 3 agents in the fixed states 0, 1, 2 each pick 0 or 1; the
    shared reward is the fraction of agents whose action is their state's parity (best: 0, 1, 0)."""

    observation_space = AgentsDiscrete(3, 3)
    action_space = AgentsDiscrete(2, 3)
    max_episode_steps = 1

    def reset(self, key):
        return initial_state(jnp.arange(3, dtype=jnp.int32), None, key)

    def step(self, state: EnvState, action):
        reward = jnp.mean((action == state.obs % 2).astype(jnp.float32))
        return state.replace(reward=reward, terminated=jnp.ones((), bool))
