"""The allowed values of a run's keys, checked once before anything compiles: every key's type, default, range and
meaning is declared in rlq/declared/ (the run's own keys in rlq/declared/run.py, each algorithm's, env's and
controller's in its ``Config`` there; ranges, choices and lists of sizes: rlq/lib/settings.py). ``problems`` names the
first key whose value its declaration refuses, as one line.

Hydra's schemas check the types of the run's, ``algo.``, ``env.`` and ``controller.`` keys as the config is composed; a
run key that takes null is an untyped value there, whose declared type is checked here, as is every run key the
command gave, as written (a typed node converts some values it takes). Checks that relate
several keys or need the env (a minibatch that divides the batch, an action space an algorithm supports) are the
algorithms', envs' and controllers' ``check`` functions and rlq/run/checks/validate.py.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from rlq.config.compose import group_override
from rlq.config.plain import MISSING, select
from rlq.config.spec import RunSpec, as_spec
from rlq.config.types import given_values
from rlq.declared import run
from rlq.lib import settings
from rlq.lib.settings import Constraint, OneOf, Range, Sizes

__all__ = ["Constraint", "OneOf", "Range", "Sizes", "problems"]


def _written(spec: RunSpec) -> dict[str, Any]:
    """The values the command wrote (``key=value``, not a group choice nor a deletion), as Hydra's parser reads them."""
    return given_values([o for o in spec.overrides if not group_override(o) and not o.startswith("~")])


def _type_problem(spec: RunSpec) -> str | None:
    """The first of the run's own keys whose value its declaration refuses, the one check of their types. A key the
    command gave is held to it as written (its range's or choices' line where it has one, else its type's), so that
    the line names the value given where the run's schema converted it (``logger.wandb.tags=[1,2]`` to strings,
    ``checkpoint={keep_best:1}`` to true). Any other key with no range is held to its type as composed: the schema
    leaves a key that takes null untyped (``video.at_end``, ``init_from``), and a preset or a recorded run may set it."""
    written = _written(spec)
    for key in settings.declared(run.Config):
        if key.name in written:
            line = settings.refusal(key, written[key.name], key.name)
        elif key.type is Any or dataclasses.is_dataclass(key.type) or key.allowed is not None:
            continue  # free-form; a group; a range or choices, whose line says more than the type's
        else:
            value = select(spec.values, key.name, MISSING)
            line = settings.refusal(key, value, key.name) if value is not MISSING else None
        if line is not None:
            return line
    return None


def _run_problem(spec: RunSpec) -> str | None:
    """The first of the run's own keys (rlq/declared/run.py) whose value its declaration refuses: its type, then its
    range."""
    return _type_problem(spec) or settings.problems(run.Config, spec.values, "")


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
    """The first key of the run whose value its declaration refuses, as one line; None when all fit.
    The run's keys come first, then the algorithm's, the env's and the controller's."""
    spec = as_spec(run)
    return _run_problem(spec) or _algorithm_problem(spec) or _env_problem(spec) or _controller_problem(spec)
