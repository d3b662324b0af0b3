"""The brittle star learning presets (conf/experiment/brittle_star_*.yaml) compose, validate and train."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rlq.run.checks.validate import check_run_config
from tests.helpers import compose_config, train_run

pytestmark = pytest.mark.slow

PRESETS = {
    "brittle_star_qlearning": ("cpg", "qlearning"),
    "brittle_star_qlearning_decentralised": ("cpg", "qlearning"),
    "brittle_star_ppo_cpg": ("cpg", "ppo"),
    "brittle_star_ppo_direct": ("direct", "ppo"),
}


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_preset_composes_and_validates(preset: str) -> None:
    cfg = compose_config(f"experiment={preset}")
    controller, algo = PRESETS[preset]
    assert cfg.env.name == "brittle_star"
    assert cfg.controller.name == controller
    assert cfg.algo.name == algo
    assert cfg.env.physics.wall_contacts is False
    check_run_config(cfg)


def test_qlearning_preset_is_t0s_table_with_the_measured_changes() -> None:
    cfg = compose_config("experiment=brittle_star_qlearning")
    assert cfg.env.observation == "sector" and cfg.controller.mode == "leading_arm"
    assert cfg.algo.init_scale == 0.001  # T0's table
    assert cfg.env.action_repeat == 50 and cfg.algo.alpha_decay == "visits"
    assert (cfg.algo.alpha, cfg.algo.gamma, cfg.algo.epsilon.start, cfg.algo.epsilon.end) == (0.01, 0.9, 1.0, 0.05)
    assert cfg.algo.epsilon.duration < cfg.budget.env_steps


def test_decentralised_preset_gives_each_arm_its_bearing_and_role() -> None:
    cfg = compose_config("experiment=brittle_star_qlearning_decentralised")
    plain = compose_config("experiment=brittle_star_qlearning")
    assert cfg.env.observation == "arm_sectors" and cfg.env.bearing_bins == 10
    assert cfg.controller.mode == "decentralised"
    assert cfg.budget.env_steps == 2 * plain.budget.env_steps
    assert cfg.algo.num_envs == 2 * plain.algo.num_envs  # twice the decisions in the same number of steps
    assert cfg.algo.epsilon.duration == 0.8 * cfg.budget.env_steps
    for key in ("num_steps", "alpha", "alpha_decay", "gamma", "parallel_update", "replay_size"):
        assert cfg.algo[key] == plain.algo[key], key
    assert cfg.env.action_repeat == plain.env.action_repeat


def test_ppo_cpg_preset_modulates_the_cpg_every_step() -> None:
    cfg = compose_config("experiment=brittle_star_ppo_cpg")
    assert cfg.controller.mode == "parametric" and cfg.controller.modulate == "every_step"
    assert cfg.env.observation == "vector"


#: a few 0.12 s episodes of a one-segment star, one evaluation episode, no video: a preset's run end to end in seconds
TINY_EPISODES = (
    "log_every_steps=4",
    "env.segments_per_arm=1",
    "env.simulation_time=0.12",
    "env.action_repeat=2",
    "eval.episodes=1",
    "video.at_end=false",
)


@pytest.mark.slow
def test_qlearning_preset_trains_end_to_end(tmp_path: Path) -> None:
    result = train_run(
        tmp_path,
        "experiment=brittle_star_qlearning",
        "algo.num_envs=2",
        "algo.num_steps=2",
        "budget.env_steps=8",
        *TINY_EPISODES,
    )
    assert result.env_steps == 8
    table = np.asarray(result.state.table)
    assert table.shape == (1, 5, 5) and np.all(np.isfinite(table))
    assert (tmp_path / "checkpoints" / "final.msgpack").exists()


@pytest.mark.slow
def test_decentralised_preset_trains_end_to_end(tmp_path: Path) -> None:
    result = train_run(
        tmp_path,
        "experiment=brittle_star_qlearning_decentralised",
        "algo.num_envs=2",
        "algo.num_steps=2",
        "algo.replay_size=16",
        "algo.replay_batch=4",
        "budget.env_steps=4",
        *TINY_EPISODES,
    )
    assert result.env_steps == 4
    table, visits = np.asarray(result.state.table), np.asarray(result.state.visits)
    assert table.shape == (1, 10, 4) and np.all(np.isfinite(table))
    assert visits.sum() == 2 * (2 * 5 + 4)  # 2 steps x (2 envs x 5 arms + one replayed batch of 4)
