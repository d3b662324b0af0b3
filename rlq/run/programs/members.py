"""In-program sweeps: `rlq train 'sweep.algo.lr=[1e-4,3e-4,1e-3]' num_seeds=4` trains 3 x 4 seeds in
one compiled program, vmapped like seeds, each member (one value of every swept key) on the seeds
its own run would use, and writes each member out as its own run.

The program's seed axis holds ``members x num_seeds`` seeds, member-major. It is the algorithm's own
program: its state is the algorithm's, and the swept hyperparameters are, like every numeric
hyperparameter, the chunk's argument, one value per seed (``seed_values``, put into the argument by
rlq/run/programs/build.py; ``AlgorithmSpec.sweepable`` names the keys): a sweep is a vmap over
(state, hyperparameters). The run directory holds that program's run (resumable as a whole, its
config giving the values again); when it ends, ``write_members`` splits its metrics and checkpoints
into ``members/<key>=<value>/``, each a run directory that `rlq eval`, `rlq resume`, `rlq compare`
and `init_from` read as the separate run's, and writes ``sweep_summary.csv``.

Checkpoints of layout 1 (``checkpoint.LAYOUT``; rlq before the hyperparameters left the state) held each seed's
swept values after the algorithm's state, as its last leaves: ``state_leaves`` reads both layouts.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np

from rlq.config.plain import read_recorded
from rlq.config.recorded import yaml_text
from rlq.config.spec import RunSpec, as_spec, config_yaml, member_spec, program_spec
from rlq.errors import ConfigError
from rlq.run.programs.keys import seed_keys
from rlq.store import checkpoint
from rlq.store.files import write_atomic
from rlq.store.jsonfiles import SUMMARY_FIX, read_json_object, read_rows
from rlq.store.logging import seed_rows
from rlq.store.runs import distinguishing_keys, final_table, load_runs, write_csv
from rlq.store.sidecar import HASH_KEY, config_hash

MEMBERS_DIR = "members"
#: the members' table, written last and whole: a sweep's run is complete once it is there
SWEEP_SUMMARY = "sweep_summary.csv"


def swept(run: RunSpec | Mapping[str, Any]) -> dict[str, Any]:
    """The swept keys (``algo.lr``) and their values, in the order given."""
    return dict(as_spec(run).training.sweep)


def members(run: RunSpec | Mapping[str, Any]) -> list[dict[str, float]]:
    """Every combination of the swept values, the first key slowest (one member: no sweep)."""
    grid = swept(run)
    return [dict(zip(grid, values, strict=True)) for values in itertools.product(*grid.values())]


def sweeping(run: RunSpec | Mapping[str, Any]) -> bool:
    return bool(swept(run))


def member_count(run: RunSpec | Mapping[str, Any]) -> int:
    return len(members(run)) if sweeping(run) else 1


def check(run: RunSpec | Mapping[str, Any], sweepable: Sequence[str]) -> None:
    """ConfigError for a sweep the algorithm cannot run in one program (``sweepable``: its keys)."""
    spec = as_spec(run)
    grid = swept(spec)
    if not grid:
        return
    algo = f"algo={spec.algorithm['name']}"
    allowed = ", ".join(f"algo.{k}" for k in sweepable)
    for name, values in grid.items():
        key = name.removeprefix("algo.")
        if not name.startswith("algo.") or key not in sweepable:
            reason = f"{algo} sweeps {allowed} in one program" if sweepable else f"{algo} has no in-program sweep"
            raise ConfigError(f"sweep.{name}: {reason}; use `rlq train -m {name}=a,b` for any key")
        if not isinstance(values, list | tuple):
            raise ConfigError(f"sweep.{name}={values!r}: give a list, e.g. 'sweep.{name}=[1e-4,3e-4]'")
        if len(values) == 0:
            raise ConfigError(f"sweep.{name}=[]: give at least one value")
        for value in values:
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ConfigError(f"sweep.{name}: {value!r} is not a finite number")
    if spec.training.init_from:
        raise ConfigError("init_from and sweep.* together are not supported: start each run with -m")


def program_config(run: RunSpec | Mapping[str, Any]) -> RunSpec:
    """The spec the program is built from: ``num_seeds`` counts every member's seeds."""
    spec = as_spec(run)
    return program_spec(spec, member_count(spec)) if sweeping(spec) else spec


