"""Runs spread over devices (rlq/run/programs/devices.py, rlq/lib/sharding.py) give the numbers of the same
run on one device, and a checkpoint written on 4 devices resumes on 1. The 4 devices are CPU host
devices forced in a process of their own (tests/run/sharded_runs.py trains the runs)."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

from rlq.errors import ConfigError
from rlq.run.programs.devices import local_devices, select_devices, shape_note
from rlq.store import checkpoint
from tests.helpers import REPO, compose_config, run_forced_devices_module
from tests.run.sharded_runs import FAST_COMPILE

pytestmark = pytest.mark.slow

RTOL, ATOL = 1e-4, 1e-5  # float sums split over devices add up in another order


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("sharded")
    run_forced_devices_module("tests.run.sharded_runs", out, timeout=900)
    return out


def metric_rows(run_dir: Path, seed: int | str | None = None) -> list[dict]:
    rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    rows = [{k: v for k, v in row.items() if k != "wall_s"} for row in rows]
    return [row for row in rows if seed is None or row["seed"] == seed]


def assert_same_rows(got: list[dict], want: list[dict]) -> None:
    assert [(r["kind"], r["env_steps"], r["seed"], sorted(r)) for r in got] == [
        (r["kind"], r["env_steps"], r["seed"], sorted(r)) for r in want
    ]
    for a, b in zip(got, want, strict=True):
        for key, value in a.items():
            if isinstance(value, float):
                assert math.isclose(value, b[key], rel_tol=RTOL, abs_tol=ATOL) or (
                    math.isnan(value) and math.isnan(b[key])
                ), (a["kind"], a["env_steps"], key, value, b[key])


def assert_same_state(got: Path, want: Path, seeds: slice = slice(None)) -> None:
    a, b = checkpoint.leaves(got), checkpoint.leaves(want)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_allclose(np.asarray(x), np.asarray(y)[seeds], rtol=RTOL, atol=ATOL)


def test_ppo_seeds_split_over_4_devices_match_1(runs):
    assert_same_rows(metric_rows(runs / "ppo_seeds_4"), metric_rows(runs / "ppo_1"))
    assert_same_state(runs / "ppo_seeds_4/checkpoints/final.msgpack", runs / "ppo_1/checkpoints/final.msgpack")


def test_ppo_envs_of_one_seed_split_over_4_devices_match_1(runs):
    assert_same_rows(metric_rows(runs / "ppo_envs_4", seed=0), metric_rows(runs / "ppo_1", seed=0))
    final = "checkpoints/final.msgpack"
    assert_same_state(runs / "ppo_envs_4" / final, runs / "ppo_1" / final, seeds=slice(0, 1))


def test_dqn_seeds_and_envs_split_over_4_devices_match_1(runs):
    assert_same_rows(metric_rows(runs / "dqn_4"), metric_rows(runs / "dqn_1"))
    assert_same_state(runs / "dqn_4/checkpoints/final.msgpack", runs / "dqn_1/checkpoints/final.msgpack")


def test_pqn_envs_and_minibatches_split_over_4_devices_match_1(runs):
    assert_same_rows(metric_rows(runs / "pqn_4"), metric_rows(runs / "pqn_1"))
    assert_same_state(runs / "pqn_4/checkpoints/final.msgpack", runs / "pqn_1/checkpoints/final.msgpack")


def test_map_elites_offspring_split_over_4_devices_match_1(runs):
    rows = metric_rows(runs / "map_elites_4")
    assert any(r["kind"] == "eval" and r["archive-occupancy"] > 0 for r in rows)
    assert_same_rows(rows, metric_rows(runs / "map_elites_1"))
    final = "checkpoints/final.msgpack"
    assert_same_state(runs / "map_elites_4" / final, runs / "map_elites_1" / final)


def test_checkpoint_written_on_4_devices_resumes_on_1(runs, tmp_path):
    stopped = tmp_path / "stopped"
    shutil.copytree(runs / "ppo_seeds_4", stopped)
    for path in (stopped / "checkpoints").glob("final.*"):
        path.unlink()  # as if the job had stopped after its intermediate checkpoint
    env = {**os.environ, "XLA_FLAGS": FAST_COMPILE, "WANDB_MODE": "disabled"}
    proc = subprocess.run(
        [sys.executable, "-m", "rlq.cli", "resume", f"run={stopped}", "devices=1"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads((stopped / "summary.json").read_text())["resumed_from_env_steps"] == 256
    assert_same_state(stopped / "checkpoints/final.msgpack", runs / "ppo_seeds_4/checkpoints/final.msgpack")
    assert_same_rows(metric_rows(stopped), metric_rows(runs / "ppo_seeds_4"))


def test_device_counts_that_do_not_divide_the_axis_are_config_errors(runs):
    errors = json.loads((runs / "errors.json").read_text())
    assert "algo.num_envs=6 over 4 devices" in errors["envs"] and "devices=1" in errors["envs"]
    assert "algo.batch_size=7 over 2 devices" in errors["offspring"]
    assert "devices=5 but this machine has 4" in errors["too_many"]


@pytest.mark.parametrize("spec", [2, [0, 0], [1], 0, "two"])
def test_devices_this_machine_lacks_are_config_errors(spec):
    with pytest.raises(ConfigError, match="devices"):
        select_devices(spec)


def test_platform_cpu_selects_the_cpu_devices_and_others_must_exist():
    assert {d.platform for d in local_devices("cpu")} == {"cpu"}
    assert local_devices(None) == jax.local_devices()
    if jax.default_backend() == "cpu":
        with pytest.raises(ConfigError, match="platform=gpu but JAX finds no gpu device"):
            select_devices(None, "gpu")


def test_a_gpu_preset_on_a_cpu_gets_a_note_naming_what_to_run_instead():
    gpu_preset = compose_config("experiment=lunar_ppo_gpu")
    note = shape_note(gpu_preset, "cpu")
    assert note is not None and "shaped for a gpu" in note and note.endswith("on a CPU use experiment=lunar_ppo")
    assert shape_note(gpu_preset, "gpu") is None
    assert shape_note(compose_config("experiment=lunar_ppo"), "cpu") is None  # a preset for any device
    bare = compose_config("shaped_for.platform=gpu", "shaped_for.note=")
    assert (
        shape_note(bare, "cpu")
        == "this config is shaped for a gpu (shaped_for.platform) and runs on the cpu here, which is slow"
    )


PLACEMENTS = """
import json, sys
from rlq.run.programs.devices import placement
from tests.helpers import compose_config
out = {}
for name, overrides in json.loads(sys.argv[1]).items():
    where = placement(compose_config(*overrides))
    out[name] = [where.seed_shards, where.env_shards, where.note]
print(json.dumps(out))
"""


def test_by_default_a_run_splits_seeds_only_and_says_which_devices_it_leaves():
    """On 4 forced CPU devices: never one seed's envs over devices unless asked (devices=all or a count)."""
    cases = {
        "one_seed": ["num_seeds=1"],
        "two_seeds": ["num_seeds=2"],
        "four_seeds": ["num_seeds=4"],
        "all": ["num_seeds=1", "devices=all"],
        "count": ["num_seeds=2", "devices=4"],
    }
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=4", "JAX_PLATFORMS": "cpu"}
    proc = subprocess.run(
        [sys.executable, "-c", PLACEMENTS, json.dumps(cases)], cwd=REPO, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["one_seed"][:2] == [1, 1] and "4 local devices: num_seeds=1 runs on 1" in got["one_seed"][2]
    assert "devices=all also splits each seed's envs" in got["one_seed"][2]
    assert got["two_seeds"][:2] == [2, 1] and got["two_seeds"][2] is not None
    assert got["four_seeds"] == [4, 1, None]
    assert got["all"] == [1, 4, None]
    assert got["count"] == [2, 2, None]
