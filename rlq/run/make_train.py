"""A run's training as one jittable function, for users who want rlq's loop without the CLI (PureJaxRL's shape)::

    import jax
    import jax.numpy as jnp
    from rlq import make_train

    train = make_train(["algo=ppo", "env=cartpole"])
    out = jax.jit(train)(jax.random.PRNGKey(0))        # one seed
    out = jax.jit(jax.vmap(train))(keys)               # several seeds in one program
    lrs = {"lr": jnp.array([1e-4, 3e-4, 1e-3])}        # three learning rates in one program
    out = jax.jit(jax.vmap(train, in_axes=(None, 0)))(key, lrs)

The overrides are `rlq train`'s, checked the same way (tuned settings included); the function runs the algorithm's
``init`` and its whole budget of updates in one ``scan``, then the greedy evaluation the run's ``eval`` section
describes. Its second argument, ``hyperparams``, takes any of the algorithm's numeric hyperparameters
(``train.hyperparams``: their names and the config's values) as arrays, which ``init`` and every update get, so a
sweep is a ``vmap`` over them. With
``fold_in(PRNGKey(seed), i)`` as key it trains what seed ``i`` of `rlq train seed=<seed>` trains (up to float
rounding: XLA fuses one scan of all updates and the CLI's chunks differently); its evaluation draws other episodes
than the CLI's.
Nothing is written: no checkpoints, logs or videos (the CLI's runner does those).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple

import jax

from rlq.algos import make_algo
from rlq.config import RunSpec, resolve
from rlq.errors import ConfigError
from rlq.lib.rollout import evaluate
from rlq.run.checks.validate import check_run_config
from rlq.run.programs.env_stack import evaluation_env, make_env


class TrainOutput(NamedTuple):
    """What a training function returns: the algorithm's final state, each update's metrics (stacked along a
    leading update axis) and the final greedy evaluation's per-episode record (``episode_return``, ...)."""

    state: Any
    metrics: dict[str, jax.Array]
    evaluation: dict[str, jax.Array]


def make_train(run: Sequence[str] | RunSpec = ()) -> Callable[..., TrainOutput]:
    """The training function of `rlq train <overrides>` (or of a resolved ``RunSpec``):
    ``(key, hyperparams=None) -> TrainOutput``, pure and jittable; ``hyperparams`` replaces some of the config's
    numeric hyperparameters (``train.hyperparams`` names them). Raises ConfigError or UsageError with the line the
    CLI would print."""
    spec = run if isinstance(run, RunSpec) else resolve(list(run))
    check_run_config(spec, memory=False)
    env = make_env(spec)
    algo = make_algo(spec.algorithm, env, spec.budget.env_steps)
    eval_env = evaluation_env(spec, env)
    episodes = int(spec.evaluation.episodes)

    def train(key: jax.Array, hyperparams: Mapping[str, Any] | None = None) -> TrainOutput:
        unknown = sorted(set(hyperparams or {}) - set(algo.hyperparams))
        if unknown:
            names = ", ".join(algo.hyperparams) or "none"
            raise ConfigError(f"hyperparams {', '.join(unknown)}: algo={spec.algorithm['name']} takes {names}")
        values = {**algo.hyperparams, **(hyperparams or {})}
        init_key, eval_key = key, jax.random.fold_in(key, 10_007)
        first = algo.init(init_key, values)
        state, metrics = jax.lax.scan(lambda s, _: algo.update(s, values), first, None, algo.num_updates)
        return TrainOutput(state, metrics, evaluate(eval_env, algo.policy(state), eval_key, episodes))

    train.__doc__ = f"`rlq train {' '.join(spec.overrides)}` as one function: (key, hyperparams=None) -> TrainOutput"
    train.hyperparams = dict(algo.hyperparams)  # type: ignore[attr-defined]
    return train
