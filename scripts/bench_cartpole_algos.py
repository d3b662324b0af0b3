"""Throughput and time-to-threshold of every CartPole preset, through `rlq train`.

    python scripts/bench_cartpole_algos.py --num-seeds 3 --out cartpole_algos.json
    python scripts/bench_cartpole_algos.py --algos dqn ppo --num-seeds 3 64

For each preset: whole-process wall time, compile time, steady env steps/s (all seeds, compile
excluded), final greedy return per seed, and the env steps and loop wall time at which the mean
greedy return first reached the issue's threshold (evaluated every --eval-every env steps).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from bench_common import run_figures, run_rlq, time_to_threshold, write_report

PRESETS = {
    "ppo": ("experiment=cartpole_ppo", 475.0),
    "dqn": ("experiment=cartpole_dqn", 475.0),
    "reinforce": ("experiment=cartpole_reinforce", 400.0),
    "random_search": ("experiment=cartpole_random_search", 475.0),
    "qlearning": ("experiment=cartpole_qlearning", 195.0),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algos", nargs="+", default=list(PRESETS), choices=list(PRESETS))
    parser.add_argument("--num-seeds", type=int, nargs="+", default=[3])
    parser.add_argument("--eval-every", type=int, default=25_000)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    results = []
    for algo in args.algos:
        preset, threshold = PRESETS[algo]
        for num_seeds in args.num_seeds:
            overrides = [preset, f"num_seeds={num_seeds}", f"eval.every_steps={args.eval_every}", "logger=quiet"]
            overrides.append("video.at_end=false")
            run = run_rlq(overrides)
            row = {
                "algo": algo,
                "command": "rlq train " + " ".join(overrides),
                "num_seeds": num_seeds,
                **run_figures(run),
                "threshold": threshold,
                "time_to_threshold": time_to_threshold(run["rows"], threshold),
            }
            print(json.dumps(row), flush=True)
            results.append(row)
    write_report("cartpole_presets", results, args.out)


if __name__ == "__main__":
    main()
