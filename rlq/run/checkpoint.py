"""Checkpoints of the full (all-seed) learner state, as flax msgpack plus a JSON sidecar.

The state is stored as its list of leaves, restored into the structure of a template built from
the same config: env states may hold pytrees flax cannot serialise (MJX ``Data``, brax ``State``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jax
from flax import serialization

from rlq.errors import CheckpointError


def save(directory: Path, name: str, state: Any, meta: dict[str, Any]) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.msgpack"
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(serialization.msgpack_serialize({"leaves": jax.device_get(jax.tree.leaves(state))}))
    tmp.replace(path)
    (directory / f"{name}.json").write_text(json.dumps(meta, indent=2))
    return path


def leaves(path: Path) -> list[Any]:
    """The state's leaves as ``save`` stored them, in ``jax.tree.leaves`` order."""
    stored = serialization.msgpack_restore(Path(path).read_bytes())["leaves"]
    return [stored[str(i)] for i in range(len(stored))] if isinstance(stored, dict) else list(stored)


def load(path: Path, template: Any) -> Any:
    """Restore a state saved by ``save`` into the structure of ``template``."""
    leaves_ = leaves(path)
    structure = jax.tree.structure(template)
    expected = len(jax.tree.leaves(template))
    if expected != len(leaves_):
        raise ValueError(f"{path} holds {len(leaves_)} arrays, the run's config builds {expected}")
    return jax.tree.unflatten(structure, leaves_)


def meta(path: Path) -> dict[str, Any]:
    """The JSON sidecar ``save`` wrote next to the checkpoint ``path``."""
    return json.loads(Path(path).with_suffix(".json").read_text())


def env_steps(path: Path) -> int:
    """Env steps per seed at which the checkpoint ``path`` was written (from its JSON sidecar)."""
    return int(json.loads(Path(path).with_suffix(".json").read_text())["env_steps"])


def _intermediate(directory: Path) -> list[Path]:
    """The ``step_*`` checkpoints (``checkpoint.every_steps``), oldest first."""
    return sorted(directory.glob("step_*.msgpack"), key=env_steps)


def latest(run_dir: Path) -> Path:
    """The final checkpoint, or the latest intermediate one of an unfinished run."""
    directory = Path(run_dir) / "checkpoints"
    final = directory / "final.msgpack"
    if final.exists():
        return final
    found = _intermediate(directory)
    if not found:
        raise FileNotFoundError(f"no checkpoint in {directory}")
    return found[-1]


def resumable(run_dir: Path) -> Path:
    """The latest intermediate checkpoint of an unfinished run (``checkpoint.every_steps`` > 0)."""
    directory = Path(run_dir) / "checkpoints"
    if (directory / "final.msgpack").exists():
        raise ValueError(f"{run_dir} has finished (checkpoints/final.msgpack exists): nothing to resume")
    found = _intermediate(directory)
    if not found:
        raise FileNotFoundError(
            f"no intermediate checkpoint in {directory}; train with checkpoint.every_steps>0 to make runs resumable"
        )
    return found[-1]


def resolve(run_dir: Path, name: str | None) -> Path:
    """The checkpoint a command names: None, the latest (``latest``); ``final``; a step count
    ``N`` (``step_N.msgpack``, kept with ``checkpoint.every_steps``); or a path to a .msgpack file."""
    directory = Path(run_dir) / "checkpoints"
    if name is None:
        return latest(run_dir)
    if name == "final" or name.isdigit():
        path = directory / ("final.msgpack" if name == "final" else f"step_{int(name)}.msgpack")
        if not path.exists():
            kept = [str(env_steps(p)) for p in _intermediate(directory)]
            kept += ["final"] if (directory / "final.msgpack").exists() else []
            raise CheckpointError(
                f"no checkpoint {path.name} in {directory}; kept: {', '.join(kept) or 'none'} "
                "(checkpoint=<env steps> or checkpoint=final)"
            )
        return path
    path = Path(name)
    if not path.exists():
        raise CheckpointError(f"no checkpoint file {name} (checkpoint=<env steps>, final, or a .msgpack path)")
    return path
