"""One validation pass per run: `rlq train` checks a config once (a sweep: each job once, before the first
starts) and builds the bare env once, though validation and training both need it."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import rlq.cli.checked
import rlq.cli.train
import rlq.envs.cartpole
from rlq.cli.main import main

TINY = ["budget.env_steps=2048", "eval.episodes=2", "video.at_end=false", "logger=quiet"]


@pytest.fixture
def counted(monkeypatch):
    calls = {"check_run_config": 0, "env builds": 0}
    check, make = rlq.cli.checked.check_run_config, rlq.envs.cartpole.make

    def counting_check(cfg):
        calls["check_run_config"] += 1
        return check(cfg)

    def counting_make(env_cfg):
        calls["env builds"] += 1
        return make(env_cfg)

    monkeypatch.setattr(rlq.cli.checked, "check_run_config", counting_check)
    monkeypatch.setattr(rlq.cli.train, "check_run_config", counting_check)
    monkeypatch.setattr(rlq.envs.cartpole, "make", counting_make)
    monkeypatch.setattr("rlq.envs._BUILT", type(rlq.envs._BUILT)())  # no env left over from other tests
    return calls


@pytest.mark.slow  # a whole run through the CLI (~6 s)
def test_a_run_is_checked_once_and_builds_its_env_once(tmp_path: Path, counted, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    main(["train", "env.max_episode_steps=321", *TINY])  # an env config no other test builds
    assert counted == {"check_run_config": 1, "env builds": 1}


@pytest.mark.slow  # 10-20 s on 2 cores: the full suite runs it
def test_each_sweep_job_is_checked_once(tmp_path: Path, counted, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(os.environ, "HYDRA_FULL_ERROR", "1")
    main(["train", "-m", "seed=0,1", "env.max_episode_steps=322", *TINY])
    assert counted["check_run_config"] == 2  # both jobs before the first starts; the jobs do not check again
    assert counted["env builds"] == 1
