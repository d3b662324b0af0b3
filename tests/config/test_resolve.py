"""rlq.config.resolve: a command's overrides as a RunSpec of frozen sections, composed without JAX."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest
from omegaconf import OmegaConf

from rlq.config import RunSpec, resolve
from rlq.config.compose import compose
from rlq.errors import ConfigError, UsageError


def test_the_sections_hold_the_composed_values_as_typed_read_only_fields(tmp_path):
    spec = resolve(["algo=dqn", "num_seeds=2", "seed=7", "budget.env_steps=1e5", f"hydra.run.dir={tmp_path}/run"])
    assert isinstance(spec, RunSpec)
    assert (spec.seeds.seed, spec.seeds.count) == (7, 2)
    assert spec.budget.env_steps == 100_000 and isinstance(spec.budget.env_steps, int)
    assert "budget.env_steps=100000" in spec.overrides  # float notation rewritten, so Hydra records the integer
    assert spec.composed is None  # an override was rewritten: Hydra composes the run again from spec.overrides
    assert spec.algorithm["name"] == "dqn" and spec.env["name"] == "cartpole"
    assert spec.choices["algo"] == "dqn"
    assert (spec.outputs.dir_key, spec.outputs.dir) == ("hydra.run.dir", f"{tmp_path}/run")
    assert spec.outputs.run_name == "cartpole-dqn"
    with pytest.raises(dataclasses.FrozenInstanceError):
        spec.seeds.count = 3  # type: ignore[misc]
    with pytest.raises(TypeError):
        spec.algorithm["lr"] = 1.0  # type: ignore[index]


def test_the_config_is_what_hydra_composes_and_a_single_run_keeps_hydras_node(tmp_path):
    overrides = ["algo=ppo", "algo.lr=0.001", f"hydra.run.dir={tmp_path}/run"]
    spec = resolve(overrides)
    assert spec.composed is not None and spec.composed.hydra.run.dir == f"{tmp_path}/run"
    assert "hydra" not in spec.config
    expected = compose(overrides)
    assert OmegaConf.to_container(spec.config) == OmegaConf.to_container(expected)
    assert spec.algorithm["lr"] == 0.001
    sweep_job = resolve(["algo=ppo", f"hydra.sweep.dir={tmp_path}/sweep"], multirun=True)
    assert sweep_job.composed is None and sweep_job.outputs.dir_key == "hydra.sweep.dir"


@pytest.mark.parametrize(
    "overrides,error,words",
    [
        (["algo"], UsageError, "is not an override"),
        (["~num_seeds=1"], UsageError, "a key cannot be deleted"),
        (["algo=nosuch"], ConfigError, "unknown algo 'nosuch'"),
        (["algo.lrr=1e-3"], ConfigError, "did you mean algo.lr?"),
        (["num_seeds=two"], ConfigError, "num_seeds must be an integer"),
    ],
)
def test_a_bad_override_is_one_line(overrides, error, words):
    with pytest.raises(error, match=words.replace("?", r"\?")):
        resolve(overrides)


def test_resolving_imports_no_jax():
    code = "import sys, rlq.config; rlq.config.resolve(['algo=dqn', 'env=lunar']); assert 'jax' not in sys.modules"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.parametrize(
    ("overrides", "composes"),
    [
        (["env=lunar", "algo=dqn"], 1),  # the card's command: its group choices' config is the run's
        (["env=lunar", "algo=dqn", "seed=3"], 2),  # a value: checked against the choices' own config
    ],
)
def test_group_choices_alone_are_composed_once(overrides, composes, monkeypatch):
    from rlq.config import compose as compose_module

    calls = []
    real = compose_module._compose
    monkeypatch.setattr(compose_module, "_compose", lambda *args: calls.append(args) or real(*args))
    resolve(overrides)
    assert len(calls) == composes


def test_a_value_of_another_type_is_still_refused_beside_group_choices():
    with pytest.raises(ConfigError, match="seed must be an integer"):
        resolve(["env=lunar", "algo=dqn", "seed=[1]"])
