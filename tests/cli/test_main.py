"""The `rlq` entry point's process set-up."""

from __future__ import annotations

import os
import subprocess
import sys

from rlq.cli.main import PREALLOCATE, gpu_memory_on_demand


def test_jax_takes_gpu_memory_as_the_run_needs_it_unless_the_user_chose() -> None:
    unset: dict[str, str] = {}
    gpu_memory_on_demand(unset)
    assert unset == {PREALLOCATE: "false"}
    for chosen in ("true", "false"):
        environ = {PREALLOCATE: chosen}
        gpu_memory_on_demand(environ)
        assert environ == {PREALLOCATE: chosen}


def test_every_command_sets_it_before_it_runs() -> None:
    env = {k: v for k, v in os.environ.items() if k != PREALLOCATE}
    code = "import os; from rlq.cli.main import main; main(['--help']); print(os.environ.get('" + PREALLOCATE + "'))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "false"
