"""Algorithm registry: ``algo.name`` selects the ``SPEC`` of an algorithm's module (rlq/algos/spec.py), which tells
the runner how to declare, build, check and place it. ``algo_settings`` turns the composed ``algo`` section into the
algorithm's typed ``Config``, what its functions take; ``make_algo`` and ``check_algo`` take either."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rlq.algos import dqn, es, map_elites, ppo, pqn, qlearning, random_search, reinforce
from rlq.algos.base import Algorithm
from rlq.algos.spec import AlgorithmSpec
from rlq.lib.env_api import Env
from rlq.lib.registry import choose
from rlq.lib.settings import typed
from rlq.lib.spaces import AgentsDiscrete

ALGORITHMS: dict[str, AlgorithmSpec] = {
    "ppo": ppo.SPEC,
    "dqn": dqn.SPEC,
    "pqn": pqn.SPEC,
    "reinforce": reinforce.SPEC,
    "qlearning": qlearning.SPEC,
    "random_search": random_search.SPEC,
    "map_elites": map_elites.SPEC,
    "es": es.SPEC,
}


def algorithm_spec(algo_cfg: Mapping[str, Any] | Any) -> AlgorithmSpec:
    """The spec of the algorithm that ``algo_cfg`` (the ``algo`` section or an algorithm's ``Config``) names."""
    name = algo_cfg["name"] if isinstance(algo_cfg, Mapping) else algo_cfg.name
    return choose(ALGORITHMS, name, "algo.name")


def algo_settings(algo_cfg: Mapping[str, Any] | Any) -> Any:
    """The named algorithm's ``Config`` with the values of the ``algo`` section (a ``Config`` already: itself)."""
    return typed(algorithm_spec(algo_cfg).config, algo_cfg, "algo")


def make_algo(algo_cfg: Mapping[str, Any] | Any, env: Env, budget_env_steps: int) -> Algorithm:
    return algorithm_spec(algo_cfg).make(algo_settings(algo_cfg), env, budget_env_steps)


def check_algo(algo_cfg: Mapping[str, Any] | Any, env: Env) -> str | None:
    spec = algorithm_spec(algo_cfg)
    algo_cfg = algo_settings(algo_cfg)
    per_agent = any(isinstance(s, AgentsDiscrete) for s in (env.observation_space, env.action_space))
    if per_agent and not spec.agents:
        agents = tuple(sorted(name for name, other in ALGORITHMS.items() if other.agents))
        return (
            f"algo={algo_cfg.name} cannot learn one observation and action per arm (env.observation=arm_sectors, "
            f"controller.mode=decentralised); use algo={'|'.join(agents)}, which shares one learner over the arms"
        )
    return spec.check(algo_cfg, env)
