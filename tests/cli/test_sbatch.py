"""scripts/slurm/train.sbatch run as a plain script (no SLURM): it trains with checkpoints into its run
directory; run again on an unfinished run (a requeued job) it resumes; on a finished run it does nothing."""

import os
import subprocess
import sys

from tests.helpers import REPO

SCRIPT = REPO / "scripts" / "slurm" / "train.sbatch"
TINY = ["budget.env_steps=2048", "log_every_steps=512", "eval.every_steps=0", "eval.episodes=2"]


def test_sbatch_script_trains_resumes_and_stops(tmp_path):
    shim = tmp_path / "bin"
    shim.mkdir()
    (shim / "rlq").write_text(f'#!/bin/sh\nexec "{sys.executable}" -m rlq.cli "$@"\n')
    (shim / "rlq").chmod(0o755)
    run_dir = tmp_path / "run"
    env = {
        **os.environ,
        "PATH": f"{shim}:{os.environ['PATH']}",
        "RUN_DIR": str(run_dir),
        "CHECKPOINT_EVERY": "1024",
        "WANDB_MODE": "disabled",
        "SLURM_JOB_ID": "123",
    }

    def sbatch(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            ["bash", str(SCRIPT), *args], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
        )

    first = sbatch(*TINY, "logger=quiet", "video.at_end=false")
    assert first.returncode == 0, first.stderr[-3000:]
    checkpoints = run_dir / "checkpoints"
    assert (checkpoints / "final.msgpack").exists() and list(checkpoints.glob("step_*.msgpack"))

    (checkpoints / "final.msgpack").unlink()  # as if the job had been stopped before its end
    again = sbatch(*TINY)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "resuming" in again.stdout and (checkpoints / "final.msgpack").exists()

    done = sbatch(*TINY)
    assert done.returncode == 0 and "is finished" in done.stdout
