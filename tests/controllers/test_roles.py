"""Decentralised CPG modulation (rlq/controllers/roles.py): one role per arm -> one modulation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from omegaconf import OmegaConf

from rlq.controllers import controller_settings
from rlq.controllers import cpg as cpg_controller
from rlq.controllers import oscillators as cpg
from rlq.controllers.roles import IDLE, LEADER, LEFT, RIGHT, leading_arm_roles, role_modulation
from rlq.envs import env_settings
from rlq.envs.brittle_star.env import arm_bearing_bins, sector_index
from rlq.lib.spaces import AgentsDiscrete
from tests.controllers.test_cpg import RecordingEnv, cpg_preset, rollout

#: a distinct J per oscillator, so a value taken from the wrong oscillator shows
J = jnp.linspace(0.1, 0.55, 10)
#: the identity table's pattern, decentralised: an arm's own bearing bin (of 5) -> its role
IDENTITY_ROLES = np.array([LEADER, LEFT, LEFT, RIGHT, RIGHT])


def assert_same(got: cpg.Modulation, expected: cpg.Modulation) -> None:
    for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(expected), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-7)


def test_leading_arm_roles():
    np.testing.assert_array_equal(leading_arm_roles(0, 5), [LEADER, RIGHT, RIGHT, LEFT, LEFT])
    np.testing.assert_array_equal(leading_arm_roles(3, 5), [RIGHT, LEFT, LEFT, LEADER, RIGHT])


@pytest.mark.parametrize("lead", range(5))
def test_t0s_roles_give_t0s_leading_arm_modulation(lead):
    got = role_modulation(jnp.asarray(leading_arm_roles(lead, 5)), J, 2.0)
    assert_same(got, cpg.leading_arm_modulation(lead, J, 2.0))


def test_roles_by_hand_on_three_arms():
    """Arm 0 rows left, arm 1 rows right, arm 2 idles: R on arms 0 and 1, no lift, IP/OOP biases
    pi/2 (left) and mirrored (right), and the left-right neighbours 0, 1 in anti-phase."""
    amplitude = jnp.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    mod = role_modulation(jnp.array([LEFT, RIGHT, IDLE]), amplitude, 1.5)
    np.testing.assert_allclose(mod.R, [0.1, 0.2, 0.3, 0.4, 0.0, 0.0])
    np.testing.assert_allclose(mod.X, 0.0)
    np.testing.assert_allclose(mod.omega, 1.5)
    expected = np.zeros((6, 6))
    expected[0, 1], expected[1, 0] = np.pi / 2, -np.pi / 2  # left rower: rho[IP_0, OOP_0] = pi/2
    expected[3, 2], expected[2, 3] = np.pi / 2, -np.pi / 2  # right rower: rho[OOP_1, IP_1] = pi/2
    expected[0, 2], expected[2, 0] = np.pi, -np.pi  # (IP_left, IP_right, pi)
    np.testing.assert_allclose(mod.rho, expected, atol=1e-7)


def test_two_leaders_lift_and_bias_their_neighbours():
    amplitude = jnp.full(6, 0.2)
    mod = role_modulation(jnp.array([LEADER, LEADER, IDLE]), amplitude, 1.0)
    np.testing.assert_allclose(mod.X, [0, 0.2, 0, 0.2, 0, 0])
    np.testing.assert_allclose(mod.R, 0.0)
    # every edge touches a leader: (IP_a, IP_b, pi/4) and (OOP_b, OOP_a, pi/4) for (0, 1), (1, 2), (2, 0)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        assert float(mod.rho[2 * a, 2 * b]) == pytest.approx(np.pi / 4)
        assert float(mod.rho[2 * b + 1, 2 * a + 1]) == pytest.approx(np.pi / 4)


@pytest.mark.parametrize("yaw", [-3.0, 0.0, 1.3, 3.1])
@pytest.mark.parametrize("offset", [-0.5, 0.0, 0.6])
def test_the_identity_pattern_per_arm_is_t0s_identity_table(yaw, offset):
    """Each arm's own bearing bin through the decentralised identity table gives the roles T0's
    identity table picks from the sector observation (the arm facing the target leads)."""
    for arm in range(5):
        angle = yaw + 2 * np.pi * arm / 5 + offset
        direction = jnp.array([np.cos(angle), np.sin(angle)])
        bins = arm_bearing_bins(direction, jnp.asarray(yaw), 5, 5)
        lead = int(sector_index(direction, jnp.asarray(yaw)))
        np.testing.assert_array_equal(IDENTITY_ROLES[np.asarray(bins)], leading_arm_roles(lead, 5))


def wrapped(**overrides):
    cfg = OmegaConf.merge(cpg_preset(), overrides)
    return cpg_controller.wrap(
        RecordingEnv(), controller_settings(cfg), env_settings({"name": "brittle_star", "num_arms": 5})
    )


def test_decentralised_controller_takes_a_role_per_arm():
    env = wrapped(mode="decentralised")
    assert env.action_space == AgentsDiscrete(4, 5)
    roles = jnp.array([RIGHT, LEADER, IDLE, LEFT, RIGHT])
    state = rollout(env, [roles] * 3)[-1]
    assert_same(state.inner.modulation, role_modulation(roles, env._leading_amplitude, np.pi))


def test_t0s_roles_move_the_joints_as_the_leading_arm_mode():
    leading = rollout(wrapped(mode="leading_arm"), [jnp.array(2)] * 20)[-1]
    as_roles = rollout(wrapped(mode="decentralised"), [jnp.asarray(leading_arm_roles(2, 5))] * 20)[-1]
    assert float(jnp.max(jnp.abs(leading.obs))) > 0.1  # the joints move
    np.testing.assert_allclose(as_roles.obs, leading.obs, atol=1e-6)


def test_check_refuses_fewer_than_three_arms():
    cfg = OmegaConf.merge(cpg_preset(), {"mode": "decentralised"})
    problem = cpg_controller.check(controller_settings(cfg), env_settings({"name": "brittle_star", "num_arms": 2}))
    assert problem == "controller.mode=decentralised needs a ring of at least 3 arms, got env.num_arms=2"
    assert cpg_controller.check(controller_settings(cfg), env_settings({"name": "brittle_star", "num_arms": 3})) is None
