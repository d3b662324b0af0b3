"""Tabular Q-learning: many parallel envs, one shared Q-table, ε-greedy with a decaying ε.

Each vectorised step gives one transition per env; they update the one table either
``sequential`` (default): one after the other in env order, which is exactly serial Q-learning
on the interleaved stream of transitions, so α keeps its meaning whatever ``num_envs`` is (a
plain sum of TD updates would apply k·α to a pair visited by k envs at once, and diverges for
k·α > 2); or ``mean``: every visited (s, a) moves once, by α, towards the mean of its targets,
which is one scatter instead of ``num_envs`` chained ones (for thousands of envs on a GPU).

``alpha_decay=visits`` turns α into a per-(s, a) sample-average step size, max(α, 1/n) for the
n-th visit of the pair (with ``mean``: a batch of c visits after n moves by max(α, c/(n + c))), so
a pair's value is the average of all its targets until 1/n reaches the floor α. With very noisy
rewards (the brittle star's ~1 mm per step) a constant α averages only the last ~1/α updates.

Decentralised control (``AgentsDiscrete`` observations and actions, e.g. the brittle star's
``env.observation=arm_sectors`` with ``controller.mode=decentralised``): every agent picks its own
ε-greedy action from the one table indexed by its own state, and every agent's transition (its
state, action, next state; the env's reward) updates that table (parameter sharing).

``replay_size`` > 0 keeps the last ``replay_size`` transitions (rlq/lib/learning/replay.py); after each
vectorised step's own update, ``replay_updates`` batches of ``replay_batch`` of them, drawn
uniformly, are applied again with the same rule (T0's replay exercise).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from rlq.algos import qtable_batch
from rlq.algos.base import Algorithm, Hyperparams, updates_for_budget
from rlq.algos.qtable_figure import qtable_image
from rlq.algos.spec import AlgorithmSpec
from rlq.declared.qlearning import Config
from rlq.lib.agents import discrete_actions_problem, num_agents
from rlq.lib.env_api import Env, EnvState
from rlq.lib.learning import replay
from rlq.lib.learning.schedules import check_epsilon, epsilon_greedy, epsilon_schedule, epsilon_values
from rlq.lib.rollout import env_step, episode_summary, reset_batch
from rlq.lib.spaces import AgentsDiscrete, Discrete


class QState(struct.PyTreeNode):
    table: jax.Array  # [num_states, num_actions]
    visits: jax.Array  # [num_states, num_actions], float: updates per pair (replayed ones too)
    env_state: EnvState
    key: jax.Array
    env_steps: jax.Array
    episodes: jax.Array  # completed episodes over all envs (for per-episode ε decay)
    replay: replay.ReplayState | None = None  # recent transitions (algo.replay_size > 0)


def td_targets(
    table: jax.Array, r: jax.Array, s_next: jax.Array, terminated: jax.Array, gamma: float | jax.Array
) -> jax.Array:
    """r + γ·max_a Q(s′, a), or r alone when s′ is terminal (truncation still bootstraps)."""
    return r + gamma * jnp.where(terminated, 0.0, jnp.max(table[s_next], axis=-1))


def q_update(
    table: jax.Array,
    s: jax.Array,
    a: jax.Array,
    r: jax.Array,
    s_next: jax.Array,
    terminated: jax.Array,
    alpha: float | jax.Array,
    gamma: float | jax.Array,
) -> jax.Array:
    """One transition: Q(s, a) ← (1 − α)·Q(s, a) + α·(r + γ·max Q(s′, ·)); target r when terminated."""
    target = td_targets(table, r, s_next, terminated, gamma)
    return table.at[s, a].set((1.0 - alpha) * table[s, a] + alpha * target)


def sequential_q_update(
    table: jax.Array,
    visits: jax.Array,
    s: jax.Array,
    a: jax.Array,
    r: jax.Array,
    s_next: jax.Array,
    terminated: jax.Array,
    alpha: float | jax.Array,
    gamma: float | jax.Array,
    sample_average: bool = False,
) -> tuple[jax.Array, jax.Array]:
    """A batch of transitions applied one after the other (each sees the table the previous left).

    Returns the new table and visit counts; with ``sample_average`` the n-th visit of a pair uses
    the step size max(α, 1/n)."""

    def one(carry, transition):
        table, visits = carry
        s, a, r, s_next, terminated = transition
        visits = visits.at[s, a].add(1.0)
        step = jnp.maximum(alpha, 1.0 / visits[s, a]) if sample_average else alpha
        return (q_update(table, s, a, r, s_next, terminated, step, gamma), visits), None

    return jax.lax.scan(one, (table, visits), (s, a, r, s_next, terminated))[0]


def mean_q_update(
    table: jax.Array,
    visits: jax.Array,
    s: jax.Array,
    a: jax.Array,
    r: jax.Array,
    s_next: jax.Array,
    terminated: jax.Array,
    alpha: float | jax.Array,
    gamma: float | jax.Array,
    sample_average: bool = False,
) -> tuple[jax.Array, jax.Array]:
    """A batch of transitions: each visited (s, a) moves towards the mean of its targets, by α, or
    with ``sample_average`` by max(α, c/(n + c)) for c visits in this batch after n before."""
    error = td_targets(table, r, s_next, terminated, gamma) - table[s, a]
    total = jnp.zeros_like(table).at[s, a].add(error)
    count = jnp.zeros_like(table).at[s, a].add(1.0)
    new_visits = visits + count
    step = jnp.maximum(alpha, count / jnp.maximum(new_visits, 1.0)) if sample_average else alpha
    return table + step * total / jnp.maximum(count, 1.0), new_visits


PARALLEL_UPDATES = {"sequential": sequential_q_update, "mean": mean_q_update}
ALPHA_DECAYS = ("none", "visits")


def check(cfg: Config, env: Env) -> str | None:
    problem = discrete_actions_problem("qlearning", env)
    if problem:
        return problem
    if not isinstance(env.observation_space, Discrete | AgentsDiscrete):
        return "algo=qlearning needs discrete observations; set env.discretize (see experiment=cartpole_qlearning)"
    per_step = int(cfg.num_envs) * max(1, num_agents(env.observation_space))
    if 0 < int(cfg.replay_size) < per_step:
        return (
            f"algo.replay_size={cfg.replay_size} cannot hold one step's {per_step} transitions "
            f"(algo.num_envs x agents); give 0 (no replay) or >= {per_step}"
        )
    if cfg.parallel_update not in PARALLEL_UPDATES:
        return f"algo.parallel_update must be one of {', '.join(PARALLEL_UPDATES)}, got '{cfg.parallel_update}'"
    if cfg.alpha_decay not in ALPHA_DECAYS:
        return f"algo.alpha_decay must be one of {', '.join(ALPHA_DECAYS)}, got '{cfg.alpha_decay}'"
    if not 0.0 < float(cfg.alpha) <= 1.0:
        return f"algo.alpha must be in (0, 1], got {cfg.alpha}"
    return check_epsilon(cfg.epsilon, "algo.epsilon")


#: the numeric keys that enter the update only as arithmetic: program inputs (``Algorithm.update``'s second argument)
SWEEPABLE = ("alpha", "gamma", "epsilon.start", "epsilon.end", "epsilon.decay")


def make(cfg: Config, env: Env, budget_env_steps: int) -> Algorithm:
    obs_space, action_space = env.observation_space, env.action_space
    assert isinstance(obs_space, Discrete | AgentsDiscrete), "check() admits only discrete observations"
    assert isinstance(action_space, Discrete | AgentsDiscrete), "check() admits only discrete actions"
    num_states, num_actions = obs_space.n, action_space.n
    steps_per_update = cfg.num_envs * cfg.num_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)
    defaults = {"alpha": float(cfg.alpha), "gamma": float(cfg.gamma)}
    defaults.update({f"epsilon.{name}": float(getattr(cfg.epsilon, name)) for name in ("start", "end", "decay")})
    sample_average = cfg.alpha_decay == "visits"
    rule = PARALLEL_UPDATES[cfg.parallel_update]

    replay_size, replay_batch, replay_rounds = int(cfg.replay_size), int(cfg.replay_batch), int(cfg.replay_updates)

    def step(state: QState, key: jax.Array, hp: Mapping[str, Any]):
        eps = epsilon_schedule(cfg.epsilon, epsilon_values(hp))(state.env_steps, state.episodes)

        def learn(table, visits, s, a, r, s_next, terminated):
            return rule(table, visits, s, a, r, s_next, terminated, hp["alpha"], hp["gamma"], sample_average)

        action = epsilon_greedy(key, state.table[state.env_state.obs], eps)  # per env, or per env and agent
        env_state, traj = env_step(env, state.env_state, state.env_state.obs, action, {})
        batch = qtable_batch.flat_transitions(traj)
        table, visits = qtable_batch.apply(learn, state.table, state.visits, batch)
        buffer = state.replay
        if buffer is not None:
            buffer = replay.add(buffer, batch)
            table, visits = qtable_batch.replay_updates(
                learn, table, visits, buffer, jax.random.fold_in(key, 1), replay_batch, replay_rounds
            )
        state = state.replace(
            table=table,
            visits=visits,
            replay=buffer,
            env_state=env_state,
            env_steps=state.env_steps + cfg.num_envs,
            episodes=state.episodes + traj.done.sum(),
        )
        return state, (traj, eps)

    def init(key: jax.Array, hp: Hyperparams) -> QState:
        key, table_key, env_key = jax.random.split(key, 3)
        scale = cfg.init_scale
        table = jax.random.uniform(table_key, (num_states, num_actions), minval=-scale, maxval=scale)
        zero = jnp.zeros((), jnp.int32)
        buffer = qtable_batch.empty_buffer(replay_size) if replay_size > 0 else None
        env_state = reset_batch(env, env_key, cfg.num_envs)
        return QState(table, jnp.zeros_like(table), env_state, key, zero, zero, buffer)

    def update(state: QState, hp: Hyperparams) -> tuple[QState, dict]:
        """One update at the numeric hyperparameters ``hp`` (``SWEEPABLE``)."""
        key, run_key = jax.random.split(state.key)
        state, (traj, eps) = jax.lax.scan(
            lambda st, k: step(st, k, hp), state.replace(key=key), jax.random.split(run_key, cfg.num_steps)
        )
        metrics = {**episode_summary(traj), "epsilon": eps.mean(), "env_steps": state.env_steps}
        return state, metrics

    def policy(state: QState):
        def greedy(obs, key):
            return jnp.argmax(state.table[obs], axis=-1)

        return greedy

    def figures(state: QState) -> dict[str, np.ndarray]:
        return {"qtable": qtable_image(np.asarray(state.table), np.asarray(state.visits))}

    return Algorithm(
        init,
        update,
        policy,
        num_updates,
        steps_per_update,
        figures=figures,
        figures_at_eval=True,
        params=lambda s: s.table,
        hyperparams=defaults,
    )


SPEC = AlgorithmSpec(
    config=Config,
    make=make,
    check=check,
    sweepable=SWEEPABLE,
    agents=True,
)
