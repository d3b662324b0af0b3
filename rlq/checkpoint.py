"""Checkpoints of the full (all-seed) learner state, as flax msgpack plus a JSON sidecar."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jax
from flax import serialization


def save(directory: Path, name: str, state: Any, meta: dict[str, Any]) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.msgpack"
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(serialization.to_bytes(jax.device_get(state)))
    tmp.replace(path)
    (directory / f"{name}.json").write_text(json.dumps(meta, indent=2))
    return path


def load(path: Path, template: Any) -> Any:
    """Restore a state saved by ``save`` into the structure of ``template``."""
    return serialization.from_bytes(template, Path(path).read_bytes())


def latest(run_dir: Path) -> Path:
    directory = Path(run_dir) / "checkpoints"
    final = directory / "final.msgpack"
    if final.exists():
        return final
    found = sorted(directory.glob("*.msgpack"), key=lambda p: p.stat().st_mtime)
    if not found:
        raise FileNotFoundError(f"no checkpoint in {directory}")
    return found[-1]