def seed_values(spec: RunSpec, per_member: int) -> dict[str, np.ndarray]:
    """Each program seed's swept values (``sweep.algo.lr`` -> ``lr``), member-major, as float32: the values the
    chunk's hyperparameter argument holds for them (rlq.run.programs.build.hyper_values)."""
    rows = members(spec)
    return {
        name.removeprefix("algo."): np.repeat(np.asarray([m[name] for m in rows], np.float32), per_member)
        for name in swept(spec)
    }


def init_keys(program: RunSpec | Mapping[str, Any]) -> jax.Array:
    """What the program's ``init`` takes (``program``: ``program_config``'s): the seeds' keys, each member's seeds
    those of its separate run."""
    spec = as_spec(program)
    return seed_keys(int(spec.seeds.seed), int(spec.seeds.count), member_count(spec))


def state_leaves(path: Path, run: RunSpec | Mapping[str, Any]) -> list[Any]:
    """The algorithm state's leaves in the checkpoint ``path`` of the run ``run``: of a sweep's checkpoint of layout 1
    (``checkpoint.LAYOUT``), without the swept values it held as its last leaves (the config gives them)."""
    leaves = checkpoint.leaves(path)
    if sweeping(run) and int(checkpoint.meta(path).get(checkpoint.LAYOUT_KEY, 1)) < 2:
        return leaves[: len(leaves) - len(swept(run))]
    return leaves


def load_state(path: Path, template: Any, run: RunSpec | Mapping[str, Any]) -> Any:
    """``checkpoint.load`` of the run ``run``'s checkpoint ``path``, a sweep's of either layout (``state_leaves``)."""
    return checkpoint.load(path, template, state_leaves(path, run))


def member_dirname(member: Mapping[str, float]) -> str:
    return ",".join(f"{name}={value}" for name, value in member.items())


def _split_rows(all_rows: list[dict[str, Any]], first: int, count: int) -> list[dict[str, Any]]:
    """The rows of seeds ``first .. first+count-1``, renumbered from 0, with their own mean rows."""
    out: list[dict[str, Any]] = []
    groups: dict[tuple[str, int], list[dict[str, Any]]] = {}
    for row in all_rows:
        if isinstance(row.get("seed"), int) and first <= row["seed"] < first + count:
            groups.setdefault((row["kind"], row["env_steps"]), []).append(row)
    for (kind, env_steps), rows in groups.items():
        rows.sort(key=lambda r: r["seed"])
        names = [k for k in rows[0] if k not in ("kind", "env_steps", "seed")]
        metrics = {k: np.asarray([np.nan if r.get(k) is None else r[k] for r in rows], np.float64) for k in names}
        out += seed_rows(env_steps, kind, metrics)
    return out


#: the per-seed lists of a checkpoint's sidecar (``eval.keep=best``'s kept.json), cut to each member's seeds
PER_SEED_META = ("eval_return", "from_env_steps")


def member_part(value: Any, seeds: slice, total: int) -> Any:
    """``value`` with each list of ``total`` entries (in dicts at any depth) cut to ``seeds``: a member's share of
    per-seed figures (the summary's ``kept``)."""
    if isinstance(value, dict):
        return {k: member_part(v, seeds, total) for k, v in value.items()}
    if isinstance(value, list) and len(value) == total:
        return value[seeds]
    return value


def _split_checkpoint(
    source: Path, target_dir: Path, member: int, per_member: int, spec: RunSpec, meta: dict[str, Any]
) -> None:
    """The member's seeds of a program checkpoint (its state's leaves, ``state_leaves``)."""
    leaves = state_leaves(source, spec)
    part = [np.asarray(leaf)[member * per_member : (member + 1) * per_member] for leaf in leaves]
    checkpoint.save(target_dir, source.stem, part, meta)


