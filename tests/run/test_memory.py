"""Sizes checked before compiling (rlq/run/memory.py): the estimate is a lower bound, the refusal names the key."""

from __future__ import annotations

import pytest

from rlq.errors import ConfigError
from rlq.run.build import checked_env
from rlq.run.memory import GIB, check_evaluation_size, check_fits, check_training_sizes, free_bytes
from tests.helpers import compose_config


def test_free_memory_is_known_on_this_machine():
    free = free_bytes()
    assert free is not None and free > 0


def test_a_size_within_the_free_memory_passes_and_one_beyond_names_its_key():
    check_fits(GIB, "x", "algo.num_envs", 2 * GIB)
    check_fits(10 * GIB, "x", "algo.num_envs", None)  # unknown: not refused
    with pytest.raises(ConfigError, match=r"^x needs at least 2.0 GiB of device memory, 1.0 GiB is free; lower k$"):
        check_fits(2 * GIB, "x", "k", GIB)


def test_a_replay_buffer_beyond_the_free_memory_is_refused():
    cfg = compose_config("algo=dqn", "algo.buffer_size=100000000")
    env = checked_env(cfg, "env=cartpole")
    check_training_sizes(cfg, env, "algo.num_envs", int(cfg.algo.num_envs), 4 * GIB)  # 3.0 GiB of observations
    with pytest.raises(ConfigError, match=r"algo.buffer_size=100,000,000 \(the replay buffer\) needs at least 3.0 GiB"):
        check_training_sizes(cfg, env, "algo.num_envs", int(cfg.algo.num_envs), 2 * GIB)


def test_an_evaluation_counts_its_keys_and_states():
    env = checked_env(compose_config(), "env=cartpole")
    check_evaluation_size(env, 1000, GIB)  # 4 MB of keys, 3 x 894 bytes of states a step
    with pytest.raises(
        ConfigError, match=r"^episodes=1,000,000 x 500 steps needs at least 6.2 GiB .*; lower episodes$"
    ):
        check_evaluation_size(env, 1_000_000, GIB)
