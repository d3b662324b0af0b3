"""Contradicting group choices are refused with one line, exit 2, before anything is made (rlq/config/choices.py)."""

from __future__ import annotations

import pytest

from rlq.config.choices import check_choices, preset_choices
from tests.cli.test_bad_inputs import check_bad_input

CASES = [
    (
        ["train", "experiment=cartpole_dqn", "algo=ppo"],
        "experiment=cartpole_dqn sets algo=dqn, which algo=ppo contradicts: drop algo=ppo to run the preset, "
        "or drop experiment=cartpole_dqn to choose the groups yourself",
    ),
    (["train", "algo=ppo", "experiment=lunar_ppo", "env=cartpole"], "experiment=lunar_ppo sets env=lunar"),
    (
        ["train", "experiment=cartpole_ppo", "experiment=cartpole_dqn"],
        "experiment is given twice (experiment=cartpole_ppo and experiment=cartpole_dqn), and only the last would "
        "count: give experiment once",
    ),
    (["train", "algo=ppo", "algo=dqn"], "algo is given twice"),
    (["train", "env/physics=fast", "env=brittle_star", "env/physics=default"], "env/physics is given twice"),
    (["train", "--cfg", "job", "experiment=cartpole_dqn", "algo=ppo"], "which algo=ppo contradicts"),
    (["train", "-m", "experiment=cartpole_dqn", "algo=dqn,ppo"], "job 1 of 2 (algo=ppo): experiment=cartpole_dqn"),
]


@pytest.mark.parametrize("argv,fragment", CASES)
def test_a_contradiction_is_one_line_and_exit_2(argv, fragment, tmp_path, monkeypatch, capsys):
    check_bad_input(argv, None, fragment, tmp_path, monkeypatch, capsys)


def test_choices_that_agree_pass():
    check_choices(["experiment=cartpole_dqn", "algo=dqn", "env=cartpole", "algo.lr=1e-3", "logger=quiet"])
    check_choices(["algo=ppo", "+algo.extra=1", "hydra/launcher=basic", "hydra.run.dir=x"])


def test_the_preset_choices_come_from_its_defaults_list():
    assert preset_choices("cartpole_dqn") == {"env": "cartpole", "algo": "dqn"}
    assert preset_choices("brittle_star_map_elites")["env/physics"] == "fast"
    assert preset_choices("no_such_preset") == {}
