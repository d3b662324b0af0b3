"""The declarations as Hydra's schemas (rlq/config/store.py): a composed algo, env or controller section is a typed
node built from its declaration, whatever composes it (rlq's compose, in a fresh process too), so a value of the wrong
type or an unknown key is refused while composing, and integer keys written in float notation still read as
integers."""

from __future__ import annotations

import dataclasses
import pickle
import subprocess
import sys

import pytest
from omegaconf import OmegaConf

from rlq.config import resolve
from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.config.conf_dir import CONF_DIR
from rlq.config.store import DECLARED, RUN_SCHEMA, SCHEMA, schema
from rlq.declared import map_elites, ppo, random_search
from rlq.declared.envs import brittle_star
from rlq.errors import ConfigError
from rlq.lib import settings
from tests.helpers import quick_sample, run_cli_in_process


def test_a_schema_has_the_declarations_fields_types_and_defaults():
    made = schema(random_search.Config)
    assert [f.name for f in dataclasses.fields(made)] == [f.name for f in dataclasses.fields(random_search.Config)]
    node = OmegaConf.structured(made)
    assert OmegaConf.to_container(node) == settings.defaults(random_search.Config)
    assert OmegaConf.get_type(node.ars) is schema(random_search.ArsConfig)
    # a group that may be null takes a mapping (from a tuned file or an override), whose keys the declaration checks
    # when the run's Config is built
    node.archive = {"shape": [3, 3]}
    built = settings.typed(random_search.Config, OmegaConf.to_container(node), "algo")
    assert built.archive is not None and built.archive.shape == (3, 3) and built.archive.cells == 400
    node.archive = {"shapee": [3, 3]}
    with pytest.raises(ConfigError, match="algo.archive.shapee is not a key of algo.archive"):
        settings.typed(random_search.Config, OmegaConf.to_container(node), "algo")


