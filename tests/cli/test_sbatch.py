"""scripts/slurm/train.sbatch run as a plain script (no SLURM): it trains with checkpoints into its run
directory; run again on an unfinished run (a requeued job) it resumes; on a finished run it does nothing."""

import pytest

from tests.helpers import REPO, sbatch_runner

pytestmark = pytest.mark.slow

SCRIPT = REPO / "scripts" / "slurm" / "train.sbatch"
TINY = ["budget.env_steps=2048", "log_every_steps=512", "eval.every_steps=0", "eval.episodes=2"]


def test_sbatch_script_trains_resumes_and_stops(tmp_path):
    run_dir = tmp_path / "run"
    sbatch = sbatch_runner(SCRIPT, tmp_path, 1024, "123")

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
