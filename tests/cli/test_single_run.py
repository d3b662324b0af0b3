"""A single `rlq train` runs the config its check composed (rlq.cli.train.run_composed) instead of
composing it again through ``hydra.main``: the run directory's record, the logging and the callbacks
must be what Hydra's single run leaves."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from tests.helpers import REPO, run_cli, run_dirs

pytestmark = pytest.mark.slow

TINY = ["budget.env_steps=2048", "log_every_steps=1024", "eval.episodes=2", "logger=quiet", "video.at_end=false"]


def test_single_run_leaves_hydras_record_and_calls_its_callbacks(workdir: Path) -> None:
    events = workdir / "events.txt"
    probe = ["+hydra.callbacks.probe._target_=tests.cli.hydra_probe.Probe", f"+hydra.callbacks.probe.path={events}"]
    pythonpath = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
    proc = run_cli("train", *TINY, *probe, cwd=workdir, env={"PYTHONPATH": pythonpath})
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    assert events.read_text().splitlines() == ["run_start", "job_start", "job_end COMPLETED", "run_end"]
    assert OmegaConf.to_container(OmegaConf.load(run_dir / ".hydra" / "overrides.yaml")) == TINY
    hydra = OmegaConf.load(run_dir / ".hydra" / "hydra.yaml").hydra
    assert hydra.mode == "RUN" and list(hydra.overrides.hydra) == [*probe, "hydra.mode=RUN"]
    assert hydra.runtime.output_dir == str(run_dir.resolve())
    assert OmegaConf.load(run_dir / ".hydra" / "config.yaml").budget.env_steps == 2048
    assert "final greedy eval return" in (run_dir / "rlq.log").read_text()  # Hydra's job logging, to the run dir
