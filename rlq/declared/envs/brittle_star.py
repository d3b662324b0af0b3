"""The brittle stars' keys (biorobot's brittle star, MJX): ``env=brittle_star``, directed locomotion toward a random
target (tutorial T0's defaults: 20 s at 0.04 s per control step, 0.002 s x time_scale x physics steps, = 500 steps
per episode) and ``env=brittle_star_undirected``, undirected locomotion with no target (T2's: 5 s = 125 steps per
episode; reward = increase of the distance from the origin). Both compose env/physics (conf/env/physics/: default,
or fast, the validated fast physics) and are driven through their CPG (conf/env/driven_by/)."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.declared.envs.shared import Discretize
from rlq.lib.settings import NON_NEGATIVE, POSITIVE, POSITIVE_INT, WHOLE, Range, setting


@dataclass(frozen=True)
class Physics:
    """``env.physics``: MJX speed options (docs/brittle_star.md); biorobot's model by default."""

    #: false: collide with the floor only (265 -> 53 contact candidates)
    wall_contacts: bool = setting(True)
    #: MuJoCo's sensors (rlq reads qpos/xpos directly; true only costs time)
    sensors: bool = setting(False)
    #: 3: no torsional friction, 4 instead of 6 constraint rows per contact
    condim: int = setting(4, Range(1, 6, integer=True))
    #: newton | cg
    solver: str = setting("newton")
    #: biorobot's setting
    iterations: int = setting(1, POSITIVE_INT)
    #: biorobot's setting
    ls_iterations: int = setting(5, POSITIVE_INT)
    #: pyramidal | elliptic
    cone: str = setting("pyramidal")
    #: false: no joint-limit constraint rows (50 of 368 when pruned); the P-controlled joints rarely reach them
    joint_limits: bool = setting(True)


@dataclass(frozen=True)
class _Shared:
    """The keys both brittle stars have, with the same defaults but the name (env/physics=fast sets some of them)."""

    name: str = setting("brittle_star")
    #: 1 to 5: the env's check
    num_arms: int = setting(5, WHOLE)
    #: false: torque control
    p_control: bool = setting(True)
    #: uniform noise on initial joint positions and velocities
    joint_randomization: float = setting(0.0, NON_NEGATIVE)
    random_initial_rotation: bool = setting(False)
    #: vector: flat Box (joints, disk, target) | sector: Discrete(5), the arm facing the target | arm_sectors: one
    #: state per arm, the target's bearing from that arm (controller.mode=decentralised); sector and arm_sectors
    #: need a target (env=brittle_star)
    observation: str = setting("vector")
    #: bins per observation dimension for tabular methods (rlq.declared.envs.shared.Discretize)
    discretize: Discretize | None = setting(None)
    #: control steps per agent decision (rlq's ActionRepeat wrapper: rewards summed)
    action_repeat: int = setting(1, POSITIVE_INT)
    physics_steps_per_control_step: int = setting(10, POSITIVE_INT)
    #: physics timestep = 0.002 s x time_scale
    time_scale: float = setting(2.0, POSITIVE)
    physics: Physics = setting(Physics())
    #: jax (MJX's JAX implementation) | warp (MuJoCo Warp's CUDA kernels, same model, pip install -e ".[cuda]") |
    #: auto (warp on an NVIDIA GPU with warp-lang, else jax); docs/brittle_star.md
    mjx_impl: str = setting("jax")
    #: warp: contact buffer shared by all envs of a batch (>= 53 per 5 x 5 env x envs x seeds)
    warp_contacts: int = setting(868352, POSITIVE_INT)


@dataclass(frozen=True)
class UndirectedConfig(_Shared):
    """``env=brittle_star_undirected``'s keys."""

    name: str = setting("brittle_star_undirected")
    segments_per_arm: int = setting(3, POSITIVE_INT)
    #: biorobot's half-extents (walls at +-10 m)
    arena_size: tuple[float, ...] = setting((10.0, 10.0))
    #: s; sets the episode length
    simulation_time: float = setting(5.0, POSITIVE)


@dataclass(frozen=True)
class Config(_Shared):
    """``env=brittle_star``'s keys."""

    name: str = setting("brittle_star")
    segments_per_arm: int = setting(5, POSITIVE_INT)
    #: biorobot's AquariumArenaConfiguration.size (half-extents: walls at +-10, +-5 m)
    arena_size: tuple[float, ...] = setting((10.0, 5.0))
    #: m, in a uniformly random direction
    target_distance: float = setting(3.0, NON_NEGATIVE)
    #: s; sets the episode length
    simulation_time: float = setting(20.0, POSITIVE)
    #: end the episode within 0.2 m of the target (biorobot)
    terminate_at_target: bool = setting(True)
    #: arm_sectors: bins of 360 deg / bearing_bins, bin 0 centred on the arm
    bearing_bins: int = setting(5, POSITIVE_INT)
