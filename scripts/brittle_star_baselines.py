"""Brittle star directed locomotion: distance closed toward a random target by five policies.

(a) ``random``: a uniformly random leading arm at every control step (leading-arm CPG);
(b) ``identity``: the argmax of T0's identity Q-table over the sector observation (lead with the
    arm facing the target);
(c) ``qlearning``: tabular Q-learning, trained with ``experiment=brittle_star_qlearning``;
(d) ``ppo_cpg``: PPO modulating the CPG in closed loop, ``experiment=brittle_star_ppo_cpg``;
(e) ``ppo_direct``: PPO setting the 50 joint targets, ``experiment=brittle_star_ppo_direct``.

Every policy runs one episode (20 s) toward each of ``--episodes`` random targets; the targets are
the same for every policy (same evaluation key; the direct controller's reset key is aligned
with the CPG's, and the script checks the targets agree). The identity table and the learned
Q-tables go through one compiled program that takes the table as input, so equal greedy tables
give equal distances. (c)-(e) are trained in this process with ``rlq.run.train.train`` (budgets
times ``--budget-scale``); every seed of a run is evaluated.

Results go to ``--out`` (JSON) after every measurement. An existing file with the same evaluation
settings is extended, so the policies can be run by separate commands into one file.

    python scripts/brittle_star_baselines.py --policies random identity qlearning --out bs.json
    python scripts/brittle_star_baselines.py --policies ppo_cpg --out bs.json
    python scripts/brittle_star_baselines.py --smoke --out /tmp/bs_smoke.json     # CPU smoke test
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

if "--nondeterministic" not in sys.argv:
    # GPU scatter-adds (atomics) make the contact dynamics differ from run to run at float level,
    # and frictional chaos turns that into centimetres: the same table evaluated twice closed
    # 0.153 and 0.152 m on average (up to 0.155 m apart on one target). Deterministic ops make
    # equal policies give equal distances (evaluation about 2x slower on the GPU).
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} --xla_gpu_deterministic_ops=true".strip()

import jax
import jax.numpy as jnp
import numpy as np
from omegaconf import DictConfig, OmegaConf

from rlq.algos import make_algo
from rlq.config.compose import compose
from rlq.envs import Env, EnvState, Wrapper
from rlq.lib.batch import seed_entry
from rlq.lib.rollout import PolicyFn, evaluate, reset_batch
from rlq.run.checks.validate import check_run_config
from rlq.run.programs.env_stack import make_env
from rlq.run.train import train

POLICIES = ("random", "identity", "qlearning", "ppo_cpg", "ppo_direct")
PRESETS = {
    "random": "brittle_star_qlearning",  # untrained: only its env (sector observation, leading-arm CPG)
    "identity": "brittle_star_qlearning",
    "qlearning": "brittle_star_qlearning",
    "ppo_cpg": "brittle_star_ppo_cpg",
    "ppo_direct": "brittle_star_ppo_direct",
}
TRAINED = ("qlearning", "ppo_cpg", "ppo_direct")
#: overrides of --smoke: tiny budgets, 2 envs, 1 segment per arm (faster compilation), 5-step episodes
SMOKE_OVERRIDES = [
    "algo.num_envs=2",
    "algo.num_steps=4",
    "env.segments_per_arm=1",
    "env.simulation_time=0.2",
    "log_every_steps=8",
    "eval.episodes=1",
]
SMOKE_PPO = ["algo.num_minibatches=2", "algo.update_epochs=1"]


def log(message: str) -> None:
    print(f"[baselines {time.strftime('%H:%M:%S')}] {message}", file=sys.stderr, flush=True)


class CPGResetKey(Wrapper):
    """Gives the wrapped env the reset key the CPG controller gives its env (the first half of a
    split), so a direct-controller env draws the same target as a CPG env from the same key."""

    def reset(self, key: jax.Array) -> EnvState:
        return self.env.reset(jax.random.split(key)[0])

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        return self.env.step(state, action)


def eval_env(cfg: DictConfig) -> Env:
    env = make_env(cfg)
    return CPGResetKey(env) if cfg.controller.name == "direct" else env


def run_config(policy: str, overrides: list[str], budget_scale: float = 1.0) -> DictConfig:
    """The preset's config with ``overrides``; budgets (and the epsilon schedule) times ``budget_scale``."""
    cfg = compose([f"experiment={PRESETS[policy]}", "logger=quiet", "video.at_end=false", *overrides])
    if budget_scale != 1.0:
        cfg.budget.env_steps = max(1, int(cfg.budget.env_steps * budget_scale))
        cfg.log_every_steps = max(1, int(cfg.log_every_steps * budget_scale))
        if cfg.algo.get("epsilon") is not None:
            cfg.algo.epsilon.duration = max(1, int(cfg.algo.epsilon.duration * budget_scale))
    check_run_config(cfg)
    return cfg


