"""rlq against rl-zoo's tuned LunarLander recipes on this machine's CPU: for each pair (DQN, PPO), one
Stable-Baselines3 training with rl-baselines3-zoo's LunarLander-v3 hyperparameters (scripts/rlzoo_reference.py,
under a Python that has torch and stable-baselines3: ``--reference-python``) and one `rlq train` of the pair's
tuned recipe, each timed process start to exit, then each final greedy policy scored on Gymnasium's Box2D
LunarLander-v3 over the same episodes (reset seeds ``--eval-seed`` .. + episodes - 1, which neither training
uses: SB3 seeds its envs with ``--seed`` + i, rlq trains on its JAX port).

    python scripts/bench_rlzoo.py --pairs dqn ppo --seed 101 --out rlzoo.json
    python scripts/bench_rlzoo.py --smoke --out /tmp/smoke.json      # tiny budgets: does everything run?

rlq's side: `rlq train experiment=lunar_dqn` and `rlq train algo=ppo env=lunar machine=cpu`, each with
``seed=S logger.wandb.mode=disabled video.at_end=false`` and an empty compile cache (a cold process), then
`rlq eval run=<dir> env=lunar_box2d episodes=100 seed=<eval seed>`, whose episodes are kept for their spread.
The pairs run one after the other, the reference first; the report is rewritten after each run.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench_common import device_name, run_rlq
from rlzoo_reference import RECIPES

SCRIPTS = Path(__file__).resolve().parent
REFERENCE_PYTHON = os.environ.get("RLZOO_PYTHON", "/work/sb3venv/bin/python")
RLZOO_SOURCE = "DLR-RM/rl-baselines3-zoo hyperparams/{algo}.yml, LunarLander-v3 (commit 22e3ff2, 2026-04-23)"

#: each pair's rlq command (its tuned CPU recipe, as a user types it)
RLQ_PAIRS = {"dqn": ["experiment=lunar_dqn"], "ppo": ["algo=ppo", "env=lunar", "machine=cpu"]}
#: --smoke: tiny budgets, a short final evaluation
SMOKE_STEPS = 2048
SMOKE_EPISODES = 5
SMOKE_RLQ = {
    "dqn": ["budget.env_steps=2048", "algo.learning_starts=1024", "log_every_steps=1024"],
    "ppo": ["budget.env_steps=16384", "log_every_steps=16384"],
}
SMOKE_COMMON = ["eval.every_steps=0", "eval.episodes=4"]


def rlq_overrides(pair: str, seed: int, smoke: bool) -> list[str]:
    """The `rlq train` overrides of a pair (the benchmark adds the run directory and compile cache)."""
    extra = [*SMOKE_RLQ[pair], *SMOKE_COMMON] if smoke else []
    return [*RLQ_PAIRS[pair], f"seed={seed}", "logger.wandb.mode=disabled", "video.at_end=false", *extra]


def reference_args(pair: str, seed: int, model: Path, smoke: bool, threads: int | None = None) -> list[str]:
    """scripts/rlzoo_reference.py's training arguments for a pair."""
    steps = ["--steps", str(SMOKE_STEPS)] if smoke else []
    threads_arg = ["--threads", str(threads)] if threads else []
    return ["train", "--algo", pair, "--seed", str(seed), "--model", str(model), *steps, *threads_arg]


def episode_stats(returns: list[float]) -> dict:
    """Mean and population standard deviation of the episodes' returns (rl-zoo's and SB3's ``mean ± std``)."""
    return {
        "box2d_mean": round(statistics.fmean(returns), 2),
        "box2d_std": round(statistics.pstdev(returns), 2),
        "box2d_episodes": len(returns),
        "box2d_min": round(min(returns), 2),
        "box2d_over_200": sum(r >= 200 for r in returns),
    }


def last_json_line(stdout: str) -> dict:
    return json.loads(stdout.strip().splitlines()[-1])


def timed(cmd: list[str], what: str, **kwargs) -> tuple[subprocess.CompletedProcess, float]:
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"{what} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    return proc, wall


def reference_side(pair: str, seed: int, work: Path, args: argparse.Namespace) -> dict:
    model = work / f"sb3_{pair}.zip"
    train_args = reference_args(pair, seed, model, args.smoke, args.torch_threads)
    proc, wall = timed([args.reference_python, str(SCRIPTS / "rlzoo_reference.py"), *train_args], f"SB3 {pair}")
    trained = last_json_line(proc.stdout)
    eval_args = ["eval", "--algo", pair, "--model", str(model), "--episodes", str(args.episodes)]
    eval_args += ["--first-seed", str(args.eval_seed), "--threads", "1"]  # one observation a step: one thread
    proc, eval_wall = timed([args.reference_python, str(SCRIPTS / "rlzoo_reference.py"), *eval_args], "SB3 eval")
    returns = last_json_line(proc.stdout)["episode_returns"]
    return {
        "pair": pair,
        "side": "rl-zoo (SB3)",
        "command": "python scripts/rlzoo_reference.py " + " ".join(train_args),
        "hyperparameters": RECIPES[pair],
        "env_steps": trained["env_steps"],
        "n_envs": trained["n_envs"],
        "torch_threads": trained["torch_threads"],
        "train_wall_s": trained["train_wall_s"],
        "process_wall_s": round(wall, 2),
        **episode_stats(returns),
        "eval_process_s": round(eval_wall, 2),
        "episode_returns": returns,
    }


