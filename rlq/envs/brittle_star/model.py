"""The brittle star's MuJoCo model: biorobot's morphology in its aquarium, plus rlq's speed options.

biorobot builds the MJCF (disk, arms, P-control actuators, aquarium with floor and walls); this
module compiles it with biorobot's environment settings (timestep 0.002 x time scale, Euler
without Euler damping, 1 solver iteration, 5 line-search iterations) and then applies the
``physics`` options to the ``MjModel`` before ``mjx.put_model``:

- ``wall_contacts=false``: the four wall colliders stop colliding, so the body meets the floor
  only (265 -> 53 contact candidates for 5 x 5). Identical physics while the robot stays off the
  walls (5 m or more away with the default arenas).
- ``sensors=false``: MuJoCo's 254 sensors (touch sensors need contact forces) are skipped at every
  physics step. rlq reads qpos/xpos directly, so this changes nothing.
- ``condim``, ``solver``, ``iterations``, ``ls_iterations``, ``cone``: solver settings; these do
  change the physics and are validated by ``scripts/bench_brittle_star.py``.
"""

from __future__ import annotations

import contextlib
import io
import re
import warnings
from dataclasses import dataclass

import mujoco
import numpy as np

with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
    # mujoco.mjx prints "Failed to import warp" on import and biorobot's renderer import warns
    # about a missing X display; neither matters for the JAX backend rlq uses.
    warnings.simplefilter("ignore")
    from biorobot.brittle_star.mjcf.arena.aquarium import AquariumArenaConfiguration, MJCFAquariumArena
    from biorobot.brittle_star.mjcf.morphology.morphology import MJCFBrittleStarMorphology
    from biorobot.brittle_star.mjcf.morphology.specification.default import (
        default_brittle_star_morphology_specification,
    )
    from mujoco import mjx  # imported here so the warp message stays quiet

#: biorobot places arm k at angle 2*pi*k/5 around the disk, whatever the number of arms.
MAX_ARMS = 5
PHYSICS_TIMESTEP = 0.002  # biorobot's base timestep, multiplied by the time scale
DISK_BODY = "BrittleStarMorphology/central_disk"
FREE_JOINT = "BrittleStarMorphology/freejoint/"
INITIAL_HEIGHT = 0.11  # biorobot's reset height of the disk
TARGET_RADIUS = 0.2  # biorobot's target site: reaching it ends a directed episode
_ACTUATOR_NAME = re.compile(r"arm_(\d+)_segment_(\d+)_(in_plane|out_of_plane)_joint")
_SOLVERS = {"newton": mujoco.mjtSolver.mjSOL_NEWTON, "cg": mujoco.mjtSolver.mjSOL_CG}
_CONES = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}


@dataclass(frozen=True)
class PhysicsOptions:
    """Contact pruning and solver settings (defaults: biorobot's model, sensors off)."""

    wall_contacts: bool = True
    sensors: bool = False
    condim: int = 4
    solver: str = "newton"
    iterations: int = 1
    ls_iterations: int = 5
    cone: str = "pyramidal"
    joint_limits: bool = True

    def __post_init__(self) -> None:
        if self.solver not in _SOLVERS:
            raise ValueError(f"env.physics.solver must be one of {sorted(_SOLVERS)}, got {self.solver!r}")
        if self.cone not in _CONES:
            raise ValueError(f"env.physics.cone must be one of {sorted(_CONES)}, got {self.cone!r}")
        if self.condim not in (1, 3, 4, 6):
            raise ValueError(f"env.physics.condim must be 1, 3, 4 or 6, got {self.condim!r}")
        if self.iterations < 1 or self.ls_iterations < 1:
            raise ValueError("env.physics.iterations and env.physics.ls_iterations must be >= 1")


@dataclass(frozen=True)
class ActuatorLayout:
    """Which arm, segment and joint kind (0: in-plane, 1: out-of-plane) each action drives."""

    arm: np.ndarray
    segment: np.ndarray
    kind: np.ndarray
    qpos_adr: np.ndarray
    qvel_adr: np.ndarray
    low: np.ndarray
    high: np.ndarray


def check_morphology(num_arms: int, segments_per_arm: int) -> None:
    if not 1 <= num_arms <= MAX_ARMS:
        raise ValueError(f"env.num_arms must be between 1 and {MAX_ARMS} (biorobot's arm slots), got {num_arms}")
    if segments_per_arm < 1:
        raise ValueError(f"env.segments_per_arm must be >= 1, got {segments_per_arm}")


