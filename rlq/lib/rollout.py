"""Shared rollout and evaluation: scans of a batched, auto-resetting env, and one greedy episode's states (videos)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from rlq.lib.env_api import Env, EnvState, first_episodes_only
from rlq.lib.sharding import shard_envs

#: (batched obs, key) -> (batched action, aux dict of per-env arrays such as log-probs)
ActFn = Callable[[jax.Array, jax.Array], tuple[jax.Array, dict[str, jax.Array]]]
#: (one obs, key) -> one action: the greedy policy used for evaluation and video
PolicyFn = Callable[[jax.Array, jax.Array], jax.Array]


class Transition(struct.PyTreeNode):
    """A batch of transitions; leading axes (time, env) or (env,)."""

    obs: jax.Array
    action: jax.Array
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    next_obs: jax.Array  # the true successor (``final_obs`` when the episode ended)
    info: dict[str, jax.Array]
    aux: dict[str, Any]

    @property
    def done(self) -> jax.Array:
        return jnp.logical_or(self.terminated, self.truncated)


def reset_batch(env: Env, key: jax.Array, num_envs: int) -> EnvState:
    """``num_envs`` fresh envs, the batch split over the mesh's env devices (rlq.lib.sharding)."""
    return shard_envs(jax.vmap(env.reset)(jax.random.split(key, num_envs)))


def reference_observation(env: Env) -> jax.Array:
    """The flat first observation of the env reset with key 0: the fixed point ``evaluate(obs_ref=...)`` sums
    observations about, the same for every batch of a run."""
    return env.reset(jax.random.PRNGKey(0)).obs.reshape(-1).astype(jnp.float32)


def env_step(env: Env, state: EnvState, obs: jax.Array, action: jax.Array, aux: dict) -> tuple[EnvState, Transition]:
    """Step a batch of envs and package the transition."""
    nxt = shard_envs(jax.vmap(env.step)(state, action))
    transition = Transition(
        obs=obs,
        action=action,
        reward=nxt.reward,
        terminated=nxt.terminated,
        truncated=nxt.truncated,
        next_obs=nxt.info["final_obs"],
        info={k: v for k, v in nxt.info.items() if k != "final_obs"},
        aux=aux,
    )
    return nxt, transition


def rollout(env: Env, state: EnvState, act: ActFn, key: jax.Array, num_steps: int) -> tuple[EnvState, Transition]:
    """``num_steps`` steps of a batch of envs; the transitions come stacked as (time, env)."""

    def one_step(state: EnvState, step_key: jax.Array):
        action, aux = act(state.obs, step_key)
        return env_step(env, state, state.obs, action, aux)

    return jax.lax.scan(one_step, state, jax.random.split(key, num_steps))


def episode_summary(transition: Transition) -> dict[str, jax.Array]:
    """Mean return and length of the episodes completed in a batch (NaN when none ended)."""
    done = transition.done.astype(jnp.float32)
    count = done.sum()
    denom = jnp.maximum(count, 1.0)
    nan_if_none = jnp.where(count > 0, 1.0, jnp.nan)
    return {
        "episode_return": nan_if_none * (transition.info["episode_return"] * done).sum() / denom,
        "episode_length": nan_if_none * (transition.info["episode_length"] * done).sum() / denom,
        "episodes": count,
    }


