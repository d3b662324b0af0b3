"""Random policy search: each update samples a population of parameter vectors, scores each
over full episodes and keeps the best one seen so far (by mean return).

The policy is deterministic. ``hidden: []`` gives a linear policy ``y = W·obs (+ b)``; otherwise
an ``rlq.networks.MLP``. Actions: for two discrete actions one output and the sign rule
``a = 1 if y >= 0`` (the textbook CartPole search); for n > 2 argmax over n outputs; for Box
actions the outputs clipped to the bounds.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct
from jax.flatten_util import ravel_pytree
from omegaconf import DictConfig

from rlq.algos.base import Algorithm, updates_for_budget
from rlq.envs.base import Env
from rlq.envs.spaces import Box, Discrete, Space, flat_dim
from rlq.networks import MLP, encode_obs
from rlq.scoring import make_scoring_fn


@struct.dataclass
class RandomSearchState:
    best_params: jax.Array  # flat vector
    best_fitness: jax.Array
    key: jax.Array
    env_steps: jax.Array
    generation: jax.Array


def num_outputs(action_space: Space) -> int:
    if isinstance(action_space, Discrete):
        return 1 if action_space.n == 2 else action_space.n
    return action_space.shape[0]


def decode_action(y: jax.Array, action_space: Space) -> jax.Array:
    """Policy outputs -> env action: sign rule (2 actions), argmax (n actions), clip (Box)."""
    if isinstance(action_space, Discrete):
        if action_space.n == 2:
            return (y[..., 0] >= 0).astype(jnp.int32)
        return jnp.argmax(y, axis=-1)
    return jnp.clip(y, jnp.asarray(action_space.low), jnp.asarray(action_space.high))


def linear_policy(params: dict, obs: jax.Array) -> jax.Array:
    """``obs @ w (+ b)``; without ``b`` this is T1's rule ``a = 1 if w·obs >= 0``."""
    y = obs @ params["w"]
    return y + params["b"] if "b" in params else y


def check(cfg: DictConfig, env: Env) -> str | None:
    if not isinstance(env.action_space, Discrete | Box):
        return "random_search needs a Discrete or Box action space"
    if not env.max_episode_steps:
        return f"random_search scores full episodes; give env={type(env.unwrapped).__name__} a time limit"
    if cfg.sampling not in ("uniform", "gaussian"):
        return f"algo.sampling must be uniform or gaussian, got {cfg.sampling!r} (e.g. algo.sampling=uniform)"
    if not cfg.low < cfg.high:
        return f"algo.low={cfg.low} must be below algo.high={cfg.high}"
    return None


def sizes(cfg: DictConfig) -> list[str]:
    return ["population", "episodes"]


def make(cfg: DictConfig, env: Env, budget_env_steps: int) -> Algorithm:
    obs_space, action_space = env.observation_space, env.action_space
    out = num_outputs(action_space)
    if cfg.hidden:
        net = MLP(tuple(cfg.hidden), out, cfg.activation)
        example = net.init(jax.random.PRNGKey(0), encode_obs(jnp.zeros(obs_space.shape, jnp.float32), obs_space))

        def outputs(params, obs):
            return net.apply(params, obs)
    else:
        example = {"w": jnp.zeros((flat_dim(obs_space), out), jnp.float32)}
        if cfg.bias:
            example["b"] = jnp.zeros((out,), jnp.float32)
        outputs = linear_policy
    flat0, unravel = ravel_pytree(example)
    dim = flat0.shape[0]

    def apply(params, obs, key):
        return decode_action(outputs(params, encode_obs(obs, obs_space)), action_space)

    scoring_fn = make_scoring_fn(env, apply, cfg.episodes, unravel)
    # Every scored episode runs at most max_episode_steps steps: the budget is never exceeded;
    # metrics report the true count.
    steps_per_update = cfg.population * cfg.episodes * env.max_episode_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)

    def uniform(key, shape):
        return jax.random.uniform(key, shape, minval=cfg.low, maxval=cfg.high)

    def init(key: jax.Array) -> RandomSearchState:
        key, sub = jax.random.split(key)
        zero = jnp.zeros((), jnp.int32)
        return RandomSearchState(uniform(sub, (dim,)), jnp.asarray(-jnp.inf, jnp.float32), key, zero, zero)

    def ask(state: RandomSearchState, key: jax.Array) -> jax.Array:
        shape = (cfg.population, dim)
        if cfg.sampling == "uniform":
            return uniform(key, shape)
        normal_key, uniform_key = jax.random.split(key)
        around = jnp.clip(state.best_params + cfg.sigma * jax.random.normal(normal_key, shape), cfg.low, cfg.high)
        return jnp.where(jnp.isfinite(state.best_fitness), around, uniform(uniform_key, shape))

    def update(state: RandomSearchState) -> tuple[RandomSearchState, dict]:
        key, ask_key, score_key = jax.random.split(state.key, 3)
        candidates = ask(state, ask_key)
        fitness, _, extras = scoring_fn(candidates, score_key)
        i = jnp.argmax(fitness)
        better = fitness[i] > state.best_fitness
        best_params = jnp.where(better, candidates[i], state.best_params)
        best_fitness = jnp.where(better, fitness[i], state.best_fitness)
        env_steps = state.env_steps + extras["env_steps"]
        metrics = {
            "best_fitness": best_fitness,
            "generation_max_fitness": fitness[i],
            "generation_mean_fitness": fitness.mean(),
            "episode_return": extras["episode_return"].mean(),
            "episode_length": extras["episode_length"].mean(),
            "env_steps": env_steps,
        }
        return RandomSearchState(best_params, best_fitness, key, env_steps, state.generation + 1), metrics

    def policy(state: RandomSearchState):
        params = unravel(state.best_params)
        return lambda obs, key: apply(params, obs, key)

    return Algorithm(init, update, policy, num_updates, steps_per_update)
