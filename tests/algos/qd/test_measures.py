"""Fitness and descriptor measures: the LunarLander landing descriptor (reported by the env itself) and the
named checks."""

import jax
import jax.numpy as jnp
import numpy as np

from rlq.algos.qd import measures
from rlq.envs.cartpole import CartPole
from rlq.envs.lunar.env import LunarLander
from rlq.envs.lunar.landing import LandingReport
from rlq.envs.wrappers import AutoReset, EpisodeStats, TimeLimit
from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import Box, Discrete

#: scripted LunarLander observations [x, y, vx, vy, angle, angular vel, leg 1, leg 2] per step
SCRIPT = np.array(
    [
        [0.0, 1.0, 0.0, -0.5, 0, 0, 0, 0],
        [0.1, 0.5, 0.3, -0.4, 0, 0, 0, 0],
        [0.2, 0.0, 0.0, -0.3, 0, 0, 1, 0],  # first contact: speed 0.3
        [0.3, 0.0, 0.0, -0.9, 0, 0, 1, 1],  # a later, faster moment does not count
        [0.4, 0.0, 0.0, 0.0, 0, 0, 1, 1],
    ],
    np.float32,
)


class Scripted(Env):
    observation_space = Box((-10.0,) * 8, (10.0,) * 8)
    action_space = Discrete(4)

    def reset(self, key: jax.Array) -> EnvState:
        return initial_state(jnp.asarray(SCRIPT[0]), jnp.zeros((), jnp.int32), key)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        t = state.inner + 1
        return state.replace(obs=jnp.asarray(SCRIPT)[t], inner=t, reward=jnp.ones(()))


def test_landing_is_final_x_and_the_speed_at_first_contact():
    env = AutoReset(EpisodeStats(LandingReport(TimeLimit(Scripted(), 4))))
    state = env.reset(jax.random.PRNGKey(0))
    seen = []
    for _ in range(5):
        state = env.step(state, jnp.zeros((), jnp.int32))
        seen.append(np.asarray(state.info["landing"]))
    np.testing.assert_allclose(seen[0], [0.1, 0.5], rtol=1e-6)  # no contact yet: the current speed
    np.testing.assert_allclose(seen[1], [0.2, 0.3], rtol=1e-6)
    np.testing.assert_allclose(seen[3], [0.4, 0.3], rtol=1e-6)  # episode end (4 steps): x 0.4, touchdown 0.3
    np.testing.assert_allclose(seen[4], [0.1, 0.5], rtol=1e-6)  # the next episode starts afresh


def test_checks_name_the_choices_and_what_the_env_reports():
    keys = {"episode_return", "final_xy", "energy"}
    assert measures.check("return", "final_xy", keys) is None
    assert "one of return, energy, distance" in measures.check("speed", None, keys)
    assert measures.check("return", "landing", keys) == (
        "algo.descriptor=landing is not reported by this env; it reports final_xy, last_obs"
    )
    assert "brittle star" in measures.check("energy", None, {"episode_return"})
    assert "env=brittle_star_undirected" in measures.check("distance", None, keys)
    assert measures.check("distance", "final_xy", keys | {"distance_from_origin"}) is None


def test_distance_fitness_is_how_far_each_episode_ended_from_its_start():
    record = {"distance_from_origin": jnp.array([0.5, 1.25]), "episode_return": jnp.array([9.0, -9.0])}
    np.testing.assert_allclose(np.asarray(measures.FITNESS["distance"](record)), [0.5, 1.25])


def test_the_landing_descriptor_comes_with_lunar_lander_only():
    lunar = measures.wrap_measure(LunarLander(), "landing")
    assert isinstance(lunar, LandingReport)
    reported = set(lunar.reset(jax.random.PRNGKey(0)).info) | {"episode_return"}
    assert measures.check("return", "landing", reported) is None
    cartpole = CartPole()
    assert measures.wrap_measure(cartpole, "landing") is cartpole  # no env-specific wrapper reaches another env
    assert isinstance(measures.wrap_measure(cartpole, "last_obs"), measures.LastObservation)
