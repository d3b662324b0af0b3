"""The task options that rlq's LunarLander and Gymnasium's Box2D reference share, read from
``conf/env/lunar*.yaml`` (their one home)."""

from __future__ import annotations

from typing import Any

from omegaconf import DictConfig

TASK_KEYS = ("continuous", "enable_wind", "wind_power", "turbulence_power", "gravity", "max_episode_steps")


def task_options(cfg: DictConfig) -> dict[str, Any]:
    """Gymnasium's LunarLander-v3 arguments and the time limit, as both env constructors take them."""
    return {key: cfg[key] for key in TASK_KEYS}
