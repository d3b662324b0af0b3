"""Anchor for scripts/bench_cartpole_ppo.py: PPO on gymnax CartPole-v1 written the way PureJaxRL
writes it: one file, ``make_train(config) -> train(rng)``, the whole run one jitted program
(``lax.scan`` over updates, each a ``lax.scan`` over env steps, then epochs x minibatches), with
PureJaxRL's published CartPole settings and network (separate 64-64 tanh actor and critic,
orthogonal init, clipped value loss, Adam with gradient clipping and a linearly annealed rate).

It is our own code, kept in scripts/ as a benchmark anchor only: rlq never imports it. Timed as a
user times PureJaxRL: the whole process, Python start to exit. Prints one JSON line: the wall
time of ``train`` (compile included) and the mean return of the last finished training episodes.

    python scripts/anchor_purejaxrl_ppo.py [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import flax.linen as nn
import gymnax
import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax.training.train_state import TrainState

CONFIG = {
    "LR": 2.5e-4,
    "NUM_ENVS": 4,
    "NUM_STEPS": 128,
    "TOTAL_TIMESTEPS": 500_000,
    "UPDATE_EPOCHS": 4,
    "NUM_MINIBATCHES": 4,
    "GAMMA": 0.99,
    "GAE_LAMBDA": 0.95,
    "CLIP_EPS": 0.2,
    "ENT_COEF": 0.01,
    "VF_COEF": 0.5,
    "MAX_GRAD_NORM": 0.5,
}


class ActorCritic(nn.Module):
    num_actions: int

    @nn.compact
    def __call__(self, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        def tower(out: int, scale: float) -> jax.Array:
            x = obs
            for _ in range(2):
                x = nn.tanh(nn.Dense(64, kernel_init=nn.initializers.orthogonal(np.sqrt(2)))(x))
            return nn.Dense(out, kernel_init=nn.initializers.orthogonal(scale))(x)

        return tower(self.num_actions, 0.01), jnp.squeeze(tower(1, 1.0), -1)


def make_train(config: dict[str, Any]):
    num_updates = config["TOTAL_TIMESTEPS"] // config["NUM_STEPS"] // config["NUM_ENVS"]
    minibatch = config["NUM_ENVS"] * config["NUM_STEPS"] // config["NUM_MINIBATCHES"]
    env, params = gymnax.make("CartPole-v1")
    net = ActorCritic(env.action_space(params).n)

    def schedule(count):
        done = count // (config["NUM_MINIBATCHES"] * config["UPDATE_EPOCHS"])
        return config["LR"] * (1.0 - done / num_updates)

    def train(rng: jax.Array) -> dict[str, jax.Array]:
        rng, init_key, reset_key = jax.random.split(rng, 3)
        obs_shape = env.observation_space(params).shape
        tx = optax.chain(optax.clip_by_global_norm(config["MAX_GRAD_NORM"]), optax.adam(schedule, eps=1e-5))
        state = TrainState.create(apply_fn=net.apply, params=net.init(init_key, jnp.zeros(obs_shape)), tx=tx)
        obs, env_state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(reset_key, config["NUM_ENVS"]), params)
        episode = (jnp.zeros(config["NUM_ENVS"]), jnp.zeros(config["NUM_ENVS"]))  # running return, last return

        def env_step(carry, _):
            state, env_state, obs, episode, rng = carry
            rng, act_key, step_key = jax.random.split(rng, 3)
            logits, value = net.apply(state.params, obs)
            action = jax.random.categorical(act_key, logits)
            log_prob = jax.nn.log_softmax(logits)[jnp.arange(action.shape[0]), action]
            keys = jax.random.split(step_key, config["NUM_ENVS"])
            next_obs, env_state, reward, terminated, truncated, _ = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
                keys, env_state, action, params
            )
            done = jnp.logical_or(terminated, truncated)  # gymnax 1.0 splits them; PureJaxRL treats both as done
            running = episode[0] + reward
            episode = (jnp.where(done, 0.0, running), jnp.where(done, running, episode[1]))
            transition = (obs, action, log_prob, value, reward, done)
            return (state, env_state, next_obs, episode, rng), transition

        def gae(values, rewards, dones, last_value):
            def step(carry, t):
                advantage, next_value = carry
                value, reward, done = t
                delta = reward + config["GAMMA"] * next_value * (1 - done) - value
                advantage = delta + config["GAMMA"] * config["GAE_LAMBDA"] * (1 - done) * advantage
                return (advantage, value), advantage

            _, advantages = jax.lax.scan(
                step, (jnp.zeros_like(last_value), last_value), (values, rewards, dones), reverse=True
            )
            return advantages, advantages + values

        def loss_fn(p, batch):
            obs, action, old_log_prob, old_value, advantage, target = batch
            logits, value = net.apply(p, obs)
            log_probs = jax.nn.log_softmax(logits)
            log_prob = log_probs[jnp.arange(action.shape[0]), action]
            clipped_value = old_value + jnp.clip(value - old_value, -config["CLIP_EPS"], config["CLIP_EPS"])
            value_loss = 0.5 * jnp.maximum((value - target) ** 2, (clipped_value - target) ** 2).mean()
            ratio = jnp.exp(log_prob - old_log_prob)
            adv = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
            clipped_ratio = jnp.clip(ratio, 1 - config["CLIP_EPS"], 1 + config["CLIP_EPS"])
            actor_loss = -jnp.minimum(ratio * adv, clipped_ratio * adv).mean()
            entropy = -(jnp.exp(log_probs) * log_probs).sum(-1).mean()
            return actor_loss + config["VF_COEF"] * value_loss - config["ENT_COEF"] * entropy

        def update_step(carry, _):
            carry, (obs_b, action_b, logp_b, value_b, reward_b, done_b) = jax.lax.scan(
                env_step, carry, None, config["NUM_STEPS"]
            )
            state, env_state, obs, episode, rng = carry
            _, last_value = net.apply(state.params, obs)
            advantages, targets = gae(value_b, reward_b, done_b, last_value)
            batch = (obs_b, action_b, logp_b, value_b, advantages, targets)

            def epoch(carry, _):
                state, rng = carry
                rng, perm_key = jax.random.split(rng)
                perm = jax.random.permutation(perm_key, config["NUM_ENVS"] * config["NUM_STEPS"])
                flat = jax.tree.map(lambda x: x.reshape((-1, *x.shape[2:]))[perm], batch)
                minibatches = jax.tree.map(
                    lambda x: x.reshape((config["NUM_MINIBATCHES"], minibatch, *x.shape[1:])), flat
                )

                def sgd(state, mb):
                    grads = jax.grad(loss_fn)(state.params, mb)
                    return state.apply_gradients(grads=grads), None

                state, _ = jax.lax.scan(sgd, state, minibatches)
                return (state, rng), None

            (state, rng), _ = jax.lax.scan(epoch, (state, rng), None, config["UPDATE_EPOCHS"])
            return (state, env_state, obs, episode, rng), episode[1].mean()

        carry = (state, env_state, obs, episode, rng)
        _, last_returns = jax.lax.scan(update_step, carry, None, num_updates)
        return {"last_episode_return": last_returns}

    return train


def main() -> None:
    start = time.perf_counter()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    out = jax.block_until_ready(jax.jit(make_train(CONFIG))(jax.random.PRNGKey(args.seed)))
    returns = np.asarray(out["last_episode_return"])
    print(
        json.dumps(
            {
                "train_wall_s": round(time.perf_counter() - start, 3),
                "final_train_return": float(returns[-10:].mean()),
                "env_steps": int(returns.shape[0] * CONFIG["NUM_STEPS"] * CONFIG["NUM_ENVS"]),
            }
        )
    )


if __name__ == "__main__":
    main()
