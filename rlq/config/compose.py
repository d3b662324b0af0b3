"""Compose a run config from conf/ with Hydra's compose API, and the checks of composition itself: known groups,
options and keys, readable overrides, interpolations that resolve; each problem as one line that names the fix."""

from __future__ import annotations

import dataclasses
import difflib
import functools
import re
import typing
from collections.abc import Callable
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf
from omegaconf.errors import ValidationError

from rlq.config.choices import GROUPS, check_choices, group_options
from rlq.config.store import declared_key, declared_run_key, hydra_conf_dir
from rlq.config.types import example, given_values, integer_key, integers_written, type_name
from rlq.errors import ConfigError, UsageError
from rlq.lib import settings

#: overrides that leave the pair's tuned settings out: a component's own defaults (conf/tuned/ is for `rlq train`)
WITHOUT_TUNED = ["~tuned", "~tuned/controller", "~tuned/machine"]


#: config groups whose keys are free (XLA's option names, the env's options): ``+`` adds to them
FREE_KEYS = ("compiler_options", "eval.env", "sweep")


def _closest(word: str, choices: list[str]) -> str | None:
    """The choice ``word`` was most likely meant to be (a typo's correction), if any is close."""
    close = difflib.get_close_matches(word, choices, n=1, cutoff=0.6)
    return close[0] if close else None


def _unknown_key_hint(key: str, overrides: list[str]) -> str:
    """' (did you mean algo.lr?)' for a misspelt ``key``, from the keys of its parent in the composed config."""
    if not overrides and "." not in key:
        return ""
    parent, _, leaf = key.rpartition(".")
    try:
        cfg = compose([o for o in overrides if group_override(o)])
    except Exception:
        return ""
    node = OmegaConf.select(cfg, parent, default=None) if parent else cfg
    if not isinstance(node, DictConfig):
        return ""
    match = _closest(leaf, [str(k) for k in node])
    return f" (did you mean {parent + '.' if parent else ''}{match}?)" if match else ""


def explain_hydra_error(err: Exception, overrides: list[str] | None = None) -> str:
    """One line for an error of Hydra's composition (``overrides``: the command's, for a did-you-mean hint)."""
    refusal = typed_refusal(err)
    if refusal is not None:
        return _typed_line(refusal, overrides or [])
    text = str(err)
    missing = re.search(r"Could not find '([\w/]+)/(\w+)'", text)
    if missing:
        group, option = missing.groups()
        options = group_options(group)
        match = _closest(option, options)
        hint = f"did you mean {group}={match}?" if match else f"e.g. {group}={options[0]}"
        return f"unknown {group} '{option}'; choose one of: {', '.join(options)} ({hint})"
    ambiguous = re.search(r"Ambiguous value for argument '([^']+)'", text)
    if ambiguous:
        return (
            f"{ambiguous.group(1)} gives several values, which is a sweep: add -m "
            f"(rlq train -m {ambiguous.group(1)}), or give one value"
        )
    unknown_key = re.search(r"Key '([\w.]+)' is not in struct", text) or re.search(
        r"Could not override '([\w.]+)'", text
    )
    if unknown_key:
        key = unknown_key.group(1)
        append = re.search(r"To append to your config use (\S+)", text)
        if key in FREE_KEYS and append:
            return f"{key} is a group of free keys, which an override adds to with a leading +: {append.group(1)}"
        free = next((f for f in FREE_KEYS if key.startswith(f + ".")), None)
        hint = f" (a new key of {free} is added with {append.group(1)})" if free and append else ""
        hint = hint or _unknown_key_hint(key, overrides or [])
        return f"unknown config key '{key}'; `rlq train --cfg job` lists the keys{hint}"
    first = next((line for line in text.splitlines() if line.strip()), type(err).__name__).strip()
    override = getattr(err, "override", None)  # Hydra's OverrideParseException names the override it could not read
    if isinstance(override, str):
        return (
            f"cannot read the override '{override}' ({first}); check its brackets and braces, and quote a "
            "value that holds '=', '<' or '>' so that the quotes reach rlq: in a shell, 'key=\"a>=b\"'"
        )
    return first


def compose(overrides: list[str], with_hydra: bool = False) -> DictConfig:
    """Compose the run config as Hydra will, without making a run directory (``with_hydra``:
    keep Hydra's own node, e.g. ``hydra.run.dir``); integer keys of a schema written in float notation
    (``algo.buffer_size=1e5``) read as integers."""
    return compose_typed(overrides, with_hydra)[0]


