"""Per-shard minibatches on 4 forced CPU devices, for tests/run/test_per_shard_minibatches.py, in a process
of its own (the forced host device count must be set before JAX initialises). ``python -m
tests.run.per_shard_runs <out.json>`` writes the collectives of the compiled PPO chunk with each
``algo.minibatch_shuffle``, the config error of shares the minibatches do not divide, and the greedy
return of a CartPole PPO run whose one seed's envs split over the 4 devices."""

from __future__ import annotations

import json
import os
import re
import sys
import tempfile
from pathlib import Path

COLLECTIVE = re.compile(r"= (.+?) (all-gather|all-to-all|all-reduce|collective-permute|reduce-scatter)(?:-start)?\(")
#: a small split run: 8 envs over 4 devices, 24 steps (a size no other array of the chunk has)
SMALL = ("algo.num_envs=8", "algo.num_steps=24", "algo.hidden=[16]", "budget.env_steps=768", "log_every_steps=384")
#: XLA's quick CPU backend for the programs only inspected (the partitioner's collectives are the same)
FAST_COMPILE = {"xla_backend_optimization_level": 0, "xla_llvm_disable_expensive_passes": True}
COMMON = ("env=cartpole", "algo=ppo", "num_seeds=1", "devices=all", "video.at_end=false", "logger=quiet")


def collectives(shuffle: str, *overrides: str) -> list[list[str]]:
    """[kind, shape] of every collective in the compiled chunk program."""
    import jax

    from rlq.run.programs.build import build
    from tests.helpers import compose_config

    programs = build(compose_config(*COMMON, *SMALL, f"algo.minibatch_shuffle={shuffle}", *overrides))
    state = jax.eval_shape(programs.init, jax.random.split(jax.random.key(0), 1), programs.hyper_shape)
    text = (
        programs.chunk.lower(state, programs.hyper_shape).compile(FAST_COMPILE).as_text()
    )  # partitioned as ever, less optimised
    return [[m.group(2), m.group(1)] for m in map(COLLECTIVE.search, text.splitlines()) if m]


def unsplittable() -> str:
    from rlq.errors import ConfigError
    from rlq.run.programs.devices import placement
    from tests.helpers import compose_config

    try:
        placement(compose_config(*COMMON, "algo.num_envs=4", "algo.num_steps=3", "algo.num_minibatches=4"))
    except ConfigError as err:
        return str(err)
    return ""


def main(out: Path) -> None:
    from tests.helpers import train_run

    report = {
        "global": collectives("global"),
        "per_shard": collectives("per_shard"),
        "per_shard_unrolls": collectives(
            "per_shard", "algo.recompute_gae=true", "algo.clip_value=false", "algo.batch_size=4"
        ),
        "unsplittable": unsplittable(),
    }
    result = train_run(Path(tempfile.mkdtemp()), *COMMON, "budget.env_steps=500000", "algo.minibatch_shuffle=per_shard")
    report["eval_return"] = [float(x) for x in result.eval_return]
    out.write_text(json.dumps(report))


if __name__ == "__main__":
    os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=4"  # before JAX starts
    os.environ["JAX_PLATFORMS"] = "cpu"
    main(Path(sys.argv[1]))
