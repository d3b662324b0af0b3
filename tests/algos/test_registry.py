"""The registries: every algorithm, controller and env a config can name is listed once and found one way."""

from __future__ import annotations

import os

import pytest
from omegaconf import OmegaConf

from rlq.algos import ALGORITHMS, algorithm_spec
from rlq.algos.spec import AlgorithmSpec
from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.controllers import CONTROLLERS
from rlq.errors import ConfigError
from rlq.lib.registry import choose
from tests.helpers import REPO


def yaml_names(group: str) -> set[str]:
    """The ``name`` of every option of ``group`` as it composes (an algorithm's from its schema)."""
    return {str(composed(group, p.stem).get("name")) for p in (REPO / "conf" / group).glob("*.yaml")}


def composed(group: str, option: str):
    return compose([f"{group}={option}", *WITHOUT_TUNED])[group]


def test_every_algo_config_names_a_registered_algorithm_with_a_spec() -> None:
    assert yaml_names("algo") <= set(ALGORITHMS)
    for name in ALGORITHMS:
        spec = algorithm_spec(OmegaConf.create({"name": name}))
        assert isinstance(spec, AlgorithmSpec)


def test_every_controller_config_is_registered() -> None:
    assert yaml_names("controller") <= set(CONTROLLERS)


def test_the_env_axis_names_a_key_of_the_algorithms_own_config() -> None:
    for path in (REPO / "conf" / "algo").glob("*.yaml"):
        cfg = composed("algo", path.stem)
        key, size = algorithm_spec(cfg).env_batch(cfg)
        assert key.startswith("algo.") and size > 0, (path.name, key, size)


def test_an_unregistered_name_is_one_config_error_with_the_choices() -> None:
    with pytest.raises(ConfigError, match=r"algo.name='sac' is not one of rlq's: choose one of ppo, dqn"):
        algorithm_spec(OmegaConf.create({"name": "sac"}))
    with pytest.raises(ConfigError, match="controller.name='pid'"):
        choose(CONTROLLERS, "pid", "controller.name")


def test_importing_the_algorithms_starts_no_jax_backend():
    """A run over several processes joins them (jax.distributed.initialize) after the config, and so every
    algorithm, is imported: an import that started JAX's backend (evosax's does) refused every such run."""
    import subprocess
    import sys

    code = "import rlq.algos, rlq.cli.train; from jax._src import xla_bridge; assert not xla_bridge._backends"
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env={**os.environ, "JAX_PLATFORMS": "cpu"}
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
