"""Videos of a policy: one greedy episode as frames, written with mediapy.

`rlq render run=<dir>` renders a finished run's checkpoint; the training loop calls
``write_episode_video`` at the end of a run (``video.at_end``). An env renders by implementing
``Env.render(states)`` over states stacked along time; the episode itself is one compiled scan
(rlq.lib.rollout.episode_program): nothing here builds a program.

MuJoCo envs (rlq.envs.mujoco.render) draw on the host through OpenGL. Where no GL backend loads,
``write_episode_video`` saves the arrays the frames are drawn from (``<name>.npz``: ``qpos`` per
frame, the target, ``fps``, the env's name) instead, and ``render_saved`` (`rlq render run=<dir>
states=<npz>`) draws them on a machine that has GL.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import jax
import numpy as np

from rlq.envs.mujoco.gl import NoGLError
from rlq.lib.env_api import Env, EnvState
from rlq.lib.rollout import PolicyFn, episode_states
from rlq.store.outputs import check_output_file


@runtime_checkable
class DrawsFrames(Protocol):
    """An env that draws its frames one at a time (``MujocoRendering``, without importing mujoco)."""

    def frame_arrays(self, states: EnvState) -> dict[str, np.ndarray]: ...

    def draw_frames(self, arrays: Mapping[str, np.ndarray]) -> Iterator[np.ndarray]: ...


#: keys of a saved-states file that are not per-frame arrays of ``DrawsFrames.draw_frames``
_META = ("fps", "env")


def _ffmpeg() -> None:
    """mediapy needs an ffmpeg binary: use the one on PATH, else imageio-ffmpeg's."""
    import mediapy

    if shutil.which("ffmpeg") is None:
        import imageio_ffmpeg

        mediapy.set_ffmpeg(imageio_ffmpeg.get_ffmpeg_exe())


def read_video(path: Path | str) -> np.ndarray:
    """The frames of an mp4 (rlq's videos, e.g. ``videos/final_seed0.mp4``) as a uint8 array (T, H, W, 3).

    Read with imageio-ffmpeg's own reader and binary: ``mediapy.read_video`` passes ``-vsync``, which the
    ffmpeg that imageio-ffmpeg ships (8.x) no longer knows ("Unrecognized option 'vsync'"), so mediapy
    reads these videos back only with an older ffmpeg of its own on PATH."""
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta["size"]
    frames = [np.frombuffer(frame, np.uint8).reshape(height, width, 3) for frame in reader]
    return np.stack(frames) if frames else np.zeros((0, height, width, 3), np.uint8)


def partial_path(path: Path) -> Path:
    """Where ``write_video`` writes the frames of ``path`` until the last is encoded."""
    return path.with_name(f"{path.stem}.part{path.suffix}")


def write_video(path: Path, frames: Iterable[np.ndarray], fps: int) -> Path:
    """Encode uint8 frames (H, W, 3) into an mp4 at ``fps``, each as it comes: from an iterator
    (``frame_stream``) ffmpeg encodes the frames before while the next is drawn. An error before
    the first frame leaves no file; one later leaves none at ``path`` either (the frames go to a
    ``.part`` file first)."""
    import mediapy

    check_output_file(path)
    _ffmpeg()
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = partial_path(path)
    try:
        mediapy.write_video(str(partial), (np.asarray(frame, np.uint8) for frame in frames), fps=fps)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return partial.replace(path)


def has_renderer(env: Env) -> bool:
    return type(env.unwrapped).render is not Env.render


def host_states(states: EnvState, length: int | None = None) -> EnvState:
    """Stacked states copied to the host once, cut to their first ``length + 1`` (reset state and
    ``length`` steps; None: all)."""
    end = None if length is None else length + 1
    return jax.tree.map(lambda x: np.asarray(x)[:end], jax.device_get(states))


def render_states(env: Env, states: EnvState, length: int | None = None) -> np.ndarray:
    """uint8 frames (T, H, W, 3) of states of ``env`` stacked along time (as ``episode_states``
    gives them; any wrapper stack, device or host arrays). ``NoGLError`` where a MuJoCo env finds
    no OpenGL."""
    return np.asarray(env.render(host_states(states, length)), np.uint8)


