"""``env=humanoid``'s keys: type, default and range (conf/env/humanoid.yaml holds the same defaults, with their
meanings). Apart from rlq/envs/humanoid/env.py so that reading them imports no brax or MuJoCo."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rlq.envs.options import Discretize
from rlq.lib.settings import FINITE, NON_NEGATIVE, POSITIVE_INT, setting


@dataclass(frozen=True)
class Config:
    name: str = setting("humanoid")
    episode_length: int = setting(1000, POSITIVE_INT)
    action_repeat: int = setting(1, POSITIVE_INT)
    discretize: Discretize | None = setting(None)
    reset_cache: bool = setting(True)
    mjx_impl: str = setting("jax")
    warp_contacts: int = setting(1048576, POSITIVE_INT)
    unroll_physics: str = setting("none")
    substep_carry: str = setting("data")
    vectorized_cdof: bool = setting(False)
    vectorized_com_vel: bool = setting(False)
    quick_model_load: bool = setting(False)
    randomize: dict[str, Any] | None = setting(None)  # per-env domain randomisation: randomize.py's check
    forward_reward_weight: float = setting(1.25, FINITE)
    ctrl_cost_weight: float = setting(0.1, NON_NEGATIVE)
    healthy_reward: float = setting(5.0, FINITE)
    terminate_when_unhealthy: bool = setting(True)
    healthy_z_range: tuple[float, ...] = setting((1.0, 2.0))
    reset_noise_scale: float = setting(0.01, NON_NEGATIVE)
    exclude_current_positions_from_observation: bool = setting(True)
    n_frames: int = setting(5, POSITIVE_INT)
