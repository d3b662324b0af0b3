"""PQN (Gallici et al. 2024, "Simplifying Deep Temporal Difference Learning"): Q-learning from many
parallel envs without a replay buffer or a target network.

One ``update`` runs ``num_steps`` ε-greedy steps of ``num_envs`` envs, computes Peng's Q(λ) returns
backwards through them with the current network (``rlq.lib.learning.advantages.q_lambda_returns``), and regresses
Q(s, a) on them for ``update_epochs`` passes of ``num_minibatches`` shuffled minibatches (the learner
loop PPO uses). LayerNorm in the Q-network keeps the bootstrapped targets stable without a target net.
Many envs and large batches suit a GPU, where a DQN with 16 envs waits on each env step.
Decentralised control (``AgentsDiscrete`` observations and actions): independent learners sharing one
Q-network (rlq/lib/agents.py); each agent's Q(λ) returns bootstrap from its own next observation with
the env's one reward, and the loss is averaged over the agents.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import optax
from flax import struct

from rlq.algos.base import Algorithm, Hyperparams, updates_for_budget
from rlq.algos.spec import AlgorithmSpec
from rlq.declared.pqn import Config
from rlq.lib.agents import discrete_actions_problem, per_agent
from rlq.lib.env_api import Env, EnvState
from rlq.lib.learning import optimizers
from rlq.lib.learning.advantages import q_lambda_returns
from rlq.lib.learning.minibatches import flat_items, minibatch_epochs, shard_problem, shuffle_shards
from rlq.lib.learning.networks import MLP, encode_obs
from rlq.lib.learning.schedules import check_epsilon, epsilon_greedy, epsilon_schedule
from rlq.lib.rollout import episode_summary, reset_batch, rollout
from rlq.lib.sharding import shard_envs
from rlq.lib.spaces import AgentsDiscrete, Discrete

#: the numeric keys an in-program sweep may give each member (they enter the update only as arithmetic)
SWEEPABLE = ("lr", "gamma", "lam")


class PQNState(struct.PyTreeNode):
    params: Any
    opt_state: optax.OptState
    env_state: EnvState
    key: jax.Array
    env_steps: jax.Array
    episodes: jax.Array  # completed episodes over all envs (for per-episode ε decay)


def check(cfg: Config, env: Env) -> str | None:
    problem = discrete_actions_problem("pqn", env)
    if problem:
        return problem
    if (cfg.num_envs * cfg.num_steps) % cfg.num_minibatches:
        return (
            f"algo.num_minibatches={cfg.num_minibatches} must divide the update's "
            f"algo.num_envs*algo.num_steps={cfg.num_envs * cfg.num_steps} transitions"
        )
    if not 0.0 <= cfg.lam <= 1.0:
        return f"algo.lam must lie in [0, 1], got {cfg.lam}"
    return check_epsilon(cfg.epsilon, "algo.epsilon")


def q_lambda_targets(
    reward: jax.Array, next_q: jax.Array, terminated: jax.Array, done: jax.Array, gamma: Any, lam: Any
) -> jax.Array:
    """Peng's Q(λ) returns (``rlq.lib.learning.advantages.q_lambda_returns``) from Q-values of the true successors,
    (time, env, actions), or with agents (time, env, agents, actions): then one return per agent, which
    bootstraps from that agent's own next observation with the env's one reward and termination."""
    next_q_max = next_q.max(-1)
    reward, terminated, done = (per_agent(x, next_q_max) for x in (reward, terminated, done))
    return q_lambda_returns(reward, next_q_max, terminated, done, gamma, lam)


def check_env_shards(cfg: Config, shards: int) -> str | None:
    """Per-shard minibatches need each env device's share of the update's transitions to split into
    ``num_minibatches`` equal parts."""
    return shard_problem(cfg.minibatch_shuffle, cfg.num_envs * cfg.num_steps, shards, cfg.num_minibatches)


def make(cfg: Config, env: Env, budget_env_steps: int) -> Algorithm:
    obs_space, action_space = env.observation_space, env.action_space
    assert isinstance(action_space, Discrete | AgentsDiscrete), "check() admits only discrete actions"
    net = MLP(tuple(cfg.hidden), action_space.n, cfg.activation, layer_norm=bool(cfg.layer_norm))
    agent_id = bool(cfg.agent_id)
    steps_per_update = cfg.num_envs * cfg.num_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)
    grad_steps = num_updates * cfg.update_epochs * cfg.num_minibatches
    defaults = {name: float(getattr(cfg, name)) for name in SWEEPABLE}

    def optimizer(lr: Any) -> optax.GradientTransformation:
        return optimizers.adam(lr, grad_steps if cfg.anneal_lr else None, cfg.max_grad_norm)

    tx = optimizer(defaults["lr"])
    epsilon = epsilon_schedule(cfg.epsilon)
    reward_scaling = float(cfg.reward_scaling)

    def q_values(params, obs):
        return net.apply(params, encode_obs(obs, obs_space, agent_id))

    def loss_fn(params, batch):
        q = q_values(params, batch["obs"])
        q_taken = jnp.take_along_axis(q, batch["action"][..., None], axis=-1)[..., 0]
        return 0.5 * jnp.mean((q_taken - batch["target"]) ** 2), q_taken.mean()

    def init(key: jax.Array, hp: Hyperparams) -> PQNState:
        key, net_key, env_key = jax.random.split(key, 3)
        env_state = reset_batch(env, env_key, cfg.num_envs)
        params = net.init(net_key, encode_obs(env_state.obs[0], obs_space, agent_id))
        zero = jnp.zeros((), jnp.int32)
        return PQNState(params, tx.init(params), env_state, key, zero, zero)

    def update(state: PQNState, hp: Hyperparams) -> tuple[PQNState, dict]:
        """One update at the numeric hyperparameters ``hp`` (``SWEEPABLE``)."""
        tx_hp = optimizer(hp["lr"])

        def minibatch_step(carry, minibatch, _key):  # the loss draws no randomness
            params, opt_state = carry  # the minibatch is split over the env devices: each takes its share's gradient
            (loss, q_mean), grads = jax.value_and_grad(loss_fn, has_aux=True)(params, shard_envs(minibatch))
            updates, opt_state = tx_hp.update(grads, opt_state, params)
            return (optax.apply_updates(params, updates), opt_state), {"loss": loss, "q_mean": q_mean}

        key, roll_key, learn_key = jax.random.split(state.key, 3)
        eps = epsilon(state.env_steps, state.episodes)

        def act(obs, k):
            return epsilon_greedy(k, q_values(state.params, obs), eps), {}

        env_state, traj = rollout(env, state.env_state, act, roll_key, cfg.num_steps)
        next_q = q_values(state.params, traj.next_obs)
        reward = traj.reward * reward_scaling
        targets = q_lambda_targets(reward, next_q, traj.terminated, traj.done, hp["gamma"], hp["lam"])
        data = {"obs": traj.obs, "action": traj.action, "target": targets}
        shards = shuffle_shards(cfg.minibatch_shuffle)
        data = jax.tree.map(lambda x: flat_items(x, env_major=shards > 1), data)
        (params, opt_state), metrics = minibatch_epochs(
            minibatch_step,
            (state.params, state.opt_state),
            data,
            learn_key,
            cfg.update_epochs,
            cfg.num_minibatches,
            shards,
        )
        env_steps = state.env_steps + steps_per_update
        episodes = state.episodes + traj.done.sum()
        metrics = {
            **jax.tree.map(jnp.mean, metrics),
            **episode_summary(traj),
            "epsilon": eps,
            "env_steps": env_steps,
        }
        return PQNState(params, opt_state, env_state, key, env_steps, episodes), metrics

    def policy(state: PQNState):
        def greedy(obs, key):
            return jnp.argmax(q_values(state.params, obs), axis=-1)

        return greedy

    return Algorithm(
        init, update, policy, num_updates, steps_per_update, params=lambda s: s.params, hyperparams=defaults
    )


SPEC = AlgorithmSpec(
    config=Config,
    make=make,
    check=check,
    check_env_shards=check_env_shards,
    sweepable=SWEEPABLE,
    agents=True,
)
