"""Algorithm registry: ``algo.name`` selects the module ``rlq.algos.<name>``.

Each module exposes ``make(algo_cfg, env, budget_env_steps) -> Algorithm`` and optionally
``check(algo_cfg, env) -> str | None`` (an error message for an unsupported env) and
``sizes(algo_cfg) -> list[str]`` (config keys that must be positive integers) and
``env_axis(algo_cfg) -> (key, size)`` (the config key and size of the batch of independent envs
or candidates one seed runs in parallel, which a run with fewer seeds than devices splits over
them; rlq/run/devices.py) and ``eval_metrics(algo_cfg) -> tuple[str, ...]`` (the names its
``Algorithm.state_metrics`` add to each evaluation row, for checking ``stop.when`` up front).
"""

from __future__ import annotations

import importlib

from omegaconf import DictConfig

from rlq.algos.base import Algorithm
from rlq.lib.env_api import Env


def algo_module(algo_cfg: DictConfig):
    return importlib.import_module(f"rlq.algos.{algo_cfg.name}")


def make_algo(algo_cfg: DictConfig, env: Env, budget_env_steps: int) -> Algorithm:
    return algo_module(algo_cfg).make(algo_cfg, env, budget_env_steps)


def check_algo(algo_cfg: DictConfig, env: Env) -> str | None:
    check = getattr(algo_module(algo_cfg), "check", None)
    return check(algo_cfg, env) if check else None
