"""``init_from=<run dir>[:checkpoint]``: a new run whose policy starts from a trained run's parameters.

The new run is fresh in everything else (optimiser, replay buffer, envs, counters, its own seeds and
config, e.g. domain randomisation added to a trained humanoid); only the parts of the state that make the
policy come over: the networks (and their targets), PPO's observation normalisation, a Q-table, a
black-box search's best genotype. The checkpoint's seeds are dealt to the new run's in turn (seed i takes
the trained seed i mod their count). The algorithm and the networks' shapes must be the trained run's."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
import numpy as np

from rlq.config.plain import read_recorded_config, select
from rlq.errors import ConfigError

#: the parts of an algorithm's state that make its policy, as attribute paths
POLICY_PARTS = (
    ("params",),
    ("obs_stats",),
    ("learner", "params"),
    ("learner", "target_params"),
    ("learner", "ema_params"),
    ("table",),
    ("best_params",),
)


def parse_init_from(text: str) -> tuple[Path, str | None]:
    """``<run dir>[:checkpoint]`` -> (run dir, checkpoint name or None: the newest intact one); a checkpoint is
    ``final`` or env steps (``:40000``)."""
    head, sep, tail = str(text).rpartition(":")
    if sep and head and (tail == "final" or tail.isdigit()):
        return Path(head), tail
    return Path(text), None


def check_init_from(cfg: Mapping[str, Any]) -> None:
    """Before anything compiles: the run ``init_from`` names exists, has the checkpoint, and trained this algo."""
    from rlq.store import checkpoint

    init_from, this_algo = cfg["init_from"], cfg["algo"]["name"]
    run_dir, name = parse_init_from(init_from)
    recorded = run_dir / ".hydra" / "config.yaml"
    if not recorded.is_file():
        raise ConfigError(f"init_from={init_from}: {run_dir} is not an rlq run directory (no .hydra/config.yaml)")
    algo = select(read_recorded_config(recorded), "algo.name")
    if algo != this_algo:
        raise ConfigError(
            f"init_from={init_from}: that run trained algo={algo}, this one is algo={this_algo}; "
            "parameters carry over within one algorithm"
        )
    try:
        checkpoint.resolve(run_dir, name)
    except Exception as err:
        raise ConfigError(f"init_from={init_from}: {err}") from None


def _part(state: Any, path: tuple[str, ...]) -> Any:
    for name in path:
        state = getattr(state, name, None)
        if state is None:
            return None
    return state


def _with_part(state: Any, path: tuple[str, ...], value: Any) -> Any:
    if len(path) == 1:
        return state.replace(**{path[0]: value})
    return state.replace(**{path[0]: _with_part(getattr(state, path[0]), path[1:], value)})


def _dealt(trained: Any, fresh: Any, where: str) -> Any:
    """``trained``'s leaves over ``fresh``'s seeds (leading axis), after checking structure and shapes."""
    t_leaves, t_def = jax.tree.flatten(trained)
    f_leaves, f_def = jax.tree.flatten(fresh)
    same_tree = str(t_def) == str(f_def)  # PyTreeDef's own comparison has no type stubs
    if not same_tree or any(np.shape(t)[1:] != np.shape(f)[1:] for t, f in zip(t_leaves, f_leaves, strict=True)):
        shapes = [np.shape(t)[1:] for t in t_leaves], [np.shape(f)[1:] for f in f_leaves]
        raise ConfigError(
            f"init_from: the trained run's {where} does not fit this run's (shapes {shapes[0]} vs {shapes[1]}): "
            "give the network the trained run's sizes (algo.hidden, ...) and the same env spaces"
        )
    count = np.shape(f_leaves[0])[0]
    picked = [
        np.asarray(t)[np.arange(count) % np.shape(t)[0]].astype(np.asarray(f).dtype)
        for t, f in zip(t_leaves, f_leaves, strict=True)
    ]
    return jax.tree.unflatten(f_def, picked)


def warm_state(cfg: Mapping[str, Any], fresh: Any) -> Any:
    """``fresh`` (a new run's initial all-seed state, on the host) with the policy parts of ``cfg.init_from``'s
    checkpoint; a ConfigError says what does not fit."""
    from rlq.store import checkpoint
    from rlq.tools.evaluate import restore_run

    run_dir, name = parse_init_from(cfg["init_from"])
    _, _, trained, path = restore_run(run_dir, name)
    trained = jax.device_get(trained)
    parts = [p for p in POLICY_PARTS if _part(fresh, p) is not None and _part(trained, p) is not None]
    if not parts:
        raise ConfigError(
            f"init_from={cfg['init_from']}: its state has no policy parameters this run's algorithm reads"
        )
    for part in parts:
        fresh = _with_part(fresh, part, _dealt(_part(trained, part), _part(fresh, part), ".".join(part)))
    steps = checkpoint.env_steps(path)
    print(f"rlq: policy from {path} ({steps:,} env steps): {', '.join('.'.join(p) for p in parts)}", flush=True)
    return fresh
