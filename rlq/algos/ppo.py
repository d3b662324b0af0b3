"""Proximal Policy Optimisation (clipped objective, GAE, minibatch epochs), discrete or continuous.

One update steps ``num_envs`` envs for ``U * num_steps`` steps (one scan), computes GAE within
each unroll of ``num_steps`` steps, and takes ``update_epochs`` passes of ``num_minibatches``
shuffled minibatches. ``U`` is 1 unless ``batch_size`` is set, which takes brax's meaning: a
minibatch holds ``batch_size`` unrolls, so ``U = batch_size * num_minibatches / num_envs``.
With ``recompute_gae`` (brax), minibatches are whole unrolls and every minibatch recomputes GAE
with the current value net; otherwise advantages are fixed once per update (PureJaxRL).
Decentralised control (``AgentsDiscrete`` observations and actions, the brittle star's arms): one
actor-critic shared by the agents reads each agent's observation (rlq/lib/agents.py); the joint
policy factorises over them (``rlq.lib.learning.distributions.categorical(joint=True)``) and the value is the mean of
the agents' values (``joint_value``), learnt from the env's one reward.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import optax
from flax import struct

from rlq.algos.base import Algorithm, Hyperparams, updates_for_budget
from rlq.algos.ppo_batches import Layout, fixed_advantages, whole_unrolls
from rlq.algos.spec import AlgorithmSpec
from rlq.declared.ppo import Config
from rlq.lib.agents import agent_space, agents_problem, num_agents
from rlq.lib.env_api import Env, EnvState
from rlq.lib.learning import distributions as dist
from rlq.lib.learning import normalize as running
from rlq.lib.learning import optimizers
from rlq.lib.learning.advantages import unroll_gae
from rlq.lib.learning.minibatches import minibatch_epochs, shard_problem, shuffle_shards
from rlq.lib.learning.networks import COMPUTE_DTYPES, ActorCritic, compute_dtype, encode_obs
from rlq.lib.policy_export import PolicyExport, mlp_policy
from rlq.lib.rollout import episode_summary, reset_batch, rollout
from rlq.lib.sharding import shard_envs
from rlq.lib.spaces import AgentsDiscrete, Box, Discrete

__all__ = ["SPEC", "SWEEPABLE", "Config", "PPOState", "check", "make", "steps_per_update"]

#: the numeric keys an in-program sweep may give each member (they enter the update only as arithmetic)
SWEEPABLE = ("lr", "clip_eps", "vf_coef", "ent_coef", "gamma", "gae_lambda")


class PPOState(struct.PyTreeNode):
    params: Any
    opt_state: optax.OptState
    obs_stats: running.RunningStats
    env_state: EnvState
    key: jax.Array
    env_steps: jax.Array


def unrolls_per_update(cfg: Config) -> int:
    batch_size = cfg.batch_size
    return 1 if batch_size is None else batch_size * cfg.num_minibatches // cfg.num_envs


def steps_per_update(cfg: Config) -> int:
    """Env steps one update collects: ``unrolls_per_update`` unrolls of ``num_steps`` from every env."""
    return cfg.num_envs * unrolls_per_update(cfg) * cfg.num_steps


def check(cfg: Config, env: Env) -> str | None:
    if not isinstance(env.action_space, Discrete | Box | AgentsDiscrete):
        return "ppo needs a Discrete or Box action space"
    problem = agents_problem("ppo", env.observation_space, env.action_space)
    if problem:
        return problem
    batch_size = cfg.batch_size
    if batch_size is not None:
        if (batch_size * cfg.num_minibatches) % cfg.num_envs:
            return (
                f"algo.batch_size*algo.num_minibatches={batch_size * cfg.num_minibatches} must be a multiple "
                f"of algo.num_envs={cfg.num_envs} (brax semantics: unrolls per minibatch)"
            )
    elif (cfg.num_envs * cfg.num_steps) % cfg.num_minibatches:
        return (
            f"algo.num_minibatches={cfg.num_minibatches} must divide "
            f"algo.num_envs*algo.num_steps={cfg.num_envs * cfg.num_steps}"
        )
    if cfg.recompute_gae:
        if cfg.clip_value:
            return "algo.recompute_gae=true needs algo.clip_value=false (brax's unclipped value loss)"
        if (unrolls_per_update(cfg) * cfg.num_envs) % cfg.num_minibatches:
            unrolls = unrolls_per_update(cfg) * cfg.num_envs
            return f"algo.recompute_gae=true takes minibatches of whole unrolls: algo.num_minibatches must divide {unrolls}"
    kind = cfg.action_dist
    if isinstance(env.action_space, Box):
        if kind not in dist.ACTION_DISTS:
            return f"algo.action_dist must be one of {', '.join(dist.ACTION_DISTS)}, got {kind!r}"
        if kind == "tanh_normal" and not env.action_space.bounded:
            return "algo.action_dist=tanh_normal needs a bounded action space; use algo.action_dist=clipped_normal"
    if cfg.normalize_obs and not isinstance(env.observation_space, Box):
        return "algo.normalize_obs=true needs a Box observation space; set algo.normalize_obs=false"
    dtype = cfg.compute_dtype
    if dtype not in COMPUTE_DTYPES:
        return f"algo.compute_dtype must be one of {', '.join(COMPUTE_DTYPES)}, got {dtype!r}"
    return None


def check_env_shards(cfg: Config, shards: int) -> str | None:
    """Per-shard minibatches need each env device's share of the learning items (transitions, or whole
    unrolls with ``recompute_gae``) to split into ``num_minibatches`` equal parts."""
    items = unrolls_per_update(cfg) * cfg.num_envs * (1 if cfg.recompute_gae else cfg.num_steps)
    return shard_problem(cfg.minibatch_shuffle, items, shards, cfg.num_minibatches)


def clipped_surrogate(ratio, advantages, clip_eps: float) -> jax.Array:
    """PPO's policy loss on normalised advantages."""
    adv = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
    return -jnp.minimum(ratio * adv, jnp.clip(ratio, 1 - clip_eps, 1 + clip_eps) * adv).mean()


