"""scripts/key_path.py: the files a key's value passes through, found by watching a tiny run."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.helpers import REPO

SCRIPT = REPO / "scripts" / "key_path.py"


@pytest.mark.slow
def test_the_learning_rate_is_followed_from_the_command_line_to_the_optimizer(tmp_path) -> None:
    out = tmp_path / "path.json"
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--key", "algo.lr", "--out", str(out)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    found = json.loads(out.read_text())
    files = found["path_files"]
    assert "adam(lr)" in files["rlq/lib/learning/optimizers.py"]
    assert any(call.startswith("make(") for call in files["rlq/algos/ppo.py"])
    assert "rlq/config/spec.py" in files
    # a whole config holds every key: counted apart, and it reaches the runner
    assert "rlq/run/train.py" in found["whole_config_files"]
    assert "rlq/run/train.py" not in files


def test_a_key_with_a_value_is_refused_in_one_line() -> None:
    proc = subprocess.run([sys.executable, str(SCRIPT), "--key", "algo.lr=3"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == ["key_path: --key must be a config key such as algo.lr, got 'algo.lr=3'"]
