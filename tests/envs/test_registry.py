"""The env registry: a process builds each bare env config once."""

import pytest

from rlq.envs import KEEP_BUILT, make_base_env
from rlq.errors import ConfigError
from tests.helpers import compose_config


def test_the_same_env_config_gives_the_same_env_and_another_config_a_new_one():
    env = make_base_env(compose_config("env=cartpole").env)
    assert make_base_env(compose_config("env=cartpole").env) is env
    assert make_base_env(compose_config("env=cartpole", "env.max_episode_steps=100").env) is not env


def test_only_the_newest_envs_are_kept():
    first = make_base_env(compose_config("env=cartpole", "env.max_episode_steps=11").env)
    for steps in range(12, 12 + KEEP_BUILT):
        make_base_env(compose_config("env=cartpole", f"env.max_episode_steps={steps}").env)
    assert make_base_env(compose_config("env=cartpole", "env.max_episode_steps=11").env) is not first


def test_an_unknown_env_name_is_a_config_error():
    with pytest.raises(ConfigError, match="env.name=.pong. is not one of rlq.s: choose one of cartpole, lunar"):
        make_base_env(compose_config("env=cartpole", "env.name=pong").env)
