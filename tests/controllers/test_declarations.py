"""Each controller declares its keys (``Config`` in its module); conf/controller/<name>.yaml holds exactly the
declared defaults, and every controller section of a tuned file or an experiment sets declared keys only, each of
its type and in its range."""

from __future__ import annotations

from pathlib import Path

import pytest
from omegaconf import OmegaConf

from rlq.controllers import CONTROLLERS, controller_config
from rlq.lib import settings
from tests.algos.test_declarations import CONF, dotted, plain_yaml


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
    paths = [*sorted((CONF / "tuned").rglob("*.yaml")), *sorted((CONF / "experiment").glob("*.yaml"))]
    return [(str(p.relative_to(CONF)), controller_of(p)) for p in paths if "controller" in plain_yaml(p)]


@pytest.mark.parametrize("name", list(CONTROLLERS))
def test_the_controller_yaml_holds_the_declared_defaults(name: str) -> None:
    config = declaration(name)
    preset = plain_yaml(CONF / "controller" / f"{name}.yaml")
    assert preset == settings.defaults(config)
    for key, value in preset.items():
        assert settings.conforms(value, settings.declared_type(config, key)), (name, key, value)
    numeric = [k.name for k in settings.declared(config) if k.type in (int, float) and k.allowed is None]
    assert not numeric, f"controller={name}: numeric keys without a range: {numeric}"


@pytest.mark.parametrize(("path", "name"), presets())
def test_every_tuned_and_experiment_controller_key_is_declared_typed_and_in_range(path: str, name: str) -> None:
    config = declaration(name)
    section = plain_yaml(CONF / path)["controller"]
    known = {key.name for key in settings.declared(config)}
    unknown = [key for key in dotted(section) if key not in known]
    assert not unknown, f"{path}: controller keys that controller={name} does not declare: {unknown}"
    for key, value in section.items():
        assert settings.conforms(value, settings.declared_type(config, key)), (path, key, value)
    assert settings.problems(config, section, "controller") is None
