"""Runs for tests/run/test_devices.py, in a process of its own: the forced host device count
must be set before JAX initialises. ``python -m tests.run.sharded_runs <dir>`` trains each run
of ``RUNS`` into ``<dir>/<name>`` and writes ``<dir>/errors.json``, the config errors of device
counts that do not divide the axis they must split."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

#: XLA's quick CPU compile (the 1- and 4-device runs and the resumed run all use it, so they compare)
FAST_COMPILE = "--xla_backend_optimization_level=0 --xla_llvm_disable_expensive_passes=true"

COMMON = ("env=cartpole", "eval.episodes=4", "video.at_end=false", "logger=quiet", "budget.env_steps=512")
PPO = ("algo=ppo", "algo.num_envs=8", "algo.num_steps=32", "algo.hidden=[16]", "log_every_steps=256")
DQN = (
    "algo=dqn",
    "num_seeds=2",
    "algo.num_steps=16",
    "algo.learning_starts=128",
    "algo.buffer_size=1024",
    "algo.batch_size=32",
    "algo.hidden=[16]",
    "log_every_steps=256",
)
PQN = ("algo=pqn", "num_seeds=1", "algo.num_envs=8", "algo.num_steps=16", "algo.hidden=[16]", "log_every_steps=256")
MAP_ELITES = ("algo=map_elites", "num_seeds=1", "algo.batch_size=8", "budget.env_steps=8000", "log_every_steps=4000")
#: name -> overrides. A seed's run does not depend on num_seeds, so ppo_1's seed 0 is ppo_envs_4's
#: reference; ppo_seeds_4 also writes the intermediate checkpoint the resume test starts from.
RUNS = {
    "ppo_1": (*PPO, "num_seeds=4", "devices=1"),
    "ppo_seeds_4": (*PPO, "num_seeds=4", "devices=4", "checkpoint.every_steps=256"),
    # global minibatches: the 1-device run's sampling (per_shard, the default, samples per env device)
    "ppo_envs_4": (*PPO, "num_seeds=1", "devices=4", "algo.minibatch_shuffle=global"),
    "dqn_1": (*DQN, "devices=1"),
    "dqn_4": (*DQN, "devices=4"),  # 2 seeds x 4 devices: seeds over 2, each seed's envs over 2
    "pqn_1": (*PQN, "devices=1"),
    "pqn_4": (*PQN, "devices=4", "algo.minibatch_shuffle=global"),  # one seed: its envs and minibatches over 4 devices
    "map_elites_1": (*MAP_ELITES, "devices=1"),
    "map_elites_4": (*MAP_ELITES, "devices=4"),
}
#: overrides that 4 devices cannot split
UNSPLITTABLE = {
    "envs": ("algo=ppo", "num_seeds=1", "algo.num_envs=6", "algo.num_minibatches=2", "devices=all"),
    "offspring": ("algo=map_elites", "num_seeds=2", "algo.batch_size=7", "devices=all"),
    "too_many": ("algo=ppo", "devices=5"),
}


def main(out: Path) -> None:
    from omegaconf import OmegaConf

    from rlq.errors import ConfigError
    from rlq.run.checks.validate import check_run_config
    from rlq.run.train import train
    from tests.helpers import compose_config

    errors = {}
    for name, overrides in UNSPLITTABLE.items():
        try:
            check_run_config(compose_config(*COMMON, *overrides))
        except ConfigError as err:
            errors[name] = str(err)
    (out / "errors.json").write_text(json.dumps(errors))
    for name, overrides in RUNS.items():
        cfg = compose_config(*COMMON, *overrides)
        check_run_config(cfg)
        run_dir = out / name
        (run_dir / ".hydra").mkdir(parents=True)
        OmegaConf.save(cfg, run_dir / ".hydra" / "config.yaml")  # what `rlq resume` reads
        train(cfg, run_dir)


if __name__ == "__main__":
    os.environ["XLA_FLAGS"] = f"{FAST_COMPILE} --xla_force_host_platform_device_count=4"  # before JAX starts
    main(Path(sys.argv[1]))
