"""Checkpoints of the full (all-seed) learner state, as flax msgpack plus a JSON sidecar.

The state is stored as its list of leaves, restored into the structure of a template built from
the same config: env states may hold pytrees flax cannot serialise (MJX ``Data``, brax ``State``).

Each file is written atomically (a temporary file, fsync, rename), the msgpack first, then its
sidecar with the msgpack's size and SHA-256: a writer killed at any moment leaves either the
previous checkpoints alone or a checkpoint whose sidecar is missing or does not match, which
``verify`` refuses (CheckpointError) and ``resumable`` skips for the previous intact one.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
import numpy as np
from flax import serialization

from rlq.config.plain import select
from rlq.errors import CheckpointError
from rlq.lib.sharding import to_host
from rlq.store.files import write_atomic
from rlq.store.sidecar import check_sidecar, config_hash

#: the layout of the state ``save`` stores, recorded in its sidecar (``LAYOUT_KEY``): 2 since an in-program sweep's
#: state is the algorithm's alone; sidecars without it are of layout 1, where a sweep's state held each seed's swept
#: hyperparameters after it, as its last leaves (rlq.run.programs.members.state_leaves reads both)
LAYOUT = 2
LAYOUT_KEY = "layout"


#: the name of ``eval.keep=best``'s checkpoint (rlq/run/kept.py): each seed's kept state
KEPT = "kept"


def save(directory: Path, name: str, state: Any, meta: dict[str, Any]) -> Path:
    """``<directory>/<name>.msgpack`` and its JSON sidecar. Copying a state spread over processes to the
    host gathers it (a collective), so every process of such a run calls this (rlq/run/programs/distributed.py)."""
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.msgpack"
    data = serialization.msgpack_serialize({"leaves": to_host(jax.tree.leaves(state))})
    write_atomic(path, data)
    sidecar = {**meta, LAYOUT_KEY: LAYOUT, "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    write_atomic(path.with_suffix(".json"), json.dumps(sidecar, indent=2).encode())
    return path


def reopen_final(directory: Path, env_steps: int, extra: dict[str, Any]) -> Path:
    """``final.msgpack`` back as ``step_<env_steps>.msgpack``, its sidecar with ``extra``: a run stopped
    before its end was recorded (its final evaluation) is resumable again. The new sidecar is written
    first: a stop in between leaves the run as it was."""
    final = directory / "final.msgpack"
    path = directory / f"step_{env_steps}.msgpack"
    write_atomic(path.with_suffix(".json"), json.dumps({**meta(final), **extra}, indent=2).encode())
    os.replace(final, path)
    final.with_suffix(".json").unlink(missing_ok=True)
    return path


def meta(path: Path) -> dict[str, Any]:
    """The JSON sidecar ``save`` wrote next to the checkpoint ``path``."""
    sidecar = Path(path).with_suffix(".json")
    try:
        found = json.loads(sidecar.read_text())
    except FileNotFoundError:
        raise CheckpointError(f"{path} has no sidecar {sidecar.name} (its writer was stopped)") from None
    except (OSError, ValueError) as err:
        raise CheckpointError(f"{sidecar} is unreadable (truncated or corrupt): {err}") from None
    if not isinstance(found, dict) or "env_steps" not in found:
        raise CheckpointError(f"{sidecar} is truncated or corrupt (no env_steps)")
    return found


def _verified_bytes(path: Path) -> bytes:
    """The checkpoint's bytes, after checking them against the sidecar's size and SHA-256."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"no checkpoint {path}")
    expected = meta(path)
    data = path.read_bytes()
    if "sha256" in expected:  # checkpoints of earlier rlq versions have no checksum
        if len(data) != expected["bytes"]:
            raise CheckpointError(f"{path} is truncated: {len(data)} bytes, its sidecar says {expected['bytes']}")
        if hashlib.sha256(data).hexdigest() != expected["sha256"]:
            raise CheckpointError(f"{path} is corrupt: its SHA-256 differs from the one its sidecar recorded")
    return data


def verify(path: Path) -> dict[str, Any]:
    """The sidecar of an intact checkpoint; CheckpointError for a missing, truncated or corrupt one."""
    _verified_bytes(path)
    return meta(path)