def evaluate(
    env: Env,
    policy: PolicyFn,
    key: jax.Array,
    num_episodes: int,
    max_steps: int | None = None,
    obs_moments: bool = False,
    obs_ref: jax.Array | None = None,
) -> dict[str, jax.Array]:
    """Run ``num_episodes`` episodes in parallel with ``policy``; figures of each first episode.

    The loop stops once every episode has ended, so a batch of short episodes costs its longest
    episode's steps, not the time limit's (what a latency-bound GPU spends its time on), and
    its steps start no new episodes (``first_episodes_only``).

    ``env`` must auto-reset and carry episode statistics (``make_env`` does both). Every
    episode ends within ``max_steps`` (the env's time limit by default); per-episode values
    from ``info`` (return, length, and any env metrics) are read at the step it ended.
    ``obs_moments``: the record also holds, per episode, the count, sum and summed squares of the
    observations its policy acted on (``obs_count``, ``obs_sum``, ``obs_sq_sum``: the running
    observation statistics of augmented random search). With ``obs_ref`` (a flat observation) the sums are of
    ``obs - obs_ref``: float32 sums of squares about a typical observation keep the variance that raw squares
    cancel away, and a component that never changes sums to exactly zero (``reference_observation``).
    """
    max_steps = max_steps or env.max_episode_steps
    if not max_steps:
        raise ValueError("evaluation needs an env with a time limit or an explicit max_steps")
    reset_key, run_key = jax.random.split(key)
    state = reset_batch(env, reset_key, num_episodes)
    keys = jax.random.split(run_key, num_episodes)
    record = {k: jnp.zeros_like(v) for k, v in state.info.items() if k != "final_obs"}
    if obs_moments:
        flat = state.obs.reshape(num_episodes, -1).astype(jnp.float32)
        record.update(obs_count=jnp.zeros(num_episodes, jnp.float32), obs_sum=jnp.zeros_like(flat))
        record["obs_sq_sum"] = jnp.zeros_like(flat)

    step_keys = jax.vmap(lambda k: jax.random.split(k, max_steps), out_axes=1)(keys)

    def one_step(carry):
        t, state, record, finished = carry
        action = jax.vmap(policy)(state.obs, step_keys[t])
        nxt = jax.vmap(env.step)(state, action)
        first_end = jnp.logical_and(nxt.done, jnp.logical_not(finished))
        record = {
            k: jnp.where(first_end.reshape(first_end.shape + (1,) * (v.ndim - 1)), nxt.info[k], v)
            if k in nxt.info
            else v
            for k, v in record.items()
        }
        if obs_moments:
            acting = jnp.logical_not(finished).astype(jnp.float32)
            flat_obs = state.obs.reshape(num_episodes, -1).astype(jnp.float32)
            seen = (flat_obs if obs_ref is None else flat_obs - obs_ref) * acting[:, None]
            record["obs_count"] = record["obs_count"] + acting
            record["obs_sum"] = record["obs_sum"] + seen
            record["obs_sq_sum"] = record["obs_sq_sum"] + seen * seen
        return (t + 1, *shard_envs((nxt, record, jnp.logical_or(finished, nxt.done))))

    def running(carry) -> jax.Array:
        t, _, _, finished = carry
        return jnp.logical_and(t < max_steps, jnp.logical_not(jnp.all(finished)))

    start = (jnp.zeros((), jnp.int32), state, record, jnp.zeros(num_episodes, bool))
    with first_episodes_only():
        _, _, record, finished = jax.lax.while_loop(running, one_step, start)
    record["finished"] = finished
    return record


def episode_program(
    env: Env, policy_of: Callable[[Any], PolicyFn], max_steps: int
) -> Callable[[Any, jax.Array], tuple[EnvState, jax.Array]]:
    """One compiled program ``(policy state, key) -> (states, done)`` of a greedy episode of
    ``policy_of(policy state)`` (reset state first, then ``max_steps`` steps): the training loop's
    stage videos call it with each new state and compile it once."""

    def run(policy_state, key):
        reset_key, run_key = jax.random.split(key)
        policy = policy_of(policy_state)
        first = env.reset(reset_key)

        def one(state, k):
            nxt = env.step(state, policy(state.obs, k))
            return nxt, (nxt, nxt.done)

        _, (states, done) = jax.lax.scan(one, first, jax.random.split(run_key, max_steps))
        states = jax.tree.map(lambda a, b: jnp.concatenate([jnp.asarray(a)[None], b]), first, states)
        return states, done

    return jax.jit(run)


def episode_length(done: jax.Array, max_steps: int) -> int:
    """Steps up to and including the first ``done`` (``max_steps`` when the episode never ended)."""
    ended = np.asarray(done)
    return int(np.argmax(ended)) + 1 if ended.any() else max_steps


def episode_states(env: Env, policy: PolicyFn, key: jax.Array, max_steps: int) -> tuple[EnvState, int]:
    """The states of one greedy episode (reset state first) and its number of steps."""
    states, done = episode_program(env, lambda _: policy, max_steps)(None, key)
    return states, episode_length(done, max_steps)
