import jax
import jax.numpy as jnp
import numpy as np

from rlq.run.build import make_env
from rlq.run.render import episode_states, has_renderer
from tests.conftest import compose_config


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
