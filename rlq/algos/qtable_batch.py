"""Transitions of tabular Q as flat batches: one per env, or one per (env, agent) in decentralised
control, and their replay (T0's exercise) through the project's one buffer (rlq/lib/learning/replay.py)."""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct

from rlq.lib.learning import replay
from rlq.lib.rollout import Transition

#: (table, visits, s, a, r, s_next, terminated) -> (table, visits): a batch update rule with its
#: step size and discount bound (rlq.algos.qlearning.PARALLEL_UPDATES)
Learn = Callable[..., tuple[jax.Array, jax.Array]]


class QTransition(struct.PyTreeNode):
    """A flat batch (or one item) of tabular transitions."""

    s: jax.Array
    a: jax.Array
    r: jax.Array
    s_next: jax.Array
    terminated: jax.Array


def flat_transitions(traj: Transition) -> QTransition:
    """One transition per env (obs ``(E,)``), or per env and agent (obs ``(E, A)``) in env-major
    order: each agent's own state, action and next state, the env's reward and termination shared."""
    if traj.obs.ndim == 1:
        return QTransition(traj.obs, traj.action, traj.reward, traj.next_obs, traj.terminated)
    agents = traj.obs.shape[1]
    return QTransition(
        s=traj.obs.reshape(-1),
        a=traj.action.reshape(-1),
        r=jnp.repeat(traj.reward, agents),
        s_next=traj.next_obs.reshape(-1),
        terminated=jnp.repeat(traj.terminated, agents),
    )


def empty_buffer(capacity: int) -> replay.ReplayState:
    example = QTransition(
        s=jnp.zeros((), jnp.int32),
        a=jnp.zeros((), jnp.int32),
        r=jnp.zeros((), jnp.float32),
        s_next=jnp.zeros((), jnp.int32),
        terminated=jnp.zeros((), bool),
    )
    return replay.init(capacity, example)


def apply(learn: Learn, table: jax.Array, visits: jax.Array, batch: QTransition) -> tuple[jax.Array, jax.Array]:
    return learn(table, visits, batch.s, batch.a, batch.r, batch.s_next, batch.terminated)


def replay_updates(
    learn: Learn,
    table: jax.Array,
    visits: jax.Array,
    buffer: replay.ReplayState,
    key: jax.Array,
    batch_size: int,
    updates: int,
) -> tuple[jax.Array, jax.Array]:
    """``updates`` batches of ``batch_size`` transitions drawn uniformly from ``buffer``, each applied
    with ``learn`` to the table the previous one left (visits count replayed updates too)."""

    def one(carry, sample_key):
        table, visits = carry
        return apply(learn, table, visits, replay.sample(buffer, sample_key, batch_size)), None

    return jax.lax.scan(one, (table, visits), jax.random.split(key, updates))[0]
