"""Frames of the brittle star: a camera above and behind the disk, looking down at an angle.

Directed locomotion: the camera looks at the midpoint of the disk and the target and stands far
enough back to keep both in view; the target (biorobot's red disc site, on a fixed body) is moved
to the episode's ``target_xy``. Undirected: the camera follows the disk.
"""

from __future__ import annotations

from collections.abc import Iterator

import mujoco
import numpy as np

from rlq.envs.brittle_star import model as bsm
from rlq.envs.mujoco.render import HEIGHT, WIDTH, free_camera, qpos_frames

TARGET_BODY = "target"
ELEVATION = -40.0  # degrees below the horizon
AZIMUTH = 90.0  # the camera stands on the -y side, looking along +y
#: camera distance: at least this, else this much per metre of disk-target separation
MIN_DISTANCE = 2.0
DISTANCE_PER_METRE = 1.4


def _free_xy(mj_model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    adr = int(mj_model.joint(bsm.FREE_JOINT).qposadr[0])
    return qpos[:, adr : adr + 2]


def brittle_star_frames(
    mj_model: mujoco.MjModel,
    qpos: np.ndarray,
    target_xy: np.ndarray | None = None,
    height: int = HEIGHT,
    width: int = WIDTH,
) -> Iterator[np.ndarray]:
    """uint8 frames (height, width, 3), one at a time, of the poses ``qpos`` (T, nq); ``target_xy`` (T, 2) or
    (2,) places the target of a directed model (None: undirected, no target drawn)."""
    qpos = np.asarray(qpos, np.float64)
    disk = mj_model.body(bsm.DISK_BODY).id
    directed = target_xy is not None
    targets = np.zeros((len(qpos), 2))
    if target_xy is not None:
        targets = np.broadcast_to(np.asarray(target_xy, np.float64), (len(qpos), 2))
        target = mj_model.body(TARGET_BODY).id
        separation = np.linalg.norm(_free_xy(mj_model, qpos) - targets, axis=-1).max(initial=0.0)
        distance = max(MIN_DISTANCE, DISTANCE_PER_METRE * float(separation) + 1.0)
    else:
        distance = MIN_DISTANCE

    def prepare(t: int, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if directed:
            model.body_pos[target, :2] = targets[t]

    def camera(t: int, data: mujoco.MjData) -> mujoco.MjvCamera:
        lookat = np.array([*data.xpos[disk, :2], 0.0])
        if directed:
            lookat[:2] = 0.5 * (lookat[:2] + targets[t])
        return free_camera(lookat, distance, ELEVATION, AZIMUTH)

    return qpos_frames(mj_model, qpos, camera, height, width, prepare)
