"""scripts/bench_rlzoo.py's pure parts (no torch, no training): the commands it runs and the figures it reports."""

from __future__ import annotations

import pytest

from tests.helpers import script_module


@pytest.fixture(scope="module")
def bench():
    with script_module("bench_rlzoo") as module:
        yield module


def test_commands_are_the_tuned_recipes_and_smoke_shrinks_them(bench) -> None:
    full = bench.rlq_overrides("dqn", 101, smoke=False)
    assert full[:2] == ["experiment=lunar_dqn", "seed=101"] and "video.at_end=false" in full
    assert not any(o.startswith("budget.") for o in full)
    assert bench.rlq_overrides("ppo", 7, smoke=False)[:3] == ["algo=ppo", "env=lunar", "machine=cpu"]
    assert "budget.env_steps=2048" in bench.rlq_overrides("dqn", 7, smoke=True)
    assert bench.reference_args("ppo", 5, "m.zip", smoke=False) == [
        "train",
        "--algo",
        "ppo",
        "--seed",
        "5",
        "--model",
        "m.zip",
    ]
    assert bench.reference_args("dqn", 5, "m.zip", smoke=True)[-2:] == ["--steps", str(bench.SMOKE_STEPS)]


def test_rlzoo_recipes_are_rl_zoo_lunarlander_v3_entries(bench) -> None:
    dqn, ppo = bench.RECIPES["dqn"], bench.RECIPES["ppo"]
    assert (dqn["n_timesteps"], dqn["policy_kwargs"], dqn["target_update_interval"]) == (
        100_000,
        {"net_arch": [256, 256]},
        250,
    )
    assert (ppo["n_envs"], ppo["n_timesteps"], ppo["n_steps"], ppo["gamma"]) == (16, 1_000_000, 1024, 0.999)


def test_episode_stats_and_arguments(bench) -> None:
    stats = bench.episode_stats([100.0, 300.0, 200.0, 250.0])
    assert stats == {
        "box2d_mean": 212.5,
        "box2d_std": 73.95,
        "box2d_episodes": 4,
        "box2d_min": 100.0,
        "box2d_over_200": 3,
    }
    assert bench.parse_args(["--smoke", "--out", "x.json"]).episodes == bench.SMOKE_EPISODES
    args = bench.parse_args(["--pairs", "ppo", "--out", "x.json"])
    assert (args.pairs, args.episodes, args.seed) == (["ppo"], 100, 101)
