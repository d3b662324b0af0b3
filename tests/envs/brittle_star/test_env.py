"""biorobot's brittle star on MJX behind rlq's protocol.

MJX compiles slowly on CPU (about a minute per program here), so one small pruned model
(5 arms x 2 segments, floor contacts only) is reset and stepped by programs compiled once for
the module. Faithfulness to biorobot's own MJX env (same disk trajectory, reward, energy for the
same actions) was checked by hand; see docs/brittle_star.md.
"""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

pytest.importorskip("biorobot")

from mujoco import mjx  # noqa: E402

from rlq.config.compose import WITHOUT_TUNED
from rlq.envs import make_base_env  # noqa: E402
from rlq.envs.brittle_star.env import sector_index, sector_table, wrap_angle  # noqa: E402
from rlq.envs.brittle_star.model import contact_candidates  # noqa: E402
from tests.helpers import compose_config  # noqa: E402

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::UserWarning")]

SMALL = ("env.segments_per_arm=2", "env.physics.wall_contacts=false")
STEPS = 3


def base_env(*overrides: str):
    return make_base_env(compose_config(*overrides, *WITHOUT_TUNED).env)  # the env's own defaults, not PPO's pair


@pytest.fixture(scope="module")
def env():
    return base_env("env=brittle_star", *SMALL)


@pytest.fixture(scope="module")
def trajectory(env):
    """Reset 2 envs and take STEPS control steps with random joint targets."""
    reset = jax.jit(jax.vmap(env.reset))
    step = jax.jit(jax.vmap(env.step))
    states = [reset(jax.random.split(jax.random.PRNGKey(0), 2))]
    key = jax.random.PRNGKey(1)
    for _ in range(STEPS):
        key, sub = jax.random.split(key)
        action = jax.vmap(env.action_space.sample)(jax.random.split(sub, 2))
        states.append(step(states[-1], action))
    return states


def test_spaces_follow_the_morphology(env):
    assert env.action_space.shape == (20,)  # 5 arms x 2 segments x (in-plane, out-of-plane)
    np.testing.assert_allclose(env.action_space.high[:4], [0.7854, 0.5236, 0.7854, 0.5236], atol=1e-4)
    assert env.observation_space.shape == (2 * 20 + 12 + 5,)
    assert env.max_episode_steps == 500 and env.control_timestep == pytest.approx(0.04)


def test_actuators_are_arm_major_then_segment_then_ip_oop(env):
    layout = env.layout
    np.testing.assert_array_equal(layout.arm, np.repeat(np.arange(5), 4))
    np.testing.assert_array_equal(layout.segment, np.tile([0, 0, 1, 1], 5))
    np.testing.assert_array_equal(layout.kind, np.tile([0, 1], 10))
    model = env.mj_model
    for i in (0, 1, 7):
        name = model.actuator(i).name
        kind = "in_plane" if layout.kind[i] == 0 else "out_of_plane"
        assert f"arm_{layout.arm[i]}_segment_{layout.segment[i]}_{kind}_joint" in name


def test_arm_k_points_at_k_times_72_degrees(env):
    """The geometry behind the sector table: biorobot's arm k leaves the disk at angle 2*pi*k/5."""
    model = env.mj_model
    disk = model.body("BrittleStarMorphology/central_disk").id
    for k in range(5):
        arm = model.body(f"BrittleStarMorphology/arm_{k}")
        assert arm.parentid[0] == disk
        w, _, _, z = arm.quat
        expected = float(wrap_angle(jnp.asarray(2 * np.pi * k / 5)))
        assert np.arctan2(arm.pos[1], arm.pos[0]) == pytest.approx(expected, abs=1e-5)
        assert float(wrap_angle(jnp.asarray(2 * np.arctan2(z, w)))) == pytest.approx(
            expected, abs=1e-5
        )  # the arm's x axis turns with it


def test_reset_and_step_shapes_and_info(env, trajectory):
    first, last = trajectory[0], trajectory[-1]
    assert first.obs.shape == (2, 57) and bool(jnp.all(jnp.isfinite(last.obs)))
    assert last.reward.shape == (2,) and not bool(last.done.any())
    for key in ("distance_closed", "distance_to_target", "final_xy", "descriptor", "energy"):
        assert key in first.info and key in last.info
        assert first.info[key].shape == last.info[key].shape
    assert last.info["final_xy"].shape == (2, 2)
    np.testing.assert_allclose(first.info["distance_to_target"], 3.0, atol=1e-5)
    assert not np.allclose(first.inner.target_xy[0], first.inner.target_xy[1])  # random target per env
    returns = sum(s.reward for s in trajectory[1:])
    np.testing.assert_allclose(last.info["distance_closed"], returns, atol=1e-5)
    assert bool(jnp.all(last.info["energy"] > 0))
    assert jax.tree.structure(first) == jax.tree.structure(last)


