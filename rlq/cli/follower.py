"""The processes of a run over several processes other than process 0 (rlq/run/programs/distributed.py):
"followers", which run the same command and take part in every collective but write nothing the
run keeps. Their copy of the run's files goes to a scratch directory, removed when they end."""

from __future__ import annotations

import tempfile
from pathlib import Path

from rlq.config.spec import RunSpec, with_values

#: a follower's console and W&B settings (process 0 logs the run)
QUIET: dict[str, object] = {"logger.console": False, "logger.wandb.mode": "disabled"}


def follower_dir() -> Path | None:
    """A new scratch directory for this process's copy of the run's files where it is a follower;
    None for process 0 and for a run of one process."""
    import jax

    if not jax.distributed.is_initialized() or jax.process_index() == 0:
        return None
    return Path(tempfile.mkdtemp(prefix=f"rlq-process{jax.process_index()}-"))


def as_follower(args: list[str], spec: RunSpec, scratch: Path) -> tuple[list[str], RunSpec]:
    """A follower process's run: in ``scratch``, with no console and no W&B (process 0 logs the run); the
    overrides returned (for Hydra, where it composes the config again) and ``spec`` with them set (its composed
    config too)."""
    values: dict[str, object] = {"hydra.run.dir": str(scratch), **QUIET}
    spec = with_values(spec, values)
    kept = [a for a in args if a.split("=", 1)[0].lstrip("+") not in values]
    overrides = [*kept, *(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in values.items())]
    return overrides, spec


def quiet_follower(spec: RunSpec) -> RunSpec:
    """``spec`` without the console and W&B, as a follower runs it."""
    return with_values(spec, QUIET)
