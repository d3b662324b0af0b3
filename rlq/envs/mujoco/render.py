"""Frames of MuJoCo envs, drawn on the host with ``mujoco.Renderer`` (offscreen).

A MuJoCo env renders in two steps: ``frame_arrays(states)`` takes the few per-frame arrays a
picture needs (``qpos``, ...) from its stacked states, and ``draw(arrays)`` turns them into
frames: for each frame the positions are copied into an ``MjData`` of the env's ``mj_model``,
``mj_forward`` places the bodies, and the renderer draws them. Where no OpenGL backend loads,
drawing raises ``NoGLError``; the arrays can then be saved and drawn on another machine
(rlq.store.render).
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any

import mujoco
import numpy as np

from rlq.envs.mujoco.gl import NoGLError, require_gl
from rlq.lib.env_api import EnvState

HEIGHT, WIDTH = 480, 640

#: per frame: the camera to draw from (a camera of the model by name or id, or a free MjvCamera)
CameraFn = Callable[[int, mujoco.MjData], "str | int | mujoco.MjvCamera"]
#: per frame, before ``mj_forward``: edits of the (private) model copy and data, e.g. a target's place
PrepareFn = Callable[[int, mujoco.MjModel, mujoco.MjData], None]


def open_renderer(model: mujoco.MjModel, height: int = HEIGHT, width: int = WIDTH) -> mujoco.Renderer:
    """An offscreen renderer; ``NoGLError`` where no OpenGL context can be made."""
    require_gl()
    logging.getLogger("OpenGL").setLevel(logging.WARNING)  # PyOpenGL logs its import at INFO
    try:
        return mujoco.Renderer(model, height, width)
    except Exception as err:  # MuJoCo raises ImportError, FatalError, OSError... per backend
        raise NoGLError(f"MuJoCo cannot open an OpenGL context: {type(err).__name__}: {err}") from err


def qpos_frames(
    mj_model: mujoco.MjModel,
    qpos: np.ndarray,
    camera: CameraFn,
    height: int = HEIGHT,
    width: int = WIDTH,
    prepare: PrepareFn | None = None,
) -> Iterator[np.ndarray]:
    """uint8 frames (height, width, 3) of the poses ``qpos`` (T, nq) of ``mj_model``, drawn one at a
    time as they are asked for, so a video encoder can work on one frame while the next is drawn.

    The renderer opens at the first frame (``NoGLError`` there where no OpenGL loads) and closes
    when the frames run out or the iterator is closed. The model is copied (its offscreen buffer
    is enlarged to the frame size where needed), so the env's own model is never changed.
    """
    qpos = np.asarray(qpos, np.float64)
    if qpos.ndim != 2 or qpos.shape[1] != mj_model.nq:
        raise ValueError(f"qpos must be (frames, {mj_model.nq}), got {qpos.shape}")
    return _draw(mj_model, qpos, camera, height, width, prepare)


def _draw(
    mj_model: mujoco.MjModel,
    qpos: np.ndarray,
    camera: CameraFn,
    height: int,
    width: int,
    prepare: PrepareFn | None,
) -> Iterator[np.ndarray]:
    model = copy.deepcopy(mj_model)
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
    data = mujoco.MjData(model)
    renderer = open_renderer(model, height, width)
    try:
        for t, pose in enumerate(qpos):
            data.qpos[:] = pose
            data.qvel[:] = 0.0
            if prepare is not None:
                prepare(t, model, data)
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera=camera(t, data))
            yield renderer.render()
    finally:
        renderer.close()


def stack_frames(frames: Iterable[np.ndarray], count: int) -> np.ndarray:
    """``count`` frames of one shape in one uint8 array (T, H, W, 3), filled as they come."""
    stacked: np.ndarray | None = None
    for t, frame in enumerate(frames):
        if stacked is None:
            stacked = np.empty((count, *np.shape(frame)), np.uint8)
        stacked[t] = frame
    return stacked if stacked is not None else np.empty((0, HEIGHT, WIDTH, 3), np.uint8)


def free_camera(lookat: np.ndarray, distance: float, elevation: float, azimuth: float) -> mujoco.MjvCamera:
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = lookat
    camera.distance, camera.elevation, camera.azimuth = distance, elevation, azimuth
    return camera


class MujocoRendering:
    """Mixin of MuJoCo envs (listed before ``Env``): ``render`` is ``draw(frame_arrays(states))``.

    ``frame_arrays`` takes states of the env itself (wrappers hand theirs through
    ``Env.base_states``); ``draw_frames`` needs only the arrays, so saved arrays render later, and
    yields the frames one at a time, so a video is encoded while it is drawn (rlq.store.render).
    """

    def frame_arrays(self, states: EnvState) -> dict[str, np.ndarray]:
        """Host arrays, one row per frame (``qpos`` at least), of states stacked along time."""
        raise NotImplementedError

    def draw_frames(self, arrays: Mapping[str, np.ndarray]) -> Iterator[np.ndarray]:
        """uint8 frames (480, 640, 3) of ``frame_arrays``' output, one at a time; ``NoGLError`` at
        the first where there is no OpenGL."""
        raise NotImplementedError

    def draw(self, arrays: Mapping[str, np.ndarray]) -> np.ndarray:
        """All frames of ``draw_frames`` in one array (T, 480, 640, 3)."""
        return stack_frames(self.draw_frames(arrays), len(arrays["qpos"]))

    def render(self, states: EnvState) -> Any:
        return self.draw(self.frame_arrays(states))
