"""Each env declares its keys (``ENV_CONFIGS``, rlq/declared/envs/: type, default, range); composing
conf/env/<name>.yaml, with the groups it composes (env/physics), gives exactly the declared defaults, and every env section of a tuned file or an experiment
sets declared keys only, each of its type and in its range."""

from __future__ import annotations

from pathlib import Path

import pytest
from omegaconf import OmegaConf

from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.envs import ENV_CONFIGS, env_config
from rlq.lib import settings
from tests.declared import assert_declared_typed_in_range, assert_numeric_keys_ranged, assert_typed, dotted, plain_yaml
from tests.declared import presets as declared_presets


def declaration(name: str) -> type:
    return env_config(OmegaConf.create({"name": name}))


def env_of(path: Path) -> str:
    """The env a preset sets keys of: an experiment's ``override /env``, a tuned file's ``<env>_...`` name; the shared
    physics files (conf/tuned/physics/) are the brittle star's, whose physics keys both brittle stars declare."""
    if path.parent.name == "physics":
        return "brittle_star"
    for entry in plain_yaml(path).get("defaults", []):
        if isinstance(entry, dict) and "override /env" in entry:
            return str(entry["override /env"])
    named = [e for e in ENV_CONFIGS if path.stem.startswith(f"{e}_")]
    assert named, path
    return max(named, key=len)


def presets() -> list[tuple[str, str]]:
    return declared_presets("env", env_of)


@pytest.mark.parametrize("name", list(ENV_CONFIGS))
def test_the_env_yaml_holds_the_declared_defaults(name: str) -> None:
    config = declaration(name)
    composed = OmegaConf.to_container(compose([f"env={name}", *WITHOUT_TUNED]).env, resolve=False)
    assert isinstance(composed, dict)
    assert composed == settings.defaults(config)
    assert_typed(config, composed, name)
    assert_numeric_keys_ranged(config, f"env={name}")


@pytest.mark.parametrize(("path", "name"), presets())
def test_every_tuned_and_experiment_env_key_is_declared_typed_and_in_range(path: str, name: str) -> None:
    assert_declared_typed_in_range(declaration(name), path, "env", name)


def test_the_fast_physics_preset_sets_declared_keys_in_range() -> None:
    env = compose(["env=brittle_star", "env/physics=fast", *WITHOUT_TUNED]).env
    config = declaration("brittle_star")
    assert {key.name for key in settings.declared(config)} >= set(dotted(OmegaConf.to_container(env)))
    assert settings.problems(config, env, "env") is None
