"""What the runner needs from an algorithm, in one place: each algorithm module defines ``SPEC``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rlq.algos.base import Algorithm
from rlq.lib.env_api import Env


def _no_problem(cfg: Any, env: Env) -> str | None:
    return None


def _no_shard_problem(cfg: Any, shards: int) -> str | None:
    return None


def _no_metrics(cfg: Any) -> tuple[str, ...]:
    return ()


@dataclass(frozen=True)
class AlgorithmSpec:
    """An algorithm as the runner sees it.

    ``config`` is the algorithm's declaration of its keys (a frozen dataclass: each key's type, default and
    allowed values, rlq/lib/settings.py; rlq/declared/<name>.py, registered as Hydra's schema of algo=<name>), and
    every function here takes an instance of it (``algo_settings``, rlq/algos/__init__.py, builds it from the composed section); ``make(algo_cfg, env,
    budget_env_steps)`` builds the pure functions of one run; ``check(algo_cfg, env)`` is a one-line problem with
    an env the algorithm cannot train on (rules across keys and the env); ``env_axis`` is the ``algo.`` key of the
    batch of envs or candidates one seed runs in parallel, which a run with fewer seeds than devices splits over
    them (rlq/run/programs/devices.py), and ``check_env_shards(algo_cfg, shards)`` a one-line problem with splitting it over ``shards`` devices; ``eval_metrics(algo_cfg)``
    names what ``Algorithm.state_metrics`` adds to each evaluation row (to check ``stop.when`` up front);
    ``sweepable`` the keys of an in-program sweep; ``agents``: it takes one observation and action per agent
    (``AgentsDiscrete``, the brittle star's decentralised control), sharing its learner over the agents.
    """

    config: type[Any]
    make: Callable[[Any, Env, int], Algorithm]
    check: Callable[[Any, Env], str | None] = _no_problem
    env_axis: str = "num_envs"
    check_env_shards: Callable[[Any, int], str | None] = _no_shard_problem
    eval_metrics: Callable[[Any], tuple[str, ...]] = _no_metrics
    #: the numeric hyperparameters: ``algo.`` keys (``epsilon.start`` for a nested one) that enter the update only
    #: as arithmetic, never a Python branch, shape or loop length. ``Algorithm.update`` takes them as its argument,
    #: and so does the chunk program (runs that differ only in them share one compiled program,
    #: rlq/run/programs/build.py), where an in-program sweep (``sweep.algo.<key>=[...]``) gives each member its own
    sweepable: tuple[str, ...] = ()
    agents: bool = False
    #: the ``algo.`` key of the steps each env takes per update; None where an update is one generation of whole
    #: episodes (black-box searches)
    unroll_axis: str | None = "num_steps"

    def env_batch(self, algo_cfg: Any) -> tuple[str, int]:
        """The config key and size of the batch ``env_axis`` names."""
        return f"algo.{self.env_axis}", int(getattr(algo_cfg, self.env_axis))

    def unroll(self, algo_cfg: Any) -> int:
        """The steps each env of the batch takes per update (``unroll_axis``; 1 for a black-box search)."""
        return int(getattr(algo_cfg, self.unroll_axis)) if self.unroll_axis else 1