def targets(env: Env, key: jax.Array, episodes: int) -> np.ndarray:
    """The target xy of each evaluation episode (``evaluate`` resets with the first half of ``key``)."""
    state = jax.jit(lambda k: reset_batch(env, k, episodes))(jax.random.split(key)[0])
    inner = state.inner
    while not hasattr(inner, "target_xy"):
        inner = inner.env
    return np.asarray(inner.target_xy, np.float64)


class TableEvaluator:
    """Greedy Q-table policies evaluated by one compiled program that takes the table as input.

    Chaotic frictional contact turns float-level differences between two compiled programs into
    centimetres of distance closed, so two programs score the same greedy policy differently.
    Every table (the identity one and each learned one) runs through this one program: with
    deterministic GPU ops (set above) equal greedy tables give equal trajectories, and differences
    between tables are the policies'."""

    def __init__(self, env: Env, episodes: int):
        def run(table: jax.Array, key: jax.Array) -> dict[str, jax.Array]:
            return evaluate(env, lambda obs, _: jnp.argmax(table[obs], axis=-1), key, episodes)

        self._run = jax.jit(run)

    def __call__(self, table: jax.Array, key: jax.Array) -> dict[str, Any]:
        t0 = time.perf_counter()
        return summarize(jax.device_get(self._run(jnp.asarray(table, jnp.float32), key)), t0)


def distances(env: Env, policy: PolicyFn, key: jax.Array, episodes: int) -> dict[str, Any]:
    t0 = time.perf_counter()
    return summarize(jax.device_get(jax.jit(lambda k: evaluate(env, policy, k, episodes))(key)), t0)


def summarize(record: dict[str, Any], t0: float) -> dict[str, Any]:
    distance = np.asarray(record["distance_closed"], np.float64)
    return {
        "distance_closed_mean": float(distance.mean()),
        "distance_closed_std": float(distance.std()),
        "distance_closed_stderr": float(distance.std() / np.sqrt(len(distance))),
        "reached_target": int(np.sum(np.asarray(record["distance_to_target"]) < 0.2)),
        "finished": int(np.sum(record["finished"])),
        "energy_mean": float(np.mean(record["energy"])),
        "eval_wall_s": round(time.perf_counter() - t0, 2),
        "distance_closed": [round(float(d), 5) for d in distance],
    }


def random_arm(num_arms: int) -> PolicyFn:
    return lambda obs, k: jax.random.randint(k, (), 0, num_arms)


def train_and_policies(
    cfg: DictConfig, runs_dir: Path, name: str
) -> tuple[dict[str, Any], list[PolicyFn], np.ndarray | None]:
    """Train ``cfg`` in this process; the run's figures, each seed's greedy policy and, for
    tabular Q, the seeds' Q-tables."""
    run_dir = runs_dir / name
    run_dir.mkdir(parents=True, exist_ok=True)
    result = train(cfg, run_dir)
    log(result.line())
    algo = make_algo(cfg.algo, make_env(cfg), cfg.budget.env_steps)
    policies = [algo.policy(seed_entry(result.state, i, result.num_seeds)) for i in range(result.num_seeds)]
    train_rows = [
        json.loads(line)
        for line in (run_dir / "metrics.jsonl").read_text().splitlines()
        if '"kind": "train"' in line and '"seed": "mean"' in line
    ]
    figures = {
        **result.as_dict(),
        "run_dir": str(run_dir),
        "train_episode_return_last": train_rows[-1].get("episode_return") if train_rows else None,
    }
    tables = None
    if cfg.algo.name == "qlearning":
        tables = np.asarray(result.state.table)
        figures["q_tables"] = tables.round(5).tolist()
        figures["greedy_arm_per_state"] = tables.argmax(-1).tolist()
    return figures, policies, tables


def eval_settings(args: argparse.Namespace, overrides: list[str]) -> dict[str, Any]:
    return {"episodes": args.episodes, "seed": args.seed, "env_overrides": [o for o in overrides if "env." in o]}


def load_previous(path: Path, settings: dict[str, Any]) -> dict[str, Any]:
    if not path.exists():
        return {}
    try:
        old = json.loads(path.read_text())
    except json.JSONDecodeError:
        return {}
    if old.get("eval") != settings:
        log(f"{path} holds results for other evaluation settings: overwriting it")
        return {}
    return old.get("policies", {})


