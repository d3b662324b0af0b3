"""The run's own keys have one home, rlq/declared/run.py: conf/config.yaml writes none of them (its defaults list
names the declaration's schema first, conf/logger/ and conf/machine/ only what a choice changes), the config composed
with no override gives every declared key its declared default and no undeclared key, every run key a preset
(conf/experiment/, conf/tuned/) sets is declared and of its type, and the run's range check reads the declaration."""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest
from omegaconf import OmegaConf

from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.config.conf_dir import CONF_DIR
from rlq.config.store import RUN_SCHEMA
from rlq.declared import run
from rlq.lib import settings
from rlq.run.checks.constraints import problems
from tests.helpers import compose_config

#: the groups a preset sets besides the run's own keys: the components' (rlq/declared/), Hydra's and the defaults list
NOT_RUN_KEYS = ("defaults", "hydra", "algo", "env", "controller")
#: conf/config.yaml's groups chosen from their own directories: each file holds that group's keys
GROUP_DIRS = ("logger", "machine")


def _yaml(path: Path) -> dict[str, Any]:
    data = OmegaConf.to_container(OmegaConf.load(path), resolve=False)
    assert isinstance(data, dict)
    return {str(k): v for k, v in data.items()}


def _leaves(node: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """Each dotted key of ``node`` and its value; a group of free-form options (a ``dict`` key of the declaration,
    ``eval.env``) is one leaf."""
    for key, value in node.items():
        name = f"{prefix}{key}"
        annotation = declaration(name)
        inner = settings.optional_type(annotation)[0] if annotation is not None else None
        if isinstance(value, Mapping) and isinstance(inner, type) and dataclasses.is_dataclass(inner):
            yield from _leaves(value, f"{name}.")
        else:
            yield name, value


def declaration(key: str) -> Any:
    """The declared annotation of the run's dotted ``key``; None where rlq/declared/run.py has none."""
    config: Any = run.Config
    annotation: Any = None
    for part in key.split("."):
        inner = settings.optional_type(annotation)[0] if annotation is not None else config
        if not (isinstance(inner, type) and dataclasses.is_dataclass(inner)):
            return None
        hints = typing.get_type_hints(inner)
        if part not in hints:
            return None
        annotation = hints[part]
    return annotation


def _default(key: str) -> Any:
    value: Any = run.Config()
    for part in key.split("."):
        value = getattr(value, part)
    return settings.plain(value)


def _of_type(value: Any, annotation: Any) -> bool:
    return annotation is Any or settings.conforms(value, annotation)


def composed_run_keys() -> dict[str, Any]:
    """The run's own keys of the config composed with no override and no tuned file (conf/config.yaml's defaults
    list: the run's schema, then its groups' default choices, ``logger`` and ``machine`` among them), dotted, and their
    values."""
    data = OmegaConf.to_container(compose(WITHOUT_TUNED), resolve=False)
    assert isinstance(data, dict)
    return dict(_leaves({str(k): v for k, v in data.items() if k not in NOT_RUN_KEYS}))


def test_conf_config_yaml_writes_no_run_key_its_defaults_list_names_the_declaration_first():
    top = _yaml(CONF_DIR / "config.yaml")
    assert sorted(top) == ["defaults", "hydra"], "a run key's default is written once, in rlq/declared/run.py"
    assert top["defaults"][0] == RUN_SCHEMA
    for group in GROUP_DIRS:  # a choice of a run group writes only what it changes
        for path in sorted((CONF_DIR / group).glob("*.yaml")):
            same = {k: v for k, v in _leaves({group: _yaml(path)}) if v == _default(k)}
            assert same == {}, f"{path.name} repeats the declared defaults of {sorted(same)}"


def test_every_run_key_of_the_composed_config_is_declared_with_its_default():
    keys = composed_run_keys()
    assert "num_seeds" in keys and "eval.episodes" in keys and "logger.wandb.mode" in keys and "eval.env" in keys
    undeclared = [key for key in keys if declaration(key) is None]
    assert undeclared == [], f"run keys of the composed config with no declaration in rlq/declared/run.py: {undeclared}"
    differ = {
        key: (value, _default(key))
        for key, value in keys.items()
        if value != _default(key) or type(value) is not type(_default(key))
    }
    assert differ == {}, f"the composed value and rlq/declared/run.py's default differ: {differ}"


def test_every_declared_run_key_is_composed():
    keys = composed_run_keys()
    leaves = [k.name for k in settings.declared(run.Config) if not dataclasses.is_dataclass(k.type)]
    assert [key for key in leaves if key not in keys] == []


@pytest.mark.parametrize("group", GROUP_DIRS)
def test_each_choice_of_a_run_group_has_the_declared_keys_of_their_types(group):
    for path in sorted((CONF_DIR / group).glob("*.yaml")):
        for key, value in _leaves({group: _yaml(path)}):
            annotation = declaration(key)
            assert annotation is not None, f"{path.name}: {key} is not declared"
            assert _of_type(value, annotation), f"{path.name}: {key}={value!r} is not {annotation}"


def _presets() -> list[Path]:
    return sorted([*(CONF_DIR / "experiment").glob("*.yaml"), *(CONF_DIR / "tuned").rglob("*.yaml")])


def test_every_run_key_a_preset_sets_is_declared_and_of_its_type():
    seen = set()
    for path in _presets():
        data = _yaml(path)
        for key, value in _leaves({k: v for k, v in data.items() if k not in NOT_RUN_KEYS}):
            annotation = declaration(key)
            assert annotation is not None, f"{path.relative_to(CONF_DIR)}: {key} is not a declared run key"
            assert _of_type(value, annotation), f"{path.relative_to(CONF_DIR)}: {key}={value!r} is not {annotation}"
            seen.add(key)
    assert {"run_name", "budget.env_steps", "shaped_for.platform", "chunk_loop"} <= seen


#: the run keys whose values a range or a set of choices bounds (the former table of rlq/run/checks/constraints.py)
BOUNDED = (
    "seed", "num_seeds", "budget.env_steps", "log_every_steps", "chunk_loop", "program_cache", "shaped_for.platform",
    "eval.episodes", "guard.max_abs_loss", "guard.max_params_norm", "eval.every_steps", "checkpoint.every_steps",
    "checkpoint.keep_last", "video.every_steps", "return_window", "video.max_steps", "logger.wandb.mode",
)  # fmt: skip


def test_each_bounded_run_key_declares_its_range():
    allowed = {key.name: key.allowed for key in settings.declared(run.Config)}
    assert [key for key in BOUNDED if allowed.get(key) is None] == []


def test_the_range_check_reads_the_run_declaration():
    assert problems(compose_config()) is None
    assert problems(compose_config("eval.every_steps=-1")) == "eval.every_steps must be an integer >= 0, got -1"
    assert problems(compose_config("video.every_steps=-2")) == "video.every_steps must be an integer >= 0, got -2"


def test_a_key_with_no_range_is_held_to_its_declared_type():
    assert problems(compose_config("init_from=1")) == "init_from must be null or a string, got 1"
    assert (
        problems(compose_config("logger.wandb.tags=[a,[b]]"))
        == "logger.wandb.tags must be a list of strings, got ['a', ['b']]"
    )
    assert problems(compose_config("init_from=null", "video.at_end=true")) is None


def test_the_run_declaration_imports_no_jax():
    import subprocess
    import sys

    code = "import sys, rlq.declared.run; assert 'jax' not in sys.modules, 'jax imported'"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
