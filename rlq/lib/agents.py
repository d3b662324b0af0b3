"""Decentralised control with parameter sharing (``AgentsDiscrete`` spaces): what the deep learners
(PPO, DQN, PQN) and tabular Q share to treat each agent's observation and action as their own.

Every agent's input is its own state's one-hot (with ``agent_id`` also its index's one-hot); one
network maps it to that agent's outputs. The MLPs act on the last axis, so applying the network to
inputs shaped (..., agents, features) is the shared network applied to each agent (a vmap over the
agent axis) with one set of parameters. The env's reward and termination are one per env, shared by
its agents: ``per_agent`` broadcasts them over the agent axis.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from rlq.lib.env_api import Env
from rlq.lib.spaces import AgentsDiscrete, Discrete, Space


def num_agents(space: Space) -> int:
    """The agents of a per-agent space; 0 for a single agent's."""
    return space.agents if isinstance(space, AgentsDiscrete) else 0


def agent_space(space: Space) -> Space:
    """One agent's share of a per-agent space (``Discrete(n)``); any other space as it is."""
    return Discrete(space.n) if isinstance(space, AgentsDiscrete) else space


def with_agent_id(x: jax.Array, agents: int) -> jax.Array:
    """``x`` (..., agents, features) with each agent's index one-hot appended to its features."""
    ids = jnp.broadcast_to(jnp.eye(agents, dtype=x.dtype), x.shape[:-1] + (agents,))
    return jnp.concatenate([x, ids], axis=-1)


def per_agent(x: jax.Array, like: jax.Array) -> jax.Array:
    """A per-env quantity (the shared reward, discount or termination) broadcast to ``like``'s
    per-agent shape; unchanged where there are no agents (the shapes already agree)."""
    return jnp.broadcast_to(x.reshape(x.shape + (1,) * (like.ndim - x.ndim)), like.shape)


def agents_problem(algo: str, obs_space: Space, action_space: Space) -> str | None:
    """Per-agent observations need per-agent actions and the other way round, for as many agents."""
    obs_agents, action_agents = num_agents(obs_space), num_agents(action_space)
    if obs_agents == action_agents:
        return None
    if not action_agents:
        return f"algo={algo}: one state per arm (env.observation=arm_sectors) needs one action per arm: controller.mode=decentralised"
    if not obs_agents:
        return f"algo={algo}: one action per arm (controller.mode=decentralised) needs one state per arm: env.observation=arm_sectors"
    return f"algo={algo}: the observation has {obs_agents} agents but the action {action_agents}"


def discrete_actions_problem(algo: str, env: Env) -> str | None:
    """What keeps a value learner (DQN, PQN, tabular Q), which picks among discrete actions, from ``env``: continuous
    actions, or per-agent spaces that do not meet (``agents_problem``)."""
    if not isinstance(env.action_space, Discrete | AgentsDiscrete):
        name = type(env.unwrapped).__name__
        return (
            f"algo={algo} needs a discrete action space, but {name} has continuous actions; use algo=ppo for this env"
        )
    return agents_problem(algo, env.observation_space, env.action_space)