def test_composing_in_a_fresh_process_builds_typed_nodes():
    code = (
        "from omegaconf import OmegaConf; from rlq.config.compose import compose; from rlq.config.store import schema;"
        "from rlq.declared import dqn; cfg = compose(['algo=dqn']);"
        "assert OmegaConf.get_type(cfg.algo) is schema(dqn.Config), OmegaConf.get_type(cfg.algo)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_a_composed_config_pickles_with_its_schemas():
    """A sweep's launcher (submitit) pickles the composed config: the schemas are found by name."""
    cfg = compose(["algo=random_search", *WITHOUT_TUNED])
    back = pickle.loads(pickle.dumps(cfg))
    assert OmegaConf.get_type(back.algo.ars) is schema(random_search.ArsConfig)
    with pytest.raises(Exception, match="Integer"):
        back.algo.ars.top = "many"


@pytest.mark.parametrize(("group", "name"), [(g, n) for g, configs in DECLARED.items() for n in configs])
def test_every_declaration_composes_typed(group, name):
    node = compose([f"{group}={name}", *WITHOUT_TUNED])[group]
    assert OmegaConf.get_type(node) is schema(DECLARED[group][name])


@pytest.mark.parametrize("group", list(DECLARED))
def test_every_yaml_of_a_declared_group_names_its_schema_first(group):
    """conf/<group>/<name>.yaml is a preset over its declaration: its defaults list starts with ``<name>_schema``,
    and every declaration has its yaml (``<group>=<name>``)."""
    paths = sorted((CONF_DIR / group).glob("*.yaml"))
    assert sorted(p.stem for p in paths) == sorted(DECLARED[group])
    for path in paths:
        defaults = OmegaConf.load(path).get("defaults")
        assert defaults and defaults[0] == SCHEMA.format(name=path.stem), path


def test_an_env_schema_takes_its_nested_groups_typed_and_pickles():
    """env/physics=fast sets keys of the brittle star's typed physics group; a null discretize group takes a
    mapping (checked as the env's Config is built)."""
    cfg = compose(["env=brittle_star", "env/physics=fast", "env.discretize={bins:[3]}", *WITHOUT_TUNED])
    assert OmegaConf.get_type(cfg.env.physics) is schema(brittle_star.Physics)
    assert cfg.env.physics.ls_iterations == 3 and cfg.env.discretize == {"bins": [3]}
    back = pickle.loads(pickle.dumps(cfg))
    with pytest.raises(Exception, match="Integer"):
        back.env.physics.condim = "many"


@pytest.mark.parametrize(
    "overrides,words",
    quick_sample(
        [
            (["algo.lr=abc"], "algo.lr must be a number, got 'abc' (e.g. algo.lr=0.00025)"),
            (["algo.no_such_key=1"], "unknown config key 'algo.no_such_key'"),
            (["algo=dqn", "algo.epsilon.start=x"], "algo.epsilon.start must be a number, got 'x'"),
            (["algo.hidden=[64.5]"], "algo.hidden must be a list of integers >= 1, e.g. [64,64], got [64.5]"),
            (["algo.anneal_lr=3"], "algo.anneal_lr must be a boolean (true/false), got 3"),
            (["algo.gamma=${run_name}"], "algo.gamma must be a number, got 'cartpole-ppo'"),
            (
                ["env=brittle_star", "env.num_arms=abc"],
                "env.num_arms must be an integer, got 'abc' (e.g. env.num_arms=5)",
            ),
            (["env.no_such_key=1"], "unknown config key 'env.no_such_key'"),
            (["env=brittle_star", "env.physics.nope=1"], "unknown config key 'env.physics.nope'"),
            (
                ["env=brittle_star", "env.physics.condim=2.5"],
                "env.physics.condim must be an integer in [1, 6], got 2.5",
            ),
            (["env=lunar", "env.max_episode_steps=abc"], "env.max_episode_steps must be an integer, got 'abc'"),
            (["env=lunar", "env.continuous=3"], "env.continuous must be a boolean (true/false), got 3"),
            (["controller.no_such_key=1"], "unknown config key 'controller.no_such_key'"),
            (
                ["env=brittle_star", "controller.leading_arm=x"],
                "controller.leading_arm must be null or an integer, got 'x'",
            ),
        ],
        2,
    ),
)
def test_a_value_of_another_type_is_one_line_naming_the_key(overrides, words):
    with pytest.raises(ConfigError) as caught:
        resolve(overrides)
    assert str(caught.value) == words or words in str(caught.value)
    assert "\n" not in str(caught.value)


def test_an_integer_key_written_in_float_notation_reads_as_an_integer():
    spec = resolve(["algo=dqn", "algo.buffer_size=1e5", "budget.env_steps=2e5"])
    assert spec.config.algo.buffer_size == 100000 and type(spec.config.algo.buffer_size) is int
    assert "algo.buffer_size=100000" in spec.overrides
    assert compose(["algo=dqn", "algo.buffer_size=1e5"]).algo.buffer_size == 100000
    with pytest.raises(ConfigError, match="algo.buffer_size=1e5: an integer key"):
        resolve(["algo=dqn", "algo.buffer_size=1e5"], multirun=True)
    with pytest.raises(ConfigError, match="algo.buffer_size must be an integer >= 1, got 100000.5"):
        resolve(["algo=dqn", "algo.buffer_size=100000.5"])


def test_a_nullable_group_takes_a_mapping_from_the_command_line_and_refuses_a_number():
    """``env.randomize`` is null by default: OmegaConf cannot merge an override's mapping into a typed null dict, so
    the schema leaves it untyped and rlq's own check refuses what is not a group of keys."""
    from rlq.cli.checked import check_overrides

    composed = resolve(["env=humanoid", "env.randomize={friction:[0.6,1.4],gain_delta:[-5,5]}"])
    assert {key: list(value) for key, value in composed.env["randomize"].items()} == {
        "friction": [0.6, 1.4],
        "gain_delta": [-5, 5],
    }
    with pytest.raises(ConfigError) as caught:
        check_overrides(["env=humanoid", "env.randomize=3"])
    assert str(caught.value) == "env.randomize must be null or a group of keys, got 3"


def _without_schemas() -> None:
    """Hydra's ConfigStore as a process that never registered rlq's schemas holds it: Hydra's own configs only."""
    from hydra.core.config_store import ConfigStore

    repo = ConfigStore.instance().repo
    repo.pop(f"{RUN_SCHEMA}.yaml", None)
    for group in DECLARED:
        for name in [n for n in repo.get(group, {}) if n.endswith("_schema.yaml")]:
            del repo[group][name]


def test_a_config_composes_after_an_in_process_command_set_hydras_state_aside(tmp_path):
    """An in-process command (tests/helpers.run_cli_in_process, as the slow MAP-Elites tests run `rlq train` and
    then `rlq eval`, `rlq resume` or compose) registers the schemas in Hydra's ConfigStore, and its Hydra state is
    then set back to what it was before it: a ConfigStore without them. Composing again in this process, from rlq's
    compose or another command, still finds them (once they were registered only once per process: "Could not load
    'algo/map_elites_schema'" when such a test ran alone)."""
    from hydra.core.singleton import Singleton

    saved = Singleton.get_state()
    try:
        _without_schemas()
        proc = run_cli_in_process("train", "algo=map_elites", "--cfg", "job", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert OmegaConf.get_type(compose(["algo=map_elites"]).algo) is schema(map_elites.Config)
        proc = run_cli_in_process("train", "algo=map_elites", "--cfg", "job", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr[-2000:]
        _without_schemas()
        assert OmegaConf.get_type(compose(["algo=ppo"]).algo) is schema(ppo.Config)
    finally:
        Singleton.set_state(saved)
