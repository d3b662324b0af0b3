"""Algorithm registry: ``algo.name`` selects a module of ``ALGORITHMS``, whose ``SPEC`` (rlq/algos/spec.py)
tells the runner how to build, check and place it."""

from __future__ import annotations

from omegaconf import DictConfig

from rlq.algos.base import Algorithm
from rlq.algos.spec import AlgorithmSpec
from rlq.lib.env_api import Env
from rlq.lib.registry import load
from rlq.lib.spaces import AgentsDiscrete

ALGORITHMS = {
    "ppo": "rlq.algos.ppo",
    "dqn": "rlq.algos.dqn",
    "pqn": "rlq.algos.pqn",
    "reinforce": "rlq.algos.reinforce",
    "qlearning": "rlq.algos.qlearning",
    "random_search": "rlq.algos.random_search",
    "map_elites": "rlq.algos.map_elites",
    "es": "rlq.algos.es",
}


def algorithm_spec(algo_cfg: DictConfig) -> AlgorithmSpec:
    spec = load(ALGORITHMS, algo_cfg.name, "algo.name").SPEC
    assert isinstance(spec, AlgorithmSpec)
    return spec


def make_algo(algo_cfg: DictConfig, env: Env, budget_env_steps: int) -> Algorithm:
    return algorithm_spec(algo_cfg).make(algo_cfg, env, budget_env_steps)


def check_algo(algo_cfg: DictConfig, env: Env) -> str | None:
    spec = algorithm_spec(algo_cfg)
    per_agent = any(isinstance(s, AgentsDiscrete) for s in (env.observation_space, env.action_space))
    if per_agent and not spec.agents:
        agents = tuple(sorted(name for name in ALGORITHMS if algorithm_spec(DictConfig({"name": name})).agents))
        return (
            f"algo={algo_cfg.name} cannot learn one observation and action per arm (env.observation=arm_sectors, "
            f"controller.mode=decentralised); use algo={'|'.join(agents)}, which shares one learner over the arms"
        )
    return spec.check(algo_cfg, env)
