"""The task options that rlq's LunarLander and Gymnasium's Box2D reference share, and the declarations of both
envs' keys (``Config``, ``Box2DConfig``: type, default and range; conf/env/lunar*.yaml are their presets)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rlq.envs.options import TIME_LIMIT, Discretize
from rlq.lib.settings import FINITE, NON_NEGATIVE, POSITIVE_INT, setting


@dataclass(frozen=True)
class Solver:
    """``env.solver``: Box2D's sequential-impulse solver as rlq's port runs it."""

    velocity_iterations: int = setting(180, POSITIVE_INT)
    position_iterations: int = setting(60, POSITIVE_INT)
    warm_start: bool = setting(True)
    block_solve: bool = setting(True)
    toi: bool = setting(True)
    unroll: int = setting(1, POSITIVE_INT)
    component_unroll: int = setting(1, POSITIVE_INT)
    sweep_layout: str = setting("auto")


@dataclass(frozen=True)
class Box2DConfig:
    """``env=lunar_box2d``'s keys (Gymnasium's LunarLander-v3, for `rlq eval`)."""

    name: str = setting("lunar_box2d")
    continuous: bool = setting(False)
    max_episode_steps: int | None = setting(1000, TIME_LIMIT)
    gravity: float = setting(-10.0, FINITE)  # in (-12, 0): the env's check
    enable_wind: bool = setting(False)
    wind_power: float = setting(15.0, NON_NEGATIVE)
    turbulence_power: float = setting(1.5, NON_NEGATIVE)


@dataclass(frozen=True)
class Config(Box2DConfig):
    """``env=lunar``'s keys (rlq's JAX port of LunarLander): Gymnasium's task keys, then the port's own."""

    name: str = setting("lunar")
    solver: Solver = setting(Solver())
    lockstep_reset: bool = setting(False)
    reset_cache: bool = setting(False)
    discretize: Discretize | None = setting(None)
    action_repeat: int = setting(1, POSITIVE_INT)


TASK_KEYS = ("continuous", "enable_wind", "wind_power", "turbulence_power", "gravity", "max_episode_steps")


def task_options(cfg: Box2DConfig) -> dict[str, Any]:
    """Gymnasium's LunarLander-v3 arguments and the time limit, as both env constructors take them."""
    return {key: getattr(cfg, key) for key in TASK_KEYS}
