"""Build a run's parts from its config: the env stack (env -> controller -> wrappers)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import jax.numpy as jnp

from rlq.algos import algo_settings, algorithm_spec
from rlq.algos.qd.measures import wrap_measure
from rlq.config.spec import RunSpec, as_spec, evaluation_spec
from rlq.controllers import wrap_controller
from rlq.envs import env_settings, make_base_env
from rlq.envs.wrappers import (
    ActionRepeat,
    AutoReset,
    DiscretizeObservation,
    EpisodeStats,
    ReturnWindow,
    TimeLimit,
)
from rlq.errors import ConfigError
from rlq.lib.env_api import Env, info_shapes


def make_env(run: RunSpec | Mapping[str, Any], autoreset: bool = True) -> Env:
    """env -> controller -> time limit -> episode statistics -> auto-reset -> return window -> discretisation.

    ``env.discretize`` (bins, low, high per observation dimension), when set, turns a Box
    observation into one integer for tabular methods. ``env.action_repeat`` > 1 holds each
    action for that many control steps (after the controller, so a CPG keeps integrating). A
    black-box algorithm's ``algo.descriptor`` may add the wrapper that measures it
    (``rlq.algos.qd.measures``). ``return_window`` > 0 keeps each auto-reset env's last finished
    returns for the loop's ``return_window`` metric.
    """

    spec = as_spec(run)
    env_cfg = env_settings(spec.env)
    env = make_base_env(env_cfg)
    if not env.jittable:
        return env  # a HostEnv (reference simulator): evaluated on the host as it is
    env = wrap_controller(env, spec.controller, env_cfg)
    repeat = env_cfg.action_repeat
    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise ConfigError(f"env.action_repeat must be an integer >= 1, got {repeat!r}")
    if repeat > 1:
        env = ActionRepeat(env, repeat)
    if env.max_episode_steps:
        env = TimeLimit(env, env.max_episode_steps)
    # only the black-box algorithms have a descriptor key (rlq/declared/map_elites.py, random_search.py)
    env = wrap_measure(env, spec.algorithm.get("descriptor"))
    env = EpisodeStats(env)
    if autoreset:
        env = AutoReset(env)
        if spec.training.return_window:
            env = ReturnWindow(env, spec.training.return_window)
    discretize = env_cfg.discretize
    if discretize:
        env = DiscretizeObservation(env, tuple(discretize.bins), tuple(discretize.low), tuple(discretize.high))
    return env


def checked_env(run: RunSpec | Mapping[str, Any], label: str, autoreset: bool = True) -> Env:
    """``make_env(run, autoreset)``, with an env's own checks (a bad value, a missing sub-key) raised as
    one ``ConfigError`` line that starts with ``label``."""
    try:
        return make_env(run, autoreset)
    except ConfigError:
        raise
    except (ValueError, KeyError, AttributeError, TypeError) as err:
        raise ConfigError(f"{label}: {str(err).splitlines()[0]}") from err


def evaluation_env(run: RunSpec | Mapping[str, Any], env: Env) -> Env:
    """The env the evaluation program steps: ``env``, or, where ``eval.env`` gives env options,
    the run's env with those options over its own (e.g. the humanoid's physics traced in loops,
    which compiles faster: docs/humanoid.md)."""
    spec = as_spec(run)
    if not spec.evaluation.env:
        return env
    return checked_env(evaluation_spec(spec), "eval.env")


#: ``info`` entries an evaluation row does not report under their own name (rlq.run.result.eval_summary)
_NOT_EVAL_METRICS = ("final_obs", "episode_return", "episode_length")


def evaluation_metrics(run: RunSpec | Mapping[str, Any], env: Env) -> list[str]:
    """The names of an evaluation row's metrics (``rlq.run.result.eval_summary``), known before
    anything is compiled: ``return``, ``length``, each scalar number the evaluation env reports in
    ``info`` (read from its reset, traced abstractly) and the algorithm's ``eval_metrics``."""
    spec = as_spec(run)
    names = {"return", "length"}
    for key, value in info_shapes(evaluation_env(spec, env)).items():
        if key not in _NOT_EVAL_METRICS and value.shape == () and jnp.issubdtype(value.dtype, jnp.number):
            names.add(key)
    return sorted(names | set(algorithm_spec(spec.algorithm).eval_metrics(algo_settings(spec.algorithm))))
