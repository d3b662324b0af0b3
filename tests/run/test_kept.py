"""``eval.keep=best``: each seed's best evaluated state, kept across a resume, scored again at the end."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from rlq.cli.checked import check_overrides
from rlq.errors import ConfigError
from rlq.run.hooks import ChunkEnd, PeriodicEval
from rlq.run.kept import KeepSeedsBest, improved, merged
from rlq.store import checkpoint
from tests.helpers import run_cli, run_dirs


class Silent:
    def log(self, *args):
        pass


def _state(value: float) -> dict:
    return {"w": np.full((2, 3), value), "shared": np.full(5, value)}  # two seeds; a leaf the seeds share


def test_improved_takes_ties_and_never_nan():
    best = np.array([3.0, 3.0, 3.0, -np.inf])
    assert improved(np.array([3.0, 2.0, np.nan, 1.0]), best).tolist() == [True, False, False, True]


def test_merged_picks_each_seeds_entry_and_leaves_a_shared_leaf_to_the_new_state():
    out = merged(_state(1.0), _state(0.0), np.array([False, True]))
    np.testing.assert_array_equal(out["w"], [[0.0] * 3, [1.0] * 3])
    np.testing.assert_array_equal(out["shared"], np.full(5, 1.0))


def test_each_seed_keeps_its_best_evaluation_and_a_new_hook_reads_them_back(tmp_path):
    returns = iter([[1.0, 5.0], [3.0, 2.0], [2.0, 9.0]])

    def evaluate(state, index):
        return {"return": np.array(next(returns))}

    keeper = KeepSeedsBest(tmp_path, 2)
    hook = PeriodicEval(evaluate, every_chunks=1, logger=Silent(), listeners=[keeper])
    for i in range(3):
        hook.on_chunk(ChunkEnd(i, 1000 * (i + 1), _state(float(i)), {}, last=False))
    meta = checkpoint.meta(tmp_path / "kept.msgpack")
    assert meta["eval_return"] == [3.0, 9.0] and meta["from_env_steps"] == [2000, 3000]
    np.testing.assert_array_equal(keeper.state["w"], [[1.0] * 3, [2.0] * 3])

    again = KeepSeedsBest(tmp_path, 2)  # a resumed run's
    chosen, from_steps = again.with_final(_state(7.0), np.array([3.0, 1.0]), 4000, {"env_steps": 4000})
    np.testing.assert_array_equal(chosen["w"], [[7.0] * 3, [2.0] * 3])  # seed 0: a tie goes to the later state
    assert from_steps == [4000, 3000]
    assert checkpoint.meta(tmp_path / "kept.msgpack")["from_env_steps"] == [4000, 3000]


def test_a_keep_other_than_last_or_best_is_refused():
    with pytest.raises(ConfigError, match=r"eval.keep must be one of last, best, got 'maybe'"):
        check_overrides(["eval.keep=maybe"])


KEEP_BEST = [
    "env=cartpole",
    "algo=dqn",
    "budget.env_steps=8192",
    "algo.learning_starts=1000",
    "log_every_steps=2048",
    "checkpoint.every_steps=4096",
    "eval.every_steps=2048",
    "eval.episodes=4",
    "eval.keep=best",
    "video.at_end=false",
    "logger.wandb.mode=disabled",
    "num_seeds=3",
]


@pytest.fixture(scope="module")
def kept_run(tmp_path_factory) -> Path:
    workdir = tmp_path_factory.mktemp("kept")
    proc = run_cli("train", *KEEP_BEST, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    assert "kept states' (from env steps" in proc.stdout
    return run_dir


@pytest.mark.slow  # two CLI runs of CartPole DQN (~40 s)
def test_a_run_reports_its_kept_states_fresh_score_and_a_resumed_run_the_same(kept_run, tmp_path):
    summary = json.loads((kept_run / "summary.json").read_text())
    rows = [json.loads(line) for line in (kept_run / "metrics.jsonl").read_text().splitlines()]
    evals = {r["env_steps"]: r for r in rows if r["kind"] == "eval"}
    kept = {r["seed"]: r for r in rows if r["kind"] == "kept" and r["seed"] != "mean"}
    assert sorted(evals) == [2048, 4096, 6144, 8192] and len(kept) == 3
    assert summary["eval_return"] == summary["kept"]["eval"]["return"] == [kept[s]["return"] for s in range(3)]
    for seed, steps in enumerate(summary["kept"]["from_env_steps"]):
        chosen = [r["return"] for r in rows if r["kind"] == "eval" and r["seed"] == seed and r["env_steps"] == steps]
        best = max(r["return"] for r in rows if r["kind"] == "eval" and r["seed"] == seed)
        assert chosen == [best] and kept[seed]["from_env_steps"] == steps

    stopped = tmp_path / "stopped"  # killed in its third chunk: resumed from step_4096, kept.msgpack as it was
    shutil.copytree(kept_run, stopped)
    for path in [*(stopped / "checkpoints").glob("final.*"), stopped / "summary.json"]:
        path.unlink()
    proc = run_cli("resume", f"run={stopped}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    resumed = json.loads((stopped / "summary.json").read_text())
    assert resumed["resumed_from_env_steps"] == 4096 and resumed["kept"] == summary["kept"]

    proc = run_cli("eval", f"run={kept_run}", "episodes=4", cwd=tmp_path)  # the states the run reported, by default
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads((kept_run / "eval_cartpole.json").read_text())["checkpoint"].endswith("kept.msgpack")


def test_a_finished_keep_best_runs_readers_take_its_kept_states_unless_told_otherwise(tmp_path):
    directory = tmp_path / "checkpoints"
    for name in ("final", "kept"):
        checkpoint.save(directory, name, _state(1.0), {"env_steps": 4000, "chunks_done": 4})
    best, last = {"eval": {"keep": "best"}}, {"eval": {"keep": "last"}}
    assert checkpoint.resolve_noting(tmp_path, None, best)[0].name == "final.msgpack"  # not finished: no summary
    (tmp_path / "summary.json").write_text("{}")
    assert checkpoint.resolve_noting(tmp_path, None, best)[0].name == "kept.msgpack"
    assert checkpoint.resolve_noting(tmp_path, None, last)[0].name == "final.msgpack"
    assert checkpoint.resolve_noting(tmp_path, "final", best)[0].name == "final.msgpack"
    assert checkpoint.resolve(tmp_path, "kept").name == "kept.msgpack"
    (directory / "kept.msgpack").write_bytes(b"\0" * 10)  # damaged: the final state, and a note why
    path, notes = checkpoint.resolve_noting(tmp_path, None, best)
    assert path.name == "final.msgpack" and len(notes) == 1 and "kept.msgpack" in notes[0]


@pytest.mark.slow  # one CLI run of CartPole DQN, two members of two seeds (~20 s)
def test_each_member_of_a_sweep_keeps_its_own_seeds_kept_states_and_figures(tmp_path):
    swept = [a for a in KEEP_BEST if not a.startswith(("num_seeds", "budget", "checkpoint"))]
    proc = run_cli("train", *swept, "budget.env_steps=4096", "num_seeds=2", "sweep.algo.lr=[1e-3,3e-4]", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(tmp_path)
    sweep_meta = checkpoint.meta(run_dir / "checkpoints" / "kept.msgpack")
    sweep_kept = json.loads((run_dir / "summary.json").read_text())["kept"]
    assert len(sweep_meta["eval_return"]) == len(sweep_kept["from_env_steps"]) == 4
    assert len(list((run_dir / "members").iterdir())) == 2
    for index, lr in enumerate(("0.001", "0.0003")):  # the sweep's order: its seeds 0-1, then 2-3
        member = run_dir / "members" / f"algo.lr={lr}"
        seeds = slice(2 * index, 2 * index + 2)
        meta = checkpoint.meta(member / "checkpoints" / "kept.msgpack")
        assert meta["eval_return"] == sweep_meta["eval_return"][seeds]
        assert meta["from_env_steps"] == sweep_meta["from_env_steps"][seeds]
        summary = json.loads((member / "summary.json").read_text())
        assert summary["kept"]["from_env_steps"] == sweep_kept["from_env_steps"][seeds]
        assert summary["kept"]["eval"]["return"] == summary["eval_return"] == sweep_kept["eval"]["return"][seeds]
        assert len(checkpoint.leaves(member / "checkpoints" / "kept.msgpack")[0]) == 2
