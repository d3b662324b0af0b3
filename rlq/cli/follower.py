"""The processes of a run over several processes other than process 0 (rlq/run/programs/distributed.py):
"followers", which run the same command and take part in every collective but write nothing the
run keeps. Their copy of the run's files goes to a scratch directory, removed when they end."""

from __future__ import annotations

import tempfile
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

#: a follower's console and W&B settings (process 0 logs the run)
QUIET: dict[str, object] = {"logger.console": False, "logger.wandb.mode": "disabled"}


def follower_dir() -> Path | None:
    """A new scratch directory for this process's copy of the run's files where it is a follower;
    None for process 0 and for a run of one process."""
    import jax

    if not jax.distributed.is_initialized() or jax.process_index() == 0:
        return None
    return Path(tempfile.mkdtemp(prefix=f"rlq-process{jax.process_index()}-"))


def as_follower(args: list[str], composed: DictConfig | None, scratch: Path) -> list[str]:
    """A follower process's run: in ``scratch``, with no console and no W&B (process 0 logs the run);
    set in ``composed`` and in the overrides returned (for Hydra, where it composes the config again)."""
    values: dict[str, object] = {"hydra.run.dir": str(scratch), **QUIET}
    if composed is not None:
        for key, value in values.items():
            OmegaConf.update(composed, key, value)
    kept = [a for a in args if a.split("=", 1)[0].lstrip("+") not in values]
    return [*kept, *(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in values.items())]


def quiet_follower(cfg: DictConfig) -> None:
    """``cfg`` without the console and W&B, as a follower runs it."""
    for key, value in QUIET.items():
        OmegaConf.update(cfg, key, value)
