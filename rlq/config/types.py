"""An overridden key keeps the type of its default: integer keys given in float notation (``budget.env_steps=1e6``)
read as integers, any other change of type refused with one line that gives an example."""

from __future__ import annotations

from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

from rlq.errors import ConfigError

#: string keys that false also switches off
SWITCHABLE = ("compile_cache",)
#: keys that take a word or a boolean (auto | true | false), checked by their own code (rlq/run/programs/distributed.py)
WORD_OR_BOOLEAN = ("distributed.enabled",)


def type_name(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean (true/false)"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, (list, ListConfig)):
        return "a list, e.g. [64,64]"
    if isinstance(value, (dict, DictConfig)):
        return "a group of keys"
    return "a string"


def compatible(default: Any, given: Any) -> bool:
    if default is None or given is None:
        return True
    if isinstance(default, bool):
        return isinstance(given, bool)
    if isinstance(default, int):
        return isinstance(given, int) and not isinstance(given, bool)
    if isinstance(default, float):
        return isinstance(given, (int, float)) and not isinstance(given, bool)
    if isinstance(default, (list, ListConfig)):
        return isinstance(given, (list, ListConfig))
    if isinstance(default, (dict, DictConfig)):
        return isinstance(given, (dict, DictConfig))
    return isinstance(given, str)


def _example(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (list, ListConfig)):
        return "[" + ",".join(str(v) for v in value) + "]"
    return str(value)


def integral_floats(defaults: DictConfig, cfg: DictConfig, keys: list[str]) -> dict[str, int]:
    """Integer keys given in float notation (``budget.env_steps=1e6``), as ints."""
    fixed = {}
    for key in keys:
        default = OmegaConf.select(defaults, key, throw_on_missing=False)
        given = OmegaConf.select(cfg, key, throw_on_missing=False)
        is_int = isinstance(default, int) and not isinstance(default, bool)
        if is_int and isinstance(given, float) and given.is_integer():
            fixed[key] = int(given)
    return fixed


def check_types(defaults: DictConfig, cfg: DictConfig, keys: list[str]) -> None:
    """Each overridden key keeps the type of its default (ints stay ints, lists stay lists)."""
    for key in keys:
        default = OmegaConf.select(defaults, key, throw_on_missing=False)
        given = OmegaConf.select(cfg, key, throw_on_missing=False)
        if (key in SWITCHABLE and given is False) or (key in WORD_OR_BOOLEAN and isinstance(given, bool)):
            continue
        if not compatible(default, given):
            raise ConfigError(f"{key} must be {type_name(default)}, got {given!r} (e.g. {key}={_example(default)})")
