"""`rlq resume run=<dir>`: continue an unfinished run from its latest intermediate checkpoint.

For jobs stopped by a time limit or a preemption: train with ``checkpoint.every_steps`` > 0, then
resume as often as needed. The run keeps its directory, config and metrics file (rows logged after
the checkpoint are dropped and logged again), its wall clock (counting on from the checkpoint's)
and its W&B run (the same run id, ``<run dir>/wandb_id``).
``devices=`` places the run on other devices than it was trained on (a checkpoint holds host
arrays, so any device count that splits the run resumes it).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

from omegaconf import DictConfig, OmegaConf

from rlq.cli.args import parse_args
from rlq.errors import UsageError
from rlq.run import checkpoint
from rlq.run.devices import placement
from rlq.run.evaluate import load_run_config
from rlq.run.lock import run_lock
from rlq.run.logging import drop_rows_after

if TYPE_CHECKING:
    from rlq.run.train import RunResult

RESUME_USAGE = "usage: rlq resume run=<run dir> [devices=N|[i,j]]"
HELP = f"""{RESUME_USAGE}

Continue an unfinished run from its latest intermediate checkpoint (checkpoints/step_*.msgpack), in its own
directory and with its own config; the run must have been trained with checkpoint.every_steps > 0.

options:
  run=DIR      the run directory of the stopped run (required)
  devices=...  the local devices to resume on (N: the first N, [i,j]: those; default all): any count that
               splits the run, whatever it was trained on
"""


def resume_main(args: list[str]) -> None:
    options, env_overrides = parse_args(args, allowed={"run", "devices"}, usage=RESUME_USAGE)
    if env_overrides:
        raise UsageError(f"a resumed run keeps its config; drop {' '.join(env_overrides)} ({RESUME_USAGE})")
    run_dir = Path(options["run"])
    cfg = load_run_config(run_dir)
    if "devices" in options:
        cfg.devices = OmegaConf.create(f"devices: {options['devices']}").devices  # YAML, as Hydra reads it
        placement(cfg)
    path, skipped = checkpoint.resumable(run_dir)
    with run_lock(run_dir):
        result = continue_run(cfg, run_dir, path, skipped)
    print(result.line(), flush=True)


def continue_run(cfg: DictConfig, run_dir: Path, path: Path, skipped: list[str]) -> RunResult:
    """Train ``run_dir``'s run on from its checkpoint ``path`` (``checkpoint.resumable``), saying which
    later checkpoints were skipped as damaged; the caller holds the run directory's lock."""
    from rlq.run.train import train

    for problem in skipped:
        print(f"rlq: warning: {problem}; falling back to an earlier checkpoint", file=sys.stderr, flush=True)
    drop_rows_after(run_dir / "metrics.jsonl", checkpoint.env_steps(path))
    print(f"rlq: resuming {run_dir} from {path.name}", flush=True)
    return train(cfg, run_dir, resume=path)
