"""Compile seconds of each job of a hyperparameter sweep, the sweep run as one whole process (`rlq train -m`).

A sweep over the algorithms' numeric hyperparameters compiles its programs once: the first job compiles, the
later ones load them from the compile cache (issue 76's goal: at most 2 s each). This runs the sweep as a user
would, with a fresh compile cache unless `--cache` names one, and reads each job's compile seconds and the programs
it loaded from its `summary.json`, and its console line (`rlq: programs loaded from the compile cache: ...`) from
the sweep's output. It prints the JSON (and writes it to `--out`), with the load average before and after: on a
shared machine the figures are only as quiet as it was.

    python scripts/bench_sweep_compile.py --optuna 6 --small                          # CartPole PPO, 6 Optuna trials
    python scripts/bench_sweep_compile.py --algo dqn --env lunar --values 1e-4,3e-4,1e-3,3e-3 --out sweep.json  # GPU
    python scripts/bench_sweep_compile.py --key algo.sigma --algo es --values 0.3,0.5 --small --override program_cache=never
    python scripts/bench_sweep_compile.py --algo dqn --env lunar --values 1e-4,3e-4,1e-3 --small --processes

Hydra's basic and Optuna sweepers run every job in one process, whose later jobs take the programs from memory;
``--processes`` runs each value of ``--values`` as a `rlq train` process of its own, one after another on one
compile cache, as the jobs of a SLURM array do: each later job then loads the programs from the cache's file.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_common import QUIET, device_name, rlq_commit

#: a job's last console line names its run directory after the final " | "
FINAL_LINE = re.compile(r"^rlq: [\d,]+ env steps.* \| (?P<dir>\S+)$")
#: each job's line of the programs it loaded and compiled (rlq/run/programs/compiling.py, CompiledPrograms.line)
PROGRAMS_LINE = re.compile(r"^rlq: programs loaded from the compile cache: .*$")
#: budgets of `--small`: a few chunks, enough to time the compile (the learning is not the point)
SMALL_BUDGET = {"cartpole": 20_000, "lunar": 20_000}


def sweep_command(args: argparse.Namespace, sweep_dir: Path, cache: str) -> list[str]:
    """The `rlq train -m` arguments of the sweep."""
    if args.optuna:
        low, high = args.interval
        searched = [
            "hydra/sweeper=optuna",
            f"hydra.sweeper.n_trials={args.optuna}",
            "hydra.sweeper.sampler.seed=0",
            f"{args.key}=tag(log,interval({low},{high}))",
        ]
    else:
        searched = [f"{args.key}={args.values}"]
    budget = (
        [f"budget.env_steps={args.budget or SMALL_BUDGET.get(args.env, 20_000)}"] if args.small or args.budget else []
    )
    return [
        "train",
        "-m",
        f"algo={args.algo}",
        f"env={args.env}",
        *searched,
        *budget,
        f"compile_cache={cache}",
        f"hydra.sweep.dir={sweep_dir}",
        *QUIET,
        *args.override,
    ]


def process_commands(args: argparse.Namespace, work: Path, cache: str) -> list[list[str]]:
    """``--processes``: one `rlq train` command per value of ``--values``, each with its own run directory."""
    budget = (
        [f"budget.env_steps={args.budget or SMALL_BUDGET.get(args.env, 20_000)}"] if args.small or args.budget else []
    )
    return [
        [
            "train",
            f"algo={args.algo}",
            f"env={args.env}",
            f"{args.key}={value}",
            *budget,
            f"compile_cache={cache}",
            f"hydra.run.dir={work / f'job{index}'}",
            *QUIET,
            *args.override,
        ]
        for index, value in enumerate(args.values.split(","))
    ]


def jobs_of(stdout: str) -> list[dict]:
    """Each job of the sweep, in the order it ran: its directory, compile seconds, the programs it loaded from
    the compile cache (whole, or compiled by JAX's cache) and its console line of programs."""
    jobs, programs_line = [], None
    for line in stdout.splitlines():
        if PROGRAMS_LINE.match(line):
            programs_line = line
        found = FINAL_LINE.match(line)
        if not found:
            continue
        run_dir = Path(found["dir"])
        summary = json.loads((run_dir / "summary.json").read_text())
        jobs.append(
            {
                "job": run_dir.name,
                "compile_s": summary["compile_s"],
                "process_wall_s": summary["process_wall_s"],
                "cached_programs": summary["cached_programs"],
                "compile_cache_hits": summary["compile_cache_hits"],
                "programs_line": programs_line,
                "eval_return_mean": summary["eval_return_mean"],
            }
        )
        programs_line = None
    return jobs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algo", default="ppo")
    parser.add_argument("--env", default="cartpole")
    parser.add_argument("--key", default="algo.lr", help="the swept key")
    parser.add_argument("--values", default="1e-4,3e-4,1e-3,3e-3", help="the basic sweeper's values of --key")
    parser.add_argument("--optuna", type=int, default=0, help="trials of Hydra's Optuna sweeper instead of --values")
    parser.add_argument("--interval", type=float, nargs=2, default=(1e-6, 1e-2), help="--optuna's log interval")
    parser.add_argument(
        "--processes", action="store_true", help="each value of --values in a process of its own (a SLURM array)"
    )
    parser.add_argument("--small", action="store_true", help="a small budget (a few chunks): compile, not learning")
    parser.add_argument("--budget", type=int, default=0, help="budget.env_steps of each job (implies --small)")
    parser.add_argument("--cache", default=None, help="the compile cache directory (default: a fresh one)")
    parser.add_argument("--override", nargs="*", default=[], help="more `rlq train` overrides")
    parser.add_argument(
        "--goal", type=float, default=2.0, help="compile seconds the jobs after the first should keep to"
    )
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cache = args.cache or str(Path(tmp) / "cache")
        commands = (
            process_commands(args, Path(tmp) / "runs", cache)
            if args.processes
            else [sweep_command(args, Path(tmp) / "sweep", cache)]
        )
        argv = commands[0]
        load_before = os.getloadavg()
        start = time.perf_counter()
        jobs = []
        for command in commands:
            # one stream, in the order printed: a job's programs line comes before its final line
            proc = subprocess.run(
                [sys.executable, "-m", "rlq.cli", *command], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
            )
            if proc.returncode != 0:
                raise SystemExit(f"rlq {' '.join(command)} failed:\n{proc.stdout[-3000:]}")
            jobs += jobs_of(proc.stdout)
        wall = time.perf_counter() - start
        load_after = os.getloadavg()
    later = [job["compile_s"] for job in jobs[1:]]
    report = {
        "benchmark": "sweep_compile",
        "device": device_name(),
        "commit": rlq_commit(),
        "command": "rlq "
        + " ".join(a for a in argv if not a.startswith(("compile_cache=", "hydra.sweep.dir=", "hydra.run.dir="))),
        "processes": len(commands),
        "cpu_count": os.cpu_count(),
        "load_average_before": [round(x, 2) for x in load_before],
        "load_average_after": [round(x, 2) for x in load_after],
        "process_wall_s": round(wall, 2),
        "jobs": jobs,
        "first_job_compile_s": jobs[0]["compile_s"] if jobs else None,
        "later_jobs_compile_s_max": max(later) if later else None,
        "later_jobs_compile_s_mean": round(sum(later) / len(later), 3) if later else None,
        "goal_s": args.goal,
        "goal_met": bool(later) and max(later) <= args.goal,
    }
    text = json.dumps(report, indent=2)
    if args.out:
        args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
