"""LunarLander presets through `rlq train`: time to a greedy return of 200, and transfer to Box2D.

    python scripts/bench_lunar_train.py --presets lunar_ppo lunar_dqn --num-seeds 3 --out lunar_train.json

For each preset: whole-process wall time, compile time, steady env steps/s (all seeds), final greedy return
per seed (100 episodes each on `env=lunar`), the greedy evaluations along the way, the env steps and loop
wall time at which the mean over seeds and every seed first reached 200, and (unless --no-transfer) each
seed's mean return over 100 episodes of Gymnasium's Box2D LunarLander-v3 from
`rlq eval run=<dir> env=lunar_box2d episodes=100`.

`--cache cold` gives every run an empty compile cache (JAX's and rlq's program cache); `--cache shared` gives
each preset one empty cache for all its `--seeds` runs, so the first is cold and the others are warm (a user's
next run of the same config, any seed).

    python scripts/bench_lunar_train.py --presets lunar_ppo_gpu --num-seeds 1 --seeds 0 1 2 --cache shared

How often a preset misses 200 (a handful of single-seed runs cannot tell one miss in ten from one in fifty):
many seeds side by side in one process, each scored on the port, counted in ``seeds_below_threshold``:

    python scripts/bench_lunar_train.py --presets lunar_ppo_gpu --num-seeds 48 --seeds 900 --no-transfer
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from bench_common import box2d_returns, run_figures, run_rlq, time_to_threshold, write_report

THRESHOLD = 200.0


def eval_curve(rows: list[dict]) -> list[dict]:
    """The mean-over-seeds greedy evaluations: env steps per seed, loop wall time, return."""
    return [
        {"env_steps": r["env_steps"], "wall_s": r.get("wall_s"), "return": r.get("return")}
        for r in rows
        if r["kind"] == "eval" and r["seed"] == "mean"
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=["lunar_ppo", "lunar_dqn"])
    parser.add_argument("--num-seeds", type=int, default=3)
    parser.add_argument("--overrides", nargs="*", default=[], help="extra `rlq train` overrides for every preset")
    parser.add_argument("--no-transfer", action="store_true", help="skip the Box2D evaluation (needs gymnasium[box2d])")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument(
        "--runs-dir", type=Path, default=None, help="keep each run's directory here (default: temporary)"
    )
    parser.add_argument(
        "--cache",
        choices=["user", "cold", "shared"],
        default="user",
        help="user: the user's compile cache; cold: an empty one per run; shared: one empty one per preset",
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="one run per base seed, in order")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    results = []
    for preset in args.presets:
        with tempfile.TemporaryDirectory() as tmp:
            for index, seed in enumerate(args.seeds):
                overrides = [f"experiment={preset}", f"num_seeds={args.num_seeds}", f"seed={seed}", "logger=quiet"]
                overrides += ["video.at_end=false", *args.overrides]
                cache_dir = Path(tmp) / ("compile_cache" if args.cache == "shared" else f"compile_cache_{seed}")
                cache = {"user": "user", "cold": "cold", "shared": "warm" if index else "cold"}[args.cache]
                cache_overrides = [] if cache == "user" else [f"compile_cache={cache_dir}"]
                run_dir = (args.runs_dir or Path(tmp)) / f"{preset}_seed{seed}"
                run = run_rlq(overrides + cache_overrides, keep_dir=run_dir)
                row = {
                    "preset": preset,
                    "command": "rlq train " + " ".join(overrides),
                    "compile_cache": cache,
                    "seed": seed,
                    "num_seeds": args.num_seeds,
                    **run_figures(run),
                    "cached_programs": run["summary"].get("cached_programs", []),
                    "eval_curve": eval_curve(run["rows"]),
                    "threshold": THRESHOLD,
                    "seeds_below_threshold": sum(r < THRESHOLD for r in run["summary"]["eval_return"]),
                    "time_to_threshold_mean": time_to_threshold(run["rows"], THRESHOLD),
                    "time_to_threshold_every_seed": time_to_threshold(run["rows"], THRESHOLD, every_seed=True),
                }
                if not args.no_transfer:
                    try:
                        row["box2d_return"] = box2d_returns(run_dir, args.episodes)
                    except RuntimeError as error:  # keep the training figures
                        row["box2d_error"] = str(error)[-1000:]
                print(json.dumps(row), flush=True)
                results.append(row)
                write_report("lunar_presets", results, args.out)


if __name__ == "__main__":
    main()
