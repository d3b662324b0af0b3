"""A policy that collapsed: its entropy fell near zero while its return stayed far from good, which the divergence
guard (rlq/run/stops/guard.py) does not see: every number stays finite. REINFORCE at ``algo.lr=100`` on CartPole turns
deterministic within 20,000 env steps (entropy 0.0, from 0.69) at a return of 27 and exits 0 otherwise.

Checked on the host at each train row (the chunk's metrics have left the device already): no sync is added. Only
algorithms that log an ``entropy`` (PPO, REINFORCE) on a Discrete action space (a Gaussian's differential entropy
has no zero: a healthy policy's falls below any fraction of its start) are watched. The rule, per seed:

- the chunk's mean entropy is at most ``ENTROPY_FRACTION`` of the first update's, and
- the chunk's train return (``episode_return``) is at most ``R0 + max(RETURN_SHARE x (best - R0), |R0|)``: no better
  than twice the first update's return ``R0`` (a collapse before learning), nor than a quarter of the way from it to
  the best train return so far (a collapse after learning).

Measured on the tuned CartPole recipes (4 seeds each, full budgets): PPO's entropy stays above 0.33 (of 0.69) and
REINFORCE's above 0.30, where returns are near 500; REINFORCE at ``algo.lr`` 1, 100 or 1e6 falls to 0.00-0.14
at returns of 26-33 (a random policy's: 22). The warning is one line, once per run, and ``summary.json`` lists it
under ``warnings``; the run goes on (exit 0).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from rlq.run.hooks import ChunkEnd, Hook
from rlq.store.jsonfiles import read_rows
from rlq.store.logging import RunLogger

#: the entropy "near zero": at most this share of the first update's
ENTROPY_FRACTION = 0.25
#: the return "far from good": below this share of the way from the first update's return to the best so far
RETURN_SHARE = 0.25
ENTROPY, RETURN = "entropy", "episode_return"


def _first_finite(values: np.ndarray) -> np.ndarray:
    """Per row (seed) of ``values`` (seeds x updates), its first finite value (NaN where none)."""
    values = np.asarray(values, np.float64).reshape(len(values), -1)
    finite = np.isfinite(values)
    first = np.argmax(finite, axis=1)
    picked = values[np.arange(len(values)), first]
    return np.where(finite.any(axis=1), picked, np.nan)


def start_from_rows(path: Path, num_seeds: int) -> tuple[np.ndarray, np.ndarray] | None:
    """A resumed run's start: each seed's first train row of ``metrics.jsonl`` (entropy, return), or None."""
    entropy, returns = np.full(num_seeds, np.nan), np.full(num_seeds, np.nan)
    for row in read_rows(path, note=False).rows:
        seed = row.get("seed")
        if row.get("kind") != "train" or not isinstance(seed, int) or not 0 <= seed < num_seeds:
            continue
        if math.isnan(entropy[seed]):
            entropy[seed] = float(row.get(ENTROPY, np.nan))
        if math.isnan(returns[seed]) and isinstance(row.get(RETURN), int | float):
            returns[seed] = float(row[RETURN])
    return None if np.isnan(entropy).all() else (entropy, returns)


def collapsed(entropy: float, start_entropy: float, ret: float, start_return: float, best: float) -> bool:
    """The rule above, for one seed."""
    if not (start_entropy > 0 and math.isfinite(entropy) and math.isfinite(ret) and math.isfinite(start_return)):
        return False
    margin = max(RETURN_SHARE * (best - start_return), abs(start_return))
    return entropy <= ENTROPY_FRACTION * start_entropy and ret <= start_return + margin


class CollapseWatch(Hook):
    """Warns once when a seed's policy collapsed (the rule above) and keeps the flag for ``summary.json``.

    ``lr``: the run's ``algo.lr``, named in the advice; ``metrics``: ``metrics.jsonl``, a resumed run's start."""

    def __init__(self, logger: RunLogger, metrics: Path, lr: Any = None):
        self.logger, self.metrics, self.lr = logger, metrics, lr
        self.start: tuple[np.ndarray, np.ndarray] | None = None
        self.best: np.ndarray | None = None
        self._started = False

    def _begin(self, end: ChunkEnd) -> None:
        self._started = True
        num_seeds = len(end.summary[ENTROPY])
        updates = end.updates or {}
        if end.index == 0 and ENTROPY in updates:  # a fresh run: the first update's figures
            returns = updates.get(RETURN)
            start_return = _first_finite(returns) if returns is not None else np.full(num_seeds, np.nan)
            self.start = (_first_finite(updates[ENTROPY]), start_return)
        else:  # resumed: the first rows written
            self.start = start_from_rows(self.metrics, num_seeds)

    def on_chunk(self, end: ChunkEnd) -> None:
        if self.flags or ENTROPY not in end.summary or RETURN not in end.summary:
            return
        if not self._started:
            self._begin(end)
        if self.start is None:
            return
        start_entropy, start_return = self.start
        returns = np.asarray(end.summary[RETURN], np.float64)
        start_return = np.where(np.isnan(start_return), returns, start_return)  # no episode ended at first
        self.start = (start_entropy, start_return)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            self.best = returns if self.best is None else np.fmax(self.best, returns)
        entropy = np.asarray(end.summary[ENTROPY], np.float64)
        seeds = [
            s
            for s in range(len(entropy))
            if collapsed(entropy[s], start_entropy[s], returns[s], start_return[s], self.best[s])
        ]
        if not seeds:
            return
        s = seeds[0]
        which = f"seed {s}" if len(seeds) == 1 else f"seeds {', '.join(map(str, seeds))} (seed {s} shown)"
        flag = (
            f"policy_collapse at env step {end.env_steps:,}: {which}: entropy {entropy[s]:.3g} "
            f"(first update {start_entropy[s]:.3g}), train return {returns[s]:.4g} (first {start_return[s]:.4g}, "
            f"best {self.best[s]:.4g})"
        )
        self.flags = (flag,)
        lr = f"a lower algo.lr (now {self.lr:g})" if isinstance(self.lr, int | float) else "a lower learning rate"
        self.logger.console.warn(
            f"{flag}: the policy turned nearly deterministic without learning; training goes on, try {lr}"
        )
