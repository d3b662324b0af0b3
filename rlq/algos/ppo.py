"""Proximal Policy Optimisation (clipped objective, GAE, minibatch epochs)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax
from flax import struct
from omegaconf import DictConfig

from rlq import distributions as dist
from rlq.algos.base import Algorithm, updates_for_budget
from rlq.envs.base import Env, EnvState
from rlq.envs.spaces import Box, Discrete
from rlq.networks import ActorCritic, encode_obs
from rlq.rollout import episode_summary, reset_batch, rollout


@struct.dataclass
class PPOState:
    params: dict
    opt_state: optax.OptState
    env_state: EnvState
    key: jax.Array
    env_steps: jax.Array


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

    _, advantages = jax.lax.scan(
        backwards, jnp.zeros_like(deltas[0]), (deltas, done.astype(deltas.dtype)), reverse=True
    )
    return advantages, advantages + values


def check(cfg: DictConfig, env: Env) -> str | None:
    if not isinstance(env.action_space, Discrete | Box):
        return "ppo needs a Discrete or Box action space"
    if (cfg.num_envs * cfg.num_steps) % cfg.num_minibatches:
        return (
            f"algo.num_minibatches={cfg.num_minibatches} must divide "
            f"algo.num_envs*algo.num_steps={cfg.num_envs * cfg.num_steps}"
        )
    return None


def sizes(cfg: DictConfig) -> list[str]:
    return ["num_envs", "num_steps", "update_epochs", "num_minibatches"]


def make(cfg: DictConfig, env: Env, budget_env_steps: int) -> Algorithm:
    obs_space, action_space = env.observation_space, env.action_space
    discrete = isinstance(action_space, Discrete)
    net = ActorCritic(action_space, tuple(cfg.hidden), cfg.activation)
    steps_per_update = cfg.num_envs * cfg.num_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)
    minibatch_size = steps_per_update // cfg.num_minibatches
    grad_steps = num_updates * cfg.update_epochs * cfg.num_minibatches
    lr = optax.linear_schedule(cfg.lr, 0.0, grad_steps) if cfg.anneal_lr else cfg.lr
    tx = optax.chain(optax.clip_by_global_norm(cfg.max_grad_norm), optax.adam(lr, eps=1e-5))
    if not discrete:
        low, high = jnp.asarray(action_space.low), jnp.asarray(action_space.high)

    def forward(params, obs):
        return net.apply(params, encode_obs(obs, obs_space))

    def log_prob_entropy(out, action):
        a, log_std, _ = out
        if discrete:
            return dist.categorical_log_prob(a, action), dist.categorical_entropy(a)
        return dist.gaussian_log_prob(a, log_std, action), dist.gaussian_entropy(log_std)

    def to_env_action(action):
        return action if discrete else jnp.clip(action, low, high)

    def init(key: jax.Array) -> PPOState:
        key, net_key, env_key = jax.random.split(key, 3)
        env_state = reset_batch(env, env_key, cfg.num_envs)
        params = net.init(net_key, encode_obs(env_state.obs[0], obs_space))
        return PPOState(params, tx.init(params), env_state, key, jnp.zeros((), jnp.int32))

    def act_fn(params):
        def act(obs, key):
            out = forward(params, obs)
            a, log_std, value = out
            if discrete:
                action = dist.categorical_sample(key, a)
            else:
                action = dist.gaussian_sample(key, a, log_std)
            logp, _ = log_prob_entropy(out, action)
            return action, {"log_prob": logp, "value": value, "env_action": to_env_action(action)}

        return act

    def stepping_env_action(act):
        def act_env(obs, key):
            action, aux = act(obs, key)
            return aux.pop("env_action"), {**aux, "action": action}

        return act_env

    def loss_fn(params, batch):
        obs, action, old_logp, advantages, targets, old_values = batch
        out = forward(params, obs)
        logp, entropy = log_prob_entropy(out, action)
        value = out[2]
        ratio = jnp.exp(logp - old_logp)
        adv = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
        pg_loss = -jnp.minimum(ratio * adv, jnp.clip(ratio, 1 - cfg.clip_eps, 1 + cfg.clip_eps) * adv).mean()
        v_clipped = old_values + jnp.clip(value - old_values, -cfg.clip_eps, cfg.clip_eps)
        v_loss = 0.5 * jnp.maximum((value - targets) ** 2, (v_clipped - targets) ** 2).mean()
        ent = entropy.mean()
        total = pg_loss + cfg.vf_coef * v_loss - cfg.ent_coef * ent
        approx_kl = ((ratio - 1) - (logp - old_logp)).mean()
        return total, {"policy_loss": pg_loss, "value_loss": v_loss, "entropy": ent, "approx_kl": approx_kl}

    def update(state: PPOState) -> tuple[PPOState, dict]:
        key, roll_key, perm_key = jax.random.split(state.key, 3)
        env_state, traj = rollout(env, state.env_state, stepping_env_action(act_fn(state.params)), roll_key, cfg.num_steps)
        next_values = forward(state.params, traj.next_obs)[2]
        advantages, targets = gae(
            traj.reward, traj.aux["value"], next_values, traj.terminated.astype(jnp.float32),
            traj.done, cfg.gamma, cfg.gae_lambda,
        )
        flat = jax.tree.map(
            lambda x: x.reshape((steps_per_update,) + x.shape[2:]),
            (traj.obs, traj.aux["action"], traj.aux["log_prob"], advantages, targets, traj.aux["value"]),
        )

        def epoch(carry, epoch_key):
            params, opt_state = carry
            perm = jax.random.permutation(epoch_key, steps_per_update)
            minibatches = jax.tree.map(
                lambda x: x[perm].reshape((cfg.num_minibatches, minibatch_size) + x.shape[1:]), flat
            )

            def minibatch_step(carry, batch):
                params, opt_state = carry
                grads, stats = jax.grad(loss_fn, has_aux=True)(params, batch)
                updates, opt_state = tx.update(grads, opt_state, params)
                return (optax.apply_updates(params, updates), opt_state), stats

            return jax.lax.scan(minibatch_step, (params, opt_state), minibatches)

        (params, opt_state), stats = jax.lax.scan(
            epoch, (state.params, state.opt_state), jax.random.split(perm_key, cfg.update_epochs)
        )
        env_steps = state.env_steps + steps_per_update
        metrics = {**jax.tree.map(jnp.mean, stats), **episode_summary(traj), "env_steps": env_steps}
        return PPOState(params, opt_state, env_state, key, env_steps), metrics

    def policy(state: PPOState):
        def greedy(obs, key):
            a, _, _ = forward(state.params, obs)
            return jnp.argmax(a, axis=-1) if discrete else to_env_action(a)

        return greedy

    return Algorithm(init, update, policy, num_updates, steps_per_update)
