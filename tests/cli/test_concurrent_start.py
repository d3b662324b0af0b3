"""Two `rlq train` into one run directory: the one refused leaves the running one's record alone."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

HOLDER = """
import sys
from pathlib import Path
from rlq.store.lock import run_lock
run_dir = Path(sys.argv[1])
(run_dir / ".hydra").mkdir(parents=True)
for name in ("config.yaml", "overrides.yaml", "hydra.yaml"):
    (run_dir / ".hydra" / name).write_text("winner\\n")
with run_lock(run_dir):
    print("locked", flush=True)
    sys.stdin.read()
"""

# the second start, past the early check that would refuse it only because the first one got there
# first: two starts at the same moment both pass it, and only the lock decides
LATE = """
import sys
import rlq.cli.checked
rlq.cli.checked.check_output_dir = lambda *args, **kwargs: None
from rlq.cli.main import main
main(sys.argv[1:])
"""


def test_a_start_refused_by_the_lock_does_not_overwrite_the_running_jobs_record(tmp_path: Path):
    run_dir = tmp_path / "run"
    env = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true"}
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(run_dir)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        late = subprocess.run(
            [sys.executable, "-c", LATE, "train", "logger=quiet", "algo.lr=0.01", f"hydra.run.dir={run_dir}"],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
    finally:
        holder.communicate("")
    assert late.returncode == 2, late.stderr[-3000:]
    assert "in use by another rlq process" in late.stderr
    for name in ("config.yaml", "overrides.yaml", "hydra.yaml"):
        assert (run_dir / ".hydra" / name).read_text() == "winner\n", name
    assert not [p for p in run_dir.rglob("*") if ".tmp-" in p.name]
