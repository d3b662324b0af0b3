"""Multirun sweeps: job directories named by the swept overrides, the launcher and sweeper checks,
and ``sweep_summary.csv`` (the final-metrics table of `rlq compare`) when the sweep ends."""

from __future__ import annotations

import hashlib
import importlib.util
import shutil
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback

from rlq.config.plain import select
from rlq.errors import ConfigError, RlqError
from rlq.store.runs import distinguishing_keys, final_table, load_runs, write_csv

MAX_DIRNAME = 200  # bytes; file names stop at 255


def job_dirname(override_dirname: str, num: int) -> str:
    """A job's directory name from Hydra's ``override_dirname`` (``algo=dqn,seed=1``): one path
    component (``env/physics=fast`` -> ``env.physics=fast``), long names cut and made unique with a
    hash, the job's number where no override names it."""
    name = str(override_dirname).replace("/", ".")
    if not name:
        return str(num)
    if len(name.encode()) > MAX_DIRNAME:
        digest = hashlib.sha1(name.encode()).hexdigest()[:10]
        name = name.encode()[: MAX_DIRNAME - 11].decode(errors="ignore") + "-" + digest
    return name


def _installed(module: str) -> bool:
    """``module`` can be imported; False too where its parent package is missing (``hydra_plugins`` exists only
    once some Hydra plugin is installed, and ``find_spec`` of a submodule imports the parent)."""
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        return False


def check_launcher(args: list[str], launching: bool = False) -> None:
    """The SLURM preset and submitit's launchers need the `slurm` extra, and submitting to SLURM
    (``launching``) needs its commands; say so before Hydra fails to find them."""
    for arg in args:
        key, _, value = arg.partition("=")
        if key.lstrip("+") != "hydra/launcher" or not (value == "slurm" or value.startswith("submitit")):
            continue
        if not _installed("hydra_plugins.hydra_submitit_launcher"):
            raise ConfigError(
                f'hydra/launcher={value} needs hydra-submitit-launcher: pip install -e ".[slurm]" (or pip install "rlq[slurm]")'
            )
        missing = [command for command in ("sbatch", "srun") if shutil.which(command) is None]
        if launching and value in ("slurm", "submitit_slurm") and missing:
            raise ConfigError(
                f"hydra/launcher={value} submits jobs to SLURM, whose {' and '.join(missing)} this machine's PATH "
                "does not have; run the sweep on the cluster's login node, or here with hydra/launcher=submitit_local"
            )


#: Hydra's sweepers that sample and optimise (its plugin module, rlq's extra that installs it)
OPTIMISING_SWEEPERS = {"optuna": ("hydra_plugins.hydra_optuna_sweeper", "tune")}


def sweeper_overrides(args: list[str]) -> list[str]:
    """Overrides that an optimising sweeper (``hydra/sweeper=optuna``) needs from rlq: ``direction=maximize``,
    since a run returns its final greedy return (config key ``objective``), unless the command sets a direction.
    A ConfigError names the extra to install where the sweeper's plugin is missing."""
    chosen = [a.partition("=")[2] for a in args if a.partition("=")[0].lstrip("+") == "hydra/sweeper"]
    if not chosen or chosen[-1] not in OPTIMISING_SWEEPERS:
        return []
    module, extra = OPTIMISING_SWEEPERS[chosen[-1]]
    if not _installed(module):
        raise ConfigError(
            f'hydra/sweeper={chosen[-1]} needs hydra-{chosen[-1]}-sweeper: pip install -e ".[{extra}]" '
            f'(or pip install "rlq[{extra}]")'
        )
    if any(a.partition("=")[0].lstrip("+") == "hydra.sweeper.direction" for a in args):
        return []
    return ["hydra.sweeper.direction=maximize"]


def dirname_overrides(args: list[str]) -> list[str]:
    """Hydra overrides that leave out of the job directory names the task overrides every job shares
    (those without a sweep, such as ``budget.env_steps=2000``), so jobs are named by what varies."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    overrides = OverridesParser.create().parse_overrides([a for a in args if "=" in a and not a.startswith("-")])
    task = [o for o in overrides if not o.key_or_group.startswith("hydra")]
    if not any(o.is_sweep_override() for o in task):
        return []
    fixed = sorted({o.key_or_group for o in task if not o.is_sweep_override()})
    if not fixed:
        return []
    return ["hydra.job.config.override_dirname.exclude_keys=[" + ",".join(f"'{key}'" for key in fixed) + "]"]


def write_summary(sweep_dir: Path, metric: str = "eval/return") -> Path:
    """``<sweep dir>/sweep_summary.csv``: one row per job, its swept overrides and final metrics."""
    runs = load_runs([sweep_dir])
    keys = distinguishing_keys(runs)
    table = final_table(runs, keys, metric, root=sweep_dir)
    return write_csv(table, sweep_dir / "sweep_summary.csv")


class SweepSummary(Callback):
    """Hydra callback (conf/config.yaml ``hydra.callbacks``): the summary table when a sweep ends."""

    def on_multirun_end(self, config: Mapping[str, Any], **kwargs: Any) -> None:
        sweep_dir = Path(str(select(config, "hydra.sweep.dir")))
        try:
            path = write_summary(sweep_dir)
        except (RlqError, OSError, ValueError) as err:
            print(f"rlq: warning: no sweep summary: {err}", file=sys.stderr)
            return
        print(f"rlq: sweep summary {path} (plot: rlq compare {sweep_dir})", flush=True)