def test_observation_parts(env, trajectory):
    last = trajectory[-1]
    obs = last.obs[0]
    sl = env.obs_slices
    np.testing.assert_allclose(obs[sl["disk_position"]][:2], last.info["final_xy"][0], atol=1e-6)
    np.testing.assert_allclose(jnp.linalg.norm(obs[sl["unit_xy_direction_to_target"]]), 1.0, atol=1e-5)
    np.testing.assert_allclose(obs[sl["xy_distance_to_target"]][0], last.info["distance_to_target"][0], atol=1e-6)


def test_floor_only_pruning_cuts_contact_candidates(env):
    full = base_env("env=brittle_star", "env.segments_per_arm=2")
    pruned_ncon = contact_candidates(env.mj_model)
    full_ncon = contact_candidates(full.mj_model)
    assert pruned_ncon == 10 * 2 + 3  # capsule-plane: 2 each; disk cylinder-plane: 3
    assert full_ncon == 5 * pruned_ncon


def test_joint_limits_off_drops_the_limit_rows():
    with_limits = base_env("env=brittle_star", *SMALL)
    without = base_env("env=brittle_star", *SMALL, "env.physics.joint_limits=false")
    rows = [mjx.make_data(e.mjx_model)._impl.efc_J.shape[0] for e in (with_limits, without)]
    assert rows[0] - rows[1] == 5 * 2 * 2  # one row per limited hinge: 5 arms x 2 segments x (IP, OOP)
    assert without.mj_model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_LIMIT


def test_sector_table_is_the_tutorials():
    np.testing.assert_array_equal(sector_table(), [3, 4, 0, 1, 2])


def test_sector_faces_the_arm_pointing_at_the_target():
    for yaw in (-3.0, -1.0, 0.0, 0.5, 3.1):
        for arm in range(5):
            angle = yaw + 2 * np.pi * arm / 5 + 0.2
            direction = jnp.array([np.cos(angle), np.sin(angle)])
            assert int(sector_index(direction, jnp.asarray(yaw))) == arm


def test_sector_wraps_the_angle():
    """Target at -170 deg, disk yaw +170 deg: the raw difference -340 deg is +20 deg, straight
    ahead of arm 0; the tutorial's unwrapped bin would be floor((-340 + 180) / 72) = -3."""
    direction = jnp.array([np.cos(np.radians(-170)), np.sin(np.radians(-170))])
    assert int(sector_index(direction, jnp.asarray(np.radians(170)))) == 0
    assert float(wrap_angle(jnp.asarray(np.pi))) == pytest.approx(-np.pi)


def test_sector_observation_env():
    env = base_env("env=brittle_star", "env.observation=sector", *SMALL)
    assert env.observation_space.n == 5
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    assert state.obs.dtype == jnp.int32 and 0 <= int(state.obs) < 5


def test_undirected_defaults():
    env = base_env("env=brittle_star_undirected")
    assert env.action_space.shape == (30,)  # 5 arms x 3 segments x 2
    assert env.max_episode_steps == 125
    assert "unit_xy_direction_to_target" not in env.obs_slices


@pytest.mark.parametrize(
    "override, fragment",
    [
        ("env.num_arms=0", "env.num_arms must be between 1 and 5"),
        ("env.segments_per_arm=0", "env.segments_per_arm must be >= 1"),
        ("env.observation=pixels", "env.observation must be vector, sector or arm_sectors"),
        ("env.physics.solver=pgs", "env.physics.solver must be one of"),
    ],
)
def test_bad_morphology_or_option_raises_one_line(override, fragment):
    with pytest.raises(ValueError, match=fragment) as err:
        base_env("env=brittle_star", override)
    assert "\n" not in str(err.value)


def test_sector_needs_a_target():
    with pytest.raises(ValueError, match="needs a target"):
        base_env("env=brittle_star_undirected", "env.observation=sector")
