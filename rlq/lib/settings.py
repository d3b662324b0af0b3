"""Typed settings: a component declares its config section as a frozen dataclass whose fields carry each key's
type (the annotation), default and allowed values (``setting(default, allowed)``, kept in the field's metadata).

``typed(Config, node, prefix)`` builds the component's frozen ``Config`` from its composed section: what the runner
hands to ``make``/``check``, so that no component reads Hydra's composed config. ``problems(Config, node, prefix)`` checks a composed section against the declaration and names the first key
whose value is not allowed, as one line (``algo.lr must be a number > 0, got 0``). A field typed ``X | None``
also takes null, so the range need not say so. Rules across keys stay in the component's ``check``.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from types import NoneType, UnionType
from typing import Any, TypeVar

from rlq.errors import ConfigError

T = TypeVar("T")


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


#: how a refusal names null where a key takes it, unless the key says what null means (``null (read from SLURM)``)
NULL = "null"


@dataclass(frozen=True)
class Range:
    """A number in [low, high] (open ends with ``low_open``/``high_open``); ``integer``: whole numbers only;
    ``null``: how a refusal names null where the key takes it (what null means)."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    nullable: bool = False
    null: str = NULL

    def _text(self, bound: float) -> str:
        return str(int(bound)) if self.integer else f"{bound:g}"

    def allowed(self) -> str:
        kind = "an integer" if self.integer else "a number"
        if self.low is not None and self.high is not None:
            left, right = "(" if self.low_open else "[", ")" if self.high_open else "]"
            text = f"{kind} in {left}{self._text(self.low)}, {self._text(self.high)}{right}"
        elif self.low is not None:
            text = f"{kind} {'>' if self.low_open else '>='} {self._text(self.low)}"
        elif self.high is not None:
            text = f"{kind} {'<' if self.high_open else '<='} {self._text(self.high)}"
        else:
            text = f"{kind}"
        return f"{self.null} or {text}" if self.nullable else text

    def accepts(self, value: Any) -> bool:
        if value is None:
            return self.nullable
        if not _number(value) or not math.isfinite(value):
            return False
        if self.integer and not float(value).is_integer():
            return False
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            return False
        return not (self.high is not None and (value > self.high or (self.high_open and value == self.high)))


def _choice_text(choice: str | bool) -> str:
    """A choice as it is written: a name, or a boolean as yaml writes it."""
    return str(choice).lower() if isinstance(choice, bool) else choice


@dataclass(frozen=True)
class OneOf:
    """One of a fixed set of names, or booleans (``auto``, true or false); ``null``: as ``Range``'s."""

    choices: tuple[str | bool, ...]
    nullable: bool = False
    null: str = NULL

    def allowed(self) -> str:
        names = ", ".join(_choice_text(choice) for choice in self.choices)
        return (f"{self.null} or " if self.nullable else "") + "one of " + names

    def accepts(self, value: Any) -> bool:
        """``value`` is a choice of the choice's type (true, not 1)."""
        if value is None:
            return self.nullable
        return any(type(value) is type(choice) and value == choice for choice in self.choices)


@dataclass(frozen=True)
class Sizes:
    """A list of whole numbers >= ``low`` (layer widths, cells per archive dimension, component
    indices), never floats that would be truncated; null when ``nullable``."""

    nullable: bool = False
    low: int = 1
    example: str = "[64,64]"

    def allowed(self) -> str:
        return ("null or " if self.nullable else "") + f"a list of integers >= {self.low}, e.g. {self.example}"

    def accepts(self, value: Any) -> bool:
        if value is None:
            return self.nullable
        if not isinstance(value, Sequence) or isinstance(value, str):
            return False
        return all(isinstance(v, int) and not isinstance(v, bool) and v >= self.low for v in value)


Constraint = Range | OneOf | Sizes

POSITIVE_INT = Range(1, integer=True)
COUNT = Range(0, integer=True)
#: JAX's PRNG takes a seed as two 32-bit words, and rlq folds each seed's index into it: an unsigned 32-bit seed
SEED = Range(0, 2**32 - 1, integer=True)
#: the run's step and update counters are 32-bit integers on the device (JAX's default)
BUDGET = Range(1, 2**31 - 1, integer=True)
PROBABILITY = Range(0.0, 1.0)
POSITIVE = Range(0.0, low_open=True)
NON_NEGATIVE = Range(0.0)
#: any finite number (no NaN or Inf): a key whose bounds another check states in its own words (the env's, the
#: algorithm's), or one that means something at any value (a genotype bound, a reward weight)
FINITE = Range()
WHOLE = Range(integer=True)

