"""``objective``: the one number a run hands back to Hydra's sweepers (Optuna, Nevergrad, Ax) to optimise,
e.g. ``eval/return``: the final greedy evaluation's metric (``eval/<name>``) or the last training row's
(``train/<name>``), the mean over the run's seeds."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rlq.errors import ConfigError
from rlq.store.jsonfiles import read_rows

KINDS = ("eval", "train")


def parse_objective(text: str) -> tuple[str, str]:
    """``eval/return`` -> ("eval", "return"); a ConfigError names the form otherwise."""
    kind, sep, name = str(text).partition("/")
    if not sep or kind not in KINDS or not name:
        raise ConfigError(
            f"objective={text}: write eval/<name> or train/<name>, e.g. objective=eval/return (what a sweeper optimises)"
        )
    return kind, name


def _last_train_row(metrics: Path) -> dict[str, Any]:
    rows = read_rows(metrics).rows
    means = [row for row in rows if row.get("kind") == "train" and row.get("seed") == "mean"]
    return means[-1] if means else {}


def objective_value(text: str, final_eval: dict[str, np.ndarray], run_dir: Path) -> float:
    """The value of ``objective`` for a finished run: ``final_eval`` (per seed) for eval/, the run's
    ``metrics.jsonl`` for train/. A ConfigError lists the names there are when ``text`` names none."""
    kind, name = parse_objective(text)
    found: dict[str, Any] = dict(final_eval) if kind == "eval" else _last_train_row(run_dir / "metrics.jsonl")
    if name not in found or found[name] is None:
        names = sorted(k for k in found if k not in ("kind", "seed", "env_steps", "wall_s"))
        raise ConfigError(f"objective={text}: {kind} rows have no {name!r}; they have: {', '.join(names)}")
    return float(np.mean(np.asarray(found[name], np.float64)))
