"""A checkpoint's sidecar checked against the run that reads it, before anything is compiled.

``verify`` (rlq.store.checkpoint) says the msgpack is whole; this says it is this run's: the sidecar's
hash of the settings that shape the state (``STATE_KEYS``) matches the run's config, and its env
steps fit its file name, its chunks and the run's budget. A checkpoint copied in from another run,
or a sidecar edited or mixed up with another one's, would otherwise be found out only by the
restore, after the compile, or not at all (the same shapes, another run's values).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rlq.config.plain import plain
from rlq.errors import CheckpointError

#: the config keys that decide the state's structure and meaning; ``budget``, ``devices``, logging and cadences do not
STATE_KEYS = ("env", "algo", "controller", "num_seeds")
#: the sidecar's key for ``config_hash``
HASH_KEY = "config_sha256"


def config_hash(cfg: Mapping[str, Any]) -> str:
    """SHA-256 of the run's ``STATE_KEYS``, resolved, as canonical JSON."""
    whole = plain(cfg)
    shaped = {key: whole.get(key) for key in STATE_KEYS}
    if whole.get("sweep"):  # an in-program sweep's program holds every member (rlq/run/programs/members.py)
        shaped["sweep"] = whole["sweep"]
    return hashlib.sha256(json.dumps(shaped, sort_keys=True, default=str).encode()).hexdigest()


def _whole(meta: dict[str, Any], key: str, low: int) -> int | None:
    value = meta.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise CheckpointError(f"its sidecar's {key} is {value!r}, not an integer >= {low}")
    return value


def _problem(path: Path, meta: dict[str, Any], cfg: Mapping[str, Any], expected_hash: str) -> None:
    recorded = meta.get(HASH_KEY)
    if recorded is not None and recorded != expected_hash:
        raise CheckpointError(
            f"it was written by a run of another config (its sidecar's {HASH_KEY} differs from this run's "
            f"{', '.join(STATE_KEYS)})"
        )
    env_steps = _whole(meta, "env_steps", 0)
    # a stop inside a chunk saves the chunks done before it, none where it was the first (rlq.run.stops.slices)
    mid_chunk = meta.get("chunk_calls_done") is not None
    chunks_done, chunk_steps = _whole(meta, "chunks_done", 0 if mid_chunk else 1), _whole(meta, "chunk_steps", 1)
    named = path.stem.removeprefix("step_")
    if path.stem.startswith("step_") and named.isdigit() and int(named) != env_steps:
        raise CheckpointError(f"its sidecar says env_steps {env_steps}, its name {path.name}")
    if chunks_done is not None and chunk_steps is not None:
        # a run plans whole chunks up to its budget, and one more where what is left is below a chunk (a budget
        # below one chunk, or a run extended by less than one); a resumed run extended to a larger budget may count
        # its chunks in another size, so env steps are not a multiple of them
        budget = int(cfg["budget"]["env_steps"])
        one_more = env_steps is not None and env_steps % chunk_steps == 0 and env_steps <= budget + chunk_steps
        if env_steps is not None and env_steps > max(budget, chunk_steps) and not one_more:
            raise CheckpointError(
                f"its sidecar's env_steps {env_steps} go past the run's budget (budget.env_steps={budget})"
            )
        if chunks_done * chunk_steps > max(budget, chunk_steps) + (chunk_steps if one_more else 0):
            raise CheckpointError(
                f"its sidecar's {chunks_done} chunks of {chunk_steps} env steps go past the run's budget "
                f"(budget.env_steps={budget})"
            )


def check_sidecar(path: Path, meta: dict[str, Any], cfg: Mapping[str, Any], expected_hash: str | None = None) -> None:
    """CheckpointError (naming ``path``) where the sidecar ``meta`` of checkpoint ``path`` is not one of the run
    ``cfg``'s (``expected_hash``: ``config_hash(cfg)`` when the caller has it). Sidecars of rlq versions
    without ``config_sha256`` pass the hash check."""
    try:
        _problem(Path(path), meta, cfg, expected_hash or config_hash(cfg))
    except CheckpointError as err:
        raise CheckpointError(f"{path} does not belong to this run: {err}") from None
