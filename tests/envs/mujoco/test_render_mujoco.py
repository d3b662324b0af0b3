"""MuJoCo videos: the brittle star (through the CPG controller) and the humanoid drawn offscreen,
and the fallback that saves an episode's states where no OpenGL loads.

One tiny brittle star episode (1 segment per arm, 3 control steps) is compiled once for the
module; everything else renders on the host.
"""

from pathlib import Path
from types import SimpleNamespace

import jax
import numpy as np
import pytest
from omegaconf import OmegaConf

pytest.importorskip("biorobot")

from rlq.envs.mujoco.gl import NoGLError, gl_backend  # noqa: E402
from rlq.envs.mujoco.render import HEIGHT, WIDTH  # noqa: E402
from rlq.lib.env_api import EnvState  # noqa: E402
from rlq.lib.rollout import episode_states  # noqa: E402
from rlq.run.programs.env_stack import make_env  # noqa: E402
from rlq.store.render import (
    has_renderer,
    host_states,
    load_frame_arrays,
    render_states,
    save_frame_arrays,
)
from tests.helpers import compose_config, run_cli  # noqa: E402

pytestmark = [
    pytest.mark.slow,
    pytest.mark.filterwarnings("ignore::UserWarning"),
    pytest.mark.skipif(gl_backend() is None, reason="no OpenGL backend for MuJoCo (tried egl, osmesa, glfw)"),
]

STEPS = 3
TINY = (
    "env=brittle_star",
    "controller=cpg",
    "env.segments_per_arm=1",
    "env.physics.wall_contacts=false",
    f"env.simulation_time={STEPS * 0.04}",
)


def red_pixels(frame: np.ndarray) -> int:
    """Pixels of the target's red (biorobot's site is pure red)."""
    r, g, b = (frame[..., i].astype(int) for i in range(3))
    return int(np.sum((r > 150) & (g < 60) & (b < 60)))


@pytest.fixture(scope="module")
def cfg():
    return compose_config(*TINY)


@pytest.fixture(scope="module")
def episode(cfg):
    """(env, host states, length) of one brittle star episode under the CPG controller."""
    env = make_env(cfg, autoreset=False)
    policy = lambda obs, key: jax.random.randint(key, (), 0, 5)  # noqa: E731  (a random leading arm)
    states, length = episode_states(env, policy, jax.random.PRNGKey(0), STEPS)
    return env, host_states(states, length), length


def test_brittle_star_frames_show_the_star_and_its_target(episode):
    env, states, length = episode
    assert has_renderer(env) and env.render_fps == 25
    frames = render_states(env, states)
    assert frames.shape == (length + 1, HEIGHT, WIDTH, 3) and frames.dtype == np.uint8
    assert all(frame.std() > 20 for frame in frames)
    assert all(red_pixels(frame) > 50 for frame in frames)  # the target is in view
    assert not np.array_equal(frames[0], frames[-1])  # the star moved


def test_without_gl_the_states_are_saved_and_render_later(episode, cfg, tmp_path, monkeypatch):
    env, states, length = episode
    with monkeypatch.context() as patch:
        patch.setenv("MUJOCO_GL", "disable")
        with pytest.raises(NoGLError):
            render_states(env, states)
    path = save_frame_arrays(env, states, tmp_path / "videos" / "final_seed0.npz")
    arrays, fps, env_name = load_frame_arrays(path)
    assert (
        fps == 25
        and env_name == "BrittleStar"
        and arrays["qpos"].shape[0] == length + 1
        and arrays["target_xy"].shape == (length + 1, 2)
    )
    run_dir = tmp_path / "run"
    (run_dir / ".hydra").mkdir(parents=True)
    OmegaConf.save(cfg, run_dir / ".hydra" / "config.yaml")
    done = run_cli("render", f"run={run_dir}", f"states={path}", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert path.with_suffix(".mp4").stat().st_size > 1000


def test_final_video_saves_states_and_prints_one_line_without_gl(episode, cfg, tmp_path, monkeypatch, capsys):
    """rlq.run.videos.Seed0Video (the final and stage videos) on a machine without GL (the
    compiled episode is reused)."""
    import rlq.run.videos
    from rlq.store.logging import ConsoleSink

    env, states, length = episode
    done = np.arange(length) == length - 1
    monkeypatch.setattr(rlq.run.videos, "episode_program", lambda *args: lambda state, key: (states, done))
    monkeypatch.setenv("MUJOCO_GL", "disable")
    logger = SimpleNamespace(console=ConsoleSink(1, 1, enabled=False))
    video = rlq.run.videos.Seed0Video(cfg, SimpleNamespace(policy=lambda state: None), tmp_path, logger, env)
    path = video({"params": np.zeros(1)}, 3, "final_seed0")
    assert path == tmp_path / "videos" / "final_seed0.npz" and path.exists()
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].endswith(f"rlq render run={tmp_path} states=videos/final_seed0.npz")


def test_humanoid_frames_from_the_side_camera():
    """The host renderer on poses (compiling brax's humanoid takes minutes on CPU)."""
    from rlq.envs.humanoid.env import Humanoid

    env = Humanoid()
    qpos = np.tile(env.mj_model.qpos0, (3, 1))
    qpos[:, 0] = [0.0, 0.5, 1.0]  # walks 1 m along x: the tracking camera follows
    qpos[2, 7:] = 0.4  # bends its joints in the last frame
    pipeline = SimpleNamespace(qpos=qpos)
    states = EnvState(
        obs=None,
        reward=None,
        terminated=None,
        truncated=None,
        info={},
        inner={"brax": SimpleNamespace(pipeline_state=pipeline), "model": {}},
        extras={},
        key=None,
    )
    frames = env.render(states)
    assert env.render_fps == 67
    assert frames.shape == (3, HEIGHT, WIDTH, 3) and frames.dtype == np.uint8
    assert all(frame.std() > 20 for frame in frames)
    assert not np.array_equal(frames[1], frames[2])
    streamed = env.draw_frames({"qpos": qpos})  # what a video encodes, one frame at a time
    assert np.array_equal(next(streamed), frames[0])
    assert np.array_equal(np.stack(list(streamed)), frames[1:])


def test_mujoco_frames_open_the_renderer_at_the_first_frame(monkeypatch):
    from rlq.envs.humanoid.env import Humanoid

    env = Humanoid()
    monkeypatch.setenv("MUJOCO_GL", "disable")
    frames = env.draw_frames({"qpos": env.mj_model.qpos0[None]})
    with pytest.raises(NoGLError):
        next(frames)


def test_mujoco_gl_disable_means_no_backend(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "disable")
    assert gl_backend() is None
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    assert gl_backend() == "osmesa"  # the user's choice is not probed


def test_saving_states_needs_a_mujoco_env(tmp_path):
    env = make_env(compose_config("env=cartpole"), autoreset=False)
    with pytest.raises(TypeError):
        save_frame_arrays(env, None, tmp_path / "x.npz")


def test_relative_states_path_resolves_in_the_run_dir(tmp_path: Path):
    from rlq.cli.render import _states_path

    (tmp_path / "videos").mkdir()
    (tmp_path / "videos" / "a.npz").write_bytes(b"")
    assert _states_path(tmp_path, "videos/a.npz") == tmp_path / "videos" / "a.npz"
