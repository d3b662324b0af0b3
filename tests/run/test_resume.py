"""`rlq resume`: a run stopped after an intermediate checkpoint continues exactly as it would have."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np
import pytest

from rlq.run import checkpoint
from rlq.run.sidecar import HASH_KEY
from rlq.run.train import train
from tests.helpers import compose_config, run_cli, run_dirs

#: 4 chunks of 2048 steps; an intermediate checkpoint after the second
RESUMABLE = [
    "budget.env_steps=8192",
    "log_every_steps=2048",
    "checkpoint.every_steps=4096",
    "eval.every_steps=4096",
    "eval.episodes=4",
    "video.at_end=false",
    "logger.wandb.mode=disabled",
]


def rows(run_dir: Path) -> list[tuple]:
    lines = (run_dir / "metrics.jsonl").read_text().splitlines()
    return [(r["kind"], r["env_steps"], r["seed"]) for r in map(json.loads, lines)]


@pytest.fixture(scope="module")
def full_run(tmp_path_factory) -> Path:
    workdir = tmp_path_factory.mktemp("resume")
    proc = run_cli("train", *RESUMABLE, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    assert (run_dir / "checkpoints" / "step_4096.msgpack").exists()
    assert HASH_KEY in checkpoint.meta(run_dir / "checkpoints" / "step_4096.msgpack")  # checked before a resume
    return run_dir


def test_resumed_run_ends_where_the_uninterrupted_run_ends(full_run, tmp_path):
    stopped = tmp_path / "stopped"
    shutil.copytree(full_run, stopped)
    for path in (stopped / "checkpoints").glob("final.*"):
        path.unlink()  # as if the job had been killed during the third chunk
    ckpts = stopped / "checkpoints"  # ... and in the middle of writing a later checkpoint
    shutil.copy(ckpts / "step_4096.json", ckpts / "step_6144.json")
    (ckpts / "step_6144.msgpack").write_bytes((ckpts / "step_4096.msgpack").read_bytes()[:1000])
    leftover = ckpts / ".step_6144.msgpack.tmp-4242"  # ... and a kill -9 before the rename of another's
    leftover.write_bytes(b"\0" * 1000)
    with open(stopped / "metrics.jsonl", "a") as metrics:  # ... and in the middle of a metrics row
        metrics.write('{"kind": "train", "env_steps": 61')
    proc = run_cli("resume", f"run={stopped}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert f"removed what a stopped write left in {stopped}: checkpoints/{leftover.name}" in proc.stderr
    assert "metrics.jsonl: skipped its last line, cut short" in proc.stderr and not leftover.exists()
    assert "step_6144.msgpack is truncated" in proc.stderr and "falling back" in proc.stderr
    assert "resuming" in proc.stdout and "from step_4096" in proc.stdout and "final greedy eval return" in proc.stdout
    resumed = checkpoint.leaves(stopped / "checkpoints/final.msgpack")
    original = checkpoint.leaves(full_run / "checkpoints/final.msgpack")
    assert len(resumed) == len(original)
    for a, b in zip(resumed, original, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
    assert rows(stopped) == rows(full_run)  # the rows after the checkpoint were dropped, then logged again
    summary = json.loads((stopped / "summary.json").read_text())
    assert summary["resumed_from_env_steps"] == 4096
    assert len(summary["chunk_s"]) == 2  # only the chunks this process ran are timed
    assert len(json.loads((full_run / "summary.json").read_text())["chunk_s"]) == 4
    stopped_at = checkpoint.meta(stopped / "checkpoints/step_4096.msgpack")["wall_s"]
    walls = [r["wall_s"] for r in map(json.loads, (stopped / "metrics.jsonl").read_text().splitlines())]
    assert walls == sorted(walls) and walls[-1] > stopped_at  # the wall clock goes on from the checkpoint's
    assert summary["wall_s"] > stopped_at
    assert "resumed at 4,096" in proc.stdout  # 8,192 env steps, of which this process ran 4,096


def test_finished_run_is_not_resumed(full_run):
    proc = run_cli("resume", f"run={full_run}", cwd=full_run.parent)
    assert proc.returncode == 2 and "has finished" in proc.stderr


def test_run_killed_before_its_first_checkpoint_is_told_so(full_run, tmp_path):
    """Trained with checkpoint.every_steps=4096 and killed while writing the first: the advice is not to set it."""
    bare = tmp_path / "bare"
    shutil.copytree(full_run, bare)
    for path in (bare / "checkpoints").iterdir():
        path.unlink()
    proc = run_cli("resume", f"run={bare}", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr[-3000:]
    assert "stopped before its first one (at 4,096 env steps) was written whole" in proc.stderr
    assert "checkpoint.every_steps>0" not in proc.stderr


def test_resume_continues_the_same_wandb_run(tmp_path, monkeypatch):
    inits = []

    class FakeRun:
        def log(self, payload, step):
            pass

        def finish(self):
            pass

    def init(**kwargs):
        inits.append(kwargs)
        return FakeRun()

    monkeypatch.setitem(sys.modules, "wandb", types.SimpleNamespace(init=init, Settings=lambda **k: None))
    cfg = compose_config(*RESUMABLE[:-1], "logger.wandb.mode=offline", "logger.console=false")
    train(cfg, tmp_path)
    for path in (tmp_path / "checkpoints").glob("final.*"):
        path.unlink()
    train(cfg, tmp_path, resume=checkpoint.resumable(tmp_path)[0])
    assert len(inits) == 2 and inits[0]["id"] and inits[1]["id"] == inits[0]["id"]
    assert inits[1]["resume"] == "allow"


def test_sigterm_writes_a_resumable_checkpoint_and_resume_ends_as_the_uninterrupted_run(full_run, tmp_path):
    env = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true"}
    cmd = [sys.executable, "-m", "rlq.cli", "train", *RESUMABLE]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # metrics.jsonl appears once the signal handlers are in place, before the programs compile:
    # the signal is always seen at the end of the first chunk (env step 2048)
    deadline = time.monotonic() + 300
    while not any((d / "metrics.jsonl").exists() for d in run_dirs(tmp_path)) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()[1][-3000:]
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 128 + signal.SIGTERM, stderr[-3000:]
    (run_dir,) = run_dirs(tmp_path)
    assert "stopped by SIGTERM at env step 2,048" in stderr and f"rlq resume run={run_dir}" in stderr
    assert "Traceback" not in stderr
    assert sorted(p.name for p in (run_dir / "checkpoints").glob("*.msgpack")) == ["step_2048.msgpack"]
    log = (run_dir / "rlq.log").read_text()  # a batch job's log says why the run stopped
    assert "rlq: stopped by SIGTERM at env step 2,048" in log and f"rlq resume run={run_dir}" in log

    resumed = run_cli("resume", f"run={run_dir}", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert "from step_2048" in resumed.stdout
    for a, b in zip(
        checkpoint.leaves(run_dir / "checkpoints/final.msgpack"),
        checkpoint.leaves(full_run / "checkpoints/final.msgpack"),
        strict=True,
    ):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
    assert rows(run_dir) == rows(full_run)
