"""biorobot's brittle star on MJX: directed locomotion toward a random target (``env=brittle_star``)
and undirected locomotion (``env=brittle_star_undirected``).

The MJX model is a constant of the compiled program (not part of the state); the target is a
position in ``inner`` (it is a site without collision, so it plays no part in the physics).
Semantics follow biorobot's environments: the disk starts at (0, 0, 0.11); the target lies at
``target_distance`` in a uniformly random direction; the directed reward is the decrease of the
xy distance to the target, the undirected one the increase of the distance from the origin; a
directed episode terminates within 0.2 m of the target.

Observations (``observation: vector``) are one flat vector; ``BrittleStar.obs_slices`` names the
parts. ``observation: sector`` gives ``Discrete(5)``: the arm that faces the target (T0's state
indexer, with the angle wrapped). ``observation: arm_sectors`` gives one state per arm
(``AgentsDiscrete(bearing_bins, num_arms)``): the target's bearing relative to that arm, for
decentralised control (``controller.mode=decentralised``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from rlq.declared.envs.brittle_star import Config, UndirectedConfig
from rlq.envs.brittle_star import model as bsm
from rlq.envs.brittle_star.model import mjx
from rlq.envs.brittle_star.render import brittle_star_frames
from rlq.envs.mujoco.impl import resolve_impl, with_template_buffers
from rlq.envs.mujoco.render import MujocoRendering
from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import AgentsDiscrete, Box, Discrete

NUM_SECTORS = 5
OBSERVATIONS = ("vector", "sector", "arm_sectors")
#: MuJoCo Warp's contact buffer, shared by all envs of a batch: a 5 x 5 star on the floor makes at
#: most 53 contacts, so this holds 16,384 of them (`env.warp_contacts`)
WARP_CONTACTS = 53 << 14


@dataclass(frozen=True)
class BrittleStarConfig:
    directed: bool = True
    num_arms: int = 5
    segments_per_arm: int = 5
    p_control: bool = True
    arena_size: tuple[float, float] = (10.0, 5.0)
    target_distance: float = 3.0
    simulation_time: float = 20.0
    physics_steps_per_control_step: int = 10
    time_scale: float = 2.0
    joint_randomization: float = 0.0
    random_initial_rotation: bool = False
    terminate_at_target: bool = True
    observation: str = "vector"
    bearing_bins: int = NUM_SECTORS
    physics: bsm.PhysicsOptions = field(default_factory=bsm.PhysicsOptions)
    mjx_impl: str = "jax"
    warp_contacts: int = WARP_CONTACTS

    @property
    def control_timestep(self) -> float:
        return bsm.PHYSICS_TIMESTEP * self.time_scale * self.physics_steps_per_control_step

    @property
    def episode_steps(self) -> int:
        return max(1, math.ceil(round(self.simulation_time / self.control_timestep, 6)))


class BrittleStarInner(struct.PyTreeNode):
    data: mjx.Data
    target_xy: jax.Array  # (2,), zeros in undirected locomotion
    start_distance: jax.Array  # distance to the target at reset (directed) or 0
    energy_sum: jax.Array  # sum over control steps of mean |joint actuator force|
    steps: jax.Array


def wrap_angle(angle: jax.Array) -> jax.Array:
    """Angle in [-pi, pi)."""
    return jnp.mod(angle + jnp.pi, 2 * jnp.pi) - jnp.pi


def sector_table() -> np.ndarray:
    """Bin -> arm facing that bin: bin b covers [-pi + b*w, -pi + (b+1)*w), w = 2pi/5; biorobot's
    arm k points at angle k*w in the disk frame, so the arm nearest the bin centre is
    round(centre / w) mod 5. Gives the tutorial's table [3, 4, 0, 1, 2]."""
    width = 2 * np.pi / NUM_SECTORS
    centres = -np.pi + (np.arange(NUM_SECTORS) + 0.5) * width
    return np.mod(np.round(centres / width).astype(int), NUM_SECTORS)


def sector_index(direction_xy: jax.Array, yaw: jax.Array) -> jax.Array:
    """The arm facing the target: angle to target in the robot frame, wrapped, binned, mapped."""
    angle = wrap_angle(jnp.arctan2(direction_xy[1], direction_xy[0]) - yaw)
    width = 2 * jnp.pi / NUM_SECTORS
    bin_ = jnp.clip(jnp.floor((angle + jnp.pi) / width).astype(jnp.int32), 0, NUM_SECTORS - 1)
    return jnp.asarray(sector_table(), jnp.int32)[bin_]


