"""One home for defaults: where an env class's constructor gives a default for a setting that the env's yaml
(conf/env/<name>.yaml) also sets, the two agree, so a run built from the yaml and an env built in code are
the same env."""

from __future__ import annotations

import importlib
import inspect

import pytest
from omegaconf import OmegaConf

from rlq.envs import ENVS, Env
from tests.helpers import REPO

SCALARS = (bool, int, float, str, type(None))


def env_classes(module_name: str) -> list[type[Env]]:
    module = importlib.import_module(module_name)
    return [
        cls
        for cls in vars(module).values()
        if inspect.isclass(cls) and issubclass(cls, Env) and cls.__module__ == module.__name__
    ]


def shared_defaults(name: str) -> list[tuple[str, str, object, object]]:
    """(class, key, constructor default, yaml value) for every scalar setting both give."""
    yaml = OmegaConf.to_container(OmegaConf.load(REPO / "conf" / "env" / f"{name}.yaml"))
    assert isinstance(yaml, dict)
    pairs = []
    for cls in env_classes(ENVS[name]):
        for param in inspect.signature(cls.__init__).parameters.values():
            if param.default is inspect.Parameter.empty or param.name not in yaml:
                continue
            value = yaml[param.name]
            if isinstance(param.default, SCALARS) and isinstance(value, SCALARS):
                pairs.append((cls.__name__, param.name, param.default, value))
    return pairs


@pytest.mark.parametrize("name", sorted(ENVS))
def test_constructor_defaults_match_the_yaml(name: str) -> None:
    pairs = shared_defaults(name)
    differ = [(cls, key, default, value) for cls, key, default, value in pairs if default != value]
    assert not differ, f"constructor default != conf/env/{name}.yaml: {differ}"


def test_the_check_reaches_the_envs_whose_constructors_take_defaults() -> None:
    assert len(shared_defaults("lunar")) >= 5
    assert shared_defaults("humanoid") or shared_defaults("brittle_star")
