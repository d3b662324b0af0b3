"""Time rlq's PPO learner alone: one update on a synthetic env, per matmul precision.

The env is free (random observations of the humanoid's size), so an update's time is the PPO
learner's: acting, GAE and the minibatch SGD of ``experiment=humanoid_ppo`` (or any overrides),
compiled with the preset's ``compiler_options``. Each precision is jax's
``default_matmul_precision`` while the update is traced, so it reaches the forward and backward
matmuls of both networks.

    python scripts/bench_ppo_learner.py --out learner.json
    python scripts/bench_ppo_learner.py --precision default tensorfloat32 --epochs 1 8 --out learner.json
    python scripts/bench_ppo_learner.py --precision default --trace --hlo-dir hlo/ --out learner_trace.json
    python scripts/bench_ppo_learner.py --override 'compiler_options={}' --out learner_xla_defaults.json
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
from bench_common import device_trace_summary, run_header
from omegaconf import DictConfig

from rlq.algos import ppo
from rlq.config.compose import compose
from rlq.envs.wrappers import AutoReset, EpisodeStats, TimeLimit
from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import Box
from rlq.run.programs.compiler import options_from_config


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


def run_config(overrides: list[str]) -> DictConfig:
    """``experiment=humanoid_ppo`` as rlq composes it, with ``overrides`` (e.g. ``algo.num_envs=64``
    or ``compiler_options={}``) on top."""
    return compose(["experiment=humanoid_ppo", *overrides])


def time_update(
    cfg: DictConfig, env: Env, precision: str, repeats: int, trace: bool = False, hlo: Path | None = None
) -> dict:
    """Compile one update (with the run config's ``compiler_options``), time ``repeats`` calls after
    a warm-up; with ``trace`` also profile one call, with ``hlo`` write the optimised HLO there."""
    algo = ppo.make(cfg.algo, env, budget_env_steps=10**9)
    context = contextlib.nullcontext() if precision == "default" else jax.default_matmul_precision(precision)
    with context:
        t0 = time.perf_counter()
        at_config = jax.jit(lambda state: algo.update(state, algo.hyperparams))  # the config's values as constants
        lowered = at_config.lower(jax.eval_shape(algo.init, jax.random.PRNGKey(0), algo.hyperparams))
        update = lowered.compile(options_from_config(cfg) or None)
        compile_s = time.perf_counter() - t0
    if hlo is not None:
        hlo.write_text(update.as_text())
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    state, _ = update(state)  # warm-up
    jax.block_until_ready(state)
    t0 = time.perf_counter()
    for _ in range(repeats):
        state, metrics = update(state)
    jax.block_until_ready(state)
    update_s = (time.perf_counter() - t0) / repeats
    result = {
        "compile_s": round(compile_s, 2),
        "update_s": round(update_s, 5),
        "steps_per_update": algo.steps_per_update,
        "value_loss": float(jnp.mean(metrics["value_loss"])),
    }
    if trace:
        result["trace_1_update"] = device_trace_summary(functools.partial(update, state), top=40)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    precisions = ["default", "tensorfloat32", "bfloat16", "float32"]
    parser.add_argument("--precision", nargs="+", choices=precisions, default=precisions)
    parser.add_argument("--epochs", type=int, nargs="+", default=[1, 8], help="algo.update_epochs to time")
    parser.add_argument("--obs-dim", type=int, default=244, help="the MJX humanoid's observation size")
    parser.add_argument("--action-dim", type=int, default=17)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--override", action="append", default=[], help="config override, e.g. algo.num_envs=64")
    parser.add_argument("--trace", action="store_true", help="also profile one update (GPU kernels by busy time)")
    parser.add_argument("--hlo-dir", type=Path, help="write each compiled update's optimised HLO here")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()

    if args.hlo_dir:
        args.hlo_dir.mkdir(parents=True, exist_ok=True)
    synthetic = SyntheticEnv(args.obs_dim, args.action_dim)
    env = AutoReset(EpisodeStats(TimeLimit(synthetic, synthetic.max_episode_steps)))
    runs = {}
    for precision in args.precision:
        for epochs in args.epochs:
            cfg = run_config([f"algo.update_epochs={epochs}", *args.override])
            name = f"{precision}, {epochs} epochs"
            hlo = args.hlo_dir / f"{precision}_{epochs}_epochs.txt" if args.hlo_dir else None
            runs[name] = result = time_update(cfg, env, precision, args.repeats, args.trace, hlo)
            print(name, json.dumps({k: v for k, v in result.items() if k != "trace_1_update"}), flush=True)
    report = {
        **run_header(),
        "what": "one PPO update of experiment=humanoid_ppo's learner on a synthetic env (no physics), "
        "compiled with the preset's compiler_options",
        "overrides": args.override,
        "runs": runs,
    }
    args.out.write_text(json.dumps(report, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
