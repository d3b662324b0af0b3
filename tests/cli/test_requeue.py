"""A sweep job that runs again in its own directory (SLURM preemption, requeued by submitit) goes
on from its intermediate checkpoint instead of starting over, and ends where the uninterrupted
job ended."""

import shutil

import numpy as np
import pytest

from rlq.run import checkpoint
from tests.helpers import run_cli

pytestmark = pytest.mark.slow

JOB = [
    "-m",
    "seed=0",
    "budget.env_steps=4096",
    "log_every_steps=1024",
    "checkpoint.every_steps=1024",
    "checkpoint.keep_last=0",
    "eval.episodes=2",
    "logger=quiet",
    "video.at_end=false",
]


def test_a_requeued_sweep_job_resumes_its_own_checkpoint(tmp_path):
    sweep_dir = tmp_path / "sweep"
    first = run_cli("train", *JOB, f"hydra.sweep.dir={sweep_dir}", cwd=tmp_path)
    assert first.returncode == 0, first.stderr[-3000:]
    (job_dir,) = [p for p in sweep_dir.iterdir() if p.is_dir()]
    finished = tmp_path / "finished"
    shutil.copytree(job_dir / "checkpoints", finished)
    for path in (job_dir / "checkpoints").glob("*"):  # killed after its second checkpoint
        if not path.name.startswith("step_2048."):
            path.unlink()

    again = run_cli("train", *JOB, f"hydra.sweep.dir={sweep_dir}", cwd=tmp_path)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "resuming" in again.stdout and "step_2048.msgpack" in again.stdout
    resumed = checkpoint.leaves(job_dir / "checkpoints/final.msgpack")
    for a, b in zip(resumed, checkpoint.leaves(finished / "final.msgpack"), strict=True):
        np.testing.assert_array_equal(a, b)
