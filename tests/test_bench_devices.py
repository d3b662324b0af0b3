"""scripts/bench_devices.py's pure parts: the ceiling of strong scaling and the env batch it cuts."""

from __future__ import annotations

import pytest

from tests.helpers import script_module


@pytest.fixture(scope="module")
def bench():
    with script_module("bench_devices") as module:
        yield module


def test_ideal_speedup_is_k_times_the_cut_batch_rate_over_the_whole_batch_rate(bench):
    runs = [
        {"devices": 1, "steady_env_steps_per_s": 800.0},
        {"devices": 2, "steady_env_steps_per_s": 500.0},  # half the envs at 5/8 of the rate: 1.25x at best
        {"devices": 4, "steady_env_steps_per_s": 200.0},  # a quarter at a quarter: no gain
    ]
    assert bench.ideal_speedups(runs) == [1.0, 1.25, 1.0]


def test_the_batch_cut_is_the_one_the_devices_split(bench):
    assert bench.env_batch(["experiment=humanoid_ppo"]) == ("algo.num_envs", 4096)
    assert bench.env_batch(["env=cartpole", "algo=map_elites", "algo.batch_size=64"]) == ("algo.batch_size", 64)
