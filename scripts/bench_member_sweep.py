"""An in-program sweep against one run and against the same sweep as separate jobs.

    python scripts/bench_member_sweep.py --members 16 --out sweep.json            # 16 learning rates x 1 seed
    python scripts/bench_member_sweep.py --members 16 --separate 2 --out sweep.json

Times, process start to exit (each `rlq train` a fresh process, compile cache off): one run at the
first learning rate; `'sweep.algo.lr=[...]'` with ``--members`` learning rates (log-spaced) in one
program; and ``--separate`` of those learning rates as separate runs, whose mean stands for each job
of the `-m` equivalent (which takes about ``members`` times that). Also checks that the separate runs'
final greedy returns equal their members'.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from bench_common import run_rlq, write_report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--members", type=int, default=16)
    parser.add_argument("--separate", type=int, default=1, help="separate runs timed (the first lrs)")
    parser.add_argument("--low", type=float, default=1e-4)
    parser.add_argument("--high", type=float, default=3e-3)
    parser.add_argument("--out", type=Path)
    parser.add_argument("overrides", nargs="*", help="more `rlq train` overrides (default: CartPole PPO's recipe)")
    args = parser.parse_args()
    lrs = [float(f"{lr:.3g}") for lr in np.geomspace(args.low, args.high, args.members)]
    common = [*args.overrides, "compile_cache=null", "video.at_end=false", "logger.wandb.mode=disabled"]
    results = []
    separate = []
    for lr in lrs[: args.separate]:
        run = run_rlq([f"algo.lr={lr}", *common])
        separate.append(run)
        returns = run["summary"]["eval_return"]
        results.append({"kind": "one run", "lr": lr, "process_wall_s": run["process_wall_s"], "eval_return": returns})
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp) / "sweep"
        sweep = run_rlq([f"sweep.algo.lr=[{','.join(map(str, lrs))}]", *common], keep_dir=run_dir)
        member_returns = {
            lr: json.loads((run_dir / "members" / f"algo.lr={lr}" / "summary.json").read_text())["eval_return"]
            for lr in lrs
        }
    one = float(np.mean([r["process_wall_s"] for r in separate]))
    results.append(
        {
            "kind": "in-program sweep",
            "members": args.members,
            "process_wall_s": sweep["process_wall_s"],
            "compile_s": sweep["summary"]["compile_s"],
            "ratio_to_one_run": round(sweep["process_wall_s"] / one, 2),
            "separate_jobs_estimate_s": round(one * args.members, 1),
            "member_eval_returns": member_returns,
            "members_equal_their_runs": all(
                member_returns[lr] == run["summary"]["eval_return"] for lr, run in zip(lrs, separate, strict=False)
            ),
        }
    )
    print(json.dumps(results, indent=2))
    write_report("member_sweep", results, args.out)


if __name__ == "__main__":
    main()
