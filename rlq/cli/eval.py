"""`rlq eval run=<dir>`: greedy return of a run's checkpoint (and its final state's metrics)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from rlq.cli.args import int_option, parse_args, seed_option, warn_skipped
from rlq.errors import UsageError
from rlq.store.files import write_atomic
from rlq.store.outputs import check_output_file
from rlq.tools.evaluate import evaluate_run, load_run_config

HELP = """usage: rlq eval run=<run dir> [episodes=N] [seed=S] [env=NAME] [checkpoint=C] [env.<key>=<value> ...]

Evaluate every seed of a run's checkpoint greedily; writes <run dir>/eval_<env>.json (with the env overrides used).

options:
  run=DIR          a run directory written by `rlq train` (required)
  episodes=N       episodes per seed (default 100)
  seed=S           PRNG seed of the evaluation episodes (default 0)
  env=NAME         evaluate on another env with the same spaces (e.g. env=lunar_box2d for a lunar run)
  checkpoint=C     the checkpoint to evaluate: N (checkpoints/step_N.msgpack), final, kept, or a file
                   (default: kept.msgpack of a finished eval.keep=best run, else final.msgpack, else the
                   latest step_*)
  env.<key>=VALUE  change a key of the evaluation env's config (e.g. env.simulation_time=40)
"""


def eval_main(args: list[str]) -> None:
    options, env_overrides = parse_args(args)
    run_dir = Path(options["run"])
    episodes, seed = int_option(options, "episodes", 100), seed_option(options)
    if episodes < 1:
        raise UsageError("episodes must be >= 1")
    env_name = options.get("env") or load_run_config(run_dir).env["name"]
    check_output_file(run_dir / f"eval_{env_name}.json")
    result = evaluate_run(run_dir, options.get("env"), episodes, seed, env_overrides, options.get("checkpoint"))
    warn_skipped(result["skipped_checkpoints"], Path(result["checkpoint"]))
    out = run_dir / f"eval_{result['env']}.json"
    try:
        write_atomic(out, json.dumps(result, indent=2).encode())
        written = f" -> {out}"
    except OSError as err:  # a read-only run directory: the result still counts
        print(f"rlq: warning: {out} could not be written ({err.strerror}); the result is only printed", file=sys.stderr)
        written = ""
    per_seed = ", ".join(f"{r:.1f}" for r in result["per_seed_return"])
    print(
        f"rlq eval: {result['env']}, {episodes} episodes per seed: mean greedy return {result['mean_return']:.1f} "
        f"(seeds: {per_seed}){written}",
        file=sys.stdout,
    )
    if result["state_metrics"]:
        print("rlq eval: final state, mean over seeds: " + state_metrics_line(result["state_metrics"]), file=sys.stdout)


def state_metrics_line(metrics: dict[str, list[float]]) -> str:
    """``name value`` pairs (mean over seeds), e.g. the archive's QD metrics."""
    return ", ".join(f"{name} {np.mean(values):.4g}" for name, values in metrics.items())
