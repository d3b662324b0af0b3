"""`rlq resume run=<dir>`: continue an unfinished run from its latest intermediate checkpoint.

For jobs stopped by a time limit or a preemption: train with ``checkpoint.every_steps`` > 0, then
resume as often as needed. The run keeps its directory, config and metrics file (rows logged after
the checkpoint are dropped and logged again), its wall clock (counting on from the checkpoint's)
and its W&B run (the same run id, ``<run dir>/wandb_id``).
``devices=`` places the run on other devices than it was trained on (a checkpoint holds host
arrays, so any device count that splits the run resumes it).
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from rlq.cli.args import parse_args
from rlq.cli.follower import follower_dir, quiet_follower
from rlq.cli.resume_sweep import is_sweep_dir, resume_sweep
from rlq.config.recorded import extend_recorded, parsed_yaml
from rlq.config.spec import RunSpec, with_values
from rlq.declared import run
from rlq.errors import UsageError
from rlq.lib.settings import plain
from rlq.run.programs import members
from rlq.run.programs.devices import placement
from rlq.run.programs.distributed import start
from rlq.store import checkpoint
from rlq.store.files import remove_temporaries
from rlq.store.jsonfiles import read_rows
from rlq.store.lock import run_lock
from rlq.store.logging import METRICS_FIX, LogFile, drop_rows_after
from rlq.tools.evaluate import load_run_config

if TYPE_CHECKING:
    from rlq.run.result import RunResult

RESUME_USAGE = "usage: rlq resume run=<run dir or sweep dir> [budget.env_steps=N] [devices=N|[i,j]]"
HELP = f"""{RESUME_USAGE}

