"""Each controller declares its keys (``CONTROLLER_CONFIGS``, rlq/declared/controllers/); composing
conf/controller/<name>.yaml gives exactly the declared defaults, and every controller section of a tuned file or an experiment sets declared keys only, each of
its type and in its range."""

from __future__ import annotations

from pathlib import Path

import pytest
from omegaconf import OmegaConf

from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.controllers import CONTROLLERS, controller_config
from rlq.lib import settings
from tests.declared import assert_declared_typed_in_range, assert_numeric_keys_ranged, assert_typed, plain_yaml
from tests.declared import presets as declared_presets


def declaration(name: str) -> type:
    return controller_config(OmegaConf.create({"name": name}))


def controller_of(path: Path) -> str:
    """The controller a preset sets keys of: an experiment's ``override /controller``, a tuned file's last word."""
    for entry in plain_yaml(path).get("defaults", []):
        if isinstance(entry, dict) and "override /controller" in entry:
            return str(entry["override /controller"])
    name = path.stem.rsplit("_", 1)[-1]
    assert name in CONTROLLERS, path
    return name


def presets() -> list[tuple[str, str]]:
    return declared_presets("controller", controller_of)


@pytest.mark.parametrize("name", list(CONTROLLERS))
def test_the_controller_yaml_holds_the_declared_defaults(name: str) -> None:
    config = declaration(name)
    preset = OmegaConf.to_container(compose([f"controller={name}", *WITHOUT_TUNED]).controller, resolve=False)
    assert isinstance(preset, dict)
    assert preset == settings.defaults(config)
    assert_typed(config, preset, name)
    assert_numeric_keys_ranged(config, f"controller={name}")


@pytest.mark.parametrize(("path", "name"), presets())
def test_every_tuned_and_experiment_controller_key_is_declared_typed_and_in_range(path: str, name: str) -> None:
    assert_declared_typed_in_range(declaration(name), path, "controller", name)
