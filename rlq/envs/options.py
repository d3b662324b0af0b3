"""Declarations of env keys that no heavy module must be imported to read: the wrapper keys every JAX env has
(``discretize``, ``action_repeat``) and CartPole's. Each env family declares its own beside it (``options.py`` of
rlq/envs/lunar, brittle_star, humanoid); rlq/envs/__init__.py maps env names to them (``ENV_CONFIGS``)."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.settings import POSITIVE_INT, Range, Sizes, setting

#: ``max_episode_steps``: null (no limit) is for a host env; a JAX env needs one (rlq.run.checks.validate)
TIME_LIMIT = Range(1, integer=True)


@dataclass(frozen=True)
class Discretize:
    """``env.discretize``: bins per observation component and their bounds (tabular methods on a Box observation)."""

    bins: tuple[int, ...] = setting((), Sizes(example="[3,3,6,12]"))
    low: tuple[float, ...] = setting(())
    high: tuple[float, ...] = setting(())


@dataclass(frozen=True)
class CartPoleConfig:
    """``env=cartpole``'s keys (conf/env/cartpole.yaml holds the same defaults, with their meanings)."""

    name: str = setting("cartpole")
    max_episode_steps: int | None = setting(500, TIME_LIMIT)
    discretize: Discretize | None = setting(None)
    action_repeat: int = setting(1, POSITIVE_INT)
