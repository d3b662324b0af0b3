"""A run's record, ``<run dir>/.hydra/``: written by rlq under the run lock, not by Hydra.

Hydra writes ``.hydra/`` as soon as it makes the job's directory, before the job can take the run
lock (`rlq/store/lock.py`); a second `rlq train` into a directory in use would overwrite the running
job's ``config.yaml``. conf/config.yaml turns Hydra's writing off (``hydra.output_subdir: null``) and
the job writes the same three files here once it holds the lock. A multirun job's record also names its sweep
(``sweep_group``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rlq.config.plain import record_texts
from rlq.store.files import write_atomic

RECORD_DIR = ".hydra"


def write_record(run_dir: Path, cfg: Mapping[str, Any], hydra_cfg: Any) -> None:
    """``config.yaml`` (the job's config), ``hydra.yaml`` and ``overrides.yaml``, as Hydra writes them."""
    directory = Path(run_dir) / RECORD_DIR
    directory.mkdir(parents=True, exist_ok=True)
    for name, text in record_texts(cfg, hydra_cfg).items():
        write_atomic(directory / name, text.encode())


def sweep_group(run_dir: Path) -> str | None:
    """The W&B group of a multirun job: its sweep directory (``<date>_<time>``), None for a single run."""
    sweep_dir = Path(run_dir).resolve().parent
    if not (sweep_dir / "multirun.yaml").exists():
        return None
    return "_".join(sweep_dir.parts[-2:])
