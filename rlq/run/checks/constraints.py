"""The allowed values of config keys: each algorithm's, env's and controller's own declaration (``Config`` beside
it: rlq/algos/, rlq/envs/ ``ENV_CONFIGS``, rlq/controllers/) and, for the run's keys, one table here (ranges,
choices and lists of sizes: rlq/lib/settings.py).

The yaml files under conf/ give a run key's type (its default's, rlq.config.types); the table says which values of
a key mean something. Checks that relate several keys or need the env (a minibatch that divides the batch, an
action space an algorithm supports) are the algorithms', envs' and controllers' ``check`` functions.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rlq.config.plain import MISSING, select
from rlq.config.spec import RunSpec, as_spec
from rlq.lib import settings
from rlq.lib.settings import (
    BUDGET,
    COUNT,
    POSITIVE_INT,
    SEED,
    Constraint,
    OneOf,
    Range,
    Sizes,
)
from rlq.run.programs.cadences import CHUNK_LOOPS
from rlq.run.programs.devices import PLATFORMS
from rlq.run.programs.program_cache import MODES as PROGRAM_CACHE_MODES

#: W&B modes rlq passes to ``wandb.init``
WANDB_MODES = ("offline", "online", "disabled")


CONSTRAINTS: dict[str, Constraint] = {
    # run
    "seed": SEED,
    "num_seeds": POSITIVE_INT,
    "budget.env_steps": BUDGET,
    "log_every_steps": POSITIVE_INT,
    "chunk_loop": OneOf(CHUNK_LOOPS),
    "program_cache": OneOf(PROGRAM_CACHE_MODES),
    "shaped_for.platform": OneOf(PLATFORMS, nullable=True),
    "eval.episodes": POSITIVE_INT,
    "guard.max_abs_loss": Range(0, low_open=True, nullable=True),
    "guard.max_params_norm": Range(0, low_open=True, nullable=True),
    "eval.every_steps": COUNT,
    "checkpoint.every_steps": COUNT,
    "checkpoint.keep_last": COUNT,
    "video.every_steps": COUNT,
    "return_window": COUNT,
    "video.max_steps": Range(1, integer=True, nullable=True),
    "logger.wandb.mode": OneOf(WANDB_MODES),
}

__all__ = ["CONSTRAINTS", "Constraint", "OneOf", "Range", "Sizes", "problems"]


def _table_problem(spec: RunSpec) -> str | None:
    """The first of the table's keys whose value it refuses."""
    for key, constraint in CONSTRAINTS.items():
        value = select(spec.values, key, MISSING)
        if value is not MISSING and not constraint.accepts(value):
            return f"{key} must be {constraint.allowed()}, got {value!r}"
    return None


def _env_problem(spec: RunSpec) -> str | None:
    """The first ``env.`` key whose value the env's declaration refuses (an unknown ``env.name``: none here)."""
    from rlq.envs import ENV_CONFIGS, env_config

    env = spec.env
    if not isinstance(env, Mapping) or env.get("name") not in ENV_CONFIGS:
        return None
    return settings.problems(env_config(env), env, "env")


def _algorithm_problem(spec: RunSpec) -> str | None:
    """The first ``algo.`` key whose value the algorithm's declaration refuses (for an unknown ``algo.name`` none
    here: the registry's line names the choices)."""
    from rlq.algos import ALGORITHMS, algorithm_spec

    algo = spec.algorithm
    if not isinstance(algo, Mapping) or algo.get("name") not in ALGORITHMS:
        return None
    return settings.problems(algorithm_spec(algo).config, algo, "algo")


def _controller_problem(spec: RunSpec) -> str | None:
    """The first ``controller.`` key whose value the controller's declaration refuses (an unknown
    ``controller.name``: none here, the registry's line names the choices)."""
    from rlq.controllers import CONTROLLERS, controller_config

    controller = spec.controller
    if not isinstance(controller, Mapping) or controller.get("name") not in CONTROLLERS:
        return None
    return settings.problems(controller_config(controller), controller, "controller")


def problems(run: RunSpec | Mapping[str, Any]) -> str | None:
    """The first key of the run whose value its declaration or the table refuses, as one line; None when all fit.
    The run's keys come first, then the algorithm's, the env's and the controller's."""
    spec = as_spec(run)
    return _table_problem(spec) or _algorithm_problem(spec) or _env_problem(spec) or _controller_problem(spec)
