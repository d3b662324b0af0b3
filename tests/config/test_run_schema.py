"""The run's declaration as the primary config's schema (``run_schema``, rlq/config/store.py): the composed config is a
typed node built from rlq/declared/run.py, with untyped slots for the components' own schemas; a run key's value of
another type is refused in rlq's one line, what a typed node would convert is refused as written, and integer run
keys in float notation read as integers (tests/config/test_integers.py)."""

from __future__ import annotations

import pickle
import re

import pytest
from omegaconf import OmegaConf

from rlq.cli.checked import check_overrides
from rlq.config import resolve
from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.config.store import run_schema, schema
from rlq.declared import dqn, run
from rlq.errors import ConfigError
from rlq.lib import settings
from rlq.run.checks.constraints import problems


def test_the_composed_config_is_the_run_schemas_node_with_the_components_typed():
    cfg = compose(["algo=dqn", *WITHOUT_TUNED])
    assert OmegaConf.get_type(cfg) is run_schema()
    assert OmegaConf.get_type(cfg.eval) is schema(run.Eval) and OmegaConf.get_type(cfg.algo) is schema(dqn.Config)
    assert list(cfg)[:5] == ["controller", "env", "algo", "machine", "logger"]  # conf/config.yaml's former order
    back = pickle.loads(pickle.dumps(cfg))  # a sweep's launcher pickles it: the run's schemas are found by name
    assert OmegaConf.get_type(back) is run_schema() and OmegaConf.get_type(back.logger.wandb) is schema(run.Wandb)
    with pytest.raises(Exception, match="Integer"):
        back.num_seeds = "many"


def test_a_run_key_that_takes_null_stays_untyped_and_is_checked_as_written():
    cfg = compose(["init_from=1", "video.at_end=3", "guard.max_abs_loss=-1"])
    assert (cfg.init_from, cfg.video.at_end, cfg.guard.max_abs_loss) == (1, 3, -1)
    assert type(cfg.guard.max_abs_loss) is int


@pytest.mark.parametrize(
    "overrides,line",
    [
        (["num_seeds=abc"], "num_seeds must be an integer, got 'abc' (e.g. num_seeds=1)"),
        (["seed=1.5"], "seed must be an integer, got 1.5 (e.g. seed=0)"),
        (["checkpoint.keep_best=maybe"], "checkpoint.keep_best must be a boolean (true/false), got 'maybe'"),
        (["checkpoint.keep_best=1"], "checkpoint.keep_best must be a boolean (true/false), got 1"),
        (["chunk_loop=1"], "chunk_loop must be a string, got 1 (e.g. chunk_loop=scan)"),
        (["eval.no_such_key=1"], "unknown config key 'eval.no_such_key'"),
    ],
)
def test_a_run_keys_value_of_another_type_is_one_line_naming_it(overrides, line):
    with pytest.raises(ConfigError) as caught:
        resolve(overrides)
    assert str(caught.value).startswith(line) and "\n" not in str(caught.value)


@pytest.mark.parametrize(
    "overrides,line",
    [
        (["logger.wandb.tags=[1,2]"], "logger.wandb.tags must be a list of strings, got [1, 2]"),  # composed: strings
        (["checkpoint={keep_best:1}"], "checkpoint must be a group of keys, got {'keep_best': 1}"),  # composed: true
        (["video={at_end:3}"], "video must be a group of keys, got {'at_end': 3}"),
        (["video.at_end=3"], "video.at_end must be null or a boolean (true/false), got 3"),  # untyped in the schema
        (["guard.max_abs_loss=-1"], "guard.max_abs_loss must be null or a number > 0, got -1"),
    ],
)
def test_the_one_check_of_run_keys_holds_a_value_given_as_written(overrides, line):
    """rlq/run/checks/constraints.py checks the run's keys against their declaration: a key the command gave by its
    value as written, where the run's schema converted it or left it untyped."""
    spec = resolve(overrides)
    assert problems(spec) == line
    with pytest.raises(ConfigError, match=re.escape(line)):
        check_overrides(overrides)


def test_the_composed_defaults_are_the_declarations():
    data = OmegaConf.to_container(compose(WITHOUT_TUNED), resolve=False)
    assert isinstance(data, dict)
    assert {k: v for k, v in data.items() if k not in ("algo", "env", "controller")} == settings.plain(run.Config())