def comparisons(policies: dict[str, Any]) -> dict[str, Any]:
    def mean(name: str) -> float | None:
        entry = policies.get(name)
        return None if entry is None else entry["distance_closed_mean"]

    out = {}
    for better, worse in (("qlearning", "identity"), ("ppo_cpg", "qlearning"), ("identity", "random")):
        a, b = mean(better), mean(worse)
        if a is not None and b is not None:
            out[f"{better}>={worse}"] = {"ok": a >= b, "difference_m": round(a - b, 5)}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policies", nargs="+", choices=POLICIES, default=list(POLICIES))
    parser.add_argument("--episodes", type=int, default=32, help="random targets per policy (>= 16)")
    parser.add_argument("--seed", type=int, default=0, help="evaluation key (targets) and training seed")
    parser.add_argument("--num-seeds", type=int, default=1, help="training seeds per preset (all evaluated)")
    parser.add_argument("--budget-scale", type=float, default=1.0, help="multiplies the presets' env-step budgets")
    parser.add_argument(
        "--override", action="append", default=[], help="extra config override for every policy (repeatable)"
    )
    parser.add_argument("--runs-dir", type=Path, default=None, help="keep the training runs here (default: temp)")
    parser.add_argument(
        "--nondeterministic", action="store_true", help="skip XLA's deterministic GPU ops (faster, noisier)"
    )
    parser.add_argument("--smoke", action="store_true", help="CPU smoke test: 2 envs, 2 targets, 5-step episodes")
    parser.add_argument("--out", type=Path, default=Path("brittle_star_baselines.json"))
    args = parser.parse_args()

    overrides = list(args.override)
    if args.smoke:
        overrides = SMOKE_OVERRIDES + overrides
        args.episodes = min(args.episodes, 2)
        args.budget_scale = 0.0
    elif args.episodes < 16:
        raise SystemExit("--episodes must be >= 16 (use --smoke for a quick test)")
    settings = eval_settings(args, overrides)
    result: dict[str, Any] = {
        "device": str(jax.devices()[0].device_kind),
        "platform": jax.default_backend(),
        "jax": jax.__version__,
        "python": platform.python_version(),
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "eval": settings,
        "policies": load_previous(args.out, settings),
    }

    def save() -> None:
        result["comparisons"] = comparisons(result["policies"])
        args.out.write_text(json.dumps(result, indent=2))

    eval_key = jax.random.fold_in(jax.random.PRNGKey(args.seed), 31_337)
    reference_targets: np.ndarray | None = None
    table_evaluators: dict[str, TableEvaluator] = {}  # one per env config: identity and Q share it
    tmp = None if args.runs_dir else tempfile.TemporaryDirectory()
    runs_dir = args.runs_dir or Path(tmp.name)
    try:
        for name in args.policies:
            trained = name in TRAINED
            extra = SMOKE_PPO if args.smoke and name.startswith("ppo") else []
            run_overrides = overrides + extra + [f"seed={args.seed}", f"num_seeds={args.num_seeds}"]
            cfg = run_config(name, run_overrides, args.budget_scale if trained else 1.0)
            env = eval_env(cfg)
            xy = targets(env, eval_key, args.episodes)
            if reference_targets is None:
                reference_targets = xy
            elif not np.allclose(xy, reference_targets, atol=1e-5):
                raise SystemExit(f"{name}: evaluation targets differ from the first policy's")
            entry: dict[str, Any] = {"preset": PRESETS[name], "trained": trained}
            entry["target_angle_deg"] = np.degrees(np.arctan2(xy[:, 1], xy[:, 0])).round(2).tolist()
            tables: np.ndarray | None = None
            if trained:
                log(f"{name}: training experiment={PRESETS[name]} ({cfg.budget.env_steps:,} env steps)")
                entry["training"], seed_policies, tables = train_and_policies(cfg, runs_dir, name)
            elif name == "identity":
                seed_policies, tables = [], np.eye(env.action_space.n)[None]
            else:
                seed_policies = [random_arm(env.action_space.n)]
            if tables is not None:
                env_key = OmegaConf.to_yaml(cfg.env) + OmegaConf.to_yaml(cfg.controller)
                if env_key not in table_evaluators:
                    table_evaluators[env_key] = TableEvaluator(env, args.episodes)
                entry["evaluation"] = "greedy table as input of one compiled program"
                per_seed = [table_evaluators[env_key](table, eval_key) for table in tables]
            else:
                per_seed = [distances(env, policy, eval_key, args.episodes) for policy in seed_policies]
            for i, figures in enumerate(per_seed):
                log(
                    f"{name} seed {i}: distance closed {figures['distance_closed_mean']:.3f} "
                    f"+- {figures['distance_closed_std']:.3f} m over {args.episodes} targets"
                )
            means = [s["distance_closed_mean"] for s in per_seed]
            entry.update(per_seed[0])
            entry["distance_closed_mean"] = float(np.mean(means))
            entry["per_seed"] = per_seed if len(per_seed) > 1 else None
            entry["env"] = OmegaConf.to_container(cfg.env)
            result["policies"][name] = entry
            save()
    finally:
        if tmp is not None:
            tmp.cleanup()
    save()
    for check, value in result["comparisons"].items():
        log(f"{check}: {'yes' if value['ok'] else 'NO'} ({value['difference_m']:+.3f} m)")
    log(f"wrote {args.out}")


if __name__ == "__main__":
    main()