Continue an unfinished run from its latest intermediate checkpoint (checkpoints/step_*.msgpack), in its own
directory and with its own config; the run must have been trained with checkpoint.every_steps > 0.
A run killed after its final checkpoint, before its summary.json, makes its final evaluation and summary.
run=<sweep dir> (an `rlq train -m` sweep's) runs the sweep again in place: finished jobs are kept, stopped
ones go on from their checkpoints, the rest train, and the sweep ends with its sweep_summary.csv.
With budget.env_steps=N, extend a run, finished or not, from its newest checkpoint (final.msgpack when it
ended) to N env steps per seed; the new budget is written to its .hydra/config.yaml.

options:
  run=DIR            the run directory (required)
  budget.env_steps=N the run's new budget, above the env steps it has trained (the one key that may change)
  devices=...        the local devices to resume on (N: the first N, [i,j]: those; default all): any count that
                     splits the run, whatever it was trained on
"""

#: the config keys `rlq resume` may change: a run's budget (everything else would make it another run)
BUDGET_KEYS = {"budget.env_steps"}


def _budget(overrides: list[str]) -> dict[str, int]:
    """``budget.env_steps=N`` (``2e5`` as well) of the command; any other config key is refused with one line."""
    budget: dict[str, int] = {}
    for item in overrides:
        key, _, value = item.partition("=")
        if key not in BUDGET_KEYS:
            raise UsageError(
                f"{key} is not a budget key: a resumed run keeps its config, only {', '.join(sorted(BUDGET_KEYS))} "
                "may change (train a new run from this one's parameters with `rlq train ... init_from=<run dir>`)"
            )
        try:
            number = float(value)
        except ValueError:
            number = float("nan")
        if not number.is_integer():
            raise UsageError(f"{key}={value} is not a whole number of env steps, e.g. {key}=200000")
        if number < 1:
            raise UsageError(f"{key}={value} is not a positive number of env steps, e.g. {key}=200000")
        budget[key] = int(number)
    return budget


def resume_main(args: list[str]) -> None:
    config_args = [a for a in args if "." in a.partition("=")[0]]
    options, _ = parse_args([a for a in args if a not in config_args], {"run", "devices"}, RESUME_USAGE)
    budget = _budget(config_args)
    run_dir = Path(options["run"])
    if is_sweep_dir(run_dir):
        devices = [f"devices={options['devices']}"] if "devices" in options else []
        return resume_sweep(run_dir, [*config_args, *devices])
    # the processes srun started now, not those the run was trained on: a run resumes on one process or several;
    # joined before the run's config is loaded (its checks start JAX's backends)
    start(plain(run.Config().distributed))  # the declared defaults: enabled=auto
    spec = load_run_config(run_dir)
    if "devices" in options:
        spec = with_values(spec, {"devices": parsed_yaml(options["devices"])})  # YAML, as Hydra reads it
        placement(spec)
    read_rows(run_dir / "metrics.jsonl", METRICS_FIX, note=False)  # damage refused before anything is changed
    if not budget and members.members_pending(spec, run_dir):
        if follower_dir() is None:  # process 0 writes the run's files
            write_members(spec, run_dir)
        return
    final = checkpoint.final_without_summary(run_dir, spec.values) if not budget else None
    skipped: list[str] = []
    if final is not None:  # killed after its final checkpoint: the rest of its end is made, nothing trained
        path = final
    elif not budget:
        path, skipped = checkpoint.resumable(run_dir, spec.values)
    else:
        path, skipped = checkpoint.newest_intact(run_dir, spec.values)
        trained, steps = checkpoint.env_steps(path), budget["budget.env_steps"]
        if steps <= trained:
            raise UsageError(
                f"budget.env_steps={steps} is not beyond the {trained:,} env steps {run_dir} has trained "
                f"({path.name}); give a larger budget"
            )
    scratch = follower_dir()
    if scratch is not None:  # a follower reads the run's checkpoint and writes its copy of the run in scratch
        spec = with_values(quiet_follower(spec), budget)
        try:
            continue_run(spec, scratch, path, skipped, finish=final is not None)
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
        return
    with run_lock(run_dir):
        remove_temporaries(run_dir)
        if budget:
            print(f"rlq: extending {run_dir} to {steps:,} env steps per seed", flush=True)
            spec = with_values(spec, budget)
            extend_recorded(run_dir / ".hydra" / "config.yaml", budget)  # as written, the devices it trained on kept
        result = continue_run(spec, run_dir, path, skipped, finish=final is not None)
    print(result.line(), flush=True)


def write_members(spec: RunSpec, run_dir: Path) -> None:
    """The members and table of a sweep's run that was stopped while writing them, without training: training wrote
    the run's final checkpoint and summary before its members, so they come out as that process would have written
    them (whole files replace half-written ones)."""
    with run_lock(run_dir):
        remove_temporaries(run_dir)
        print(f"rlq: {run_dir} trained to its end but was stopped while writing its members: writing them", flush=True)
        written = members.write_members(spec, run_dir)
    print(members.summary_lines(run_dir, written), flush=True)


def continue_run(spec: RunSpec, run_dir: Path, path: Path, skipped: list[str], finish: bool = False) -> RunResult:
    """Train ``run_dir``'s run on from its checkpoint ``path`` (``checkpoint.resumable``), saying which
    later checkpoints were skipped as damaged; the caller holds the run directory's lock. ``finish``: ``path`` is
    the final checkpoint of a run killed before its summary (``checkpoint.final_without_summary``): the run makes
    its end again, its final evaluation's rows dropped first (made again from the same state and keys, they are
    the same numbers, and its listeners, figures and video need them anyway) unless that evaluation was a
    periodic one the run reused, whose rows stay."""
    from rlq.run.train import train

    log = LogFile(run_dir / "rlq.log")
    try:
        for problem in skipped:  # to rlq.log too: the run's record says why it went on from an earlier checkpoint
            line = f"rlq: warning: {problem}; falling back to an earlier checkpoint"
            print(line, file=sys.stderr, flush=True)
            log.write(line)
    finally:
        log.close()
    meta = checkpoint.meta(path)
    final_rows = finish and not meta.get("final_reused")
    drop_rows_after(run_dir / "metrics.jsonl", int(meta["env_steps"]), final_eval=final_rows)
    if finish:
        print(
            f"rlq: {run_dir} trained to its end but was stopped before its summary: making its final evaluation and "
            "summary (nothing to train)",
            flush=True,
        )
    else:
        print(f"rlq: resuming {run_dir} from {path.name}", flush=True)
    return train(spec, run_dir, resume=path, finish=finish)
