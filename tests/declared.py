"""What the declaration tests (tests/{algos,controllers,envs}/test_declarations.py) share: the presets under conf/
that set a group's keys, and the checks that a section of them sets declared keys of their type and range."""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

from rlq.lib import settings
from tests.helpers import REPO

CONF = REPO / "conf"


def plain_yaml(path: Path) -> dict[str, Any]:
    """A yaml file as OmegaConf reads it (``1e-3`` a number, as Hydra reads it), interpolations unresolved."""
    return copy.deepcopy(_loaded(path))


@functools.cache
def _loaded(path: Path) -> dict[str, Any]:
    """Each file read once per test process (OmegaConf's loader: ~17 ms a file, and the presets of three groups
    are read at collection)."""
    data = OmegaConf.to_container(OmegaConf.load(path), resolve=False)
    assert isinstance(data, dict)
    return data


def dotted(node: dict[str, Any], prefix: str = "") -> list[str]:
    """The keys of ``node``, a group's keys below it (``epsilon.start``)."""
    keys = []
    for key, value in node.items():
        keys.append(f"{prefix}{key}")
        if isinstance(value, dict):
            keys.extend(dotted(value, f"{prefix}{key}."))
    return keys


def presets(group: str, owner_of: Callable[[Path], str]) -> list[tuple[str, str]]:
    """(path under conf/, the declaration's name) of every tuned file and experiment with a ``group`` section."""
    paths = [*sorted((CONF / "tuned").rglob("*.yaml")), *sorted((CONF / "experiment").glob("*.yaml"))]
    return [(str(p.relative_to(CONF)), owner_of(p)) for p in paths if group in plain_yaml(p)]


def assert_typed(config: type, values: dict[str, Any], where: str) -> None:
    """Each of ``values`` is of its declared type (1 == 1.0: the types too)."""
    for key, value in values.items():
        assert settings.conforms(value, settings.declared_type(config, key)), (where, key, value)


def assert_declared_typed_in_range(config: type, path: str, group: str, name: str) -> None:
    """The ``group`` section of the preset at ``path`` sets keys that ``config`` declares, of their types, in range."""
    section = plain_yaml(CONF / path)[group]
    known = {key.name for key in settings.declared(config)}
    unknown = [key for key in dotted(section) if key not in known]
    assert not unknown, f"{path}: {group} keys that {group}={name} does not declare: {unknown}"
    assert_typed(config, section, path)
    assert settings.problems(config, section, group) is None


def assert_numeric_keys_ranged(config: type, what: str) -> None:
    numeric = [k.name for k in settings.declared(config) if k.type in (int, float) and k.allowed is None]
    assert not numeric, f"{what}: numeric keys without a range: {numeric}"
