"""Time to the first training step with a cold and a warm persistent compile cache (`compile_cache=`).

Runs `rlq train experiment=<preset>` twice, as a user would, with one fresh cache directory: the
first run compiles every program and writes it there, the second reads them back. Reports, per
run, the whole process's wall time, the run's compile time (`summary.json`) and the wall time of
its first training row (`metrics.jsonl`) and when that first chunk of training began (the row's
time less the chunk's, `summary.json`'s `chunk_s`), its final greedy return, and the warm run's speed-up on each.

    python scripts/bench_compile_cache.py --preset humanoid_ppo --out compile_cache.json                 # GPU
    python scripts/bench_compile_cache.py --preset humanoid_ppo --override budget.env_steps=640 \\
        algo.num_envs=8 algo.batch_size=8 algo.num_minibatches=1 --out compile_cache_cpu.json        # CPU
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from bench_common import device_name, run_rlq


def first_train_row_s(rows: list[dict]) -> float:
    return min(r["wall_s"] for r in rows if r["kind"] == "train")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="humanoid_ppo")
    parser.add_argument("--override", nargs="*", default=[], help="more `rlq train` overrides")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    runs = []
    with tempfile.TemporaryDirectory() as cache:
        overrides = [f"experiment={args.preset}", f"compile_cache={cache}", "video.at_end=false", *args.override]
        for name in ("cold", "warm"):
            run = run_rlq(overrides)
            runs.append(
                {
                    "cache": name,
                    "process_wall_s": run["process_wall_s"],
                    "compile_s": run["summary"]["compile_s"],
                    "first_train_row_s": first_train_row_s(run["rows"]),
                    # when the first chunk of training began: its row, less the chunk's own time
                    "training_starts_s": round(first_train_row_s(run["rows"]) - run["summary"]["chunk_s"][0], 3),
                    "env_steps_per_seed": run["summary"]["env_steps"],
                    "final_eval_return": run["summary"]["eval_return"],
                }
            )
            print(json.dumps(runs[-1]), file=sys.stderr, flush=True)
    cold, warm = runs
    report = {
        "benchmark": "compile_cache",
        "device": device_name(),
        "command": "rlq train " + " ".join(o for o in overrides if not o.startswith("compile_cache=")),
        "runs": runs,
        "warm_speedup": {
            k: round(cold[k] / warm[k], 2)
            for k in ("process_wall_s", "compile_s", "first_train_row_s", "training_starts_s")
        },
    }
    if args.out:
        args.out.write_text(json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
