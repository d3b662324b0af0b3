"""Time rlq's PPO learner alone: one update on a synthetic env, per matmul precision.

The env is free (random observations of the humanoid's size), so an update's time is the PPO
learner's: acting, GAE and the minibatch SGD of ``experiment=humanoid_ppo`` (or any algo
overrides). Each precision is jax's ``default_matmul_precision`` while the update is traced,
so it reaches the forward and backward matmuls of both networks.

    python scripts/bench_ppo_learner.py --out learner.json
    python scripts/bench_ppo_learner.py --precision default tensorfloat32 --epochs 1 8 --out learner.json
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp
from omegaconf import DictConfig

from rlq.algos import ppo
from rlq.cli import compose
from rlq.envs.base import Env, EnvState, initial_state
from rlq.envs.spaces import Box
from rlq.envs.wrappers import AutoReset, EpisodeStats, TimeLimit


class SyntheticEnv(Env):
    """Gaussian observations, reward -|action|^2, truncated after ``length`` steps: costs next to nothing."""

    def __init__(self, obs_dim: int, action_dim: int, length: int = 1000):
        self.observation_space = Box.uniform(-jnp.inf, jnp.inf, obs_dim)
        self.action_space = Box.uniform(-1.0, 1.0, action_dim)
        self.obs_dim, self.max_episode_steps = obs_dim, length

    def reset(self, key: jax.Array) -> EnvState:
        key, obs_key = jax.random.split(key)
        return initial_state(jax.random.normal(obs_key, (self.obs_dim,)), {}, key)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        key, obs_key = jax.random.split(state.key)
        return state.replace(obs=jax.random.normal(obs_key, (self.obs_dim,)), reward=-jnp.sum(action**2), key=key)


def algo_config(overrides: list[str]) -> DictConfig:
    """The ``algo`` group of ``experiment=humanoid_ppo`` as rlq composes it, with ``overrides``
    (algo keys, e.g. ``num_envs=64``) on top."""
    return compose(["experiment=humanoid_ppo", *(f"algo.{item}" for item in overrides)]).algo


def time_update(cfg: DictConfig, env: Env, precision: str, repeats: int) -> dict:
    algo = ppo.make(cfg, env, budget_env_steps=10**9)
    context = contextlib.nullcontext() if precision == "default" else jax.default_matmul_precision(precision)
    with context:
        t0 = time.perf_counter()
        update = jax.jit(algo.update).lower(jax.eval_shape(algo.init, jax.random.PRNGKey(0))).compile()
        compile_s = time.perf_counter() - t0
    state = jax.jit(algo.init)(jax.random.PRNGKey(0))
    state, _ = update(state)  # warm-up
    jax.block_until_ready(state)
    t0 = time.perf_counter()
    for _ in range(repeats):
        state, metrics = update(state)
    jax.block_until_ready(state)
    update_s = (time.perf_counter() - t0) / repeats
    return {
        "compile_s": round(compile_s, 2),
        "update_s": round(update_s, 5),
        "steps_per_update": algo.steps_per_update,
        "value_loss": float(jnp.mean(metrics["value_loss"])),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--precision", nargs="+", default=["default", "tensorfloat32", "bfloat16", "float32"])
    parser.add_argument("--epochs", type=int, nargs="+", default=[1, 8], help="algo.update_epochs to time")
    parser.add_argument("--obs-dim", type=int, default=244, help="the MJX humanoid's observation size")
    parser.add_argument("--action-dim", type=int, default=17)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--override", action="append", default=[], help="algo override, e.g. num_envs=64")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()

    env = AutoReset(EpisodeStats(TimeLimit(SyntheticEnv(args.obs_dim, args.action_dim), 1000)))
    runs = {}
    for precision in args.precision:
        for epochs in args.epochs:
            cfg = algo_config([f"update_epochs={epochs}", *args.override])
            runs[f"{precision}, {epochs} epochs"] = result = time_update(cfg, env, precision, args.repeats)
            print(precision, epochs, json.dumps(result), flush=True)
    device = jax.devices()[0]
    report = {
        "date": datetime.date.today().isoformat(),
        "device": f"{device.platform} | {device.device_kind}",
        "jax": jax.__version__,
        "host": platform.processor() or platform.machine(),
        "what": "one PPO update of experiment=humanoid_ppo's learner on a synthetic env (no physics)",
        "overrides": args.override,
        "runs": runs,
    }
    args.out.write_text(json.dumps(report, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
