"""The brittle stars' keys: type, default and range (conf/env/brittle_star*.yaml and conf/env/physics/default.yaml
hold the same defaults, with their meanings). Apart from the envs so that reading them imports no MuJoCo."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.envs.options import Discretize
from rlq.lib.settings import NON_NEGATIVE, POSITIVE, POSITIVE_INT, WHOLE, Range, setting


@dataclass(frozen=True)
class Physics:
    """``env.physics``: MJX speed options (conf/env/physics/, docs/brittle_star.md)."""

    wall_contacts: bool = setting(True)
    sensors: bool = setting(False)
    condim: int = setting(4, Range(1, 6, integer=True))
    solver: str = setting("newton")
    iterations: int = setting(1, POSITIVE_INT)
    ls_iterations: int = setting(5, POSITIVE_INT)
    cone: str = setting("pyramidal")
    joint_limits: bool = setting(True)


@dataclass(frozen=True)
class _Shared:
    """The keys both brittle stars have, with the same defaults (the env/physics group's among them)."""

    num_arms: int = setting(5, WHOLE)  # 1 to 5: the env's check
    p_control: bool = setting(True)
    joint_randomization: float = setting(0.0, NON_NEGATIVE)
    random_initial_rotation: bool = setting(False)
    observation: str = setting("vector")
    discretize: Discretize | None = setting(None)
    action_repeat: int = setting(1, POSITIVE_INT)
    physics_steps_per_control_step: int = setting(10, POSITIVE_INT)
    time_scale: float = setting(2.0, POSITIVE)
    physics: Physics = setting(Physics())
    mjx_impl: str = setting("jax")
    warp_contacts: int = setting(868352, POSITIVE_INT)


@dataclass(frozen=True)
class UndirectedConfig(_Shared):
    """``env=brittle_star_undirected``'s keys."""

    name: str = setting("brittle_star_undirected")
    segments_per_arm: int = setting(3, POSITIVE_INT)
    arena_size: tuple[float, ...] = setting((10, 10))
    simulation_time: float = setting(5.0, POSITIVE)


@dataclass(frozen=True)
class Config(_Shared):
    """``env=brittle_star``'s keys."""

    name: str = setting("brittle_star")
    segments_per_arm: int = setting(5, POSITIVE_INT)
    arena_size: tuple[float, ...] = setting((10, 5))
    target_distance: float = setting(3.0, NON_NEGATIVE)
    simulation_time: float = setting(20.0, POSITIVE)
    terminate_at_target: bool = setting(True)
    bearing_bins: int = setting(5, POSITIVE_INT)
