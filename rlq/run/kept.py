"""``eval.keep=best``: each seed's best policy, chosen on the run's greedy evaluations and scored again at its end.

A DQN seed on CartPole can reach a greedy return of 500 and lose it for good late in the run (its learning rate
annealed by then): 7 of the 7 seeds that ended under 475 in the tuning runs of 2026-12-07 had evaluated at 500
at 281k or 374k env steps. With ``eval.keep=best`` the run keeps, per seed, the state of its best periodic greedy
evaluation (ties go to the later one), the final evaluation's state counting too; at its end it scores those
states on episodes none of the choosing evaluations saw (as Stable-Baselines3's ``EvalCallback`` keeps a best
model), and reports that score as the run's return. The training itself is unchanged: the kept states are copies
on the host, saved as ``checkpoints/kept.msgpack`` at each change, from which a resumed run reads them back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import numpy as np

from rlq.lib.sharding import to_host
from rlq.run.hooks import ChunkEnd, Hook
from rlq.store import checkpoint
from rlq.store.jsonfiles import read_json_object
from rlq.store.sidecar import HASH_KEY

KEPT = checkpoint.KEPT  # checkpoints/kept.msgpack and its kept.json sidecar


def improved(returns: np.ndarray, best: np.ndarray) -> np.ndarray:
    """Per seed, whether ``returns`` is at least the ``best`` so far (NaN never is)."""
    returns = np.asarray(returns, np.float64)
    return np.where(np.isnan(returns), False, returns >= best)


def merged(new: Any, old: Any, take: np.ndarray) -> Any:
    """``new``'s entry for each seed where ``take`` holds, ``old``'s elsewhere (host pytrees, seeds on the leading
    axis). A leaf without that axis (a buffer the seeds share, rlq.lib.batch.seed_entry) comes from ``new``."""
    num_seeds = len(take)

    def pick(a: Any, b: Any) -> Any:
        a = np.asarray(a)
        if a.ndim == 0 or a.shape[0] != num_seeds:
            return a
        return np.where(take.reshape((num_seeds,) + (1,) * (a.ndim - 1)), a, np.asarray(b))

    return jax.tree.map(pick, new, old)


class KeepSeedsBest(Hook):
    """Listens to PeriodicEval: per seed, the state of its best greedy return so far, on the host and in
    ``checkpoints/kept.msgpack`` (its sidecar: each seed's return and env steps). A resumed run reads them back."""

    def __init__(self, directory: Path, num_seeds: int):
        self.directory = directory
        self.returns = np.full(num_seeds, -math.inf)
        self.from_steps = np.zeros(num_seeds, np.int64)
        self.state: Any = None
        sidecar = directory / f"{KEPT}.json"
        self._stored = directory / f"{KEPT}.msgpack" if sidecar.exists() else None
        if self._stored is not None:
            meta = read_json_object(sidecar)
            self.returns = np.asarray(meta["eval_return"], np.float64)
            self.from_steps = np.asarray(meta["from_env_steps"], np.int64)

    def _held(self, template: Any) -> Any:
        """The kept states, read from their checkpoint the first time (``template``: a state of the run's shape)."""
        if self.state is None and self._stored is not None:
            self.state = checkpoint.load(self._stored, template)
        return self.state

    def _take(self, state: Any, returns: np.ndarray, env_steps: int, meta: dict[str, Any]) -> None:
        """``state`` (host arrays) kept for each seed whose ``returns`` is at least its best, and saved."""
        returns = np.asarray(returns, np.float64)
        take = improved(returns, self.returns)
        held = self._held(state)
        self.state = state if held is None else merged(state, held, take)
        self.returns = np.where(take, returns, self.returns)
        self.from_steps = np.where(take, env_steps, self.from_steps)
        meta = {
            **meta,
            "eval_return": [float(r) for r in self.returns],
            "from_env_steps": [int(s) for s in self.from_steps],
        }
        checkpoint.save(self.directory, KEPT, self.state, meta)

    def on_eval(self, end: ChunkEnd, result: dict[str, np.ndarray]) -> None:
        if not improved(result["return"], self.returns).any():
            return
        meta: dict[str, Any] = {"env_steps": end.env_steps, "chunks_done": end.index + 1}
        if end.config_sha256:
            meta[HASH_KEY] = end.config_sha256
        self._take(to_host(end.state), result["return"], end.env_steps, meta)

    def with_final(
        self, state: Any, returns: np.ndarray, env_steps: int, meta: dict[str, Any]
    ) -> tuple[Any, list[int]]:
        """The states the run ends with: per seed the best of the kept ones and the final ``state`` (host arrays),
        by the final evaluation's ``returns``, saved with ``meta``; and the env steps each comes from."""
        self._take(state, returns, env_steps, meta)
        return self.state, [int(s) for s in self.from_steps]


@dataclass(frozen=True)
class Kept:
    """What ``eval.keep=best`` ends a run with: each seed's chosen state (on the run's mesh), the env steps each
    comes from, and their greedy evaluation on fresh episodes (per-seed figures, as ``eval_summary`` gives)."""

    state: Any
    from_steps: list[int]
    scores: dict[str, np.ndarray]

    def record(self) -> dict[str, Any]:
        """The run result's ``kept`` entry (``RunResult.kept``)."""
        return {"from_env_steps": list(self.from_steps), "eval": self.scores}
