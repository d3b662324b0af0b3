"""Checkpoints are written atomically with a checksum; a bad one is refused, resume skips it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rlq.errors import CheckpointError
from rlq.store import checkpoint
from tests.helpers import REPO

STATE = {"w": np.arange(1000, dtype=np.float32), "b": np.ones((3, 4), np.int32)}


def saved(directory: Path, step: int, state=STATE) -> Path:
    return checkpoint.save(directory, f"step_{step}", state, {"env_steps": step, "chunks_done": step // 100})


def test_roundtrip_records_size_and_checksum(tmp_path):
    path = saved(tmp_path, 100)
    meta = json.loads(path.with_suffix(".json").read_text())
    assert meta["bytes"] == path.stat().st_size and len(meta["sha256"]) == 64
    restored = checkpoint.load(path, STATE)
    np.testing.assert_array_equal(restored["w"], STATE["w"])
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary files left


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda p: p.write_bytes(p.read_bytes()[:100]), "is truncated"),
        (lambda p: p.write_bytes(p.read_bytes()[:-1] + b"\x00"), "is corrupt"),
        (lambda p: p.with_suffix(".json").write_text('{"env_steps": 1'), "unreadable"),
        (lambda p: p.with_suffix(".json").unlink(), "has no sidecar"),
        (lambda p: p.unlink(), "no checkpoint"),
    ],
)
def test_damaged_checkpoint_is_refused_and_resume_falls_back(tmp_path, damage, message):
    saved(tmp_path / "checkpoints", 100)
    latest = saved(tmp_path / "checkpoints", 200, {"w": STATE["w"] * 2, "b": STATE["b"]})
    damage(latest)
    with pytest.raises(CheckpointError, match=message):
        checkpoint.load(latest, STATE)
    path, skipped = checkpoint.resumable(tmp_path)
    assert path.name == "step_100.msgpack"
    assert len(skipped) == (0 if message == "no checkpoint" else 1)
    np.testing.assert_array_equal(checkpoint.load(path, STATE)["w"], STATE["w"])
    assert checkpoint.newest_intact(tmp_path) == (path, skipped)  # eval, render and export fall back the same way


def test_readers_fall_back_past_a_damaged_final_and_refuse_when_nothing_is_intact(tmp_path):
    directory = tmp_path / "checkpoints"
    step = saved(directory, 100)
    final = checkpoint.save(directory, "final", STATE, {"env_steps": 200})
    final.write_bytes(final.read_bytes()[:50])
    path, skipped = checkpoint.newest_intact(tmp_path)
    assert path == step and len(skipped) == 1 and "final.msgpack is truncated" in skipped[0]
    assert checkpoint.resolve_noting(tmp_path, "final")[1] == []  # a named checkpoint is that one: no fallback
    step.with_suffix(".json").unlink()
    with pytest.raises(CheckpointError, match="no intact checkpoint in .*final.msgpack is truncated"):
        checkpoint.newest_intact(tmp_path)


def test_checkpoint_of_another_config_is_refused(tmp_path):
    path = saved(tmp_path, 100)
    with pytest.raises(CheckpointError, match="shape"):
        checkpoint.load(path, {"w": np.zeros(7, np.float32), "b": STATE["b"]})
    with pytest.raises(CheckpointError, match="holds 2 arrays"):
        checkpoint.load(path, {"w": STATE["w"]})


WRITER = """
import os, sys, time
import numpy as np
from rlq.store import checkpoint, files

directory = sys.argv[1]
from pathlib import Path
state = {"w": np.arange(200_000, dtype=np.float32)}
checkpoint.save(Path(directory), "step_100", state, {"env_steps": 100})

def stalled_fsync(fd):  # the bytes of step_200 are written, not yet synced nor renamed
    print("writing", flush=True)
    time.sleep(60)

files.os.fsync = stalled_fsync  # checkpoints write through rlq.store.files
checkpoint.save(Path(directory), "step_200", {"w": state["w"] * 2}, {"env_steps": 200})
"""


@pytest.mark.slow
def test_writer_killed_mid_write_leaves_the_previous_checkpoint(tmp_path):
    directory = tmp_path / "checkpoints"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(directory)], stdout=subprocess.PIPE, text=True, env=env)
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "writing"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert not (directory / "step_200.msgpack").exists()
    assert list(directory.glob(".step_200.msgpack.tmp-*")), "the kill should have hit the temporary file"
    path, skipped = checkpoint.resumable(tmp_path)
    assert path.name == "step_100.msgpack" and skipped == []
    template = {"w": np.zeros(200_000, np.float32)}
    np.testing.assert_array_equal(checkpoint.load(path, template)["w"], np.arange(200_000, dtype=np.float32))
