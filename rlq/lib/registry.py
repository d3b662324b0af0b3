"""One way to find a named part: a registry maps each name a config may give to what it names. Algorithms and
controllers map to their modules' objects, imported (an editor and the import graph follow them); envs map to
module paths imported on demand (rlq/envs/__init__.py: a CartPole run does not import MuJoCo)."""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from types import ModuleType
from typing import TypeVar

from rlq.errors import ConfigError

T = TypeVar("T")


def choose(registry: Mapping[str, T], name: str, key: str) -> T:
    """``registry[name]``; a name not in it is a ConfigError naming ``key`` and the choices."""
    if name not in registry:
        raise ConfigError(f"{key}={name!r} is not one of rlq's: choose one of {', '.join(registry)}")
    return registry[name]


def load(registry: Mapping[str, str], name: str, key: str) -> ModuleType:
    """The module ``registry[name]`` (a module path), imported; a name not in it is ``choose``'s ConfigError."""
    return importlib.import_module(choose(registry, name, key))
