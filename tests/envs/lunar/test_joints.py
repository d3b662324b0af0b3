"""The leg joints' velocity solve (b2RevoluteJoint::SolveVelocityConstraints) on what it must
achieve: the anchors' relative velocity zeroed, the limit held while it pushes, momentum kept.
Both forms of it: on stacked arrays (the CPU's) and on components (a GPU's, fused_sweeps)."""

import jax.numpy as jnp
import numpy as np
import pytest

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.physics import fused_sweeps, joints
from rlq.envs.lunar.physics.body import INV_MASS, cross_vs

DT = 1.0 / 50.0
#: per joint, an angle inside its limits and one just past its lower limit
INSIDE = np.array([0.65, -0.65])
PAST_LOWER = np.array([0.35, -0.95])


def on_components(j: int, v, w, impulse, motor, const, dt: float):
    """``fused_sweeps.joint_velocity`` with the stacked form's arguments and results."""
    hull, legs = (v[0, 0], v[0, 1], w[0]), (v[1:, 0], v[1:, 1], w[1:])
    parts = tuple((impulse[i, 0], impulse[i, 1], impulse[i, 2]) for i in range(2))
    sweep_const = fused_sweeps.sweep_joint(const)
    hull, legs, parts, motors = fused_sweeps.joint_velocity(j, hull, legs, parts, tuple(motor), sweep_const, dt)
    v = jnp.concatenate([jnp.stack(hull[:2])[None], jnp.stack(legs[:2], axis=-1)])
    w = jnp.concatenate([hull[2][None], legs[2]])
    return v, w, jnp.stack([jnp.stack(p) for p in parts]), jnp.stack(motors)


FORMS = {"stacked": joints.solve_velocity, "components": on_components}


@pytest.fixture(params=list(FORMS))
def solve(request):
    return FORMS[request.param]


def sweep(solve, joint_angles: np.ndarray, w: np.ndarray, j: int):
    """One velocity sweep of joint ``j`` from a cold start (no warm-start impulses)."""
    a = jnp.asarray(np.concatenate([[0.1], 0.1 + joint_angles + np.asarray(joints.REFERENCE)]), jnp.float32)
    v = jnp.asarray([[0.3, -1.2], [1.0, 0.5], [-0.7, 0.2]], jnp.float32)
    w = jnp.asarray(w, jnp.float32)
    impulse, motor = jnp.zeros((2, 3), jnp.float32), jnp.zeros(2, jnp.float32)
    v, w, impulse, motor, limit, consts = joints.init(a, v, w, impulse, motor, jnp.zeros(2, jnp.int32), False)
    before = (v, w)
    v, w, impulse, motor = solve(j, v, w, impulse, motor, consts[j], DT)
    return before, (v, w), impulse, motor, limit, consts[j]


def anchor_velocity(v, w, const, j: int) -> np.ndarray:
    ra, rb = const[0], const[1]
    return np.asarray(v[j + 1] + cross_vs(w[j + 1], rb) - v[0] - cross_vs(w[0], ra))


def momentum(v) -> np.ndarray:
    return np.asarray(jnp.sum(v / INV_MASS[:, None], axis=0))


@pytest.mark.parametrize("j", [0, 1])
def test_a_free_joint_pins_its_anchors_and_keeps_momentum(solve, j):
    before, (v, w), _, motor, limit, const = sweep(solve, INSIDE, np.array([0.0, 1.5, -1.5]), j)
    assert int(limit[j]) == joints.INACTIVE
    assert np.abs(anchor_velocity(*before, const, j)).max() > 0.5  # there was something to solve
    np.testing.assert_allclose(anchor_velocity(v, w, const, j), 0.0, atol=1e-4)
    np.testing.assert_allclose(momentum(v), momentum(before[0]), rtol=1e-5, atol=1e-4)
    assert 0.0 < abs(float(motor[j])) <= DT * C.LEG_SPRING_TORQUE  # the motor pushed, within its torque limit


def test_a_joint_at_its_limit_holds_it_or_lets_go_as_box2d_does(solve):
    """At the lower limit the 3 × 3 solve either holds the limit (a pushing impulse, the legs'
    relative spin stopped) or, where that impulse would pull, drops it and solves the point
    constraint alone (the leg turns away from the limit). Both happen on these cases."""
    held = released = 0
    for j in (0, 1):
        for spin in (-2.0, 3.0):
            before, (v, w), impulse, _, limit, const = sweep(solve, PAST_LOWER, np.array([0.0, spin, spin]), j)
            assert int(limit[j]) == joints.AT_LOWER
            np.testing.assert_allclose(anchor_velocity(v, w, const, j), 0.0, atol=1e-4)
            np.testing.assert_allclose(momentum(v), momentum(before[0]), rtol=1e-5, atol=1e-4)
            relative_spin = float(w[j + 1] - w[0])
            if float(impulse[j, 2]) > 0:
                held += 1
                assert relative_spin == pytest.approx(0.0, abs=1e-4)
            else:
                released += 1
                assert float(impulse[j, 2]) == 0.0
                assert relative_spin > 0.5
    assert held and released


def test_only_joint_j_and_its_bodies_change(solve):
    before, (v, w), impulse, motor, _, _ = sweep(solve, INSIDE, np.array([0.0, 1.5, -1.5]), 0)
    other = 2  # leg 1's body
    np.testing.assert_array_equal(np.asarray(v[other]), np.asarray(before[0][other]))
    assert float(w[other]) == float(before[1][other])
    np.testing.assert_array_equal(np.asarray(impulse[1]), 0.0)
    assert float(motor[1]) == 0.0
