"""An overridden key keeps the type of its default: integer keys given in float notation (``budget.env_steps=1e6``)
read as integers, any other change of type refused with one line that gives an example."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from rlq.config.plain import select
from rlq.config.store import declared_key, declared_run_key
from rlq.errors import ConfigError

#: string keys that false also switches off
SWITCHABLE = ("compile_cache",)
#: keys that take a word or a boolean (auto | true | false), checked by their own code (rlq/run/programs/distributed.py)
WORD_OR_BOOLEAN = ("distributed.enabled",)


def _is_list(value: Any) -> bool:
    """A list of a composed config (ListConfig), of plain values, or of a RunSpec's read-only values (a tuple)."""
    return isinstance(value, Sequence) and not isinstance(value, str)


def type_name(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean (true/false)"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if _is_list(value):
        return "a list, e.g. [64,64]"
    if isinstance(value, Mapping):
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
    if _is_list(default):
        return _is_list(given)
    if isinstance(default, Mapping):
        return isinstance(given, Mapping)
    return isinstance(given, str)


def example(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if _is_list(value):
        return "[" + ",".join(str(v) for v in value) + "]"
    return str(value)


def given_values(overrides: list[str]) -> dict[str, Any]:
    """The value of each ``key=value`` override as written, read by Hydra's parser (``algo.anneal_lr=3``: 3, which
    the typed node of a boolean key would have made true); not a sweep's nor a ``${...}`` that the config resolves."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    values = {}
    for item in overrides:
        try:
            (override,) = OverridesParser.create().parse_overrides([item])
        except Exception:
            continue  # composing has said what is wrong with it
        value = override.value()
        if override.is_sweep_override() or (isinstance(value, str) and "${" in value):
            continue
        values[override.key_or_group.lstrip("+")] = value
    return values


def check_types(
    defaults: Mapping[str, Any], cfg: Mapping[str, Any], keys: list[str], given_values: Mapping[str, Any] | None = None
) -> None:
    """Each overridden key keeps the type of its default (ints stay ints, lists stay lists); ``given_values``: the
    overrides' values as written, where the composed config has converted them (a schema's typed nodes)."""
    written = given_values or {}
    for key in keys:
        default = select(defaults, key)
        given = written[key] if key in written else select(cfg, key)
        if (key in SWITCHABLE and given is False) or (key in WORD_OR_BOOLEAN and isinstance(given, bool)):
            continue
        if not compatible(default, given):
            raise ConfigError(f"{key} must be {type_name(default)}, got {given!r} (e.g. {key}={example(default)})")


def _whole(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and float(value).is_integer()


def integer_key(key: str, cfg: Mapping[str, Any] | None = None) -> bool:
    """``key`` takes an integer: a run key declared so (rlq/declared/run.py), or, given ``cfg`` (the config of the
    command's group choices, or a recorded run's), a key of the component it chose declared so or one whose value
    there is an integer."""
    run_key = declared_run_key(key)
    if run_key is not None or cfg is None:
        return run_key is not None and run_key.type is int
    declaration = declared_key(cfg, key)
    if declaration is not None:
        return declaration.type is int
    try:
        value = select(cfg, key)
    except Exception:  # an interpolation of Hydra's node that resolves only in a job
        return False
    return isinstance(value, int) and not isinstance(value, bool)


def integers_written(overrides: list[str], integer: Callable[[str], bool], sweeps: bool = True) -> list[str]:
    """``overrides`` with each whole number in float notation of a key that takes an integer written as the integer
    (``budget.env_steps=1e6,2e6``: ``budget.env_steps=1000000,2000000``), the one rewrite of such numbers: a typed node
    takes an integer only so, and Hydra composes a sweep's jobs from the overrides as written. ``integer``: which keys
    take one (``integer_key``; for a sweep's jobs, which may choose other components, the run's keys only: a
    component's is refused there with the integer to write, rlq.config.resolve). ``sweeps``: a sweep's values too
    (``1e6,2e6``), else only single values (one config's line for a sweep quotes it as written)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.core.override_parser.types import ChoiceSweep

    parser = None
    out = []
    for item in overrides:
        key, given, _ = item.partition("=")
        if not given or item.startswith(("-", "~")):
            out.append(item)
            continue
        parser = parser or OverridesParser.create()
        try:
            (override,) = parser.parse_overrides([item])
        except Exception:
            out.append(item)  # composing says what is wrong with it
            continue
        value = override.value()
        values: list[Any] = list(value.list) if isinstance(value, ChoiceSweep) and sweeps else [value]
        whole = any(isinstance(v, float) for v in values) and all(map(_whole, values))
        out.append(f"{key}={','.join(str(int(v)) for v in values)}" if whole and integer(key.lstrip("+")) else item)
    return out
