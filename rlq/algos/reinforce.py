"""REINFORCE (Monte-Carlo policy gradient) with an optional baseline.

Each update rolls ``num_envs`` auto-resetting envs for ``num_steps`` steps (the env state carries
over between updates) and takes one Adam step on ``-mean(log pi(a|s) * (G_t - b))`` over the
transitions whose episode ended inside the rollout: their rewards-to-go ``G_t`` are exact. The
tail of each env's still-running episode is left out of the loss; its rewards reach the next
rollout's head, which holds the rest of that episode. ``num_steps`` should be at least the
episode length so that most transitions count.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import optax
from flax import struct

from rlq.algos.base import Algorithm, Hyperparams, updates_for_budget
from rlq.algos.spec import AlgorithmSpec
from rlq.declared.reinforce import Config
from rlq.lib.env_api import Env, EnvState
from rlq.lib.learning import distributions as dist
from rlq.lib.learning import optimizers
from rlq.lib.learning.networks import ActorCritic, encode_obs
from rlq.lib.policy_export import PolicyExport, mlp_policy
from rlq.lib.rollout import episode_summary, reset_batch, rollout
from rlq.lib.spaces import Box, Discrete

BASELINES = ("none", "mean", "value")


class ReinforceState(struct.PyTreeNode):
    params: Any
    opt_state: optax.OptState
    env_state: EnvState
    key: jax.Array
    env_steps: jax.Array


def rewards_to_go(rewards: jax.Array, dones: jax.Array, gamma: float | jax.Array) -> jax.Array:
    """``G_t = r_t + gamma * G_{t+1}`` within each episode, over (time, ...) arrays.

    ``dones[t]`` marks the last transition of an episode, so the sum restarts there. At the end
    of the arrays the sum stops too: values after an env's last done are partial.
    """

    def backwards(g_next, x):
        r, d = x
        g = r + gamma * (1.0 - d) * g_next
        return g, g

    _, g = jax.lax.scan(backwards, jnp.zeros_like(rewards[0]), (rewards, dones.astype(rewards.dtype)), reverse=True)
    return g


def complete_mask(dones: jax.Array) -> jax.Array:
    """True where the transition's episode ends within the (time, ...) arrays."""
    return jax.lax.cummax(dones.astype(jnp.int32), axis=0, reverse=True) > 0


def check(cfg: Config, env: Env) -> str | None:
    if not isinstance(env.action_space, Discrete | Box):
        return "reinforce needs a Discrete or Box action space"
    if cfg.baseline not in BASELINES:
        return f"algo.baseline must be one of {', '.join(BASELINES)}, got {cfg.baseline!r} (e.g. algo.baseline=mean)"
    limit = env.max_episode_steps
    if limit and cfg.num_steps < limit:
        return f"algo.num_steps={cfg.num_steps} must cover a full episode (>= {limit}), e.g. algo.num_steps={limit}"
    return None


#: the numeric keys that enter the update only as arithmetic: program inputs (``Algorithm.update``'s second argument)
SWEEPABLE = ("lr", "gamma", "vf_coef", "ent_coef")


def make(cfg: Config, env: Env, budget_env_steps: int) -> Algorithm:
    obs_space, action_space = env.observation_space, env.action_space
    action_dist = dist.make_action_dist(action_space)
    net = ActorCritic(action_space, tuple(cfg.hidden), cfg.activation)
    steps_per_update = cfg.num_envs * cfg.num_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)
    defaults = {name: float(getattr(cfg, name)) for name in SWEEPABLE}

    def optimizer(lr: Any) -> optax.GradientTransformation:
        """Adam at ``lr``: its state's structure does not depend on ``lr``, so one ``init`` serves every value."""
        return optimizers.adam(lr, num_updates if cfg.anneal_lr else None, cfg.max_grad_norm)

    tx = optimizer(defaults["lr"])

    def forward(params, obs):
        return net.apply(params, encode_obs(obs, obs_space))

    def init(key: jax.Array, hp: Hyperparams) -> ReinforceState:
        key, net_key, env_key = jax.random.split(key, 3)
        env_state = reset_batch(env, env_key, cfg.num_envs)
        params = net.init(net_key, encode_obs(env_state.obs[0], obs_space))
        return ReinforceState(params, tx.init(params), env_state, key, jnp.zeros((), jnp.int32))

    def act_fn(params):
        def act(obs, key):
            action = action_dist.sample(key, forward(params, obs)[:2])
            return action_dist.to_env(action), {"action": action}

        return act

    def loss_fn(params, traj, returns, mask, hp):
        out = forward(params, traj.obs)
        logp = action_dist.log_prob(out[:2], traj.aux["action"])
        entropy = action_dist.entropy(out[:2], None)
        value = out[2]
        count = jnp.maximum(mask.sum(), 1.0)

        def masked_mean(x):
            return (x * mask).sum() / count

        if cfg.baseline == "value":
            baseline = jax.lax.stop_gradient(value)
        elif cfg.baseline == "mean":
            baseline = masked_mean(returns)
        else:
            baseline = 0.0
        adv = returns - baseline
        if cfg.normalize_advantages:
            adv = (adv - masked_mean(adv)) / (jnp.sqrt(masked_mean((adv - masked_mean(adv)) ** 2)) + 1e-8)
        pg_loss = -masked_mean(logp * adv)
        v_loss = 0.5 * masked_mean((value - returns) ** 2) if cfg.baseline == "value" else 0.0
        ent = masked_mean(entropy)
        total = pg_loss + hp["vf_coef"] * v_loss - hp["ent_coef"] * ent
        return total, {"policy_loss": pg_loss, "value_loss": jnp.asarray(v_loss), "entropy": ent}

    def update(state: ReinforceState, hp: Hyperparams) -> tuple[ReinforceState, dict]:
        """One update at the numeric hyperparameters ``hp`` (``SWEEPABLE``)."""
        tx_hp = optimizer(hp["lr"])
        key, roll_key = jax.random.split(state.key)
        env_state, traj = rollout(env, state.env_state, act_fn(state.params), roll_key, cfg.num_steps)
        returns = rewards_to_go(traj.reward, traj.done, hp["gamma"])
        mask = complete_mask(traj.done).astype(jnp.float32)
        grads, stats = jax.grad(loss_fn, has_aux=True)(state.params, traj, returns, mask, hp)
        updates, opt_state = tx_hp.update(grads, state.opt_state, state.params)
        params = optax.apply_updates(state.params, updates)
        env_steps = state.env_steps + steps_per_update
        metrics = {**stats, **episode_summary(traj), "used_fraction": mask.mean(), "env_steps": env_steps}
        return ReinforceState(params, opt_state, env_state, key, env_steps), metrics

    def policy(state: ReinforceState):
        def greedy(obs, key):
            return action_dist.mode(forward(state.params, obs)[:2])

        return greedy

    def export(state: ReinforceState) -> PolicyExport:
        discrete = isinstance(action_space, Discrete)
        outputs = action_space.n if isinstance(action_space, Discrete) else action_space.shape[0]
        return mlp_policy(
            state.params["params"]["actor"],
            obs_space,
            action_space,
            tuple(cfg.hidden),
            outputs,
            cfg.activation,
            "argmax" if discrete else "clip",
        )

    return Algorithm(
        init,
        update,
        policy,
        num_updates,
        steps_per_update,
        export=export,
        params=lambda s: s.params,
        hyperparams=defaults,
    )


SPEC = AlgorithmSpec(
    config=Config,
    make=make,
    check=check,
    sweepable=SWEEPABLE,
)
