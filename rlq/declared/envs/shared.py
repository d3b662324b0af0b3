"""The env keys that rlq's wrappers read for every JAX env (``discretize``, ``action_repeat``) and the time limit's
range."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.settings import Range, Sizes, setting

#: ``max_episode_steps``: null (no limit) is for a host env; a JAX env needs one (rlq.run.checks.validate)
TIME_LIMIT = Range(1, integer=True)


@dataclass(frozen=True)
class Discretize:
    """``env.discretize``: bins per observation component and their clip ranges, for tabular methods on a Box
    observation, e.g. env.discretize={bins:[1,1,6,12],low:[-2.4,-3,-0.21,-3.5],high:[2.4,3,0.21,3.5]} (CartPole)."""

    bins: tuple[int, ...] = setting((), Sizes(example="[3,3,6,12]"))
    low: tuple[float, ...] = setting(())
    high: tuple[float, ...] = setting(())