def rlq_side(pair: str, seed: int, work: Path, args: argparse.Namespace) -> dict:
    run_dir, cache = work / f"rlq_{pair}", work / f"cc_{pair}"
    cache.mkdir()
    overrides = rlq_overrides(pair, seed, args.smoke)
    run = run_rlq([*overrides, f"compile_cache={cache}"], keep_dir=run_dir)
    summary = run["summary"]
    eval_args = [f"run={run_dir}", "env=lunar_box2d", f"episodes={args.episodes}", f"seed={args.eval_seed}"]
    _, eval_wall = timed([sys.executable, "-m", "rlq.cli", "eval", *eval_args], "rlq eval")
    (returns,) = json.loads((run_dir / "eval_lunar_box2d.json").read_text())["episode_returns"]  # one seed
    return {
        "pair": pair,
        "side": "rlq",
        "command": "rlq train " + " ".join(overrides) + " compile_cache=<empty dir>",
        "eval_command": "rlq eval run=<dir> " + " ".join(eval_args[1:]),
        "env_steps": summary["env_steps"],
        "train_wall_s": summary["wall_s"],
        "compile_s": summary["compile_s"],
        "steady_env_steps_per_s": summary["steady_env_steps_per_s"],
        "greedy_evals_on_the_port": len({r["env_steps"] for r in run["rows"] if r["kind"] == "eval"}),
        "port_greedy_return": summary["eval_return"],
        "process_wall_s": run["process_wall_s"],
        **episode_stats(returns),
        "eval_process_s": round(eval_wall, 2),
        "episode_returns": returns,
    }


def versions(reference_python: str) -> dict:
    ours = subprocess.run(
        [sys.executable, "-c", "import jax, gymnasium, Box2D; print(jax.__version__, gymnasium.__version__)"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    ref = subprocess.run(
        [reference_python, str(SCRIPTS / "rlzoo_reference.py"), "versions"], capture_output=True, text=True, check=True
    )
    return {"rlq": {"jax": ours[0], "gymnasium": ours[1]}, "reference": last_json_line(ref.stdout)}


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", nargs="+", choices=sorted(RLQ_PAIRS), default=["dqn", "ppo"])
    parser.add_argument("--seed", type=int, default=101, help="training seed of both sides")
    parser.add_argument("--eval-seed", type=int, default=10_000, help="Box2D reset seed of the first scored episode")
    parser.add_argument("--episodes", type=int, default=None, help="scored episodes (default 100, --smoke 5)")
    parser.add_argument("--sides", nargs="+", choices=["reference", "rlq"], default=["reference", "rlq"])
    parser.add_argument("--reference-python", default=REFERENCE_PYTHON)
    parser.add_argument(
        "--torch-threads", type=int, default=None, help="the reference's torch threads (default: torch's)"
    )
    parser.add_argument("--smoke", action="store_true", help="tiny budgets: check that everything runs")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    if args.episodes is None:
        args.episodes = SMOKE_EPISODES if args.smoke else 100
    return args


def main() -> None:
    args = parse_args()
    work = Path(os.environ.get("TMPDIR", "/tmp")) / f"bench_rlzoo_{os.getpid()}"
    work.mkdir(parents=True)
    report = {
        "benchmark": "bench_rlzoo",
        "date": datetime.date.today().isoformat(),
        "device": device_name(),
        "cpu_cores": os.cpu_count(),
        "rlq_commit": subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip(),
        "seed": args.seed,
        "eval": f"Box2D LunarLander-v3, {args.episodes} episodes, reset seeds {args.eval_seed}..",
        "smoke": args.smoke,
        "rlzoo": {pair: RLZOO_SOURCE.format(algo=pair) for pair in args.pairs},
        "versions": versions(args.reference_python),
        "work_dir": str(work),
        "results": [],
    }
    sides = {"reference": reference_side, "rlq": rlq_side}
    for pair in args.pairs:
        for side in args.sides:
            result = sides[side](pair, args.seed, work, args)
            report["results"].append(result)
            args.out.write_text(json.dumps(report, indent=1))
            brief = {k: v for k, v in result.items() if k not in ("episode_returns", "hyperparameters", "command")}
            print(json.dumps(brief), flush=True)


if __name__ == "__main__":
    main()
