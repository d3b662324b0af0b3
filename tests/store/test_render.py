import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.lib.rollout import episode_states
from rlq.run.programs.env_stack import make_env
from rlq.store.render import frame_stream, has_renderer, host_states, render_states, write_video
from tests.helpers import compose_config


def test_episode_states_stop_at_the_end_of_the_episode():
    env = make_env(compose_config("env=cartpole"), autoreset=False)
    push_right = lambda obs, key: jnp.array(1)  # noqa: E731  (topples the pole within ~10 steps)
    states, length = episode_states(env, push_right, jax.random.PRNGKey(0), max_steps=500)
    assert 5 < length < 100
    assert bool(states.terminated[length]) and not bool(np.any(states.terminated[:length]))
    frames = env.render(jax.tree.map(lambda x: np.asarray(x)[: length + 1], states))
    assert frames.shape == (length + 1, 400, 600, 3) and frames.dtype == np.uint8
    assert not np.array_equal(frames[0], frames[-1])


def test_has_renderer():
    assert has_renderer(make_env(compose_config("env=cartpole")))


def _frames(count: int, fail_at: int | None = None):
    """Frames of a grey level rising with time (an iterator, as a MuJoCo env draws them)."""
    for t in range(count):
        if t == fail_at:
            raise RuntimeError("drawing failed")
        yield np.full((48, 64, 3), 8 * t, np.uint8)


def test_write_video_encodes_frames_from_an_iterator(tmp_path):
    import imageio_ffmpeg

    path = write_video(tmp_path / "videos" / "v.mp4", _frames(10), fps=25)
    assert path == tmp_path / "videos" / "v.mp4" and sorted(p.name for p in path.parent.iterdir()) == ["v.mp4"]
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    assert meta["size"] == (64, 48) and meta["fps"] == 25
    frames = [np.frombuffer(frame, np.uint8) for frame in reader]
    assert len(frames) == 10
    assert float(frames[0].mean()) < 3 and abs(float(frames[-1].mean()) - 72) < 3


def test_write_video_leaves_no_file_when_drawing_fails_midway(tmp_path):
    with pytest.raises(RuntimeError, match="drawing failed"):
        write_video(tmp_path / "v.mp4", _frames(10, fail_at=5), fps=25)
    assert list(tmp_path.iterdir()) == []


def test_frame_stream_of_an_env_without_draw_frames_is_its_rendered_frames():
    env = make_env(compose_config("env=cartpole"), autoreset=False)
    states, length = episode_states(env, lambda obs, key: jnp.array(1), jax.random.PRNGKey(0), max_steps=20)
    states = host_states(states, 3)
    assert np.array_equal(np.stack(list(frame_stream(env, states))), render_states(env, states))


def test_videos_read_back_as_written(tmp_path):
    """rlq's mp4s read back frame by frame with the ffmpeg rlq writes them with (imageio-ffmpeg's when none is on
    PATH, whose ffmpeg refuses the -vsync flag mediapy.read_video passes)."""
    from rlq.store.render import read_video, write_video

    frames = np.zeros((6, 32, 48, 3), np.uint8)
    frames[:, :, :24, 0] = 255  # the left half red
    path = write_video(tmp_path / "videos" / "final_seed0.mp4", iter(frames), fps=10)
    back = read_video(path)
    assert back.shape == frames.shape and back.dtype == np.uint8
    assert back[:, 8, 4, 0].min() > 200 and back[:, 8, 44].max() < 40  # red left, black right, in every frame
