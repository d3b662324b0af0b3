"""The humanoid's feet-contact descriptor (QDax's ``humanoid_uni``) on hand-made feet: the share of an episode's
states, from the reset's to the one before its last step, in which each foot is on the floor."""

from pathlib import Path

import brax
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from rlq.algos.qd import measures
from rlq.algos.qd.scoring import make_keyed_scoring_fn, with_one_key
from rlq.envs.humanoid.feet_contact import Feet, FeetContactTime, feet_of, on_floor
from rlq.envs.wrappers import AutoReset, EpisodeStats, TimeLimit
from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import Box

#: (right, left) on the floor in the states s0 (the reset's), s1, ... of every episode
FLAGS = np.array([[1, 0], [1, 1], [1, 1], [0, 0], [0, 1], [0, 1]], np.float32)


class Feet2(Env):
    """Scripted feet: state ``t`` has the flags ``FLAGS[t]``; the episode terminates on reaching ``fall_at``."""

    observation_space = Box((-1.0,), (1.0,))
    action_space = Box((-1.0,), (1.0,))

    def __init__(self, fall_at: int = 99):
        self.fall_at = fall_at

    def reset(self, key: jax.Array) -> EnvState:
        return initial_state(jnp.zeros(1), jnp.zeros((), jnp.int32), key)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        t = state.inner + 1
        return state.replace(inner=t, reward=jnp.ones(()), terminated=t >= self.fall_at)

    def feet_on_floor(self, state: EnvState) -> jax.Array:
        return jnp.asarray(FLAGS)[state.inner]


def wrapped(limit: int = 4, fall_at: int = 99) -> Env:
    """As ``make_env`` stacks it: time limit, the descriptor's wrapper, episode statistics, auto-reset."""
    return AutoReset(EpisodeStats(FeetContactTime(TimeLimit(Feet2(fall_at), limit))))


def test_the_share_counts_the_states_acted_in_and_restarts_with_each_episode():
    env = wrapped(limit=4)
    state = env.reset(jax.random.PRNGKey(0))
    np.testing.assert_array_equal(state.info["feet_contact"], [0.0, 0.0])
    seen = []
    for _ in range(5):
        state = env.step(state, jnp.zeros(1))
        seen.append(np.asarray(state.info["feet_contact"]))
    np.testing.assert_allclose(seen[0], [1.0, 0.0])  # s0 only
    np.testing.assert_allclose(seen[1], [1.0, 0.5])  # s0, s1
    np.testing.assert_allclose(seen[2], [1.0, 2 / 3])
    np.testing.assert_allclose(seen[3], [0.75, 0.5])  # the episode's end (4 steps): s0..s3, not s4
    assert bool(state.info["episode_length"] == 1)
    np.testing.assert_allclose(seen[4], [1.0, 0.0])  # the next episode counts afresh from its reset's state


def test_scoring_reads_each_episode_at_its_end_a_fall_included():
    """The scoring function's descriptor: the 4-step time limit's episode, and one that falls after 2 steps (QDax
    masks the steps after the first done: the same states count)."""
    for env, expected in ((wrapped(limit=4), [0.75, 0.5]), (wrapped(limit=4, fall_at=2), [1.0, 0.5])):
        score = with_one_key(
            make_keyed_scoring_fn(env, lambda params, obs, key: params, 2, descriptor_key="feet_contact")
        )
        fitness, descriptors, extras = score(jnp.zeros((3, 1)), jax.random.PRNGKey(1))
        np.testing.assert_allclose(descriptors, np.tile(expected, (3, 1)))
        np.testing.assert_allclose(fitness, extras["episode_length"].mean(axis=1))  # return: 1 per step


def test_a_foot_is_on_the_floor_when_its_sphere_reaches_it():
    feet = Feet(np.array([1, 2], np.int32), np.array([0.075, 0.075], np.float32), 0.0)
    xpos = jnp.array([[0.0, 0.0, 0.0], [0.3, 0.1, 0.074], [0.3, -0.1, 0.0751]])
    np.testing.assert_array_equal(on_floor(xpos, feet), [1.0, 0.0])
    raised = Feet(feet.geoms, feet.radii, 0.01)  # a floor 1 cm up reaches both
    np.testing.assert_array_equal(on_floor(xpos, raised), [1.0, 1.0])


def test_brax_humanoid_feet_are_its_two_spheres_right_then_left():
    model = mujoco.MjModel.from_xml_path(str(Path(brax.__file__).parent / "envs" / "assets" / "humanoid.xml"))
    feet = feet_of(model)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) for g in feet.geoms]
    assert names == ["right_foot", "left_foot"] and feet.geoms[0] < feet.geoms[1]
    np.testing.assert_allclose(feet.radii, [0.075, 0.075])
    assert feet.floor_z == 0.0
    touching = [g for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]]
    assert sorted(touching) == sorted([*feet.geoms, model.geom("floor").id])  # nothing else meets the floor


def test_a_model_without_feet_is_refused():
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><geom name='floor' type='plane' size='1 1 1'/></worldbody></mujoco>"
    )
    with pytest.raises(ValueError, match="right_foot"):
        feet_of(model)


def test_the_check_names_the_descriptors_an_env_reports_through_its_own_wrappers():
    keys = {"episode_return"}
    assert measures.check("return", "final_xy", keys, own=("feet_contact",)) == (
        "algo.descriptor=final_xy is not reported by this env; it reports feet_contact, last_obs"
    )
    assert measures.check("return", "feet_contact", keys | {"feet_contact"}) is None
    env = Feet2()
    env.descriptor_wrappers = {"feet_contact": FeetContactTime}
    assert isinstance(measures.wrap_measure(TimeLimit(env, 4), "feet_contact"), FeetContactTime)
