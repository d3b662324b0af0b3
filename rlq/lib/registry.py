"""One way to find a named part: a registry maps each name a config may give to the module that holds it."""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from types import ModuleType

from rlq.errors import ConfigError


def load(registry: Mapping[str, str], name: str, key: str) -> ModuleType:
    """The module ``registry[name]``; a name not in it is a ConfigError naming ``key`` and the choices."""
    if name not in registry:
        raise ConfigError(f"{key}={name!r} is not one of rlq's: choose one of {', '.join(registry)}")
    return importlib.import_module(registry[name])
