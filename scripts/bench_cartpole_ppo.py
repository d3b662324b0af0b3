"""Benchmark `rlq train` on CartPole PPO with PureJaxRL's published settings.

Runs the real CLI in a subprocess per configuration and reports, as JSON: whole-process wall
time (Python start, imports, compile, training, final evaluation, checkpoint), compile time,
and steady env steps/s (all seeds together, compile excluded), plus the final greedy return.

    python scripts/bench_cartpole_ppo.py --num-seeds 1 --out bench_cpu.json          # CPU
    python scripts/bench_cartpole_ppo.py --num-seeds 1 64 --out bench_gpu.json       # GPU node
    python scripts/bench_cartpole_ppo.py --anchor --repeat 3 --out side_by_side.json  # vs PureJaxRL's way

``--anchor`` also times scripts/anchor_purejaxrl_ppo.py (PPO written as PureJaxRL writes it, same
settings) as a whole process, alternating with rlq's runs so that both meet the same machine
load, and reports each side's runs and median.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench_common import device_name, run_rlq

# PureJaxRL's CartPole-v1 PPO: 4 envs x 128 steps, 5e5 steps, 4 epochs, 4 minibatches,
# lr 2.5e-4 annealed, gamma 0.99, lambda 0.95, clip 0.2, entropy 0.01 (rlq's ppo defaults).
PUREJAXRL = [
    "env=cartpole",
    "algo=ppo",
    "algo.num_envs=4",
    "algo.num_steps=128",
    "budget.env_steps=500000",
    "algo.update_epochs=4",
    "algo.num_minibatches=4",
    "algo.lr=2.5e-4",
    "algo.anneal_lr=true",
    "algo.gamma=0.99",
    "algo.gae_lambda=0.95",
    "algo.clip_eps=0.2",
    "algo.ent_coef=0.01",
    "logger=quiet",
]


def run_once(num_seeds: int, extra: list[str]) -> dict:
    overrides = [*PUREJAXRL, f"num_seeds={num_seeds}", "video.at_end=false", *extra]
    run = run_rlq(overrides)
    summary = run["summary"]
    return {
        "command": "rlq train " + " ".join(overrides),
        "num_seeds": num_seeds,
        "process_wall_s": run["process_wall_s"],
        "train_wall_s": summary["wall_s"],
        "compile_s": summary["compile_s"],
        "steady_env_steps_per_s": summary["steady_env_steps_per_s"],
        "env_steps_per_seed": summary["env_steps"],
        "eval_return_mean": summary["eval_return_mean"],
        "eval_return_min": min(summary["eval_return"]),
    }


ANCHOR = Path(__file__).resolve().parent / "anchor_purejaxrl_ppo.py"


def anchor_once(seed: int) -> dict:
    """One whole process of the PureJaxRL-style anchor, Python start to exit."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, str(ANCHOR), "--seed", str(seed)], capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"{ANCHOR.name} failed:\n{proc.stderr[-3000:]}")
    return {"process_wall_s": round(wall, 2), **json.loads(proc.stdout.strip().splitlines()[-1])}


def side_by_side(repeat: int, extra: list[str]) -> dict:
    """``repeat`` rounds of one rlq run and one anchor run, alternating which goes first."""
    runs: dict[str, list[dict]] = {"rlq": [], "anchor": []}
    for i in range(repeat):
        for name in ("anchor", "rlq") if i % 2 else ("rlq", "anchor"):
            runs[name].append(run_once(1, [f"seed={i}", *extra]) if name == "rlq" else anchor_once(i))
            print(json.dumps({name: runs[name][-1]}), flush=True)
    median = {name: statistics.median(r["process_wall_s"] for r in rs) for name, rs in runs.items()}
    return {
        "runs": runs,
        "median_process_wall_s": median,
        "rlq_over_anchor": round(median["rlq"] / median["anchor"], 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-seeds", type=int, nargs="+", default=[1])
    parser.add_argument(
        "--repeat", type=int, default=1, help="runs per configuration, the best kept (--anchor: alternating rounds)"
    )
    parser.add_argument("--anchor", action="store_true", help="side by side with the PureJaxRL-style anchor")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("overrides", nargs="*", help="extra rlq overrides")
    args = parser.parse_args()
    results = []
    for num_seeds in [] if args.anchor else args.num_seeds:
        runs = [run_once(num_seeds, args.overrides) for _ in range(args.repeat)]
        best = min(runs, key=lambda r: r["process_wall_s"])
        print(json.dumps(best), flush=True)
        results.append(best)
    report = {
        "benchmark": "cartpole_ppo_purejaxrl_settings",
        "date": datetime.date.today().isoformat(),
        "device": device_name(),
        "host": {"machine": platform.machine(), "python": platform.python_version()},
        "results": results,
    }
    if args.anchor:
        report["side_by_side"] = side_by_side(args.repeat, args.overrides)
    if args.out:
        args.out.write_text(json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