def compose_typed(overrides: list[str], with_hydra: bool = False) -> tuple[DictConfig, list[str]]:
    """The composed config and the overrides it was composed from: ``overrides`` with every whole number in float
    notation of a key that takes an integer written as the integer (types.integers_written), which a typed node
    takes only so."""
    overrides = integers_written(overrides, integer_keys(overrides), sweeps=False)
    return _compose(overrides, with_hydra), overrides


def integer_keys(overrides: list[str]) -> Callable[[str], bool]:
    """Which keys of the config ``overrides`` compose take an integer (types.integer_key), the config of their
    group choices composed once asked (for a number in float notation) and then kept."""

    @functools.cache
    def chosen() -> DictConfig | None:
        try:
            return _compose([o for o in overrides if group_override(o)], with_hydra=True)
        except Exception:
            return None  # composing the overrides says what is wrong

    return lambda key: integer_key(key, chosen())


def _compose(overrides: list[str], with_hydra: bool) -> DictConfig:
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=hydra_conf_dir(), version_base="1.3"):
            return hydra_compose(config_name="config", overrides=overrides, return_hydra_config=with_hydra)
    finally:
        GlobalHydra.instance().clear()


def typed_refusal(err: Exception) -> ValidationError | None:
    """What a typed node of a schema said of a value that is not of its key's type, where composing raised ``err``
    for it (Hydra's "Error merging override" says which override, its cause which key and value)."""
    cause = err.__cause__
    if isinstance(cause, ValidationError) and cause.full_key:
        return cause
    return None


def _same_kind(value: Any, annotation: Any) -> bool:
    """``value`` is of the kind of the declared type (a number for a number, a list for a list) or null: what the
    key's range says more of than its type (a fraction for an integer, a fraction in a list of integers)."""
    if value is None:
        return True
    if isinstance(value, bool):
        return False
    if annotation in (int, float):
        return isinstance(value, int | float)
    return typing.get_origin(annotation) is tuple and isinstance(value, list)


def _typed_line(refusal: ValidationError, overrides: list[str]) -> str:
    """One line for a value a typed node refused, naming the key: its range where the value is of the key's kind
    (``algo.hidden must be a list of integers >= 1, e.g. [64,64], got [64.5]``), else its type as
    rlq/config/types.py words it (``algo.lr must be a number, got 'abc' (e.g. algo.lr=0.00025)``)."""
    key, item, _ = str(refusal.full_key).partition("[")
    value = given_values(overrides).get(key, refusal.value) if item else refusal.value
    if isinstance(value, DictConfig | ListConfig):
        value = OmegaConf.to_container(value)
    try:
        defaults = compose([o for o in overrides if group_override(o)])
        default = OmegaConf.select(defaults, key)
    except Exception:
        defaults, default = None, None
    declaration = declared_key(defaults, key) if defaults is not None else None
    if declaration is not None and declaration.allowed is not None and _same_kind(value, declaration.type):
        return f"{key} must be {declaration.allowed.allowed()}, got {value!r}"
    run_key = declared_run_key(key) if value is None else None
    line = settings.refusal(run_key, value, key) if run_key is not None else None
    if line is not None:  # null for a run key that takes none: its range or type, as rlq's check of the run words it
        return line
    words = _typed_words(defaults, key) if default is None and defaults is not None else None
    if words is not None:  # a nullable key at its null default: its declared type says what it takes
        return f"{key} must be null or {words}, got {value!r}"
    if default is None:
        first = str(refusal.msg).splitlines()[0] if refusal.msg else type(refusal).__name__
        return f"{refusal.full_key}: {first}"
    if isinstance(default, DictConfig | ListConfig):
        default = OmegaConf.to_container(default)
    return f"{key} must be {type_name(default)}, got {value!r} (e.g. {key}={example(default)})"


#: what ``OmegaConf.select`` returns for a key the config has not
_ABSENT = object()


def check_composes(overrides: list[str]) -> list[str]:
    """The overrides compose (known groups, options and keys; readable syntax): what `rlq train
    --cfg job` needs before Hydra prints the config. Returns them as they compose: an integer key given in float
    notation written as the integer (``compose_typed``), which Hydra's typed node takes only so."""
    check_group_values(overrides)
    check_choices(overrides)
    try:
        return compose_typed(overrides)[1]
    except Exception as err:
        raise ConfigError(explain_hydra_error(err, overrides)) from None