#: the metadata key of a field's allowed values
ALLOWED = "allowed"


def setting(default: T, allowed: Constraint | None = None) -> T:
    """A declared key: its default and the values it allows (None: any value of its type, e.g. a name that the
    component's ``check`` reads against the env)."""
    return dataclasses.field(default=default, metadata={ALLOWED: allowed})


def optional_type(annotation: Any) -> tuple[Any, bool]:
    """The type ``X`` of ``X | None``, and whether None was in it (a declared key has one type besides None)."""
    if isinstance(annotation, UnionType) or typing.get_origin(annotation) is typing.Union:
        args = [a for a in typing.get_args(annotation) if a is not NoneType]
        if len(args) == 1:
            return args[0], len(typing.get_args(annotation)) > 1
    return annotation, False


@dataclass(frozen=True)
class Declared:
    """One declared key: its dotted name within the section, type (``X`` of ``X | None``), default and allowed
    values (nullable where the type takes None)."""

    name: str
    type: Any
    nullable: bool
    default: Any
    allowed: Constraint | None


def _is_declaration(annotation: Any) -> bool:
    return isinstance(annotation, type) and dataclasses.is_dataclass(annotation)


def declared(config: type, prefix: str = "") -> Iterator[Declared]:
    """Every key of the declaration ``config`` in field order, a nested declaration's keys (``epsilon.start``) in
    its field's place after the group itself."""
    hints = typing.get_type_hints(config)
    for f in dataclasses.fields(config):
        inner, nullable = optional_type(hints[f.name])
        allowed = f.metadata.get(ALLOWED)
        if allowed is not None and nullable and not allowed.nullable:
            allowed = dataclasses.replace(allowed, nullable=True)
        yield Declared(f"{prefix}{f.name}", inner, nullable, f.default, allowed)
        if _is_declaration(inner):
            yield from declared(inner, f"{prefix}{f.name}.")


def declared_type(config: type, name: str) -> Any:
    """The annotation of ``config``'s key ``name``, as declared (``X | None`` with its None)."""
    return typing.get_type_hints(config)[name]


_ABSENT = object()


def _get(node: Mapping[str, Any] | None, name: str) -> Any:
    for part in name.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return _ABSENT
        node = node[part]
    return node


def problems(config: type, node: Mapping[str, Any], prefix: str) -> str | None:
    """The first key of section ``node`` (``prefix``: its name, ``algo``; empty for the run's own keys) whose value
    its declaration ``config`` does not allow, as one line; None when all fit. Keys the section has not (a null
    group's) are not checked."""
    for key in declared(config):
        if key.allowed is None:
            continue
        value = _get(node, key.name)
        if value is not _ABSENT and not key.allowed.accepts(value):
            name = f"{prefix}.{key.name}" if prefix else key.name
            return f"{name} must be {key.allowed.allowed()}, got {value!r}"
    return None


#: how a refusal names a declared type
_KINDS = {bool: "a boolean (true/false)", int: "an integer", float: "a number", str: "a string"}
#: how a refusal names the items of a declared list
_ITEMS = {bool: "booleans", int: "integers", float: "numbers", str: "strings"}


def kind(key: Declared) -> str:
    """What the declared type of ``key`` takes, in a refusal's words (``null or a list of strings``)."""
    origin = typing.get_origin(key.type)
    if origin is tuple:
        words = f"a list of {_ITEMS.get(typing.get_args(key.type)[0], 'values')}"
    else:
        words = "a group of keys" if origin is dict or _is_declaration(key.type) else _KINDS.get(key.type, "")
    return f"null or {words}" if key.nullable else words


def refusal(key: Declared, value: Any, name: str) -> str | None:
    """The line refusing ``value`` for the key ``key`` (``name``: its dotted name): its range or choices where it
    declares them, else its type; None where the declaration takes it."""
    if key.allowed is not None:
        return None if key.allowed.accepts(value) else f"{name} must be {key.allowed.allowed()}, got {value!r}"
    if key.type is Any or conforms(value, key.type | None if key.nullable else key.type):
        return None
    return f"{name} must be {kind(key)}, got {value!r}"


