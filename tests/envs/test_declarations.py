"""Each env declares its keys (``ENV_CONFIGS``: type, default, range); conf/env/<name>.yaml, with the groups it
composes (env/physics), holds exactly the declared defaults, and every env section of a tuned file or an experiment
sets declared keys only, each of its type and in its range."""

from __future__ import annotations

from pathlib import Path

import pytest
from omegaconf import OmegaConf

from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.envs import ENV_CONFIGS, env_config
from rlq.lib import settings
from tests.algos.test_declarations import CONF, dotted, plain_yaml


def declaration(name: str) -> type:
    return env_config(OmegaConf.create({"name": name}))


def env_of(path: Path) -> str:
    """The env a preset sets keys of: an experiment's ``override /env``, a tuned file's ``<env>_...`` name."""
    for entry in plain_yaml(path).get("defaults", []):
        if isinstance(entry, dict) and "override /env" in entry:
            return str(entry["override /env"])
    named = [e for e in ENV_CONFIGS if path.stem.startswith(f"{e}_")]
    assert named, path
    return max(named, key=len)


def presets() -> list[tuple[str, str]]:
    paths = [*sorted((CONF / "tuned").rglob("*.yaml")), *sorted((CONF / "experiment").glob("*.yaml"))]
    return [(str(p.relative_to(CONF)), env_of(p)) for p in paths if "env" in plain_yaml(p)]


@pytest.mark.parametrize("name", list(ENV_CONFIGS))
def test_the_env_yaml_holds_the_declared_defaults(name: str) -> None:
    config = declaration(name)
    composed = OmegaConf.to_container(compose([f"env={name}", *WITHOUT_TUNED]).env, resolve=False)
    assert isinstance(composed, dict)
    assert composed == settings.defaults(config)
    for key, value in composed.items():
        assert settings.conforms(value, settings.declared_type(config, key)), (name, key, value)
    numeric = [k.name for k in settings.declared(config) if k.type in (int, float) and k.allowed is None]
    assert not numeric, f"env={name}: numeric keys without a range: {numeric}"


@pytest.mark.parametrize(("path", "name"), presets())
def test_every_tuned_and_experiment_env_key_is_declared_typed_and_in_range(path: str, name: str) -> None:
    config = declaration(name)
    section = plain_yaml(CONF / path)["env"]
    known = {key.name for key in settings.declared(config)}
    unknown = [key for key in dotted(section) if key not in known]
    assert not unknown, f"{path}: env keys that env={name} does not declare: {unknown}"
    for key, value in section.items():
        assert settings.conforms(value, settings.declared_type(config, key)), (path, key, value)
    assert settings.problems(config, section, "env") is None


def test_the_fast_physics_preset_sets_declared_keys_in_range() -> None:
    env = compose(["env=brittle_star", "env/physics=fast", *WITHOUT_TUNED]).env
    config = declaration("brittle_star")
    assert {key.name for key in settings.declared(config)} >= set(dotted(OmegaConf.to_container(env)))
    assert settings.problems(config, env, "env") is None
