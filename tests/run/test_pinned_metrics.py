"""Refactors must not change results: short CartPole PPO (both variants) and DQN runs, and a PPO in-program sweep's
members, reproduce pinned metrics.

The pinned rows (tests/run/data/pinned_cartpole.json) were written by these tests with
``RLQ_PIN_METRICS=write``; timings are left out, every other number of every row is compared.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest

from tests.helpers import run_cli_in_process, run_dirs, train_run

PINNED = Path(__file__).parent / "data" / "pinned_cartpole.json"
RUNS = {
    "ppo": ["algo=ppo", "budget.env_steps=8192", "log_every_steps=2048"],
    "ppo_brax": [
        "algo=ppo",
        "algo.recompute_gae=true",
        "algo.clip_value=false",
        "algo.normalize_obs=true",
        "algo.batch_size=8",
        "algo.num_steps=16",
        "algo.reward_scaling=0.1",
        "budget.env_steps=8192",
        "log_every_steps=2048",
    ],
    "dqn": ["algo=dqn", "algo.learning_starts=1000", "budget.env_steps=4096", "log_every_steps=1024"],
}
#: an in-program sweep of two learning rates, one seed each (rlq/run/programs/members.py)
SWEEP = [
    "algo=ppo",
    "sweep.algo.lr=[1e-3,3e-3]",
    "num_seeds=1",
    "budget.env_steps=4096",
    "log_every_steps=1024",
    "checkpoint.every_steps=2048",
]
TIMING = ("wall_s", "steps_per_s", "compile_s", "chunk_s", "sps")


def metric_rows(run_dir: Path) -> list[dict]:
    """The metrics.jsonl rows without their timing fields."""
    rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    return [{k: v for k, v in row.items() if not any(t in k for t in TIMING)} for row in rows]


def assert_rows_equal(got: list[dict], want: list[dict]) -> None:
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        assert sorted(g) == sorted(w)
        for key, value in w.items():
            if isinstance(value, float) and not math.isnan(value):
                assert g[key] == pytest.approx(value, rel=1e-5, abs=1e-6), key
            else:
                assert g[key] == value, key


# the quick tier runs PPO; DQN and brax's PPO (7-8 s each) run in the full suite
@pytest.mark.parametrize("algo", [a if a == "ppo" else pytest.param(a, marks=pytest.mark.slow) for a in sorted(RUNS)])
def test_short_cartpole_run_reproduces_pinned_metrics(tmp_path, algo):
    train_run(tmp_path, *RUNS[algo], "seed=3", "eval.episodes=2", "video.at_end=false")
    rows = metric_rows(tmp_path)
    pinned = json.loads(PINNED.read_text()) if PINNED.exists() else {}
    if os.environ.get("RLQ_PIN_METRICS") == "write":
        pinned[algo] = rows
        PINNED.write_text(json.dumps(pinned, indent=1, sort_keys=True) + "\n")
    assert_rows_equal(rows, pinned[algo])


def sweep_member_rows(workdir: Path) -> dict[str, list[dict]]:
    """Each member's metrics rows of `rlq train` of ``SWEEP`` (seed 3) in ``workdir``, by member directory."""
    workdir.mkdir(exist_ok=True)
    quiet = ("seed=3", "eval.episodes=2", "video.at_end=false", "logger.wandb.mode=disabled")
    proc = run_cli_in_process("train", *SWEEP, *quiet, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    return {member.name: metric_rows(member) for member in sorted((run_dir / "members").iterdir())}


@pytest.mark.slow  # four members of the pinned runs above, trained again as one program (11 s)
def test_a_short_cartpole_sweep_reproduces_each_member_s_pinned_metrics(tmp_path):
    """The members train in one program with their hyperparameters as the chunk's argument, one value per seed."""
    got = sweep_member_rows(tmp_path)
    pinned = json.loads(PINNED.read_text()) if PINNED.exists() else {}
    if os.environ.get("RLQ_PIN_METRICS") == "write":
        pinned["ppo_sweep"] = got
        PINNED.write_text(json.dumps(pinned, indent=1, sort_keys=True) + "\n")
    assert sorted(got) == sorted(pinned["ppo_sweep"]) == ["algo.lr=0.001", "algo.lr=0.003"]
    for member, rows in got.items():
        assert_rows_equal(rows, pinned["ppo_sweep"][member])
