"""A full disk: one line naming the file (exit 1), the run's result kept, no partial or temporary files,
log handlers that warn once. On a tiny tmpfs where the test may mount one (root), else skipped."""

from __future__ import annotations

import json
import logging
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from rlq.cli.main import main
from tests.cli.test_bad_inputs import make_run
from tests.helpers import run_cli

TINY = ["logger=quiet", "budget.env_steps=4096", "log_every_steps=2048", "eval.episodes=2", "video.at_end=false"]


def _mount(path: Path, size: str) -> bool:
    if os.geteuid() != 0:
        return False
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], capture_output=True)
    return done.returncode == 0


@pytest.fixture
def small_disk(tmp_path: Path, request) -> Iterator[Path]:
    """An empty tmpfs of ``request.param`` bytes (default 40k) at ``tmp_path/disk``."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if not _mount(disk, getattr(request, "param", "40k")):
        pytest.skip("mounting a tmpfs needs root")
    try:
        yield disk
    finally:
        subprocess.run(["umount", str(disk)], check=True)


def fill(disk: Path) -> None:
    """Take the disk's free space, but for nothing."""
    with open(disk / "filler", "wb", buffering=0) as f:
        try:
            while True:
                f.write(b"\0" * 4096)
        except OSError:
            pass


@pytest.mark.slow
def test_a_full_disk_at_the_final_checkpoint_is_one_line_and_the_result_is_kept(small_disk: Path):
    run_dir = small_disk / "run"
    proc = run_cli("train", *TINY, f"hydra.run.dir={run_dir}", cwd=small_disk.parent)
    assert proc.returncode == 1, proc.stderr[-3000:]
    final = run_dir / "checkpoints" / "final.msgpack"
    assert proc.stderr.strip().splitlines()[-1] == f"rlq: error: No space left on device: {final}"
    assert "Error executing job" not in proc.stderr and "Traceback" not in proc.stderr
    assert not [p for p in run_dir.rglob("*") if ".tmp-" in p.name]
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["env_steps"] == 4096 and summary["final_checkpoint_error"].endswith(str(final))
    log = (run_dir / "rlq.log").read_text()
    assert "final greedy eval return" in log and "the final checkpoint was not written" in log


def test_eval_on_a_full_disk_leaves_no_empty_json(small_disk: Path, monkeypatch, capsys):
    run_dir = make_run(small_disk)
    result = {"env": "cartpole", "per_seed_return": [1.0], "mean_return": 1.0, "state_metrics": {}}
    result |= {"skipped_checkpoints": [], "checkpoint": str(run_dir / "checkpoints/final.msgpack")}
    monkeypatch.setattr("rlq.cli.eval.evaluate_run", lambda *args: result)
    fill(small_disk)
    main(["eval", f"run={run_dir}"])
    err = capsys.readouterr().err
    assert "eval_cartpole.json could not be written (No space left on device)" in err
    assert not (run_dir / "eval_cartpole.json").exists()
    assert not [p for p in run_dir.rglob("*") if ".tmp-" in p.name]


def test_a_log_handler_on_a_full_disk_warns_once(small_disk: Path, capsys):
    main(["--version"])  # what every command sets up first
    capsys.readouterr()
    fill(small_disk)
    handler = logging.FileHandler(small_disk / "debug.log")
    logger = logging.getLogger("rlq.test.full_disk")
    logger.addHandler(handler)
    try:
        for i in range(50):
            logger.warning("line %d %s", i, "x" * 4096)
    finally:
        logger.removeHandler(handler)
        handler.stream = None  # its buffer cannot be flushed either
    err = capsys.readouterr().err
    assert "--- Logging error ---" not in err
    assert err.strip().splitlines() == [
        f"rlq: warning: a log handler cannot write {small_disk / 'debug.log'} ([Errno 28] No space left on device); "
        "its further records are dropped"
    ]


def test_the_next_start_removes_temporaries_a_full_disk_left(tmp_path: Path, monkeypatch):
    run_dir = make_run(tmp_path, steps=(2048,), final=False)
    left = [run_dir / "checkpoints/.step_4096.msgpack.tmp-999", run_dir / ".summary.json.tmp-999"]
    for path in left:
        path.write_bytes(b"partial")
    monkeypatch.setattr("rlq.run.train.train", lambda cfg, run_dir, resume, finish=False: None)
    monkeypatch.setattr(
        "rlq.cli.resume.continue_run", lambda *args, **kwargs: type("R", (), {"line": lambda self: "done"})()
    )
    main(["resume", f"run={run_dir}"])
    assert not any(path.exists() for path in left)
    assert (run_dir / "checkpoints/step_2048.msgpack").exists()
