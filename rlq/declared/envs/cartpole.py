"""``env=cartpole``'s keys: CartPole-v1 (gymnax physics), a 4-d observation, 2 actions, 500-step episodes."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.declared.envs.shared import TIME_LIMIT, Discretize
from rlq.lib.settings import POSITIVE_INT, setting


@dataclass(frozen=True)
class Config:
    """``env=cartpole``'s keys: type, default, allowed values and meaning."""

    name: str = setting("cartpole")
    max_episode_steps: int | None = setting(500, TIME_LIMIT)
    #: tabular methods need discrete observations: bins and clip ranges per dimension (``Discretize``)
    discretize: Discretize | None = setting(None)
    #: control steps per agent decision (rlq's ActionRepeat wrapper: rewards summed)
    action_repeat: int = setting(1, POSITIVE_INT)
