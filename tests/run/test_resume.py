"""`rlq resume`: a run stopped after an intermediate checkpoint continues exactly as it would have."""

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import types
from pathlib import Path

import numpy as np
import pytest

from rlq.errors import RunInterrupted
from rlq.run.train import train
from rlq.store import checkpoint
from rlq.store.sidecar import HASH_KEY
from tests.helpers import compose_config, run_cli, run_cli_in_process, run_dirs

pytestmark = pytest.mark.slow

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


def test_a_run_killed_between_its_final_checkpoint_and_its_summary_is_finished_without_training(full_run, tmp_path):
    """kill -9 after the final checkpoint: before the final evaluation's rows were logged, after them (they are
    dropped and made again: the same state and keys give the same numbers), and while the final checkpoint was
    written (no sidecar: the run trains on from step_4096). Each ends as the uninterrupted run, rows not doubled."""
    expected = json.loads((full_run / "summary.json").read_text())
    lines = (full_run / "metrics.jsonl").read_text().splitlines(keepends=True)
    final_rows = [line for line in lines if json.loads(line)["kind"] == "eval" and '"env_steps": 8192' in line]
    assert final_rows and lines[-len(final_rows) :] == final_rows  # the final evaluation's rows come last
    for case in ("rows_logged", "rows_not_logged", "final_half_written"):
        killed = tmp_path / case
        shutil.copytree(full_run, killed)
        (killed / "summary.json").unlink()
        if case != "rows_logged":
            (killed / "metrics.jsonl").write_text("".join(lines[: -len(final_rows)]))
        if case == "final_half_written":
            (killed / "checkpoints" / "final.json").unlink()
        proc = run_cli_in_process("resume", f"run={killed}", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr[-3000:]
        if case == "final_half_written":
            assert "final.msgpack has no sidecar" in proc.stderr and "from step_4096" in proc.stdout
        else:
            assert "stopped before its summary: making its final evaluation and summary" in proc.stdout
            assert "resuming" not in proc.stdout
        same_end(killed, full_run)
        summary = json.loads((killed / "summary.json").read_text())
        assert summary["final_eval"] == expected["final_eval"] and summary["env_steps"] == expected["env_steps"]
        assert summary["stopped"] == expected["stopped"] == "" and summary["warnings"] == expected["warnings"]
    assert summary["resumed_from_env_steps"] == 4096
    proc = run_cli_in_process("resume", f"run={killed}", cwd=tmp_path)
    assert proc.returncode == 2 and "has finished" in proc.stderr


def test_a_run_a_stop_rule_ended_killed_before_its_summary_keeps_the_evaluation_it_reused(tmp_path):
    """A stop rule ended the run just after the evaluation at 4,096, which became its final one (one row). Killed
    before its summary: `rlq resume` makes that evaluation again with its keys, logs no second row, keeps the reason."""
    whole = tmp_path / "whole"
    proc = run_cli_in_process("train", *RESUMABLE, 'stop.when="eval/return>=1"', f"hydra.run.dir={whole}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    expected = json.loads((whole / "summary.json").read_text())
    assert expected["env_steps"] == 4096 and expected["stopped"].startswith("stop.when eval/return>=1 met")
    assert checkpoint.meta(whole / "checkpoints/final.msgpack")["final_reused"] is True
    killed = tmp_path / "killed"
    shutil.copytree(whole, killed)
    (killed / "summary.json").unlink()
    proc = run_cli_in_process("resume", f"run={killed}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert rows(killed) == rows(whole) and [kind for kind, _, _ in rows(whole)].count("eval") == 2  # seed 0, mean
    summary = json.loads((killed / "summary.json").read_text())
    assert summary["final_eval"] == expected["final_eval"] and summary["stopped"] == expected["stopped"]


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
    train(cfg, tmp_path, resume=checkpoint.resumable(tmp_path, cfg)[0])
    assert len(inits) == 2 and inits[0]["id"] and inits[1]["id"] == inits[0]["id"]
    assert inits[1]["resume"] == "allow"


def test_sigterm_while_compiling_ends_the_run_at_once_with_nothing_to_save(tmp_path):
    env = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true"}
    cmd = [sys.executable, "-m", "rlq.cli", "train", *RESUMABLE]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # metrics.jsonl appears once the signal handlers are in place, before the programs compile
    deadline = time.monotonic() + 300
    while not any((d / "metrics.jsonl").exists() for d in run_dirs(tmp_path)) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()[1][-3000:]
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 128 + signal.SIGTERM, stderr[-3000:]
    (run_dir,) = run_dirs(tmp_path)
    assert "rlq: stopped by SIGTERM before training began: nothing to save" in stderr
    assert "Traceback" not in stderr
    assert not (run_dir / "checkpoints").exists()
    assert "stopped by SIGTERM before training began" in (run_dir / "rlq.log").read_text()


def test_sigterm_mid_chunk_writes_a_resumable_checkpoint_and_resume_ends_as_the_uninterrupted_run(
    full_run, tmp_path, monkeypatch
):
    """A stop seen between two slices of a chunk: the checkpoint falls inside the chunk, its calls'
    metrics beside it, and the resumed run logs the chunk's row and ends as the run never stopped."""
    import jax

    from rlq.run import loop as loop_module
    from rlq.run.stops import slices

    monkeypatch.setattr(slices, "TARGET_S", 0.0)  # every slice one call: a chunk of 4 updates is 4 slices
    real_call, calls = loop_module.call_chunk, []

    def call_then_stop(chunk, state, count):
        out = jax.block_until_ready(real_call(chunk, state, count))
        calls.append(count)
        if len(calls) == 2:  # the first slice has trained: a stop now saves a checkpoint
            os.kill(os.getpid(), signal.SIGTERM)
            deadline = time.monotonic() + 60  # the signal thread records it
            while "SIGTERM: stopping" not in (tmp_path / "rlq.log").read_text() and time.monotonic() < deadline:
                time.sleep(0.01)
        return out

    monkeypatch.setattr(loop_module, "call_chunk", call_then_stop)
    cfg = compose_config(*RESUMABLE)
    with pytest.raises(RunInterrupted, match="stopped by SIGTERM at env step 1,024") as stopped:
        train(cfg, tmp_path)
    assert stopped.value.exit_code == 128 + signal.SIGTERM and f"rlq resume run={tmp_path}" in str(stopped.value)
    assert calls == [1, 1]
    saved = tmp_path / "checkpoints" / "step_1024.msgpack"
    assert sorted(p.name for p in saved.parent.glob("step_*")) == ["step_1024.chunk.npz", "step_1024.json", saved.name]
    assert checkpoint.meta(saved)["chunk_calls_done"] == 2 and checkpoint.meta(saved)["chunks_done"] == 0
    assert rows(tmp_path) == []  # the first chunk had not ended

    monkeypatch.setattr(loop_module, "call_chunk", real_call)
    train(cfg, tmp_path, resume=checkpoint.resumable(tmp_path, cfg)[0])
    same_end(tmp_path, full_run)
    first = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()][0]
    full_first = json.loads((full_run / "metrics.jsonl").read_text().splitlines()[0])
    assert {k: v for k, v in first.items() if k != "wall_s"} == {k: v for k, v in full_first.items() if k != "wall_s"}


def evaluations_that_stop(monkeypatch, which: int) -> threading.Event:
    """The run's ``which``-th evaluation (1-based) sends SIGTERM and then never ends on its own (as an
    evaluation, or its program's compile, that takes minutes); set the event returned to let it end."""
    from rlq.run.programs.compiling import CompiledPrograms

    real, seen, release = CompiledPrograms.evaluate, [], threading.Event()

    def evaluate(self, state, keys):
        seen.append(1)
        if len(seen) == which:
            os.kill(os.getpid(), signal.SIGTERM)
            release.wait()
        return real(self, state, keys)

    monkeypatch.setattr(CompiledPrograms, "evaluate", evaluate)
    return release


def same_end(run_dir: Path, full_run: Path) -> None:
    for a, b in zip(
        checkpoint.leaves(run_dir / "checkpoints/final.msgpack"),
        checkpoint.leaves(full_run / "checkpoints/final.msgpack"),
        strict=True,
    ):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
    assert rows(run_dir) == rows(full_run)


def test_sigterm_during_an_evaluation_skips_it_and_resume_makes_it(full_run, tmp_path, monkeypatch):
    """A stop while the evaluation after the second chunk runs (or waits for its program to compile)
    does not wait for it: the checkpoint after the chunk, the evaluation skipped, and the resumed
    run makes that evaluation first, then ends as the run never stopped."""
    release = evaluations_that_stop(monkeypatch, which=1)
    cfg = compose_config(*RESUMABLE)
    try:
        with pytest.raises(RunInterrupted, match="stopped by SIGTERM at env step 4,096, skipping its evaluation"):
            train(cfg, tmp_path)
    finally:
        release.set()
    assert "skipping its evaluation (`rlq resume` makes it)" in (tmp_path / "rlq.log").read_text()
    saved = tmp_path / "checkpoints" / "step_4096.msgpack"
    assert checkpoint.meta(saved)["eval_skipped"] is True and checkpoint.meta(saved)["chunks_done"] == 2
    assert [kind for kind, _, _ in rows(tmp_path)] == ["train"] * 4  # 2 chunks x (seed 0 + mean), no eval row
    assert not (tmp_path / "summary.json").exists()

    monkeypatch.undo()
    train(cfg, tmp_path, resume=checkpoint.resumable(tmp_path, cfg)[0])
    same_end(tmp_path, full_run)  # the eval row at 4,096 too, in its place


def test_sigterm_during_the_final_evaluation_is_said_in_the_summary_and_resume_makes_it(
    full_run, tmp_path, monkeypatch
):
    """A stop during the final evaluation: the final checkpoint goes back to step_<N>, summary.json
    says the final evaluation was skipped, and `rlq resume` makes it (and trains nothing)."""
    release = evaluations_that_stop(monkeypatch, which=2)  # the first is the periodic one at 4,096
    cfg = compose_config(*RESUMABLE)
    try:
        with pytest.raises(RunInterrupted, match="stopped by SIGTERM during the final evaluation at env step 8,192"):
            train(cfg, tmp_path)
    finally:
        release.set()
    assert "SIGTERM: stopping now, skipping the final evaluation" in (tmp_path / "rlq.log").read_text()
    ckpts = tmp_path / "checkpoints"
    assert not (ckpts / "final.msgpack").exists() and not (ckpts / "final.json").exists()
    assert checkpoint.meta(ckpts / "step_8192.msgpack")["final_pending"] is True
    checkpoint.verify(ckpts / "step_8192.msgpack")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert "during the final evaluation" in summary["final_eval_interrupted"]
    assert summary["eval_return"] == [] and summary["eval_return_mean"] is None and summary["env_steps"] == 8192

    monkeypatch.undo()
    resumed = train(cfg, tmp_path, resume=checkpoint.resumable(tmp_path, cfg)[0])
    assert resumed.chunk_s == ()  # nothing left to train
    same_end(tmp_path, full_run)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert "final_eval_interrupted" not in summary
    assert summary["eval_return"] == pytest.approx(json.loads((full_run / "summary.json").read_text())["eval_return"])


def test_sigterm_while_the_final_video_is_made_ends_the_run_with_its_result_and_checkpoint(tmp_path, monkeypatch):
    """A stop while the final video is drawn (a video that never ends on its own) does not wait for it:
    the run's result line, summary.json and final checkpoint are written, and one line says the video
    was skipped and how to make it."""
    from rlq.run.videos import Seed0Video

    release = threading.Event()

    def video(self, state, env_steps, name):
        (self.run_dir / "videos").mkdir(exist_ok=True)
        (self.run_dir / "videos" / f"{name}.part.mp4").write_bytes(b"frames")  # as ffmpeg writes them
        os.kill(os.getpid(), signal.SIGTERM)
        release.wait()

    monkeypatch.setattr(Seed0Video, "__call__", video)
    cfg = compose_config(*[o for o in RESUMABLE if not o.startswith("video.")], "video.at_end=true")
    try:
        with pytest.raises(RunInterrupted, match="stopped by SIGTERM while rendering the final video") as stopped:
            train(cfg, tmp_path)
    finally:
        release.set()
    assert stopped.value.exit_code == 128 + signal.SIGTERM
    assert f"the final checkpoint {tmp_path / 'checkpoints' / 'final.msgpack'} is saved" in str(stopped.value)
    assert f"`rlq render run={tmp_path}` makes the video" in str(stopped.value)
    checkpoint.verify(tmp_path / "checkpoints" / "final.msgpack")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["env_steps"] == 8192 and len(summary["eval_return"]) == 1
    assert "while rendering the final video" in summary["final_video_interrupted"]
    log = (tmp_path / "rlq.log").read_text()
    assert "final greedy eval return" in log and "while rendering the final video" in log
    assert "SIGTERM: skipping the final video: the run is complete (SIGTERM again stops at once)" in log
    assert list((tmp_path / "videos").iterdir()) == []  # no partial video left
    assert [kind for kind, _, _ in rows(tmp_path)].count("eval") == 4  # the periodic and the final one


def test_sigterm_during_a_stage_video_skips_it_and_resume_ends_as_the_uninterrupted_run(
    full_run, tmp_path, monkeypatch
):
    """A stop while the video after the second chunk is made (one that never ends on its own): the video
    is skipped, the chunk's checkpoint (its evaluation made) is the stop's, and the resumed run ends as
    the run never stopped."""
    from rlq.run.videos import Seed0Video

    release = threading.Event()

    def video(self, state, env_steps, name):
        os.kill(os.getpid(), signal.SIGTERM)
        release.wait()

    monkeypatch.setattr(Seed0Video, "__call__", video)
    cfg = compose_config(*RESUMABLE, "video.every_steps=4096")
    try:
        with pytest.raises(RunInterrupted, match="stopped by SIGTERM at env step 4,096: checkpoint"):
            train(cfg, tmp_path)
    finally:
        release.set()
    assert "no video step_4096_seed0: stopped while it was made" in (tmp_path / "rlq.log").read_text()
    assert "eval_skipped" not in checkpoint.meta(tmp_path / "checkpoints" / "step_4096.msgpack")
    monkeypatch.undo()
    train(compose_config(*RESUMABLE), tmp_path, resume=checkpoint.resumable(tmp_path, cfg)[0])
    same_end(tmp_path, full_run)


def test_resume_with_a_larger_budget_keeps_the_runs_chunks_and_cadences(tmp_path):
    """9 updates of 512 steps in chunks of 3 (log_every_steps=2048 on a budget of 4608); extended to
    18 updates, a fresh plan would cut chunks of 2, and one that divides the 9 done chunks of 1."""
    cadence = ["log_every_steps=2048", "eval.every_steps=4096", "checkpoint.every_steps=4096"]
    common = ["eval.episodes=2", "video.at_end=false", "logger.wandb.mode=disabled"]
    first = run_cli("train", "budget.env_steps=4608", *cadence, *common, cwd=tmp_path)
    assert first.returncode == 0, first.stderr[-3000:]
    (run_dir,) = run_dirs(tmp_path)
    resumed = run_cli("resume", f"run={run_dir}", "budget.env_steps=9216", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr[-3000:]

    def snaps(proc):
        return [line for line in (proc.stdout + proc.stderr).splitlines() if "snaps to" in line]

    assert snaps(resumed) == snaps(first)  # the same chunks: the same notes (log_every_steps snaps to 1,536)
    steps = {kind: sorted({step for k, step, _ in rows(run_dir) if k == kind}) for kind in ("train", "eval")}
    assert steps["train"] == [1536, 3072, 4608, 6144, 7680, 9216]  # rows every chunk of 1,536 env steps
    assert steps["eval"] == [4608, 9216]  # every 3 chunks (the budget's last has the final evaluation)
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["resumed_from_env_steps"] == 4608 and len(summary["chunk_s"]) == 3
    assert 0 < summary["process_wall_s"] < summary["wall_s"]
    assert "(run total " in resumed.stdout
