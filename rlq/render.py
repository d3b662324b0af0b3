"""Videos of a policy: one greedy episode as frames, written with mediapy.

`rlq render run=<dir>` renders a finished run's checkpoint; the training loop calls
``write_episode_video`` at the end of a run (``video.at_end``). An env renders by implementing
``Env.render(states)`` over states stacked along time; the episode itself is one compiled scan.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from rlq.envs.base import Env, EnvState
from rlq.rollout import PolicyFn


def episode_states(env: Env, policy: PolicyFn, key: jax.Array, max_steps: int) -> tuple[EnvState, int]:
    """The states of one greedy episode (reset state first) and its number of steps."""
    reset_key, run_key = jax.random.split(key)

    def run(reset_key, run_key):
        first = env.reset(reset_key)

        def one(state, k):
            nxt = env.step(state, policy(state.obs, k))
            return nxt, (nxt, nxt.done)

        _, (states, done) = jax.lax.scan(one, first, jax.random.split(run_key, max_steps))
        states = jax.tree.map(lambda a, b: jnp.concatenate([jnp.asarray(a)[None], b]), first, states)
        return states, done

    states, done = jax.jit(run)(reset_key, run_key)
    done = np.asarray(done)
    length = int(np.argmax(done)) + 1 if done.any() else max_steps
    return states, length


def _ffmpeg() -> None:
    """mediapy needs an ffmpeg binary: use the one on PATH, else imageio-ffmpeg's."""
    import mediapy

    if shutil.which("ffmpeg") is None:
        import imageio_ffmpeg

        mediapy.set_ffmpeg(imageio_ffmpeg.get_ffmpeg_exe())


def write_video(path: Path, frames: np.ndarray, fps: int) -> Path:
    import mediapy

    _ffmpeg()
    path.parent.mkdir(parents=True, exist_ok=True)
    mediapy.write_video(str(path), frames, fps=fps)
    return path


def has_renderer(env: Env) -> bool:
    return type(env.unwrapped).render is not Env.render


def write_episode_video(env: Env, policy: PolicyFn, key: jax.Array, path: Path, max_steps: int | None = None) -> Path:
    """Render one greedy episode of ``policy`` on ``env`` to mp4.

    ``env`` should not auto-reset (``make_env(cfg, autoreset=False)``) so the last frame shows
    the end of the episode; frames after it are cut off.
    """
    max_steps = max_steps or env.max_episode_steps or 1000
    states, length = episode_states(env, policy, key, max_steps)
    states = jax.tree.map(lambda x: np.asarray(x)[: length + 1], jax.device_get(states))
    frames = np.asarray(env.render(states), np.uint8)
    return write_video(path, frames, env.render_fps)