def leaves(path: Path) -> list[Any]:
    """The state's leaves as ``save`` stored them, in ``jax.tree.leaves`` order."""
    try:
        stored = serialization.msgpack_restore(_verified_bytes(path))["leaves"]
    except CheckpointError:
        raise
    except Exception as err:  # msgpack's own errors for bytes that are no checkpoint
        raise CheckpointError(f"{path} is not an rlq checkpoint ({type(err).__name__}: {err})") from None
    return [stored[str(i)] for i in range(len(stored))] if isinstance(stored, dict) else list(stored)


def load(path: Path, template: Any, stored: list[Any] | None = None) -> Any:
    """Restore a state saved by ``save`` into the structure of ``template``; ``stored``: the state's leaves where
    the caller read them from ``path`` (rlq.run.programs.members.state_leaves)."""
    leaves_ = leaves(path) if stored is None else stored
    structure = jax.tree.structure(template)
    expected = jax.tree.leaves(template)
    if len(expected) != len(leaves_):
        raise CheckpointError(f"{path} holds {len(leaves_)} arrays, the run's config builds {len(expected)}")
    for i, (want, got) in enumerate(zip(expected, leaves_, strict=True)):
        if tuple(np.shape(want)) != tuple(np.shape(got)):
            raise CheckpointError(
                f"{path}: array {i} has shape {np.shape(got)}, the run's config builds {tuple(np.shape(want))}"
            )
    return jax.tree.unflatten(structure, leaves_)


def env_steps(path: Path) -> int:
    """Env steps per seed at which the checkpoint ``path`` was written (from its JSON sidecar)."""
    return int(meta(path)["env_steps"])


def intermediate(directory: Path) -> list[Path]:
    """The ``step_*`` checkpoints (``checkpoint.every_steps``), oldest first (by the step in the name)."""
    found = [p for p in directory.glob("step_*.msgpack") if p.stem[len("step_") :].isdigit()]
    return sorted(found, key=lambda p: int(p.stem[len("step_") :]))


def newest_intact(run_dir: Path, cfg: Mapping[str, Any] | None = None) -> tuple[Path, list[str]]:
    """The final checkpoint, else the latest intermediate one, that verifies, falling back past any that do not (a
    writer stopped between its two renames leaves a step checkpoint without its sidecar); and a note for each one
    skipped, for the command to say which it used. What `rlq resume` does for unfinished runs, for every reader.
    ``cfg``: the run's config, whose sidecar check (rlq.store.sidecar) each candidate must pass too."""
    directory = Path(run_dir) / "checkpoints"
    final = directory / "final.msgpack"
    candidates = ([final] if final.exists() else []) + list(reversed(intermediate(directory)))
    if not candidates:
        raise CheckpointError(f"no checkpoint in {directory}")
    path, skipped = _first_intact(candidates, cfg)
    if path is None:
        raise CheckpointError(skipped[0] if len(skipped) == 1 else f"no intact checkpoint in {directory}: {skipped[0]}")
    return path, skipped


def _first_intact(candidates: list[Path], cfg: Mapping[str, Any] | None = None) -> tuple[Path | None, list[str]]:
    """The first of ``candidates`` that verifies (None: none does), and why each one before it did not; with
    ``cfg``, one whose sidecar is also the run's (``check_sidecar``)."""
    skipped = []
    expected = config_hash(cfg) if cfg is not None else None
    for path in candidates:
        try:
            found = verify(path)
            if cfg is not None:
                check_sidecar(path, found, cfg, expected)
        except CheckpointError as err:
            skipped.append(str(err))
            continue
        return path, skipped
    return None, skipped


def latest(run_dir: Path) -> Path:
    """The newest intact checkpoint (``newest_intact``): the final one, or the latest intermediate one."""
    return newest_intact(run_dir)[0]


def last_intact(directory: Path) -> Path | None:
    """The latest intermediate checkpoint that verifies, if any."""
    return _first_intact(list(reversed(intermediate(Path(directory)))))[0]


