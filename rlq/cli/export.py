"""`rlq export run=<dir> [checkpoint=<env steps>|final] [seed_index=0] [out=params.msgpack]`: one
seed's greedy policy network alone (no optimiser, replay or env state) as flax msgpack, with a JSON
sidecar (``out`` with suffix .json) that says how to rebuild and read the network
(rlq.lib.policy_export; docs/usage.md has the snippet that loads both and acts)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import jax
from flax import serialization

from rlq.cli.args import int_option, parse_args, warn_skipped
from rlq.errors import ExportError, UsageError
from rlq.lib.batch import seed_entry
from rlq.run.checks.validate import cannot_create
from rlq.store import checkpoint
from rlq.store.files import write_atomic
from rlq.store.outputs import check_output_file
from rlq.tools.evaluate import load_run_config, restore_run

EXPORT_KEYS = {"run", "checkpoint", "seed_index", "out"}
USAGE = "usage: rlq export run=<run dir> [checkpoint=<env steps>|final] [seed_index=0] [out=params.msgpack]"
HELP = f"""{USAGE}

Write one seed's greedy policy network alone (no optimiser, replay buffer or env state) as flax msgpack,
and next to it a JSON spec (sizes, activation, output head, spaces) that rebuilds it; docs/usage.md
("Export a policy") has the lines that load both and act. PPO, REINFORCE and DQN runs export;
tabular Q-learning, random search and MAP-Elites runs have no policy network and are refused, and so
are PQN runs (LayerNorm layers, which the export format does not describe) and runs of a policy shared
by agents (env.observation=arm_sectors, controller.mode=decentralised).

options:
  run=DIR          a run directory written by `rlq train` (required)
  checkpoint=C     N (checkpoints/step_N.msgpack), final, kept, or a file (default: kept of a finished
                   eval.keep=best run, else final, else the latest step_*)
  seed_index=I     which of the run's seeds (default 0)
  out=FILE         the parameters' file (default <run dir>/params.msgpack; the spec: FILE with suffix .json)
"""


#: why an algorithm's runs do not export (the others that do not keep an archive of genotypes)
NO_EXPORT = {
    "qlearning": "has no policy network to export (its greedy policy is its Q-table)",
    "pqn": "has a Q-network with LayerNorm layers, which the export format does not describe",
}
ARCHIVE = "has no policy network to export (its greedy policy is an archive of genotypes)"


def export_main(args: list[str]) -> None:
    options, env_overrides = parse_args(args, EXPORT_KEYS, USAGE)
    if env_overrides:
        raise UsageError(f"rlq export takes no env overrides; {USAGE}")
    run_dir = Path(options["run"])
    seed_index = int_option(options, "seed_index", 0)
    out = Path(options.get("out", run_dir / "params.msgpack"))
    if out.is_dir():
        raise UsageError(f"out={out} is a directory; give a file name, e.g. out={out / 'params.msgpack'}")
    check_output_file(out, "out")
    check_output_file(out.with_suffix(".json"), "out's spec")
    problem = cannot_create(out.parent)
    if problem:
        raise UsageError(f"out={out} cannot be written: {problem}")
    spec = load_run_config(run_dir)
    num_seeds, algo = spec.seeds.count, spec.algorithm["name"]
    if not 0 <= seed_index < num_seeds:
        raise UsageError(f"seed_index must be in 0..{num_seeds - 1} for this run, got {seed_index}")
    skipped: list[str] = []
    spec, programs, state, path = restore_run(run_dir, options.get("checkpoint"), spec, skipped)
    warn_skipped(skipped, path)
    if programs.algo.export is None:
        raise ExportError(
            f"algo={algo} {NO_EXPORT.get(algo, ARCHIVE)}; use rlq eval/render on the run's checkpoint {path}"
        )
    exported = programs.algo.export(jax.device_get(seed_entry(state, seed_index, int(num_seeds))))
    out.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(out, serialization.msgpack_serialize(exported.params))
    source = {
        "run": str(run_dir.resolve()),
        "checkpoint": str(Path(path).resolve()),
        "env_steps": checkpoint.env_steps(path),
        "seed_index": seed_index,
        "algo": algo,
        "env": spec.env["name"],
    }
    write_atomic(out.with_suffix(".json"), json.dumps({**exported.spec, "source": source}, indent=2).encode())
    print(f"rlq export: {out} (+ {out.with_suffix('.json').name})", file=sys.stdout)
