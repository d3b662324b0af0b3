"""Sizes checked before compiling (rlq/run/checks/memory.py): the estimate is a lower bound, the refusal names the key."""

from __future__ import annotations

import pytest

from rlq.errors import ConfigError
from rlq.run.checks.memory import (
    GIB,
    check_evaluation_size,
    check_fits,
    check_search_sizes,
    check_training_sizes,
    free_bytes,
)
from rlq.run.programs.env_stack import checked_env
from tests.cli.test_bad_inputs import check_bad_input
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


class FakeDevice:
    """A device whose allocator reports ``stats`` (a GPU's figures), or raises where it has none."""

    def __init__(self, stats):
        self.stats = stats

    def memory_stats(self):
        if isinstance(self.stats, Exception):
            raise self.stats
        return self.stats


def test_a_gpus_free_memory_is_its_allocators_limit_less_what_is_in_use():
    assert free_bytes(FakeDevice({"bytes_limit": 80 * GIB, "bytes_in_use": 2 * GIB})) == 78 * GIB
    assert free_bytes(FakeDevice({"bytes_limit": 80 * GIB})) == 80 * GIB


@pytest.mark.parametrize("stats", [None, {}, NotImplementedError("no memory figures")])
def test_a_device_without_figures_falls_back_to_the_hosts_available_memory(stats):
    host = free_bytes(FakeDevice(stats))
    assert host is not None and host > 0
    assert host == free_bytes(FakeDevice({"num_allocs": 1})) or host > GIB  # both read /proc/meminfo


def search(*overrides: str):
    cfg = compose_config(*overrides)
    return cfg, checked_env(cfg, f"env={cfg.env.name}")


def test_a_search_counts_its_candidates_genotypes():
    cfg, env = search("algo=es", "algo.population=1000", "algo.hidden=[1000]")  # 6,001 numbers a genotype
    check_search_sizes(cfg, env, GIB)
    with pytest.raises(
        ConfigError,
        match=r"^algo.population=1,000 genotypes of 6,001 numbers \(algo.hidden=\[1000\]\) needs at least 0.0 GiB .*; "
        r"lower algo.population or algo.hidden$",
    ):
        check_search_sizes(cfg, env, 20_000_000)


def test_a_search_counts_the_evaluation_of_its_candidates_episodes():
    cfg, env = search("algo=random_search", "algo.population=100000")  # x 20 episodes x 500 steps of keys
    with pytest.raises(
        ConfigError, match=r"^algo.population=100,000 x algo.episodes=20 x 500 steps \(the candidates' evaluation\)"
    ):
        check_search_sizes(cfg, env, 10 * GIB)
    cfg, env = search("algo=random_search", "algo.variant=ars", "algo.ars.directions=100000")
    with pytest.raises(ConfigError, match=r"^algo.ars.directions=200,000 x algo.episodes="):
        check_search_sizes(cfg, env, 10 * GIB)


def test_an_archive_and_cma_es_covariances_are_counted():
    cfg, env = search("algo=map_elites", "algo.archive.shape=[10000,10000]")  # 1e8 cells x 4 numbers
    with pytest.raises(ConfigError, match=r"^algo.archive.shape: an archive of 100,000,000 genotypes of 4 numbers"):
        check_search_sizes(cfg, env, GIB)
    cfg, env = search("algo=es", "algo.strategy=cma_es", "algo.hidden=[4096]")  # 24,577 numbers: 4.5 GiB
    check_search_sizes(cfg, env, 5 * GIB)
    with pytest.raises(ConfigError, match=r"CMA-ES covariance\(s\) of 24,577 x 24,577 .*or use algo.strategy=snes"):
        check_search_sizes(cfg, env, 4 * GIB)
    cfg, env = search("algo=map_elites", "algo.emitter=improvement", "algo.cma_emitters=2", "algo.hidden=[4096]")
    with pytest.raises(ConfigError, match=r"^2 CMA-ES covariance\(s\) .*use algo.emitter=gaussian"):
        check_search_sizes(cfg, env, 8 * GIB)


def test_a_generation_past_the_32_bit_step_counter_is_refused_without_a_memory_figure():
    cfg, env = search("algo=es", "algo.population=2000000", "algo.episodes=4")
    with pytest.raises(ConfigError, match=r"one generation would take 4,000,000,000 env steps per seed"):
        check_search_sizes(cfg, env, None)
    cfg, env = search("algo=ppo")
    check_search_sizes(cfg, env, 1)  # not a search: nothing to check


#: (overrides of `rlq train`, a fragment of the error line), checked against a fixed 64 GiB of free memory
POPULATIONS = [
    (["algo=es", "algo.population=1000000000"], "algo.population=1,000,000,000 x algo.episodes=16 x 500 steps"),
    (["algo=random_search", "algo.population=1000000000"], "lower algo.population or algo.episodes"),
    (["algo=map_elites", "algo.batch_size=1000000000"], "lower algo.batch_size or algo.episodes"),
    (["algo=es", "algo.hidden=[1000000,100000]"], "genotypes of 100,005,200,001 numbers"),
]


@pytest.mark.parametrize("overrides,fragment", POPULATIONS)
def test_a_population_beyond_any_machines_memory_is_one_line(overrides, fragment, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(
        "rlq.run.checks.memory.free_bytes", lambda device=None: 64 * GIB
    )  # not this machine's free memory
    check_bad_input(["train", *overrides], None, fragment, tmp_path, monkeypatch, capsys)


def test_a_gpus_free_memory_refuses_what_the_host_would_take(tmp_path, monkeypatch, capsys):
    """The figure ``free_bytes`` gives (a GPU's allocator's, faked) is the one the CLI compares with."""
    monkeypatch.setattr("rlq.run.checks.memory.free_bytes", lambda device=None: GIB)
    argv = ["train", "algo=es", "algo.population=100000"]  # 1.6e6 episodes x 500 steps of keys: 6 GiB at least
    check_bad_input(
        argv, None, "GiB of device memory, 1.0 GiB is free; lower algo.population", tmp_path, monkeypatch, capsys
    )