def conforms(value: Any, annotation: Any) -> bool:
    """``value`` (plain yaml: lists, dicts, numbers, strings) is of type ``annotation``: ``int``, ``float`` (an
    int too), ``bool``, ``str``, ``tuple[X, ...]`` (a list), ``dict[...]`` (any mapping), ``X | None`` or a declaration
    (a dict of its keys)."""
    inner, nullable = optional_type(annotation)
    if value is None:
        return nullable
    if _is_declaration(inner):
        if not isinstance(value, Mapping):
            return False
        hints = typing.get_type_hints(inner)
        return all(key in hints and conforms(item, hints[key]) for key, item in value.items())
    if typing.get_origin(inner) is dict:
        return isinstance(value, Mapping)
    if typing.get_origin(inner) is tuple:
        (item_type, _) = typing.get_args(inner)
        return isinstance(value, Sequence) and not isinstance(value, str) and all(conforms(v, item_type) for v in value)
    if inner is float:
        return _number(value)
    if inner is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, inner)


def plain(value: Any) -> Any:
    """A declared default as yaml reads it: tuples as lists, a declaration as a dict of its keys."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, tuple):
        return [plain(v) for v in value]
    return value


def defaults(config: type) -> dict[str, Any]:
    """The declaration's defaults as the yaml preset of the same keys would hold them."""
    return {f.name: plain(f.default) for f in dataclasses.fields(config)}


def _data(value: Any) -> Any:
    """``value`` (a mapping or list of a composed section, e.g. a ``dict[str, Any]`` key's) as plain dicts and lists."""
    if isinstance(value, Mapping):
        return {str(key): _data(item) for key, item in value.items()}
    if isinstance(value, Sequence) and not isinstance(value, str):
        return [_data(item) for item in value]
    return value


def _typed_value(value: Any, annotation: Any, name: str) -> Any:
    """``value`` of key ``name`` as its declared type: a declaration from its group of keys, a tuple from a list, a
    float from an integer; a ConfigError where it is not of that type."""
    inner, nullable = optional_type(annotation)
    if value is None:
        if nullable:
            return None
    elif _is_declaration(inner):
        if isinstance(value, inner):
            return value
        if isinstance(value, Mapping):
            return typed(inner, value, name)
    elif inner is Any:
        return _data(value)
    elif typing.get_origin(inner) is dict:
        if isinstance(value, Mapping):
            return _data(value)
    elif typing.get_origin(inner) is tuple:
        if isinstance(value, Sequence) and not isinstance(value, str):
            (item_type, _) = typing.get_args(inner)
            return tuple(_typed_value(item, item_type, f"{name}[{i}]") for i, item in enumerate(value))
    elif inner is float:
        if _number(value):
            return float(value)
    elif inner is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif isinstance(value, inner):
        return value
    mapping = typing.get_origin(inner) is dict or dataclasses.is_dataclass(inner)
    kind = "a group of keys" if mapping else f"of type {getattr(inner, '__name__', str(inner))}"
    raise ConfigError(f"{name} must be {'null or ' if nullable else ''}{kind}, got {value!r}")


def typed(config: type[T], node: Mapping[str, Any] | T, prefix: str) -> T:
    """The declaration ``config`` (a frozen dataclass) with the values of section ``node`` (``prefix``: its name,
    ``algo``), the defaults for keys it does not set; ``node`` already a ``config``: itself. A key the declaration
    lacks, or a value not of its key's type, is a ConfigError that names it."""
    if isinstance(node, config):
        return node
    if not isinstance(node, Mapping):
        raise ConfigError(f"{prefix} must be a group of keys, got {node!r}")
    hints = typing.get_type_hints(config)
    unknown = [str(key) for key in node if key not in hints]
    if unknown:
        raise ConfigError(f"{prefix}.{unknown[0]} is not a key of {prefix}; its keys are: {', '.join(hints)}")
    values = {str(key): _typed_value(node[key], hints[str(key)], f"{prefix}.{key}") for key in node}
    return config(**values)
