"""The declarations of rlq/declared/ as Hydra's structured configs: each algorithm's, env's and controller's ``Config``
is registered in Hydra's ConfigStore as the schema ``<name>_schema`` of its group (``algo``, ``env``,
``controller``), which conf/<group>/<name>.yaml names first in its defaults list, and the run's own (rlq/declared/run.py)
as the primary config's schema ``run_schema``, which conf/config.yaml names first. Composing ``algo=ppo`` or
``env=lunar`` so builds a typed node in struct mode from the declaration: its defaults, and each key's type checked
as it is set (by an override, a nested group such as env/physics, a tuned file or an experiment) and every unknown
key refused. The ranges stay rlq's (``rlq.lib.settings.problems``, before anything compiles).

OmegaConf takes no frozen dataclass (its nodes would be read-only), no ``tuple[int, ...]`` and no ``X | None``, so
``schema`` derives a plain dataclass with the declaration's fields and defaults (lists for tuples, ``Optional``):
the declaration stays the one home of a key's type, default and range. ``hydra_conf_dir`` is how rlq hands conf/ to
Hydra (``compose``, ``hydra.main``): it registers the schemas first, in the ConfigStore there is then, so no config
is composed without them.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import typing
from collections.abc import Mapping
from typing import Any, Optional

from rlq.config.conf_dir import CONF_DIR
from rlq.declared import ALGORITHM_CONFIGS, run
from rlq.declared.controllers import CONTROLLER_CONFIGS
from rlq.declared.envs import ENV_CONFIGS
from rlq.lib.settings import Declared, declared, optional_type, plain

#: the name of a declaration's schema in its group: ``algo/ppo_schema``
SCHEMA = "{name}_schema"

#: the primary config's schema (``run_schema``): the run's own keys (rlq/declared/run.py)
RUN_SCHEMA = "run_schema"
#: the groups whose options are components with schemas of their own: untyped slots of the run's schema
COMPONENT_GROUPS = ("controller", "env", "algo")
#: the run's groups chosen from conf/machine/ and conf/logger/: their keys are declared in rlq/declared/run.py
RUN_GROUPS = ("machine", "logger")

#: the declarations registered as schemas, by group and name (``env=lunar``)
DECLARED: dict[str, dict[str, type]] = {"algo": ALGORITHM_CONFIGS, "env": ENV_CONFIGS, "controller": CONTROLLER_CONFIGS}


def _schema_type(annotation: Any, run_key: bool = False) -> Any:
    """The type OmegaConf takes for a declared ``annotation``: a nested declaration's schema (``Any`` for one that may
    be null), ``list[X]`` for ``tuple[X, ...]``, ``dict[str, Any]`` for a mapping, ``Optional`` for ``X | None``
    (``Any`` for a ``run_key``'s)."""
    inner, nullable = optional_type(annotation)
    if run_key and (nullable or typing.get_origin(inner) is dict):
        # a run key that takes null (init_from, video.at_end, guard.max_abs_loss) stays an untyped value: a typed node
        # would convert init_from=1 to '1' and video.at_end=3 to true, which rlq's check of the run's values
        # (rlq/run/checks/constraints.py) names as written, with the declaration's type or range; and so does a group
        # of free-form options (compiler_options, eval.env, sweep), which the code that reads it checks
        return Any
    if dataclasses.is_dataclass(inner) and isinstance(inner, type):
        # a group that may be null (random search's archive) stays an untyped value: OmegaConf cannot set a null
        # group, typed or a mapping, from an override (algo.archive={shape:[4,4]}); the declaration checks its keys
        # and types as the run's Config is built (rlq.lib.settings.typed), its ranges before compiling
        if nullable:
            return Any
        inner = schema(inner)
    elif typing.get_origin(inner) is tuple:
        inner = list[typing.get_args(inner)[0]]  # type: ignore[misc]
    elif typing.get_origin(inner) is dict:
        if nullable:  # as a nullable group: OmegaConf cannot merge an override's mapping into a null dict node
            return Any
        inner = dict[str, Any]
    return Optional[inner] if nullable else inner  # noqa: UP045 (OmegaConf reads typing's Optional)


def _value(value: Any, annotation: Any) -> Any:
    """A declared default as the schema's: a nested declaration's as its schema's instance (a nullable one's as a
    mapping), tuples as lists."""
    if optional_type(annotation)[1]:
        return plain(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        hints = typing.get_type_hints(type(value))
        fields = dataclasses.fields(value)
        return schema(type(value))(**{f.name: _value(getattr(value, f.name), hints[f.name]) for f in fields})
    return list(value) if isinstance(value, tuple) else value


def _fields(config: type) -> list[tuple[str, Any, Any]]:
    """The schema's fields of the declaration ``config``: name, the type OmegaConf takes, the default."""
    hints = typing.get_type_hints(config)
    fields = []
    for f in dataclasses.fields(config):
        given = f.default if f.default_factory is dataclasses.MISSING else f.default_factory()
        default = _value(given, hints[f.name])
        if isinstance(default, list | dict) or dataclasses.is_dataclass(default):  # mutable: one per instance
            field = dataclasses.field(default_factory=functools.partial(copy.deepcopy, default))
        else:
            field = dataclasses.field(default=default)
        fields.append((f.name, _schema_type(hints[f.name], config.__module__ == run.__name__), field))
    return fields


def _made(name: str, fields: list[tuple[str, Any, Any]]) -> type:
    made = dataclasses.make_dataclass(name, fields)
    made.__module__ = __name__  # pickled by reference (a sweep's launcher pickles the composed config): __getattr__
    return made


@functools.cache
def schema(config: type) -> type:
    """The structured config OmegaConf builds a node from for the declaration ``config`` (a frozen dataclass of
    rlq.lib.settings): the same fields, types and defaults, mutable (``rlq_declared_ppo_Config``)."""
    return _made(_schema_name(config), _fields(config))


@functools.cache
def run_schema() -> type:
    """The primary config's schema (``run_schema``, first in conf/config.yaml's defaults list): the run's own keys as
    rlq/declared/run.py declares them, after an untyped slot for each component group (``controller``, ``env``,
    ``algo``: their own schemas' nodes are composed into it). The groups come first, in the defaults list's order,
    so that the composed config lists its keys in the order conf/config.yaml gave them."""
    fields = {name: (name, kind, field) for name, kind, field in _fields(run.Config)}
    slots = [(group, Any, dataclasses.field(default=None)) for group in COMPONENT_GROUPS]
    first = [fields.pop(group) for group in RUN_GROUPS]
    return _made(_schema_name(run.Config), [*slots, *first, *fields.values()])


def _schema_name(config: type) -> str:
    return f"{config.__module__.replace('.', '_')}_{config.__name__}"


def _declarations(config: type) -> list[type]:
    """``config`` and the declarations nested in it."""
    hints = typing.get_type_hints(config)
    nested = [optional_type(hints[f.name])[0] for f in dataclasses.fields(config)]
    return [
        config,
        *(d for n in nested if isinstance(n, type) and dataclasses.is_dataclass(n) for d in _declarations(n)),
    ]


def __getattr__(name: str) -> type:
    """A schema by its class name, as unpickling a composed config asks for it in another process."""
    if name == _schema_name(run.Config):
        return run_schema()
    for config in (*(c for configs in DECLARED.values() for c in configs.values()), run.Config):
        for declaration in _declarations(config):
            if _schema_name(declaration) == name and declaration is not run.Config:
                return schema(declaration)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@functools.cache
def _schema_paths() -> dict[str, tuple[str | None, str, type]]:
    """Each schema's path in the ConfigStore (``algo/ppo_schema.yaml``): its group, name and structured config."""
    paths: dict[str, tuple[str | None, str, type]] = {f"{RUN_SCHEMA}.yaml": (None, RUN_SCHEMA, run_schema())}
    for group, configs in DECLARED.items():
        for name, config in configs.items():
            paths[f"{group}/{SCHEMA.format(name=name)}.yaml"] = (group, SCHEMA.format(name=name), schema(config))
    return paths


def register_schemas() -> None:
    """Every declaration's schema in Hydra's ConfigStore (``algo/ppo_schema``, ``env/lunar_schema``, ...), those it
    lacks. Checked in the ConfigStore there is now, at each call, not once per process: Hydra's singletons may be
    set aside and restored (``Singleton.set_state``: a launcher's job, a command run in the process of another) and
    leave a ConfigStore that never held them although this process registered them before."""
    from hydra.core.config_store import ConfigStore
    from hydra.core.object_type import ObjectType

    store = ConfigStore.instance()
    for path, (group, name, node) in _schema_paths().items():
        if store.get_type(path) is not ObjectType.CONFIG:
            store.store(group=group, name=name, node=node)


def declared_key(cfg: Mapping[str, Any], key: str) -> Declared | None:
    """The declaration of the dotted ``key`` (``algo.archive.shape``, ``env.physics.condim``) of the algorithm, env
    or controller that ``cfg`` chose; None for a key of no declaration."""
    section, _, name = key.partition(".")
    chosen = cfg.get(section) if section in DECLARED else None
    config = DECLARED[section].get(str(chosen.get("name"))) if isinstance(chosen, Mapping) else None
    return next((k for k in declared(config) if k.name == name), None) if config else None


def declared_run_key(key: str) -> Declared | None:
    """The declaration of the run's own dotted ``key`` (``video.max_steps``) in rlq/declared/run.py; None for another
    key (a component's, ``algo.lr``, or none)."""
    return next((k for k in declared(run.Config) if k.name == key), None)


def hydra_conf_dir() -> str:
    """conf/ for Hydra to compose from, the schemas registered first (those Hydra's ConfigStore lacks now)."""
    register_schemas()
    return str(CONF_DIR)
