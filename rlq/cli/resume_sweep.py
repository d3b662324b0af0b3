"""`rlq resume run=<sweep dir>`: a Hydra sweep (`rlq train -m ...`) stopped part way, run again in place.

The sweep's own overrides are read from its ``multirun.yaml`` and handed to `rlq train -m` with
``hydra.sweep.dir=<sweep dir>``: each finished job is kept (its summary read back, nothing trained), a job stopped
after a checkpoint goes on from it as `rlq resume` would, a job that never started trains, and the sweep ends as
one that was never stopped, with its ``sweep_summary.csv``.
"""

from __future__ import annotations

import importlib
from pathlib import Path

from rlq.config.plain import read_recorded, select
from rlq.errors import UsageError
from rlq.run.programs.members import SWEEP_SUMMARY

#: overrides of Hydra's own that the sweep run again sets anew (rlq.tools.sweep.dirname_overrides adds the second)
SET_AGAIN = ("hydra.sweep.dir", "hydra.job.config.override_dirname.exclude_keys", "hydra.mode")


def is_sweep_dir(path: Path) -> bool:
    return (Path(path) / "multirun.yaml").is_file()


def sweep_overrides(sweep_dir: Path) -> list[str]:
    """The overrides `rlq train -m` needs to run the sweep of ``sweep_dir`` again in place."""
    try:
        recorded = read_recorded(Path(sweep_dir) / "multirun.yaml")
        task = list(select(recorded, "hydra.overrides.task") or [])
        hydra = list(select(recorded, "hydra.overrides.hydra") or [])
    except Exception as err:  # YAML's and OmegaConf's own errors for a damaged file
        raise UsageError(
            f"{sweep_dir}/multirun.yaml is unreadable ({type(err).__name__}); run the sweep again with its "
            f"`rlq train -m ...` command and hydra.sweep.dir={sweep_dir}"
        ) from None
    kept = [str(o) for o in hydra if str(o).partition("=")[0].lstrip("+~") not in SET_AGAIN]
    return ["-m", *map(str, task), *kept, f"hydra.sweep.dir={sweep_dir}"]


def resume_sweep(sweep_dir: Path, extra: list[str]) -> None:
    """Run the sweep of ``sweep_dir`` again in place (``extra``: the rest of the command, which must be empty)."""
    if extra:
        raise UsageError(
            f"{' '.join(extra)}: a sweep directory resumes as it was run; resume one job with `rlq resume "
            f"run={sweep_dir}/<job>`"
        )
    if (Path(sweep_dir) / SWEEP_SUMMARY).exists():
        raise UsageError(f"{sweep_dir} has finished ({SWEEP_SUMMARY} exists): nothing to resume")
    train_command = importlib.import_module("rlq.cli.train")  # by name, as rlq.cli.main: it imports rlq.cli.resume
    print(f"rlq: {sweep_dir} is a sweep: running it again in place (finished jobs kept, stopped ones resumed)")
    train_command.train_main(sweep_overrides(sweep_dir))
