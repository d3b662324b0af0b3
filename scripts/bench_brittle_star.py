"""Brittle star benchmark: simulation throughput and locomotion of the leading-arm CPG, per model variant.

For each physics variant (see docs/brittle_star.md):
- throughput: control steps/s of the training stack (CPG leading-arm controller, time limit,
  episode statistics, auto-reset) with random leading arms, at each ``--envs`` batch size;
- distance closed toward the target in one episode (20 s, 500 control steps by default) over
  ``--episodes`` random targets, for (a) a uniformly random leading arm at every step and (b) the
  identity Q-table policy (lead with the arm facing the target: the sector observation itself).
  Every variant sees the same targets, so the distances pair up; each variant is validated
  against the first one (the reference): identity-policy distance within ``--tolerance``.

Writes JSON to ``--out`` after every measurement (partial results survive an interruption) and
prints progress to stderr.

    python scripts/bench_brittle_star.py --out bench_brittle_star.json
    python scripts/bench_brittle_star.py --envs 1 2 --steps 3 --episodes 2 --episode-steps 5  # CPU smoke test
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import jax
import numpy as np
from omegaconf import DictConfig

from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.envs.brittle_star.model import contact_candidates
from rlq.lib.rollout import evaluate
from rlq.run.programs.env_stack import make_env

#: name -> env overrides. "biorobot" is biorobot's model exactly (its sensors on); rlq's default
#: skips the sensors; "pruned" adds floor-only contacts (same physics while off the walls);
#: "lean" also drops the joint-limit rows and uses 3 line-search iterations (validated: 1.7 %);
#: "lean_coarse" adds a 0.005 s physics timestep (8 per control step; validated: -7.8 %), on MJX's
#: JAX implementation; "fast" is the env/physics=fast preset: lean_coarse stepped by MuJoCo Warp
#: on an NVIDIA GPU with warp-lang (mjx_impl=auto); "warp" is rlq's default physics on MuJoCo Warp;
#: "condim3" drops torsional friction instead (different physics, fails the validation).
PRUNED = ["physics.wall_contacts=false"]
LEAN = [*PRUNED, "physics.joint_limits=false", "physics.ls_iterations=3"]
LEAN_COARSE = [*LEAN, "time_scale=2.5", "physics_steps_per_control_step=8"]
VARIANTS = {
    "biorobot": ["physics.sensors=true"],
    "default": [],
    "pruned": PRUNED,
    "lean": LEAN,
    "lean_coarse": LEAN_COARSE,
    "fast": [*LEAN_COARSE, "mjx_impl=auto"],
    "warp": ["mjx_impl=warp"],
    "condim3": [*PRUNED, "physics.condim=3"],
}


def log(message: str) -> None:
    print(f"[bench {time.strftime('%H:%M:%S')}] {message}", file=sys.stderr, flush=True)


def run_config(env_overrides: list[str], observation: str, episode_steps: int | None) -> DictConfig:
    """``env=brittle_star`` with its physics defaults and ``controller=cpg`` in leading-arm mode; ``env_overrides``
    are env keys (``physics.ls_iterations=3``). Without the tuned files: ``rlq train env=brittle_star`` (algo=ppo)
    would apply the PPO recipe's pruned physics, and the "default" variant would be "pruned"."""
    cfg = compose(
        ["env=brittle_star", "controller=cpg", "controller.mode=leading_arm", f"env.observation={observation}"]
        + WITHOUT_TUNED
        + [f"env.{item}" for item in env_overrides]
    )
    if episode_steps:
        control_dt = 0.002 * cfg.env.time_scale * cfg.env.physics_steps_per_control_step
        cfg.env.simulation_time = episode_steps * control_dt
    return cfg


def throughput(cfg: DictConfig, num_envs: int, steps: int, repeats: int, key: jax.Array) -> dict:
    env = make_env(cfg)
    n_arms = env.action_space.n

    def run(state, key):
        def body(state, k):
            arms = jax.random.randint(k, (num_envs,), 0, n_arms)
            return jax.vmap(env.step)(state, arms), None

        state, _ = jax.lax.scan(body, state, jax.random.split(key, steps))
        return state

    reset = jax.jit(lambda k: jax.vmap(env.reset)(jax.random.split(k, num_envs)))
    state = jax.block_until_ready(reset(key))
    t0 = time.perf_counter()
    compiled = jax.jit(run, donate_argnums=0).lower(state, key).compile()
    compile_s = time.perf_counter() - t0
    state = jax.block_until_ready(compiled(state, jax.random.fold_in(key, 0)))  # warm-up
    t0 = time.perf_counter()
    for r in range(repeats):
        state = compiled(state, jax.random.fold_in(key, r + 1))
    jax.block_until_ready(state)
    elapsed = time.perf_counter() - t0
    return {
        "num_envs": num_envs,
        "control_steps_per_s": num_envs * steps * repeats / elapsed,
        "physics_steps_per_s": num_envs * steps * repeats * cfg.env.physics_steps_per_control_step / elapsed,
        "seconds_per_batch_step": elapsed / (steps * repeats),
        "compile_s": compile_s,
    }


