"""scripts/slurm/train_multinode.sbatch run as a plain script, with a stand-in for srun that starts its two
tasks on this machine as srun would (SLURM's variables, 2 CPU devices each): the tasks train one run
together, task 0 writes it, and on a finished run the script does nothing."""

import pytest

from tests.helpers import REPO, sbatch_runner
from tests.run.sharded_runs import FAST_COMPILE
from tests.run.test_distributed import TRAIN, free_port

pytestmark = pytest.mark.slow

SCRIPT = REPO / "scripts" / "slurm" / "train_multinode.sbatch"
#: the two-process test's run, without its periodic checkpoint (the script sets its own) and evaluations
TINY = [t for t in TRAIN if not t.startswith(("checkpoint.", "eval."))] + ["eval.every_steps=0", "eval.episodes=2"]

#: srun's stand-in: drops srun's own options, starts the command as tasks 0 and 1, fails if either fails
FAKE_SRUN = """#!/bin/bash
while [[ "$1" == --* ]]; do shift; done
pids=()
for task in 0 1; do
  SLURM_NTASKS=2 SLURM_STEP_NUM_TASKS=2 SLURM_PROCID=$task SLURM_LOCALID=$task SLURM_STEP_NODELIST=127.0.0.1 \\
    "$@" > "task$task.out" 2> "task$task.err" &
  pids+=($!)
done
status=0
for pid in "${pids[@]}"; do wait "$pid" || status=1; done
exit $status
"""


def test_multinode_sbatch_script_trains_one_run_over_two_tasks(tmp_path):
    run_dir = tmp_path / "run"
    sbatch = sbatch_runner(
        SCRIPT,
        tmp_path,
        256,
        "58",
        {"srun": FAKE_SRUN},
        JAX_COORDINATOR_PORT=str(free_port()),
        JAX_PLATFORMS="cpu",
        XLA_FLAGS=f"{FAST_COMPILE} --xla_force_host_platform_device_count=2",
    )

    first = sbatch(*TINY)
    assert first.returncode == 0, (tmp_path / "task0.err").read_text()[-2000:] + (tmp_path / "task1.err").read_text()
    assert (run_dir / "checkpoints" / "final.msgpack").exists()
    assert "4 seed(s)" in (tmp_path / "task0.out").read_text()
    assert "final greedy eval return" not in (tmp_path / "task1.out").read_text()
    done = sbatch(*TINY)
    assert done.returncode == 0 and "is finished" in done.stdout
