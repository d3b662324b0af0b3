"""``objective``: the number a run returns to Hydra's sweepers, and the sweep checks that read Optuna's syntax."""

import json

import numpy as np
import pytest

from rlq.config.sweeps import sweep_jobs
from rlq.errors import ConfigError
from rlq.store.objective import objective_value, parse_objective
from rlq.tools import sweep


def test_eval_objective_is_the_mean_over_seeds_of_the_final_evaluation(tmp_path):
    final = {"return": np.array([100.0, 200.0]), "length": np.array([5.0, 7.0])}
    assert objective_value("eval/return", final, tmp_path) == 150.0
    assert objective_value("eval/length", final, tmp_path) == 6.0


def test_train_objective_is_the_last_mean_train_row(tmp_path):
    rows = [
        {"kind": "train", "seed": "mean", "env_steps": 10, "loss": 3.0},
        {"kind": "train", "seed": 0, "env_steps": 20, "loss": 9.0},
        {"kind": "train", "seed": "mean", "env_steps": 20, "loss": 1.5},
    ]
    (tmp_path / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert objective_value("train/loss", {}, tmp_path) == 1.5


def test_an_unknown_objective_names_the_metrics_there_are(tmp_path):
    with pytest.raises(ConfigError, match="no 'retrun'; they have: length, return"):
        objective_value("eval/retrun", {"return": np.ones(1), "length": np.ones(1)}, tmp_path)
    with pytest.raises(ConfigError, match="eval/<name> or train/<name>"):
        parse_objective("return")


def test_interval_sweeps_are_checked_at_both_ends():
    jobs = sweep_jobs(["algo.lr=tag(log,interval(1e-4,1e-2))", "seed=choice(0,1)"])
    assert sorted(job[0] for job in jobs) == ["algo.lr=0.0001", "algo.lr=0.0001", "algo.lr=0.01", "algo.lr=0.01"]


def test_optuna_maximises_unless_told_and_names_the_extra_when_missing(monkeypatch):
    assert sweep.sweeper_overrides(["hydra/sweeper=optuna"]) == ["hydra.sweeper.direction=maximize"]
    assert sweep.sweeper_overrides(["hydra/sweeper=optuna", "hydra.sweeper.direction=minimize"]) == []
    assert sweep.sweeper_overrides(["seed=0,1"]) == []
    monkeypatch.setattr(sweep, "_installed", lambda module: False)
    with pytest.raises(ConfigError, match=r'pip install -e "\.\[tune\]"'):
        sweep.sweeper_overrides(["hydra/sweeper=optuna"])