def locomotion(cfg: DictConfig, episodes: int, key: jax.Array) -> dict:
    env = make_env(cfg)  # sector observation: the arm facing the target
    n_arms = env.action_space.n
    policies = {
        "random_leading_arm": lambda obs, k: jax.random.randint(k, (), 0, n_arms),
        "identity_q_table": lambda obs, k: obs,
    }
    out = {}
    for name, policy in policies.items():
        t0 = time.perf_counter()
        record = jax.device_get(jax.jit(lambda k, p=policy: evaluate(env, p, k, episodes))(key))
        distance = np.asarray(record["distance_closed"], np.float64)
        out[name] = {
            "distance_closed_mean": float(distance.mean()),
            "distance_closed_std": float(distance.std()),
            "distance_closed_stderr": float(distance.std() / np.sqrt(len(distance))),
            "distance_closed_min": float(distance.min()),
            "distance_closed_max": float(distance.max()),
            "reached_target": int(np.sum(np.asarray(record["distance_to_target"]) < 0.2)),
            "energy_mean": float(np.mean(record["energy"])),
            "episodes": episodes,
            "wall_s": time.perf_counter() - t0,
            "distance_closed": [round(float(d), 5) for d in distance],  # per target, same targets in every variant
        }
        log(f"  {name}: distance closed {distance.mean():.3f} +- {distance.std():.3f} m over {episodes} targets")
    return out


def parse_variants(names: list[str], extra: list[str]) -> dict[str, list[str]]:
    variants = {}
    for name in names:
        if name not in VARIANTS:
            raise SystemExit(f"unknown variant {name!r}; known: {', '.join(VARIANTS)} (or --variant NAME=k=v,k=v)")
        variants[name] = VARIANTS[name]
    for item in extra:
        name, _, overrides = item.partition("=")
        variants[name] = [o for o in overrides.split(",") if o]
    return variants


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 256, 1024, 4096], help="batch sizes for throughput")
    parser.add_argument("--steps", type=int, default=50, help="control steps per timed call (one compiled scan)")
    parser.add_argument("--repeats", type=int, default=2, help="timed calls per batch size (after one warm-up)")
    parser.add_argument("--episodes", type=int, default=64, help="random targets per policy and variant (>= 16)")
    parser.add_argument(
        "--episode-steps", type=int, default=None, help="control steps per episode (default: 20 s = 500)"
    )
    parser.add_argument(
        "--variants", nargs="+", default=list(VARIANTS), help="named variants; the first is the reference"
    )
    parser.add_argument(
        "--variant", action="append", default=[], help="extra variant NAME=override,override (env keys)"
    )
    parser.add_argument("--segments", type=int, default=None, help="segments per arm (default: the config's 5)")
    parser.add_argument(
        "--tolerance", type=float, default=0.10, help="allowed relative difference of identity distance"
    )
    parser.add_argument("--skip-throughput", action="store_true")
    parser.add_argument("--skip-locomotion", action="store_true")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("bench_brittle_star.json"))
    args = parser.parse_args()

    variants = parse_variants(args.variants, args.variant)
    base = [f"segments_per_arm={args.segments}"] if args.segments else []
    result = {
        "device": str(jax.devices()[0].device_kind),
        "platform": jax.default_backend(),
        "platform_version": jax.devices()[0].client.platform_version,
        "jax": jax.__version__,
        "python": platform.python_version(),
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "variants": {},
    }

    def save() -> None:
        args.out.write_text(json.dumps(result, indent=2))

    key = jax.random.PRNGKey(args.seed)
    for name, overrides in variants.items():
        cfg = run_config(base + overrides, "sector", args.episode_steps)
        entry = {"overrides": overrides, "throughput": [], "locomotion": None}
        env = make_env(cfg).unwrapped
        entry["contact_candidates"] = contact_candidates(env.mj_model)
        entry["mjx_impl"] = env.mjx_impl
        result["variants"][name] = entry
        log(
            f"variant {name} ({', '.join(overrides) or 'rlq defaults'}): {entry['contact_candidates']} contact candidates, {entry['mjx_impl']}"
        )
        if not args.skip_throughput:
            for num_envs in args.envs:
                row = throughput(cfg, num_envs, args.steps, args.repeats, jax.random.fold_in(key, num_envs))
                entry["throughput"].append(row)
                log(
                    f"  {num_envs} envs: {row['control_steps_per_s']:,.0f} control steps/s (compile {row['compile_s']:.1f} s)"
                )
                save()
        if not args.skip_locomotion:
            entry["locomotion"] = locomotion(cfg, args.episodes, jax.random.fold_in(key, 10_007))
            save()

    reference = next(iter(variants))
    ref_loco = result["variants"][reference]["locomotion"]
    if ref_loco:
        ref = ref_loco["identity_q_table"]["distance_closed_mean"]
        for name, entry in result["variants"].items():
            got = entry["locomotion"]["identity_q_table"]["distance_closed_mean"]
            rel = abs(got - ref) / max(abs(ref), 1e-9)
            entry["validation"] = {"reference": reference, "relative_difference": rel, "ok": rel <= args.tolerance}
            log(f"validation {name} vs {reference}: identity distance {got:.3f} vs {ref:.3f} m ({rel:.1%})")
    save()
    log(f"wrote {args.out}")


if __name__ == "__main__":
    main()