def value_loss(value, targets, old_values, clip_eps: float | None) -> jax.Array:
    """Half the mean squared error; with ``clip_eps`` PureJaxRL's clipped variant (brax: unclipped)."""
    loss = (value - targets) ** 2
    if clip_eps is not None:
        clipped = old_values + jnp.clip(value - old_values, -clip_eps, clip_eps)
        loss = jnp.maximum(loss, (clipped - targets) ** 2)
    return 0.5 * loss.mean()


def joint_value(out: tuple) -> tuple:
    """Per-agent outputs (logits (..., A, n), None, values (..., A)) with the joint state's value: the
    mean of the agents' values, from one value head shared by the agents.

    The mean, not a value of the concatenated observations: the reward is one for all agents, and each
    agent's head sees only its own observation, so the critic stays the same per-agent network as the
    actor (independent of the agents' order and, but for ``agent_id``, of their count), while its
    mean can still express any value that adds up contributions of the agents' states."""
    logits, log_std, values = out
    return logits, log_std, values.mean(axis=-1)


def make(cfg: Config, env: Env, budget_env_steps: int) -> Algorithm:
    obs_space, action_space = env.observation_space, env.action_space
    kind = cfg.action_dist
    action_dist = dist.make_action_dist(action_space, kind)
    hidden = tuple(cfg.policy_hidden or cfg.hidden)
    value_hidden = tuple(cfg.value_hidden or cfg.hidden)
    state_std = isinstance(action_space, Box) and kind == "tanh_normal"
    dtype = compute_dtype(cfg.compute_dtype)
    net = ActorCritic(agent_space(action_space), hidden, cfg.activation, value_hidden, state_std, dtype)
    agents, agent_id = num_agents(action_space), bool(cfg.agent_id)
    normalize_obs = bool(cfg.normalize_obs)
    reward_scaling = float(cfg.reward_scaling)
    clip_value = bool(cfg.clip_value)
    recompute = bool(cfg.recompute_gae)

    unrolls, num_steps, num_envs = unrolls_per_update(cfg), cfg.num_steps, cfg.num_envs
    layout = Layout(unrolls, num_steps, num_envs)
    update_steps = steps_per_update(cfg)
    num_updates = updates_for_budget(budget_env_steps, update_steps)
    grad_steps = num_updates * cfg.update_epochs * cfg.num_minibatches
    anneal_steps = grad_steps if cfg.anneal_lr else None
    defaults = {name: float(getattr(cfg, name)) for name in SWEEPABLE}

    def optimizer(lr: Any) -> optax.GradientTransformation:
        """Adam at ``lr``: the state's structure does not depend on ``lr``, so one ``init`` serves every value."""
        return optimizers.adam(lr, anneal_steps, cfg.max_grad_norm, eps=cfg.adam_eps)

    tx = optimizer(defaults["lr"])

    def forward(params, stats, obs):
        x = encode_obs(obs, obs_space, agent_id)
        out = net.apply(params, running.normalize(stats, x) if normalize_obs else x)
        return joint_value(out) if agents else out

    def init(key: jax.Array, hp: Hyperparams) -> PPOState:
        key, net_key, env_key = jax.random.split(key, 3)
        env_state = reset_batch(env, env_key, num_envs)
        x0 = encode_obs(env_state.obs[0], obs_space, agent_id)
        params = net.init(net_key, x0)
        stats = running.init(x0.shape)
        return PPOState(params, tx.init(params), stats, env_state, key, jnp.zeros((), jnp.int32))

    def act_fn(params, stats):
        def act(obs, key):
            out = forward(params, stats, obs)
            action = action_dist.sample(key, out[:2])
            aux = {"action": action, "log_prob": action_dist.log_prob(out[:2], action)}
            if not (normalize_obs or recompute):  # else values are recomputed with the updated statistics
                aux["value"] = out[2]
            return action_dist.to_env(action), aux

        return act

    def unroll_outputs(params, stats, batch, split):
        """Network outputs on a minibatch's unrolls (size, steps, ...) and V of their last next observations.

        ``split`` (the minibatch split over env devices): the last observations join each unroll's
        row, so every device keeps its own rows; else one flat batch (the one-device numbers)."""
        obs, (size, steps) = batch["obs"], batch["obs"].shape[:2]
        if split:
            out = forward(params, stats, jnp.concatenate([obs, batch["last_obs"][:, None]], axis=1))
            last_value = out[2][:, steps]
            return jax.tree.map(lambda x: x[:, :steps], out), last_value
        flat = jnp.concatenate([obs.reshape((size * steps,) + obs.shape[2:]), batch["last_obs"]])
        out = forward(params, stats, flat)
        last_value = out[2][size * steps :]
        return jax.tree.map(lambda x: x[: size * steps].reshape((size, steps) + x.shape[1:]), out), last_value

    def fresh_gae(params, stats, batch, hp, split):
        """Network outputs on a minibatch of unrolls, and GAE from the current value net (brax)."""
        out, last_value = unroll_outputs(params, stats, batch, split)
        last_value = jax.lax.stop_gradient(last_value)
        values = jax.lax.stop_gradient(out[2])
        advantages, targets = unroll_gae(
            values,
            last_value,
            batch["next_value"],
            batch["reward"],
            batch["terminated"],
            batch["truncated"],
            batch["done"],
            hp["gamma"],
            hp["gae_lambda"],
        )
        return out, advantages, targets

    def loss_fn(params, stats, batch, key, hp, split):
        if recompute:
            out, advantages, targets = fresh_gae(params, stats, batch, hp, split)
        else:
            out, advantages, targets = forward(params, stats, batch["obs"]), batch["advantage"], batch["target"]
        action, old_logp, value = batch["action"], batch["log_prob"], out[2]
        logp, entropy = action_dist.log_prob(out[:2], action), action_dist.entropy(out[:2], key)
        ratio = jnp.exp(logp - old_logp)
        pg_loss = clipped_surrogate(ratio, advantages, hp["clip_eps"])
        v_loss = value_loss(value, targets, batch.get("value"), hp["clip_eps"] if clip_value else None)
        ent = entropy.mean()
        total = pg_loss + hp["vf_coef"] * v_loss - hp["ent_coef"] * ent
        approx_kl = ((ratio - 1) - (logp - old_logp)).mean()
        return total, {"policy_loss": pg_loss, "value_loss": v_loss, "entropy": ent, "approx_kl": approx_kl}

    def learning_data(traj, stats, params, hp, env_major):
        """What the minibatches are cut from: transitions with fixed advantages, or whole unrolls."""
        next_values = forward(params, stats, traj.next_obs)[2]
        terminated, reward = traj.terminated.astype(jnp.float32), traj.reward * reward_scaling
        data = {"obs": traj.obs, "action": traj.aux["action"], "log_prob": traj.aux["log_prob"]}
        if recompute:
            return whole_unrolls(
                data, traj.next_obs, next_values, reward, terminated, traj.truncated, traj.done, layout, env_major
            )
        values = forward(params, stats, traj.obs)[2] if normalize_obs else traj.aux["value"]
        return fixed_advantages(
            data, values, next_values, reward, terminated, traj.done, layout, hp["gamma"], hp["gae_lambda"], env_major
        )

    def update(state: PPOState, hp: Hyperparams) -> tuple[PPOState, dict]:
        """One update at the numeric hyperparameters ``hp`` (``SWEEPABLE``)."""
        tx_hp = optimizer(hp["lr"])
        key, roll_key, perm_key = jax.random.split(state.key, 3)
        act = act_fn(state.params, state.obs_stats)
        env_state, traj = rollout(env, state.env_state, act, roll_key, unrolls * num_steps)
        stats = state.obs_stats
        if normalize_obs:  # new statistics first (as brax), then values that agree with them
            stats = running.update(stats, encode_obs(traj.obs, obs_space))
        shards = shuffle_shards(cfg.minibatch_shuffle)  # per_shard: each env device shuffles its own share
        data = learning_data(traj, stats, state.params, hp, env_major=shards > 1)

        def minibatch_step(carry, minibatch, loss_key):
            params, opt_state = carry  # the minibatch is split over the env devices: each takes its share's gradient
            grads, metrics = jax.grad(loss_fn, has_aux=True)(
                params, stats, shard_envs(minibatch), loss_key, hp, shards > 1
            )
            updates, opt_state = tx_hp.update(grads, opt_state, params)
            return (optax.apply_updates(params, updates), opt_state), metrics

        (params, opt_state), metrics = minibatch_epochs(
            minibatch_step,
            (state.params, state.opt_state),
            data,
            perm_key,
            cfg.update_epochs,
            cfg.num_minibatches,
            shards,
        )
        env_steps = state.env_steps + update_steps
        metrics = {**jax.tree.map(jnp.mean, metrics), **episode_summary(traj), "env_steps": env_steps}
        return PPOState(params, opt_state, stats, env_state, key, env_steps), metrics

    def policy(state: PPOState):
        def greedy(obs, key):
            return action_dist.mode(forward(state.params, state.obs_stats, obs)[:2])

        return greedy

    def export(state: PPOState) -> PolicyExport:
        if isinstance(action_space, Discrete):
            head, outputs = "argmax", action_space.n
        else:
            dim = action_space.shape[0]
            head, outputs = ("tanh", 2 * dim) if state_std else ("clip", dim)
        stats = state.obs_stats
        return mlp_policy(
            state.params["params"]["actor"],
            obs_space,
            action_space,
            hidden,
            outputs,
            cfg.activation,
            head,
            cfg.compute_dtype,
            stats.mean if normalize_obs else None,
            running.std(stats) if normalize_obs else None,
        )

    return Algorithm(
        init, update, policy, num_updates, update_steps, export=export, params=lambda s: s.params, hyperparams=defaults
    )


SPEC = AlgorithmSpec(
    config=Config,
    make=make,
    check=check,
    check_env_shards=check_env_shards,
    sweepable=SWEEPABLE,
    agents=True,
)