def arm_bearing_bins(direction_xy: jax.Array, yaw: jax.Array, num_arms: int, bins: int) -> jax.Array:
    """Each arm's own state: the target's bearing relative to the arm, in ``bins`` equal bins.

    Arm k points at 2*pi*k/num_arms in the disk frame (biorobot's morphology); bin 0 is centred on
    the arm (target straight ahead), bin b on b * 2*pi/bins counter-clockwise from it. With 5 bins
    and the target along arm L, arm L sees bin 0, arms L-1, L-2 bins 1, 2 and L+1, L+2 bins 4, 3.
    """
    angle = jnp.arctan2(direction_xy[1], direction_xy[0]) - yaw
    relative = angle - 2 * jnp.pi * jnp.arange(num_arms) / num_arms
    width = 2 * jnp.pi / bins
    bin_ = jnp.floor(jnp.mod(relative + width / 2, 2 * jnp.pi) / width).astype(jnp.int32)
    return jnp.clip(bin_, 0, bins - 1)


def quat_to_euler(quat: jax.Array) -> jax.Array:
    """(w, x, y, z) -> extrinsic xyz Euler angles (roll, pitch, yaw), as biorobot's disk_rotation."""
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    roll = jnp.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = jnp.arcsin(jnp.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = jnp.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return jnp.stack([roll, pitch, yaw])


class BrittleStar(MujocoRendering, Env):
    """Directed or undirected locomotion of biorobot's brittle star (MJX backend).

    Videos run at the control rate (one frame per control step, rlq.envs.brittle_star.render).
    """

    def __init__(self, config: BrittleStarConfig):
        if config.observation not in OBSERVATIONS:
            raise ValueError(f"env.observation must be vector, sector or arm_sectors, got {config.observation!r}")
        if config.observation != "vector" and not config.directed:
            raise ValueError(f"env.observation={config.observation} needs a target: use env=brittle_star")
        if config.bearing_bins < 1:
            raise ValueError(f"env.bearing_bins must be >= 1, got {config.bearing_bins}")
        if config.observation == "sector" and config.num_arms != NUM_SECTORS:
            raise ValueError(f"env.observation=sector needs 5 arms, got env.num_arms={config.num_arms}")
        if config.physics_steps_per_control_step < 1 or config.time_scale <= 0 or config.simulation_time <= 0:
            raise ValueError("env.physics_steps_per_control_step, env.time_scale and env.simulation_time must be > 0")
        self.mjx_impl = resolve_impl(config.mjx_impl)
        if config.warp_contacts < 1:
            raise ValueError(f"env.warp_contacts must be >= 1, got {config.warp_contacts}")
        self.config = config
        self.mj_model = bsm.build_model(
            config.num_arms,
            config.segments_per_arm,
            config.p_control,
            (float(config.arena_size[0]), float(config.arena_size[1])),
            config.directed,
            config.time_scale,
            config.physics,
        )
        self.layout = bsm.actuator_layout(self.mj_model)
        self.mjx_model, self._blank_data = bsm.put_on_device(self.mj_model, self.mjx_impl, config.warp_contacts)
        self._disk = self.mj_model.body(bsm.DISK_BODY).id
        self._free_qpos = int(self.mj_model.joint(bsm.FREE_JOINT).qposadr[0])
        self._free_qvel = int(self.mj_model.joint(bsm.FREE_JOINT).dofadr[0])
        self.max_episode_steps = config.episode_steps
        self.control_timestep = config.control_timestep
        self.render_fps = max(1, round(1.0 / config.control_timestep))
        self.action_space = Box(tuple(map(float, self.layout.low)), tuple(map(float, self.layout.high)))
        self.obs_slices, low, high = self._observation_layout()
        self.observation_space: Discrete | AgentsDiscrete | Box = Box(low, high)
        if config.observation == "sector":
            self.observation_space = Discrete(NUM_SECTORS)
        elif config.observation == "arm_sectors":
            self.observation_space = AgentsDiscrete(config.bearing_bins, config.num_arms)

    def _observation_layout(self) -> tuple[dict[str, slice], tuple[float, ...], tuple[float, ...]]:
        inf, n = float("inf"), self.mj_model.nu
        parts = [
            ("joint_position", n, tuple(self.layout.low), tuple(self.layout.high)),
            ("joint_velocity", n, (-inf,) * n, (inf,) * n),
            ("disk_position", 3, (-inf,) * 3, (inf,) * 3),
            ("disk_rotation", 3, (-math.pi,) * 3, (math.pi,) * 3),
            ("disk_linear_velocity", 3, (-inf,) * 3, (inf,) * 3),
            ("disk_angular_velocity", 3, (-inf,) * 3, (inf,) * 3),
        ]
        if self.config.directed:
            parts += [
                ("unit_xy_direction_to_target", 2, (-1.0,) * 2, (1.0,) * 2),
                ("xy_distance_to_target", 1, (0.0,), (inf,)),
                ("target_direction_in_disk_frame", 2, (-1.0,) * 2, (1.0,) * 2),
            ]
        slices: dict[str, slice] = {}
        low: list[float] = []
        high: list[float] = []
        start = 0
        for name, size, lo, hi in parts:
            slices[name] = slice(start, start + size)
            low += map(float, lo)
            high += map(float, hi)
            start += size
        return slices, tuple(low), tuple(high)

    # ----- physics quantities
    def disk_xy(self, data: mjx.Data) -> jax.Array:
        return data.xpos[self._disk, :2]

    def disk_yaw(self, data: mjx.Data) -> jax.Array:
        return quat_to_euler(data.xquat[self._disk])[2]

    def _energy(self, data: mjx.Data) -> jax.Array:
        """Mean |joint actuator force| over the actuated joints (biorobot's joint_actuator_force)."""
        return jnp.mean(jnp.abs(data.qfrc_actuator[self.layout.qvel_adr]))

    def _observe(self, inner: BrittleStarInner) -> jax.Array:
        data = inner.data
        rotation = quat_to_euler(data.xquat[self._disk])
        direction = inner.target_xy - self.disk_xy(data)
        if self.config.observation == "sector":
            return sector_index(direction, rotation[2])
        if self.config.observation == "arm_sectors":
            return arm_bearing_bins(direction, rotation[2], self.config.num_arms, self.config.bearing_bins)
        parts = [
            data.qpos[self.layout.qpos_adr],
            data.qvel[self.layout.qvel_adr],
            data.xpos[self._disk],
            rotation,
            data.qvel[self._free_qvel : self._free_qvel + 3],
            data.qvel[self._free_qvel + 3 : self._free_qvel + 6],
        ]
        if self.config.directed:
            distance = jnp.linalg.norm(direction)
            angle = jnp.arctan2(direction[1], direction[0]) - rotation[2]
            parts += [
                direction / jnp.maximum(distance, 1e-6),
                distance[None],
                jnp.stack([jnp.cos(angle), jnp.sin(angle)]),
            ]
        return jnp.concatenate(parts).astype(jnp.float32)

    def _distance(self, inner: BrittleStarInner) -> jax.Array:
        """Directed: xy distance to the target; undirected: xy distance from the origin."""
        return jnp.linalg.norm(inner.target_xy - self.disk_xy(inner.data))

    def _info(self, inner: BrittleStarInner) -> dict[str, jax.Array]:
        xy = self.disk_xy(inner.data).astype(jnp.float32)
        distance = self._distance(inner).astype(jnp.float32)
        info = {
            "final_xy": xy,
            "descriptor": xy,
            "energy": (inner.energy_sum / jnp.maximum(inner.steps, 1)).astype(jnp.float32),
        }
        if self.config.directed:
            info["distance_to_target"] = distance
            info["distance_closed"] = (inner.start_distance - distance).astype(jnp.float32)
        else:
            info["distance_from_origin"] = distance
        return info

    # ----- rendering (host side)
    def frame_arrays(self, states: EnvState) -> dict[str, np.ndarray]:
        inner: BrittleStarInner = states.inner
        arrays = {"qpos": np.asarray(inner.data.qpos)}
        if self.config.directed:
            arrays["target_xy"] = np.asarray(inner.target_xy)
        return arrays

    def draw_frames(self, arrays: Mapping[str, np.ndarray]) -> Iterator[np.ndarray]:
        return brittle_star_frames(self.mj_model, arrays["qpos"], arrays.get("target_xy"))

    # ----- protocol
    def reset(self, key: jax.Array) -> EnvState:
        key, target_key, rotation_key, qpos_key, qvel_key = jax.random.split(key, 5)
        cfg, layout = self.config, self.layout
        qpos = (
            jnp.asarray(self.mjx_model.qpos0)
            .at[self._free_qpos : self._free_qpos + 3]
            .set(jnp.array([0.0, 0.0, bsm.INITIAL_HEIGHT]))
        )
        if cfg.random_initial_rotation:
            half = 0.5 * jax.random.uniform(rotation_key, (), minval=-jnp.pi, maxval=jnp.pi)
            quat = jnp.array([jnp.cos(half), 0.0, 0.0, jnp.sin(half)])
            qpos = qpos.at[self._free_qpos + 3 : self._free_qpos + 7].set(quat)
        qvel = jnp.zeros(self.mjx_model.nv)
        if cfg.joint_randomization > 0:
            noise = cfg.joint_randomization
            qpos = qpos.at[layout.qpos_adr].add(
                jax.random.uniform(qpos_key, (len(layout.qpos_adr),), minval=-noise, maxval=noise)
            )
            qvel = qvel.at[layout.qvel_adr].set(
                jax.random.uniform(qvel_key, (len(layout.qvel_adr),), minval=-noise, maxval=noise)
            )
        data = self._blank_data.replace(qpos=qpos, qvel=qvel)
        data = mjx.kinematics(self.mjx_model, data)
        if cfg.directed:
            angle = jax.random.uniform(target_key, (), minval=0.0, maxval=2 * jnp.pi)
            target_xy = cfg.target_distance * jnp.array([jnp.cos(angle), jnp.sin(angle)])
        else:
            target_xy = jnp.zeros(2)
        inner = BrittleStarInner(
            data=data,
            target_xy=target_xy,
            start_distance=jnp.zeros(()),
            energy_sum=jnp.zeros(()),
            steps=jnp.zeros((), jnp.int32),
        )
        if cfg.directed:
            inner = inner.replace(start_distance=self._distance(inner))
        return initial_state(self._observe(inner), inner, key, self._info(inner))

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        inner: BrittleStarInner = state.inner
        ctrl = jnp.clip(jnp.asarray(action, jnp.float32), self.layout.low, self.layout.high)

        def physics_step(data, _):
            return mjx.step(self.mjx_model, data), None

        data = inner.data.replace(ctrl=ctrl)
        if self.mjx_impl == "warp":
            data = with_template_buffers(self._blank_data, data)
        data, _ = jax.lax.scan(physics_step, data, None, length=self.config.physics_steps_per_control_step)
        nxt = inner.replace(data=data, energy_sum=inner.energy_sum + self._energy(data), steps=inner.steps + 1)
        before, after = self._distance(inner), self._distance(nxt)
        if self.config.directed:
            reward = before - after
            terminated = jnp.logical_and(self.config.terminate_at_target, after < bsm.TARGET_RADIUS)
        else:
            reward = after - before
            terminated = jnp.zeros((), bool)
        return state.replace(
            obs=self._observe(nxt),
            reward=reward.astype(jnp.float32),
            terminated=terminated,
            truncated=jnp.zeros((), bool),
            info={**state.info, **self._info(nxt)},
            inner=nxt,
        )


def config_from(env_cfg: Config | UndirectedConfig, directed: bool) -> BrittleStarConfig:
    """The simulation's config from the env's declared keys (validated: ValueError on bad values)."""
    raw = dataclasses.asdict(env_cfg)
    physics_raw = raw["physics"] or {}
    unknown = sorted(set(physics_raw) - set(bsm.PhysicsOptions.__dataclass_fields__))
    if unknown:
        raise ValueError(
            f"unknown env.physics key(s) {unknown}; known: {sorted(bsm.PhysicsOptions.__dataclass_fields__)}"
        )
    physics = bsm.PhysicsOptions(**physics_raw)
    num_arms, segments = int(raw["num_arms"]), int(raw["segments_per_arm"])
    bsm.check_morphology(num_arms, segments)
    low, high = (float(x) for x in raw["arena_size"]) if len(raw["arena_size"]) == 2 else (0.0, 0.0)
    if len(raw["arena_size"]) != 2 or min(low, high) <= 0:
        raise ValueError(f"env.arena_size must be two positive numbers [x, y], got {list(raw['arena_size'])}")
    # the target's keys exist for directed locomotion only (rlq/declared/envs/brittle_star.py: Config)
    target: dict[str, Any] = (
        {
            "target_distance": float(raw["target_distance"]),
            "terminate_at_target": bool(raw["terminate_at_target"]),
            "bearing_bins": int(raw["bearing_bins"]),
        }
        if directed
        else {}
    )
    return BrittleStarConfig(
        directed=directed,
        num_arms=num_arms,
        segments_per_arm=segments,
        p_control=bool(raw["p_control"]),
        arena_size=(low, high),
        simulation_time=float(raw["simulation_time"]),
        physics_steps_per_control_step=int(raw["physics_steps_per_control_step"]),
        time_scale=float(raw["time_scale"]),
        joint_randomization=float(raw["joint_randomization"]),
        random_initial_rotation=bool(raw["random_initial_rotation"]),
        observation=str(raw["observation"]),
        physics=physics,
        mjx_impl=str(raw["mjx_impl"]),
        warp_contacts=int(raw["warp_contacts"]),
        **target,
    )


def make(env_cfg: Config) -> BrittleStar:
    return BrittleStar(config_from(env_cfg, directed=True))