def check_package(overrides: list[str], printed: str, package: str) -> None:
    """``package`` names a node of the config `rlq train --cfg <printed>` prints (``job``: the run's
    config, ``hydra``: Hydra's node, ``all``: both), as ``--package`` asks; Hydra would print a line
    without rlq's prefix and exit 1."""
    if package == "_global_":
        return
    cfg = compose(overrides, with_hydra=printed != "job")
    if printed == "hydra":
        cfg = OmegaConf.create({"hydra": cfg.hydra})
    if OmegaConf.select(cfg, package, default=_ABSENT, throw_on_missing=False) is not _ABSENT:
        return
    parent, node = "", cfg  # the deepest node of the path that exists, whose keys the line lists
    for part in package.split("."):
        child = node.get(part) if isinstance(node, DictConfig) else None
        if not isinstance(child, DictConfig):
            break
        parent, node = f"{parent}.{part}".lstrip("."), child
    where = f"{parent} has" if parent else "its top-level keys are"
    keys = ", ".join(str(k) for k in node)
    raise ConfigError(f"--package {package}: --cfg {printed} prints no such key; {where}: {keys}")


def group_override(item: str) -> bool:
    key = item.split("=", 1)[0].lstrip("+~")
    return key.split("/")[0] in ("env", "controller", "algo", "machine", "tuned", "logger", "experiment", "hydra")


def check_group_values(overrides: list[str]) -> None:
    """A group takes the name of one option (``algo=ppo``), not a dict or list (``algo={}``, ``algo=[ppo]``):
    Hydra would take ``algo={}`` as the config itself and fail while the job runs."""
    for item in overrides:
        key, _, value = item.partition("=")
        group = key.lstrip("+~")
        if group.split("/")[0] in GROUPS and "." not in group and value.strip().startswith(("{", "[")):
            options = group_options(group)
            raise UsageError(
                f"{group}={value}: {group} takes the name of one option ({', '.join(options)}); "
                f"set its keys one by one, e.g. {group}.<key>=<value>"
            )


def check_added_keys(defaults: DictConfig, overrides: list[str]) -> None:
    """Keys added with ``+``/``++`` (which Hydra accepts anywhere) exist in the config or belong to
    a group of free keys: a misspelt ``+algo.lrr=1e-3`` would otherwise be ignored without a word."""
    for item in overrides:
        if not item.startswith("+") or group_override(item):
            continue
        key = item.split("=", 1)[0].lstrip("+")
        if key.startswith("hydra.") or any(key == f or key.startswith(f + ".") for f in FREE_KEYS):
            continue
        if OmegaConf.select(defaults, key, default=_ABSENT) is _ABSENT:
            raise ConfigError(
                f"unknown config key '{key}' (in {item}); a leading + adds keys only to {' and '.join(FREE_KEYS)}: "
                "`rlq train --cfg job` lists the keys"
            )


def _typed_words(cfg: DictConfig, key: str) -> str | None:
    """What the declared type of ``key`` takes, in the words of rlq/config/types.py (``a number``)."""
    declaration = declared_key(cfg, key)
    if declaration is None:
        return None
    kind = declaration.type
    if typing.get_origin(kind) is dict or dataclasses.is_dataclass(kind):
        return type_name({})
    sample = {int: 0, float: 0.5, bool: True, str: ""}.get(kind, [])
    return type_name(sample)


def check_interpolations(cfg: DictConfig) -> None:
    """Every ``${...}`` of the run's config (Hydra's own node aside) resolves: one line, not OmegaConf's traceback."""
    from omegaconf.errors import OmegaConfBaseException

    for key in (str(k) for k in cfg):
        if key == "hydra":
            continue
        try:
            node = cfg[key]
            if isinstance(node, DictConfig):
                OmegaConf.to_container(node, resolve=True)
        except OmegaConfBaseException as err:
            where = getattr(err, "full_key", None) or key
            resolved = re.search(r"Value '(.*)' of type", str(err))
            if isinstance(err, ValidationError) and resolved:  # a ${...} whose value a typed node refuses
                default = OmegaConf.select(cfg, where, throw_on_resolution_failure=False)
                words = _typed_words(cfg, where) or (type_name(default) if default is not None else "another value")
                raise ConfigError(f"{where} must be {words}, got {resolved.group(1)!r}") from None
            first = str(err).splitlines()[0] if str(err) else type(err).__name__
            raise ConfigError(
                f"{where}: {first}; a ${{...}} names another key of the config (`rlq train --cfg job` lists them)"
            ) from None
