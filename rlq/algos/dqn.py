"""Deep Q-Network: vectorised ε-greedy acting, replay, target network, optional Double DQN, n-step
returns and EMA.

One ``update`` runs ``num_steps`` steps of the ``num_envs`` vectorised envs in blocks of
``train_every`` steps; after each block the transitions go to the replay buffer and the learner
takes ``gradient_steps`` steps (once ``learning_starts`` env steps have been collected). With
``n_step`` > 1 each stored transition carries the return of up to n steps within its block (fewer for
the block's last steps and at episode ends) and the discount of its bootstrap.
Every ``target_every`` learner steps the target moves towards the online net by ``tau``
(``tau=1``: hard copy; ``target_every=1, tau=0.005``: Polyak averaging).
Decentralised control (``AgentsDiscrete`` observations and actions): independent learners sharing one
Q-network (rlq/lib/agents.py). The buffer stores joint transitions (one observation and action per
agent); the loss takes each agent's TD error against the env's one reward, averaged over the agents.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import optax
from flax import struct

from rlq.algos.base import Algorithm, Hyperparams, updates_for_budget
from rlq.algos.spec import AlgorithmSpec
from rlq.declared.dqn import Config
from rlq.lib.agents import discrete_actions_problem, per_agent
from rlq.lib.env_api import Env, EnvState
from rlq.lib.learning import optimizers, replay
from rlq.lib.learning.advantages import n_step_returns
from rlq.lib.learning.networks import MLP, encode_obs
from rlq.lib.learning.schedules import check_epsilon, epsilon_greedy, epsilon_schedule, epsilon_values
from rlq.lib.policy_export import PolicyExport, mlp_policy
from rlq.lib.rollout import episode_summary, reset_batch, rollout
from rlq.lib.sharding import shard_envs
from rlq.lib.spaces import AgentsDiscrete, Discrete

LOSSES = ("mse", "huber")
#: the numeric keys that enter the update only as arithmetic: program inputs (``Algorithm.update``'s second argument)
SWEEPABLE = ("lr", "gamma", "tau", "epsilon.start", "epsilon.end", "epsilon.decay")


class Learner(struct.PyTreeNode):
    params: Any
    target_params: Any
    ema_params: Any  # evaluation params when algo.ema > 0 (else the initial params)
    opt_state: optax.OptState
    steps: jax.Array


class DQNState(struct.PyTreeNode):
    learner: Learner
    buffer: replay.ReplayState
    env_state: EnvState
    key: jax.Array
    env_steps: jax.Array
    episodes: jax.Array  # completed episodes over all envs (for per-episode ε decay)


def td_target(
    reward: jax.Array,
    discount: jax.Array,
    next_q_target: jax.Array,
    next_q_online: jax.Array | None,
    double: bool,
) -> jax.Array:
    """R + discount·Q_target(s′, a*), with R the (n-step) return and discount = γ^k(1 − terminated).

    a* is the argmax of the target net, or of the online net for Double DQN. Only termination
    zeroes the discount: on truncation s′ is the true last observation and its value counts
    (``rlq.lib.learning.advantages.n_step_returns`` builds R, s′ and the discount). With agents (Q-values
    (..., agents, actions)) each agent's target bootstraps from its own next observation with the env's
    one reward and discount.
    """
    chooser = next_q_online if double and next_q_online is not None else next_q_target
    best = jnp.argmax(chooser, axis=-1)
    next_value = jnp.take_along_axis(next_q_target, best[..., None], axis=-1)[..., 0]
    return per_agent(reward, next_value) + per_agent(discount, next_value) * next_value


def polyak(target: Any, online: Any, tau: float | jax.Array) -> Any:
    """target ← (1 − τ)·target + τ·online, leaf by leaf."""
    return jax.tree.map(lambda t, o: (1.0 - tau) * t + tau * o, target, online)


def check(cfg: Config, env: Env) -> str | None:
    problem = discrete_actions_problem("dqn", env)
    if problem:
        return problem
    if cfg.num_steps % cfg.train_every:
        return f"algo.train_every={cfg.train_every} must divide algo.num_steps={cfg.num_steps}"
    if cfg.num_envs * cfg.train_every > cfg.buffer_size:
        return f"algo.buffer_size={cfg.buffer_size} must hold one block of algo.num_envs*algo.train_every transitions"
    if not 1 <= cfg.n_step <= cfg.train_every:
        return (
            f"algo.n_step={cfg.n_step} must lie in [1, algo.train_every={cfg.train_every}]: n-step returns are "
            "taken within each block of train_every vectorised steps (e.g. algo.train_every=4 algo.n_step=4)"
        )
    if cfg.loss not in LOSSES:
        return f"algo.loss must be one of {', '.join(LOSSES)}, got '{cfg.loss}'"
    return check_epsilon(cfg.epsilon, "algo.epsilon")


def notes(cfg: Config, env_steps: int) -> tuple[str, ...]:
    """What a run of ``env_steps`` env steps per seed does that its settings may not lead one to expect."""
    out = []
    if cfg.learning_starts > env_steps:
        out.append(
            f"algo.learning_starts={cfg.learning_starts} is beyond the budget ({env_steps:,} env steps per seed): "
            "the run never updates the network"
        )
    if cfg.buffer_size < cfg.batch_size:
        out.append(
            f"algo.buffer_size={cfg.buffer_size} is below algo.batch_size={cfg.batch_size}: each batch draws "
            f"its {cfg.batch_size} transitions from at most {cfg.buffer_size} (with replacement)"
        )
    return tuple(out)


def make(cfg: Config, env: Env, budget_env_steps: int) -> Algorithm:
    obs_space, action_space = env.observation_space, env.action_space
    assert isinstance(action_space, Discrete | AgentsDiscrete), "check() admits only discrete actions"
    net = MLP(tuple(cfg.hidden), action_space.n, cfg.activation, layer_norm=bool(cfg.layer_norm))
    agent_id = bool(cfg.agent_id)
    steps_per_update = cfg.num_envs * cfg.num_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)
    num_blocks = cfg.num_steps // cfg.train_every
    block_steps = cfg.num_envs * cfg.train_every
    total_learner_steps = num_updates * num_blocks * cfg.gradient_steps
    defaults = {name: float(getattr(cfg, name)) for name in SWEEPABLE if "." not in name}
    defaults.update({f"epsilon.{name}": float(getattr(cfg.epsilon, name)) for name in ("start", "end", "decay")})

    def optimizer(lr: Any) -> optax.GradientTransformation:
        """Adam at ``lr``: its state's structure does not depend on ``lr``, so one ``init`` serves every value."""
        return optimizers.adam(lr, total_learner_steps if cfg.anneal_lr else None, cfg.max_grad_norm)

    tx = optimizer(defaults["lr"])

    def q_values(params, obs):
        return net.apply(params, encode_obs(obs, obs_space, agent_id))

    def loss_fn(params, target_params, batch):
        q = q_values(params, batch["obs"])
        q_taken = jnp.take_along_axis(q, batch["action"][..., None], axis=-1)[..., 0]
        next_online = q_values(params, batch["next_obs"]) if cfg.double else None
        target = td_target(
            batch["reward"],
            batch["discount"],
            q_values(target_params, batch["next_obs"]),
            next_online,
            cfg.double,
        )
        error = q_taken - jax.lax.stop_gradient(target)
        loss = optax.huber_loss(error).mean() if cfg.loss == "huber" else jnp.mean(error**2)
        return loss, q_taken.mean()

    def learner_step(learner: Learner, key: jax.Array, buffer: replay.ReplayState, tx, hp):
        batch = shard_envs(replay.sample(buffer, key, cfg.batch_size))
        (loss, q_mean), grads = jax.value_and_grad(loss_fn, has_aux=True)(learner.params, learner.target_params, batch)
        updates, opt_state = tx.update(grads, learner.opt_state, learner.params)
        params = optax.apply_updates(learner.params, updates)
        steps = learner.steps + 1
        tau = jnp.where(steps % cfg.target_every == 0, hp["tau"], 0.0)
        ema_params = polyak(learner.ema_params, params, cfg.ema) if cfg.ema > 0 else learner.ema_params
        learner = Learner(params, polyak(learner.target_params, params, tau), ema_params, opt_state, steps)
        return learner, {"loss": loss, "q_mean": q_mean}

    def block(state: DQNState, key: jax.Array, tx, epsilon, hp):
        act_key, learn_key = jax.random.split(key)
        eps = epsilon(state.env_steps, state.episodes)

        def act(obs, k):
            return epsilon_greedy(k, q_values(state.learner.params, obs), eps), {}

        env_state, traj = rollout(env, state.env_state, act, act_key, cfg.train_every)
        returns, bootstrap, discount = n_step_returns(
            traj.reward, traj.terminated, traj.done, traj.next_obs, hp["gamma"], cfg.n_step
        )
        items = {"obs": traj.obs, "action": traj.action, "reward": returns, "next_obs": bootstrap, "discount": discount}
        items = jax.tree.map(lambda x: x.reshape((block_steps,) + x.shape[2:]), items)
        state = state.replace(
            buffer=replay.add(state.buffer, items),
            env_state=env_state,
            env_steps=state.env_steps + block_steps,
            episodes=state.episodes + traj.done.sum(),
        )
        learned, stats = jax.lax.scan(
            lambda learner, k: learner_step(learner, k, state.buffer, tx, hp),
            state.learner,
            jax.random.split(learn_key, cfg.gradient_steps),
        )
        active = state.env_steps >= cfg.learning_starts
        state = state.replace(
            learner=jax.tree.map(lambda new, old: jnp.where(active, new, old), learned, state.learner)
        )
        stats = {k: jnp.where(active, v.mean(), jnp.nan) for k, v in stats.items()}
        return state, (traj, {**stats, "epsilon": eps})

    def init(key: jax.Array, hp: Hyperparams) -> DQNState:
        key, net_key, env_key = jax.random.split(key, 3)
        env_state = reset_batch(env, env_key, cfg.num_envs)
        obs = env_state.obs[0]
        params = net.init(net_key, encode_obs(obs, obs_space))
        example = {
            "obs": obs,
            "action": jnp.zeros(action_space.shape, jnp.int32),
            "reward": jnp.zeros((), jnp.float32),
            "next_obs": obs,
            "discount": jnp.zeros((), jnp.float32),
        }
        zero = jnp.zeros((), jnp.int32)
        learner = Learner(params, params, params, tx.init(params), zero)
        return DQNState(learner, replay.init(cfg.buffer_size, example), env_state, key, zero, zero)

    def update(state: DQNState, hp: Hyperparams) -> tuple[DQNState, dict]:
        """One update at the numeric hyperparameters ``hp`` (``SWEEPABLE``)."""
        tx_hp, epsilon = optimizer(hp["lr"]), epsilon_schedule(cfg.epsilon, epsilon_values(hp))
        key, run_key = jax.random.split(state.key)
        state, (traj, stats) = jax.lax.scan(
            lambda s, k: block(s, k, tx_hp, epsilon, hp),
            state.replace(key=key),
            jax.random.split(run_key, num_blocks),
        )
        metrics = {**jax.tree.map(jnp.nanmean, stats), **episode_summary(traj), "env_steps": state.env_steps}
        return state, metrics

    def policy(state: DQNState):
        params = state.learner.ema_params if cfg.ema > 0 else state.learner.params

        def greedy(obs, key):
            return jnp.argmax(q_values(params, obs), axis=-1)

        return greedy

    def export(state: DQNState) -> PolicyExport:
        params = state.learner.ema_params if cfg.ema > 0 else state.learner.params
        return mlp_policy(
            params["params"], obs_space, action_space, tuple(cfg.hidden), action_space.n, cfg.activation, "argmax"
        )

    return Algorithm(
        init,
        update,
        policy,
        num_updates,
        steps_per_update,
        export=export,
        params=lambda s: s.learner.params,
        notes=notes(cfg, num_updates * steps_per_update),
        hyperparams=defaults,
    )


SPEC = AlgorithmSpec(
    config=Config,
    make=make,
    check=check,
    sweepable=SWEEPABLE,
    agents=True,
)
