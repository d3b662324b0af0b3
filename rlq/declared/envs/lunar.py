"""``env=lunar``'s keys (LunarLander-v3 in JAX, rlq's own port of Gymnasium's Box2D env; docs/lunar.md: Discrete(4)
actions, or with ``continuous`` Box(-1, 1, (2,)): main throttle, side throttle) and ``env=lunar_box2d``'s
(Gymnasium's Box2D LunarLander-v3 on the host: the reference simulator, for `rlq eval` only); the task options they
share."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rlq.declared.envs.shared import TIME_LIMIT, Discretize
from rlq.lib.settings import FINITE, NON_NEGATIVE, POSITIVE_INT, setting


@dataclass(frozen=True)
class Solver:
    """``env.solver``: Box2D's sequential-impulse solver as Gymnasium configures it, as rlq's port runs it."""

    #: world.Step(1/FPS, 6*30, 2*30): fewer is faster but drifts from Box2D
    velocity_iterations: int = setting(180, POSITIVE_INT)
    position_iterations: int = setting(60, POSITIVE_INT)
    warm_start: bool = setting(True)
    #: Box2D's 2-point block solver for flat leg contacts
    block_solve: bool = setting(True)
    #: continuous collision for the legs (Box2D's time-of-impact sub-steps)
    toi: bool = setting(True)
    #: velocity sweeps per compiled loop trip in the stacked (CPU) form (same results)
    unroll: int = setting(1, POSITIVE_INT)
    #: the same in the component (GPU) form: fewer trips help long runs of small GPU batches, for a longer compile
    component_unroll: int = setting(1, POSITIVE_INT)
    #: velocity and position sweeps on stacked arrays (fast on a CPU) or components (a few kernels per sweep on a
    #: GPU); auto: per platform
    sweep_layout: str = setting("auto")


@dataclass(frozen=True)
class Box2DConfig:
    """``env=lunar_box2d``'s keys: Gymnasium's LunarLander-v3 task options."""

    name: str = setting("lunar_box2d")
    continuous: bool = setting(False)
    max_episode_steps: int | None = setting(1000, TIME_LIMIT)
    #: Gymnasium allows (-12, 0): the env's check
    gravity: float = setting(-10.0, FINITE)
    enable_wind: bool = setting(False)
    #: max linear wind force (N), Gymnasium recommends 0..20
    wind_power: float = setting(15.0, NON_NEGATIVE)
    #: max turbulence torque, Gymnasium recommends 0..2
    turbulence_power: float = setting(1.5, NON_NEGATIVE)


@dataclass(frozen=True)
class Config(Box2DConfig):
    """``env=lunar``'s keys (rlq's JAX port of LunarLander): Gymnasium's task keys, then the port's own."""

    name: str = setting("lunar")
    solver: Solver = setting(Solver())
    #: auto-reset's new episode stepped in the same solver loops as the step (faster on a GPU, slower on a CPU)
    lockstep_reset: bool = setting(False)
    #: auto-reset restarts each env from its own first start (as brax): no reset in the step; for thousands of envs
    reset_cache: bool = setting(False)
    #: bins per observation dimension for tabular methods (rlq.declared.envs.shared.Discretize)
    discretize: Discretize | None = setting(None)
    #: control steps per agent decision (rlq's ActionRepeat wrapper: rewards summed)
    action_repeat: int = setting(1, POSITIVE_INT)


TASK_KEYS = ("continuous", "enable_wind", "wind_power", "turbulence_power", "gravity", "max_episode_steps")


def task_options(cfg: Box2DConfig) -> dict[str, Any]:
    """Gymnasium's LunarLander-v3 arguments and the time limit, as both env constructors take them."""
    return {key: getattr(cfg, key) for key in TASK_KEYS}
