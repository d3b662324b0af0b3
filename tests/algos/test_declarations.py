"""Each algorithm declares its keys (``Config`` in rlq/declared/<name>.py: type, default, allowed values), their one
home: conf/algo/<name>.yaml only names the schema rlq/config/store.py registers from it, so composing algo=<name>
gives exactly the declared defaults in a typed node, and every algo section of a tuned file or an experiment sets
declared keys only, each of its type and in its range."""

from __future__ import annotations

from pathlib import Path

import pytest
from omegaconf import OmegaConf

from rlq.algos import ALGORITHMS, algorithm_spec
from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.config.store import schema
from rlq.declared import ALGORITHM_CONFIGS
from rlq.lib import settings
from tests.declared import CONF, assert_declared_typed_in_range, assert_typed, plain_yaml
from tests.declared import presets as declared_presets


def declaration(name: str) -> type:
    return algorithm_spec(OmegaConf.create({"name": name})).config


def algo_of(path: Path) -> str:
    """The algorithm a tuned file or an experiment sets keys of: the experiment's ``override /algo``, a tuned file's
    ``<env>_<algo>[_<controller or machine>]`` name."""
    for entry in plain_yaml(path).get("defaults", []):
        if isinstance(entry, dict) and "override /algo" in entry:
            return str(entry["override /algo"])
    named = [a for a in ALGORITHMS if f"_{a}_" in f"{path.stem}_"]
    assert named, path
    return max(named, key=len)


def presets() -> list[tuple[str, str]]:
    return declared_presets("algo", algo_of)


def test_every_algorithm_reads_its_declaration() -> None:
    assert ALGORITHM_CONFIGS.keys() == ALGORITHMS.keys()
    for name, spec in ALGORITHMS.items():
        assert spec.config is ALGORITHM_CONFIGS[name], name


@pytest.mark.parametrize("name", list(ALGORITHMS))
def test_the_algo_yaml_names_the_schema_of_its_declaration(name: str) -> None:
    """No default lives in the yaml: composing algo=<name> gives the declared defaults, in a typed struct node."""
    config = declaration(name)
    assert plain_yaml(CONF / "algo" / f"{name}.yaml") == {"defaults": [f"{name}_schema", "_self_"]}
    node = compose([f"algo={name}", *WITHOUT_TUNED]).algo
    assert OmegaConf.get_type(node) is schema(config) and OmegaConf.is_struct(node)
    composed = OmegaConf.to_container(node, resolve=False)
    assert isinstance(composed, dict)
    assert composed == settings.defaults(config)
    assert_typed(config, composed, name)
    assert settings.problems(config, composed, "algo") is None


@pytest.mark.parametrize(("path", "name"), presets())
def test_every_tuned_and_experiment_algo_key_is_declared_typed_and_in_range(path: str, name: str) -> None:
    assert_declared_typed_in_range(declaration(name), path, "algo", name)


def test_presets_cover_every_algorithm_and_tuned_file() -> None:
    found = presets()
    assert len(found) > 20 and {name for _, name in found} == set(ALGORITHMS)


@pytest.mark.parametrize("name", list(ALGORITHMS))
def test_every_numeric_key_has_a_range(name: str) -> None:
    """A numeric key declared without allowed values would be taken unchecked (algo.mean_episodes=0 was)."""
    unchecked = [k.name for k in settings.declared(declaration(name)) if k.type in (int, float) and k.allowed is None]
    assert not unchecked, f"algo={name}: numeric keys without a range: {unchecked}"


@pytest.mark.parametrize("name", list(ALGORITHMS))
def test_the_swept_hyperparameters_are_declared_numbers(name: str) -> None:
    keys = {k.name: k for k in settings.declared(declaration(name))}
    for key in algorithm_spec(OmegaConf.create({"name": name})).sweepable:
        assert key in keys and keys[key].type is float, (name, key)


def test_a_nullable_type_lets_the_range_take_null() -> None:
    config = declaration("ppo")
    assert settings.problems(config, {"batch_size": None, "max_grad_norm": None}, "algo") is None
    assert settings.problems(config, {"batch_size": 0}, "algo") == (
        "algo.batch_size must be null or an integer >= 1, got 0"
    )
    assert settings.problems(declaration("dqn"), {"batch_size": None}, "algo") == (
        "algo.batch_size must be an integer >= 1, got None"
    )
