"""The decentralised observation (``env.observation=arm_sectors``): each arm's bearing to the target."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("biorobot")

from rlq.envs.brittle_star.env import arm_bearing_bins  # noqa: E402
from rlq.envs.brittle_star.model import mjx  # noqa: E402
from rlq.lib.spaces import AgentsDiscrete  # noqa: E402
from tests.envs.brittle_star.test_env import SMALL, base_env  # noqa: E402

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::UserWarning")]


def bins_at(angle_deg: float, yaw_deg: float, bins: int) -> list[int]:
    angle = np.radians(angle_deg)
    direction = jnp.array([np.cos(angle), np.sin(angle)])
    return np.asarray(arm_bearing_bins(direction, jnp.asarray(np.radians(yaw_deg)), 5, bins)).tolist()


def test_five_bins_by_hand():
    """Target along arm 0: arm k sees it at -72k deg, i.e. bins 0, 4, 3, 2, 1 (bin b centred on +72b deg)."""
    assert bins_at(0, 0, 5) == [0, 4, 3, 2, 1]
    assert bins_at(144, 0, 5) == [2, 1, 0, 4, 3]  # along arm 2
    assert bins_at(35, 0, 5) == [0, 4, 3, 2, 1]  # bin 0 spans +-36 deg
    assert bins_at(37, 0, 5) == [1, 0, 4, 3, 2]


def test_ten_bins_by_hand():
    """Target at 40 deg in the disk frame: arm k's bearing 40 - 72k deg, in bins of 36 deg centred on
    0, 36, ...: 40 -> 1, -32 -> 9, -104 -> 7, -176 -> 5, -248 (= 112) -> 3."""
    assert bins_at(40, 0, 10) == [1, 9, 7, 5, 3]
    assert bins_at(-150, 170, 10) == [1, 9, 7, 5, 3]  # -150 - 170 = -320 = +40 deg: wrapped


@pytest.fixture(scope="module")
def env():
    return base_env("env=brittle_star", "env.observation=arm_sectors", "env.bearing_bins=10", *SMALL)


def test_spaces(env):
    assert env.observation_space == AgentsDiscrete(10, 5)


def test_observation_of_a_hand_set_pose(env):
    """Disk at (1, 2) turned by 170 deg, target 3 m away at -150 deg in the world: 40 deg in the disk
    frame, so the arms see bins 1, 9, 7, 5, 3 (test_ten_bins_by_hand)."""
    state = env.reset(jax.random.PRNGKey(0))
    inner = state.inner
    yaw = np.radians(170)
    free = env._free_qpos
    qpos = inner.data.qpos.at[free : free + 3].set(jnp.array([1.0, 2.0, 0.11]))
    qpos = qpos.at[free + 3 : free + 7].set(jnp.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]))
    data = jax.jit(mjx.kinematics)(env.mjx_model, inner.data.replace(qpos=qpos))
    world = np.radians(-150)
    target = jnp.array([1.0, 2.0]) + 3.0 * jnp.array([np.cos(world), np.sin(world)])
    obs = env._observe(inner.replace(data=data, target_xy=target))
    assert obs.dtype == jnp.int32
    np.testing.assert_array_equal(obs, [1, 9, 7, 5, 3])


def test_reset_gives_one_bin_per_arm(env):
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    assert state.obs.shape == (5,) and state.obs.dtype == jnp.int32
    assert bool(jnp.all((state.obs >= 0) & (state.obs < 10)))


def test_arm_sectors_need_a_target_and_a_bin():
    with pytest.raises(ValueError, match="env.observation=arm_sectors needs a target"):
        base_env("env=brittle_star_undirected", "env.observation=arm_sectors")
    with pytest.raises(ValueError, match="env.bearing_bins must be >= 1"):
        base_env("env=brittle_star", "env.observation=arm_sectors", "env.bearing_bins=0")