def write_members(run: RunSpec | Mapping[str, Any], run_dir: Path) -> list[Path]:
    """Each member as its own run directory under ``<run dir>/members/``, and ``sweep_summary.csv``."""
    spec = as_spec(run)
    per_member = int(spec.seeds.count)
    all_rows = read_rows(run_dir / "metrics.jsonl").rows
    overrides_file = run_dir / ".hydra" / "overrides.yaml"
    base_overrides = [o for o in read_recorded(overrides_file) if not str(o).lstrip("+").startswith("sweep.")]
    summary = read_json_object(run_dir / "summary.json", SUMMARY_FIX)
    written = []
    for index, member in enumerate(members(spec)):
        target = run_dir / MEMBERS_DIR / member_dirname(member)
        one = member_spec(spec, member)
        (target / ".hydra").mkdir(parents=True, exist_ok=True)
        write_atomic(target / ".hydra" / "config.yaml", config_yaml(one).encode())
        overrides = [*base_overrides, *(f"{name}={value}" for name, value in member.items())]
        write_atomic(target / ".hydra" / "overrides.yaml", yaml_text(overrides).encode())
        if (run_dir / ".hydra" / "hydra.yaml").exists():
            write_atomic(target / ".hydra" / "hydra.yaml", (run_dir / ".hydra" / "hydra.yaml").read_bytes())
        rows = _split_rows(all_rows, index * per_member, per_member)
        write_atomic(target / "metrics.jsonl", "".join(json.dumps(r) + "\n" for r in rows).encode())
        seeds, total = slice(index * per_member, (index + 1) * per_member), per_member * len(members(spec))
        for source in sorted((run_dir / "checkpoints").glob("*.msgpack")):
            meta = {**checkpoint.verify(source), "num_seeds": per_member, HASH_KEY: config_hash(one.values)}
            meta.update({k: meta[k][seeds] for k in PER_SEED_META if k in meta})
            _split_checkpoint(source, target / "checkpoints", index, per_member, spec, meta)
        final = {k: v[seeds] for k, v in summary["final_eval"].items() if len(v) == total}
        returns = summary["eval_return"][seeds]
        own = {**summary, "num_seeds": per_member, "eval_return": returns, "final_eval": final}
        if "kept" in summary:
            own["kept"] = member_part(summary["kept"], seeds, total)
        own["eval_return_mean"] = float(np.mean(returns))
        own["member_of"] = str(run_dir)
        write_atomic(target / "summary.json", json.dumps(own, indent=2).encode())
        written.append(target)
    runs = load_runs([run_dir / MEMBERS_DIR])
    table = final_table(runs, distinguishing_keys(runs), "eval/return", root=run_dir / MEMBERS_DIR)
    write_csv(table, run_dir / SWEEP_SUMMARY)
    return written


def members_pending(run: RunSpec | Mapping[str, Any], run_dir: Path) -> bool:
    """Whether ``run_dir`` is an in-program sweep's run that finished training (its final checkpoint and
    ``summary.json`` are there) but was stopped while it wrote its members: ``rlq resume`` writes them."""
    run_dir = Path(run_dir)
    finished = (run_dir / "checkpoints" / "final.msgpack").exists() and (run_dir / "summary.json").exists()
    return sweeping(run) and finished and not (run_dir / SWEEP_SUMMARY).exists()


def summary_lines(run_dir: Path, written: Sequence[Path]) -> str:
    """What the console says of the members once they are written: one line each, then the table."""
    lines = []
    for target in written:
        returns = read_json_object(target / "summary.json", SUMMARY_FIX)["eval_return"]
        per_seed = ", ".join(f"{r:.1f}" for r in returns)
        lines.append(f"rlq: member {target.name}: eval return {np.mean(returns):.1f} ({per_seed}) -> {target}")
    members_dir = run_dir / MEMBERS_DIR
    lines.append(f"rlq: sweep summary {run_dir / SWEEP_SUMMARY} (plot: rlq compare {members_dir})")
    return "\n".join(lines)
