"""Whole numbers in float notation of keys that take an integer (``budget.env_steps=1e6``): one rewrite
(rlq.config.types.integers_written) for a run, a sweep's jobs and `rlq train --cfg job`. A run key's is written as the
integer in a sweep too; a component's is refused there with the integer to write (a sweep's jobs may choose other
components, and Hydra composes each from the overrides as written)."""

from __future__ import annotations

import pytest
from omegaconf import OmegaConf

import rlq.cli.train
from rlq.config import resolve
from rlq.config.recorded import env_overridden
from rlq.config.types import integer_key, integers_written
from rlq.errors import ConfigError
from tests.helpers import compose_config, quick_sample, run_cli_in_process

#: the start of a refusal's line
NO = "refused: "
#: the sweep each row's overrides join in the sweep column
SWEEP = "eval.episodes=2,3"
SWEPT_COMPONENT = "algo.buffer_size=100000.0: an integer key; a sweep's jobs take their values as written: "

#: the command's overrides | the override a run is composed from | the one a sweep's jobs are given | --cfg job's value
TABLE = [
    ("budget.env_steps=1e6", "budget.env_steps=1000000", "budget.env_steps=1000000", 1_000_000),
    ("video.max_steps=1e3", "video.max_steps=1000", "video.max_steps=1000", 1000),  # a run key that takes null
    ("num_seeds=2.0", "num_seeds=2", "num_seeds=2", 2),
    (
        "log_every_steps=1e4,2e4",
        NO + "log_every_steps=1e4,2e4 gives several values",
        "log_every_steps=10000,20000",
        None,
    ),
    (
        "algo=dqn algo.buffer_size=1e5",
        "algo.buffer_size=100000",
        NO + SWEPT_COMPONENT + "algo.buffer_size=100000",
        100000,
    ),
    (
        "algo=dqn algo.epsilon.duration=1e4",  # a nested component key
        "algo.epsilon.duration=10000",
        NO + "algo.epsilon.duration=10000.0: an integer key; a sweep's jobs take their values as written: "
        "algo.epsilon.duration=10000",
        10000,
    ),
    ("seed=1.5", NO + "seed must be an integer, got 1.5 (e.g. seed=0)", NO + "seed must be an integer, got 1.5", None),
    ("algo.lr=1e-3", "algo.lr=1e-3", "algo.lr=1e-3", 0.001),  # a number's key keeps its notation
]


@pytest.mark.parametrize(("given", "run", "sweep", "printed"), TABLE)
def test_a_run_is_composed_from_the_integer(given, run, sweep, printed):
    overrides = given.split()
    if run.startswith(NO):
        with pytest.raises(ConfigError) as caught:
            resolve(overrides)
        assert str(caught.value).startswith(run.removeprefix(NO))
    else:
        assert run in resolve(overrides).overrides


@pytest.mark.parametrize(("given", "run", "sweep", "printed"), quick_sample(TABLE, 2))
def test_a_sweeps_jobs_are_given_the_integer_or_the_line_to_write(given, run, sweep, printed, tmp_path, monkeypatch):
    launched: list[list[str]] = []
    monkeypatch.setattr(rlq.cli.train, "run_hydra", lambda args, multirun: launched.append(args))
    sweeping = [] if "," in given else [SWEEP]
    proc = run_cli_in_process("train", "-m", *sweeping, *given.split(), cwd=tmp_path)
    if sweep.startswith(NO):
        assert proc.returncode == 2 and sweep.removeprefix(NO) in proc.stderr
    else:
        assert proc.returncode == 0 and sweep in launched[0]


@pytest.mark.parametrize(("given", "run", "sweep", "printed"), quick_sample(TABLE, 2))
def test_cfg_prints_the_integer(given, run, sweep, printed, tmp_path):
    proc = run_cli_in_process("train", *given.split(), "--cfg", "job", cwd=tmp_path)
    if printed is None:
        assert proc.returncode == 2
        return
    key = given.split()[-1].split("=")[0]
    value = OmegaConf.select(OmegaConf.create(proc.stdout), key)
    assert proc.returncode == 0 and value == printed and type(value) is type(printed)


def test_a_sweep_writes_only_the_run_keys_and_one_config_every_integer_key():
    given = ["-m", "seed=0,1", "budget.env_steps=1e6", "log_every_steps=1e4,2e4", "algo.buffer_size=1e5", "seed=1.5"]
    assert integers_written(given, integer_key) == [
        "-m",
        "seed=0,1",
        "budget.env_steps=1000000",
        "log_every_steps=10000,20000",
        "algo.buffer_size=1e5",  # a component's: refused in a sweep with the integer to write
        "seed=1.5",  # not a whole number: refused as an integer key's value
    ]
    dqn = compose_config("algo=dqn")
    assert integers_written(
        ["algo.buffer_size=1e5", "log_every_steps=1e4,2e4"], lambda k: integer_key(k, dqn), False
    ) == [
        "algo.buffer_size=100000",
        "log_every_steps=1e4,2e4",  # one config's line for a sweep quotes it as written
    ]


def test_eval_and_render_take_an_envs_integer_in_float_notation():
    spec = resolve(["env=lunar", "algo=dqn"])
    assert env_overridden(spec, ["env.max_episode_steps=5e2"]).env["max_episode_steps"] == 500
