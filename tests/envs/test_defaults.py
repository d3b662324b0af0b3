"""One home for defaults: where an env class's constructor gives a default for a setting that the env's declaration
(rlq/declared/envs/) also declares, the two agree, so a run built from the config and an env built in code are the
same env."""

from __future__ import annotations

import importlib
import inspect

import pytest

from rlq.envs import ENV_CONFIGS, ENVS, Env
from rlq.lib import settings

SCALARS = (bool, int, float, str, type(None))


def env_classes(module_name: str) -> list[type[Env]]:
    module = importlib.import_module(module_name)
    return [
        cls
        for cls in vars(module).values()
        if inspect.isclass(cls) and issubclass(cls, Env) and cls.__module__ == module.__name__
    ]


def shared_defaults(name: str) -> list[tuple[str, str, object, object]]:
    """(class, key, constructor default, declared default) for every scalar setting both give."""
    yaml = settings.defaults(ENV_CONFIGS[name])
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
def test_constructor_defaults_match_the_declaration(name: str) -> None:
    pairs = shared_defaults(name)
    differ = [(cls, key, default, value) for cls, key, default, value in pairs if default != value]
    assert not differ, f"constructor default != rlq/declared/envs/ default of env={name}: {differ}"


def test_the_check_reaches_the_envs_whose_constructors_take_defaults() -> None:
    assert len(shared_defaults("lunar")) >= 5
    assert shared_defaults("humanoid") or shared_defaults("brittle_star")
