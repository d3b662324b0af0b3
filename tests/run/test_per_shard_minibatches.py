"""Per-shard minibatches (``algo.minibatch_shuffle=per_shard``) with one seed's envs split over 4 forced
CPU devices: the compiled update gathers no rollout data across devices (only the gradient and a few
scalars are reduced), and PPO still solves CartPole. tests/run/per_shard_runs.py runs it all in a
process of its own."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.helpers import run_forced_devices_module

pytestmark = pytest.mark.slow

STEPS = "24"  # tests/run/per_shard_runs.py's num_steps: a dimension only the rollout's arrays have


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("per_shard") / "report.json"
    run_forced_devices_module("tests.run.per_shard_runs", out, timeout=600)
    return json.loads(out.read_text())


def batch_traffic(collectives: list[list[str]]) -> list[list[str]]:
    """Collectives that move learning data between devices: all-to-alls, permutes, and all-gathers of
    arrays with the rollout's time axis (the chunk's output state is gathered once, and is not)."""
    moves = ("all-to-all", "collective-permute")
    return [[k, shape] for k, shape in collectives if k in moves or (k == "all-gather" and f"[{STEPS}," in shape)]


def test_global_minibatches_gather_the_rollout_from_every_device(report):
    assert batch_traffic(report["global"])  # what per_shard removes (and that the check can see it)


@pytest.mark.parametrize("variant", ["per_shard", "per_shard_unrolls"])
def test_per_shard_minibatches_gather_nothing_of_the_rollout(report, variant):
    collectives = report[variant]
    assert not batch_traffic(collectives), collectives
    assert any(kind == "all-reduce" for kind, _ in collectives)  # the minibatch gradient's reduction


def test_shares_the_minibatches_do_not_divide_are_config_errors(report):
    assert "algo.minibatch_shuffle=per_shard" in report["unsplittable"]
    assert "algo.minibatch_shuffle=global" in report["unsplittable"]


def test_ppo_with_per_shard_minibatches_over_4_devices_solves_cartpole(report):
    assert np.all(np.array(report["eval_return"]) >= 475), report["eval_return"]