def build_model(
    num_arms: int,
    segments_per_arm: int,
    p_control: bool,
    arena_size: tuple[float, float],
    with_target: bool,
    time_scale: float,
    physics: PhysicsOptions,
) -> mujoco.MjModel:
    """biorobot's brittle star in its aquarium (``arena_size``: biorobot's half-extents in m)."""
    check_morphology(num_arms, segments_per_arm)
    spec = default_brittle_star_morphology_specification(
        num_arms=num_arms,
        num_segments_per_arm=segments_per_arm,
        use_p_control=p_control,
        use_torque_control=not p_control,
    )
    arena = MJCFAquariumArena(
        AquariumArenaConfiguration(size=tuple(arena_size), attach_target=with_target, sand_ground_color=False)
    )
    arena.attach(other=MJCFBrittleStarMorphology(spec), free_joint=True)
    model = mujoco.MjModel.from_xml_string(arena.get_mjcf_str(), arena.get_mjcf_assets())
    model.opt.timestep = PHYSICS_TIMESTEP * time_scale
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    apply_physics_options(model, physics)
    return model


def apply_physics_options(model: mujoco.MjModel, physics: PhysicsOptions) -> None:
    """Edit ``model`` in place (before ``mjx.put_model``)."""
    model.opt.iterations = physics.iterations
    model.opt.ls_iterations = physics.ls_iterations
    model.opt.solver = _SOLVERS[physics.solver]
    model.opt.cone = _CONES[physics.cone]
    if not physics.sensors:
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR
    if not physics.joint_limits:
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_LIMIT
    colliding = (model.geom_contype > 0) | (model.geom_conaffinity > 0)
    model.geom_condim[colliding] = physics.condim
    if not physics.wall_contacts:
        for geom_id in range(model.ngeom):
            if model.geom(geom_id).name.endswith("_wall_collider"):
                model.geom_contype[geom_id] = 0
                model.geom_conaffinity[geom_id] = 0


def actuator_layout(model: mujoco.MjModel) -> ActuatorLayout:
    """Parse biorobot's actuator names: arm-major, then segment, then (in-plane, out-of-plane)."""
    arm, segment, kind, qpos_adr, qvel_adr = [], [], [], [], []
    for i in range(model.nu):
        match = _ACTUATOR_NAME.search(model.actuator(i).name)
        if match is None or model.actuator_trntype[i] != mujoco.mjtTrn.mjTRN_JOINT:
            raise ValueError(f"unexpected brittle star actuator {model.actuator(i).name!r}")
        joint = model.actuator_trnid[i, 0]
        arm.append(int(match.group(1)))
        segment.append(int(match.group(2)))
        kind.append(0 if match.group(3) == "in_plane" else 1)
        qpos_adr.append(int(model.jnt_qposadr[joint]))
        qvel_adr.append(int(model.jnt_dofadr[joint]))
    low, high = np.asarray(model.actuator_ctrlrange, np.float32).T
    return ActuatorLayout(
        arm=np.asarray(arm),
        segment=np.asarray(segment),
        kind=np.asarray(kind),
        qpos_adr=np.asarray(qpos_adr),
        qvel_adr=np.asarray(qvel_adr),
        low=low,
        high=high,
    )


def put_on_device(mj_model: mujoco.MjModel, impl: str, warp_contacts: int) -> tuple[mjx.Model, mjx.Data]:
    """The MJX model and the blank data every reset starts from, for MJX's JAX implementation or
    MuJoCo Warp (``rlq.envs.mujoco.impl``; Warp's data comes from the ``MjModel`` and its contact
    buffer of ``warp_contacts`` is shared by all envs of a batch)."""
    jax_model = mjx.put_model(mj_model, impl="jax")
    jax_data = mjx.make_data(jax_model, impl="jax")
    if impl != "warp":
        return jax_model, jax_data
    # MJX-JAX allocates every constraint row the model can have: Warp's rows per env (njmax) then
    # never overflow. biorobot's settings stop the solver after 1 iteration by design, so Warp's
    # "iteration limit reached" prints are switched off; its buffer overflows still print.
    from mujoco.mjx.third_party.mujoco_warp import OverflowType  # MJX's copy of MuJoCo Warp (needs warp-lang)

    quiet = int(OverflowType.ALL & ~(OverflowType.ITERATIONS | OverflowType.LS_ITERATIONS))
    model = mjx.put_model(mj_model, impl="warp").tree_replace({"opt._impl.warn_overflow": quiet})
    njmax = int(jax_data._impl.efc_J.shape[0])
    return model, mjx.make_data(mj_model, impl="warp", naconmax=int(warp_contacts), njmax=njmax)


def contact_candidates(mj_model: mujoco.MjModel) -> int:
    """Contacts MJX's JAX implementation evaluates at every physics step (fixed by the model's
    collision pairs); MuJoCo Warp makes only the contacts that touch."""
    contact = mjx.make_data(mjx.put_model(mj_model, impl="jax"), impl="jax")._impl.contact
    return int(contact.dist.shape[0])