def resumable(run_dir: Path, cfg: Mapping[str, Any] | None = None) -> tuple[Path, list[str]]:
    """The latest intact intermediate checkpoint of an unfinished run (``checkpoint.every_steps`` > 0)
    and a note for each later one that was skipped because it is truncated or corrupt."""
    directory = Path(run_dir) / "checkpoints"
    damaged: list[str] = []
    if (directory / "final.msgpack").exists():
        # a final checkpoint whose write was killed (no summary yet) is skipped like a damaged step_N
        if not (Path(run_dir) / "summary.json").exists():
            damaged = _first_intact([directory / "final.msgpack"], cfg)[1]
        if not damaged:
            raise CheckpointError(
                f"{run_dir} has finished (checkpoints/final.msgpack exists): nothing to resume; "
                f"extend it with `rlq resume run={run_dir} budget.env_steps=N`"
            )
    found = intermediate(directory)
    every = int(select(cfg, "checkpoint.every_steps") or 0) if cfg is not None else 0
    if not found and every > 0:
        raise CheckpointError(
            f"no intermediate checkpoint in {directory}: the run stopped before its first one (at {every:,} env "
            "steps) was written whole, so there is nothing to resume; train it again"
        )
    if not found:
        raise CheckpointError(
            f"no intermediate checkpoint in {directory}; train with checkpoint.every_steps>0 to make runs resumable"
        )
    path, skipped = _first_intact(list(reversed(found)), cfg)
    if path is None:
        raise CheckpointError(f"no intact checkpoint in {directory}: {skipped[0]}")
    return path, damaged + skipped


def final_without_summary(run_dir: Path, cfg: Mapping[str, Any] | None = None) -> Path | None:
    """The intact final checkpoint of a run killed after writing it but before its ``summary.json`` (written
    last), which `rlq resume` finishes without training; None for any other run."""
    final = Path(run_dir) / "checkpoints" / "final.msgpack"
    if (Path(run_dir) / "summary.json").exists() or not final.exists():
        return None
    return _first_intact([final], cfg)[0]


def resolve_noting(run_dir: Path, name: str | None, cfg: Mapping[str, Any] | None = None) -> tuple[Path, list[str]]:
    """``resolve``, and the notes of the checkpoints skipped for being truncated or corrupt (only where none was
    named: a named checkpoint is that one or an error); with ``cfg``, checked against the run (``check_sidecar``).
    A finished run of ``eval.keep=best`` (rlq/run/kept.py) reads, unless told otherwise, the states it reported:
    ``kept.msgpack``."""
    if name is None:
        kept, skipped = _kept_of_finished(Path(run_dir), cfg)
        if kept is not None:
            return kept, []
        path, more = newest_intact(run_dir, cfg)
        return path, skipped + more
    path = resolve(run_dir, name)
    if cfg is not None:
        check_sidecar(path, verify(path), cfg)
    return path, []


def _kept_of_finished(run_dir: Path, cfg: Mapping[str, Any] | None) -> tuple[Path | None, list[str]]:
    """``kept.msgpack`` of a finished run whose config ``cfg`` says ``eval.keep=best``, if it verifies (and why
    not, where it does not); None for any other run."""
    kept = run_dir / "checkpoints" / f"{KEPT}.msgpack"
    if (
        cfg is None
        or select(cfg, "eval.keep") != "best"
        or not (run_dir / "summary.json").exists()
        or not kept.exists()
    ):
        return None, []
    return _first_intact([kept], cfg)


def resolve(run_dir: Path, name: str | None) -> Path:
    """The checkpoint a command names: None, the latest (``latest``); ``final``; ``kept`` (``eval.keep=best``'s
    states); a step count ``N`` (``step_N.msgpack``, kept with ``checkpoint.every_steps``); or a path to a .msgpack
    file."""
    directory = Path(run_dir) / "checkpoints"
    if name is None:
        return latest(run_dir)
    if name in ("final", KEPT) or name.isdigit():
        path = directory / (f"{name}.msgpack" if not name.isdigit() else f"step_{int(name)}.msgpack")
        if not path.exists():
            kept = [p.stem[len("step_") :] for p in intermediate(directory)]
            kept += [other for other in ("final", KEPT) if (directory / f"{other}.msgpack").exists()]
            raise CheckpointError(
                f"no checkpoint {path.name} in {directory}; kept: {', '.join(kept) or 'none'} "
                "(checkpoint=<env steps>, checkpoint=final or checkpoint=kept)"
            )
        return path
    path = Path(name)
    if not path.exists():
        raise CheckpointError(f"no checkpoint file {name} (checkpoint=<env steps>, final, or a .msgpack path)")
    return path
