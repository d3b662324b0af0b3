"""The Algorithm protocol: pure ``init`` / ``update`` / ``policy`` functions, no I/O.

The training loop vmaps ``init`` over seeds and scans ``update``; everything an algorithm needs
between updates (parameters, optimiser state, env states, buffers, PRNG key, counters) lives
in its state pytree. ``update`` returns scalar metrics and must include ``env_steps``, the
cumulative number of env steps consumed, which the loop uses for budgets and logging.

The numeric hyperparameters are ``init``'s and ``update``'s second argument, not part of the state
(evosax's ``init(key, mean, params)`` and ``ask(key, state, params)``): ``init(key, hyperparams)``,
``update(state, hyperparams)``, ``hyperparams`` a dict of scalars with every key of
``Algorithm.hyperparams``. The init and chunk programs pass them as float32 arrays per seed, so runs
that differ only in them share their compiled programs, and an in-program sweep is the same vmap
with other values per seed (rlq/run/programs/build.py, members.py).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import jax
import numpy as np

from rlq.lib.policy_export import PolicyExport
from rlq.lib.rollout import PolicyFn

AlgoState = Any
Metrics = dict[str, jax.Array]
#: numeric hyperparameters by name (``epsilon.start`` for a nested key): Python floats or (traced) scalar arrays
Hyperparams = Mapping[str, Any]
InitFn = Callable[[jax.Array, Hyperparams], AlgoState]
UpdateFn = Callable[[AlgoState, Hyperparams], tuple[AlgoState, Metrics]]


@dataclass(frozen=True)
class Algorithm:
    #: the first state from a PRNG key at the given hyperparameters (ES's search starts at its ``sigma``)
    init: InitFn
    #: one iteration at the given hyperparameters (every key of ``hyperparams``), which enter it only as arithmetic
    update: UpdateFn
    policy: Callable[[AlgoState], PolicyFn]
    #: updates needed to spend the env-step budget
    num_updates: int
    #: nominal env steps per update (summed over parallel envs), for throughput figures
    steps_per_update: int
    #: host-side pictures of one seed's state, name -> RGB uint8 image (MAP-Elites' heatmap); the
    #: loop saves them as PNG and logs them to W&B every ``figures_every`` updates and at the end
    figures: Callable[[AlgoState], dict[str, np.ndarray]] | None = None
    #: updates between figures (0: at the end only)
    figures_every: int = 0
    #: figures also at each periodic evaluation (``eval.every_steps``; the tabular Q-table)
    figures_at_eval: bool = False
    #: pure summary metrics of a state (the archive's QD metrics), logged with each evaluation
    #: and reported by `rlq eval`
    state_metrics: Callable[[AlgoState], Metrics] | None = None
    #: the greedy policy's network parameters alone, of one seed's state on the host (`rlq export`);
    #: None where the policy is not a network (a Q-table, an archive of genotypes)
    export: Callable[[AlgoState], PolicyExport] | None = None
    #: the learned parameters of a state (network weights, a Q-table), which the loop checks for
    #: NaN/Inf after every update (rlq.run.stops.guard); None: only the losses and returns are checked
    params: Callable[[AlgoState], Any] | None = None
    #: one update is one generation of whole episodes (random search, MAP-Elites): episodes end
    #: early, so true env steps fall below the nominal ``steps_per_update`` and the progress bar
    #: counts iterations instead of env steps
    iterations: bool = False
    #: one-line notes the run prints at its start: settings that are legal but do something
    #: surprising (a learner that never starts within the budget)
    notes: tuple[str, ...] = ()
    #: ``init``'s and ``update``'s hyperparameters at the run's config values (``AlgorithmSpec.sweepable`` names
    #: them); empty for an algorithm with none. Passed as Python floats they are constants; the init and chunk
    #: programs pass them as arrays (rlq/run/programs/build.py)
    hyperparams: Mapping[str, float] = field(default_factory=dict)


def updates_for_budget(budget_env_steps: int, steps_per_update: int) -> int:
    """Whole updates that fit in the budget (at least one)."""
    return max(1, int(budget_env_steps) // int(steps_per_update))


def budget_note(budget_env_steps: int, steps_per_update: int, iterations: bool = False) -> str | None:
    """The note a run prints when its budget is below one update, which it takes anyway
    (``updates_for_budget``), so that the env steps it reports do not come as a surprise.
    ``iterations``: an update's episodes end early (``Algorithm.iterations``), so its size is a bound."""
    if int(budget_env_steps) >= int(steps_per_update):
        return None
    size = f"{'up to ' if iterations else ''}{int(steps_per_update):,} env steps per seed"
    return f"budget.env_steps={int(budget_env_steps)} is below one update ({size}): the run takes one update"


def rounded_note(budget_env_steps: int, planned: int, steps_per_update: int, iterations: bool = False) -> str | None:
    """The note of a budget a run rounds down to its whole updates (2,000 -> 1,536 at 512 env steps per update);
    None where it trains the budget, takes one update (``budget_note``) or counts iterations of varying size."""
    budget = int(budget_env_steps)
    if iterations or budget < int(steps_per_update) or planned >= budget:
        return None
    updates = planned // int(steps_per_update)
    return (
        f"budget.env_steps={budget:,} rounds down to {planned:,} env steps per seed ({updates:,} whole updates of "
        f"{int(steps_per_update):,})"
    )
