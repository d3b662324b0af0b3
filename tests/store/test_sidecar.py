"""A checkpoint's sidecar checked against the run before use: the config hash and the env steps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rlq.errors import CheckpointError
from rlq.store import checkpoint
from rlq.store.sidecar import HASH_KEY, check_sidecar, config_hash
from tests.helpers import compose_config

STATE = {"w": np.arange(8, dtype=np.float32)}


@pytest.fixture(scope="module")
def cfg():
    return compose_config("budget.env_steps=8192")


def save(run_dir: Path, name: str, **meta) -> Path:
    return checkpoint.save(run_dir / "checkpoints", name, STATE, meta)


def test_the_hash_covers_the_settings_that_shape_the_state_and_not_the_budget(cfg):
    assert config_hash(cfg) == config_hash(compose_config("budget.env_steps=16384", "eval.episodes=3"))
    assert config_hash(cfg) != config_hash(compose_config("algo.hidden=[32,32]"))
    assert config_hash(cfg) != config_hash(compose_config("num_seeds=2"))


@pytest.mark.parametrize(
    "name, meta, words",
    [
        ("step_2048", {"env_steps": 2048, HASH_KEY: "0" * 64}, "written by a run of another config"),
        ("step_4096", {"env_steps": 2048, "chunks_done": 1, "chunk_steps": 2048}, "its name step_4096.msgpack"),
        (
            "final",
            {"env_steps": 9000, "chunks_done": 4, "chunk_steps": 2048},
            "env_steps 9000 go past the run's budget",
        ),
        ("final", {"env_steps": 16384, "chunks_done": 8, "chunk_steps": 2048}, "go past the run's budget"),
        ("final", {"env_steps": "2048"}, "env_steps is '2048', not an integer"),
        ("final", {"env_steps": 2048, "chunks_done": 0, "chunk_steps": 2048}, "chunks_done is 0"),
    ],
)
def test_a_sidecar_that_is_not_the_runs_is_refused(tmp_path, cfg, name, meta, words):
    path = save(tmp_path, name, **meta)
    with pytest.raises(CheckpointError, match="does not belong to this run") as info:
        check_sidecar(path, checkpoint.verify(path), cfg)
    assert words in str(info.value)


def test_the_runs_own_sidecar_passes(tmp_path, cfg):
    path = save(tmp_path, "step_2048", env_steps=2048, chunks_done=1, chunk_steps=2048, **{HASH_KEY: config_hash(cfg)})
    check_sidecar(path, checkpoint.verify(path), cfg)
    old = save(tmp_path, "step_1024", env_steps=1024)  # rlq versions before the hash: no hash, no chunks
    check_sidecar(old, checkpoint.verify(old), cfg)
    first = {"chunks_done": 0, "chunk_calls_done": 2, "calls_per_chunk": 4, HASH_KEY: config_hash(cfg)}
    mid = save(tmp_path, "step_1024", env_steps=1024, chunk_steps=2048, **first)  # a stop inside the first chunk
    check_sidecar(mid, checkpoint.verify(mid), cfg)


def test_one_chunk_past_the_budget_passes_where_less_than_a_chunk_was_left(tmp_path, cfg):
    """A run extended by less than one chunk (8192 after 6144: one more chunk of 6144) ends past its budget."""
    own = {"chunks_done": 2, "chunk_steps": 6144, HASH_KEY: config_hash(cfg)}
    path = save(tmp_path, "final", env_steps=12288, **own)
    check_sidecar(path, checkpoint.verify(path), cfg)
    two_more = save(tmp_path, "step_18432", env_steps=18432, **{**own, "chunks_done": 3})
    with pytest.raises(CheckpointError, match="go past the run's budget"):
        check_sidecar(two_more, checkpoint.verify(two_more), cfg)


def test_readers_fall_back_past_a_foreign_checkpoint(tmp_path, cfg):
    own = {"chunks_done": 1, "chunk_steps": 2048, HASH_KEY: config_hash(cfg)}
    save(tmp_path, "step_2048", env_steps=2048, **own)
    save(tmp_path, "step_4096", env_steps=4096, **{**own, "chunks_done": 2, HASH_KEY: "f" * 64})
    path, skipped = checkpoint.resumable(tmp_path, cfg)
    assert path.name == "step_2048.msgpack"
    assert len(skipped) == 1 and "step_4096.msgpack does not belong to this run" in skipped[0]
    save(tmp_path, "final", env_steps=8192, **{**own, "chunks_done": 4, HASH_KEY: "f" * 64})
    path, skipped = checkpoint.newest_intact(tmp_path, cfg)
    assert path.name == "step_2048.msgpack" and len(skipped) == 2
    with pytest.raises(CheckpointError, match="final.msgpack does not belong to this run"):
        checkpoint.resolve_noting(tmp_path, "final", cfg)


def test_resume_says_why_it_fell_back_in_rlq_log_and_cuts_metrics_at_the_checkpoint_used(tmp_path, cfg, monkeypatch):
    from rlq.cli.resume import continue_run

    own = {"chunks_done": 1, "chunk_steps": 2048, HASH_KEY: config_hash(cfg)}
    older = save(tmp_path, "step_2048", env_steps=2048, **own)
    save(tmp_path, "step_4096", env_steps=4096, **{**own, "chunks_done": 2, HASH_KEY: "f" * 64})
    rows = [{"env_steps": s, "kind": "train"} for s in (2048, 4096)]
    (tmp_path / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    (tmp_path / "rlq.log").write_text("the first attempt's lines\n")
    monkeypatch.setattr("rlq.run.train.train", lambda cfg, run_dir, resume, finish=False: resume)
    path, skipped = checkpoint.resumable(tmp_path, cfg)
    assert continue_run(cfg, tmp_path, path, skipped) == older
    log = (tmp_path / "rlq.log").read_text().splitlines()
    assert log[0] == "the first attempt's lines"
    assert "step_4096.msgpack does not belong to this run" in log[1] and "falling back" in log[1]
    assert [json.loads(line)["env_steps"] for line in (tmp_path / "metrics.jsonl").read_text().splitlines()] == [2048]