def frame_stream(env: Env, states: EnvState) -> Iterator[np.ndarray]:
    """The frames of host ``states`` of ``env``, one at a time where the env draws them so (MuJoCo
    envs: ``draw_frames``), else rendered all at once first. ``NoGLError`` at the first frame
    where a MuJoCo env finds no OpenGL."""
    base = env.unwrapped
    if not isinstance(base, DrawsFrames):
        return iter(render_states(env, states))
    return base.draw_frames(base.frame_arrays(env.base_states(states)))


def save_frame_arrays(env: Env, states: EnvState, path: Path) -> Path:
    """Save what a MuJoCo env's frames are drawn from (host states of ``env``) to ``path`` (.npz)."""
    base = env.unwrapped
    if not isinstance(base, DrawsFrames):
        raise TypeError(f"{type(base).__name__} is not a MuJoCo env; its states cannot be saved for rendering")
    check_output_file(path)
    arrays = base.frame_arrays(env.base_states(states))
    path.parent.mkdir(parents=True, exist_ok=True)
    contents: dict[str, Any] = {**arrays, "fps": np.int64(env.render_fps), "env": np.str_(type(base).__name__)}
    np.savez_compressed(path, **contents)
    return path


def load_frame_arrays(path: Path) -> tuple[dict[str, np.ndarray], int, str]:
    """The per-frame arrays, frame rate and env class name of a file of ``save_frame_arrays``."""
    with np.load(path, allow_pickle=False) as saved:
        arrays = {k: saved[k] for k in saved.files if k not in _META}
        return arrays, int(saved["fps"]), str(saved["env"])


def render_saved(base_env: Env, states_path: Path, out: Path | None = None) -> Path:
    """Draw a file of ``save_frame_arrays`` with ``base_env`` (the same env, rebuilt from the
    run's config) into an mp4 (default: next to it). ``NoGLError`` where there is no OpenGL."""
    if not isinstance(base_env, DrawsFrames):
        raise TypeError(f"{type(base_env).__name__} is not a MuJoCo env; saved states cannot be drawn with it")
    arrays, fps, env_name = load_frame_arrays(states_path)
    if env_name != type(base_env).__name__:
        raise ValueError(f"the states were saved by {env_name}, not {type(base_env).__name__}")
    return write_video(out or states_path.with_suffix(".mp4"), base_env.draw_frames(arrays), fps)


def render_command(run_dir: Path, states_path: Path) -> str:
    """The advice that turns saved states into an mp4 on a machine with OpenGL (the states'
    path relative to the run directory where it lies inside it)."""
    if states_path.is_relative_to(run_dir):
        states_path = states_path.relative_to(run_dir)
    return f"on a machine with OpenGL run: rlq render run={run_dir} states={states_path}"


def write_states_video(env: Env, states: EnvState, length: int, path: Path) -> Path:
    """Render the first ``length`` steps of an episode's stacked states (``episode_states``) to mp4,
    and return its path. Where a MuJoCo env finds no OpenGL, the states are saved instead and the
    path returned is ``path`` with suffix ``.npz`` (``render_saved`` turns it into the mp4)."""
    states = host_states(states, length)
    try:
        return write_video(path, frame_stream(env, states), env.render_fps)
    except NoGLError:  # raised by MuJoCo envs only, at the first frame, and they can save their states
        return save_frame_arrays(env, states, path.with_suffix(".npz"))


def write_episode_video(env: Env, policy: PolicyFn, key: jax.Array, path: Path, max_steps: int | None = None) -> Path:
    """Render one greedy episode of ``policy`` on ``env`` to mp4 (or its states to .npz without
    OpenGL, see ``write_states_video``), and return its path.

    ``env`` should not auto-reset (``make_env(cfg, autoreset=False)``) so the last frame shows
    the end of the episode; frames after it are cut off.
    """
    max_steps = max_steps or env.max_episode_steps or 1000
    states, length = episode_states(env, policy, key, max_steps)
    return write_states_video(env, states, length, path)
