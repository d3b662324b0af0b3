"""The position sweeps on components (fused_positions) against the stacked ones (step._solve_positions)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.env import TERRAIN_X, LunarLander
from rlq.envs.lunar.physics import contacts as K
from rlq.envs.lunar.physics import fused_positions as FP
from rlq.envs.lunar.physics import joints as J
from rlq.envs.lunar.physics import step as P
from rlq.envs.lunar.physics.collide import terrain_edges

pytestmark = pytest.mark.slow  # the stacked and component sweeps compile for about 30 s

CASES, ITERATIONS = 64, 10


@pytest.fixture(scope="module")
def cases():
    """Landers moved sideways over their terrain's slopes and lowered until their legs sink 0-8 cm
    into it, legs turned by up to 0.3 rad (past their limits in some cases) and the bodies moved
    apart by up to 2 cm: contacts and joints all need correcting."""
    env = LunarLander()
    keys = jax.random.split(jax.random.PRNGKey(0), 4)
    inner = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(1), CASES)).inner
    v1, v2 = jax.vmap(terrain_edges, (None, 0))(TERRAIN_X, inner.terrain_y)
    c, a = inner.physics.c, inner.physics.a
    a = a.at[:, 1:].add(jax.random.uniform(keys[0], (CASES, 2), minval=-0.3, maxval=0.3))
    c = c + jax.random.uniform(keys[1], (CASES, 3, 2), minval=-0.02, maxval=0.02)
    c = c.at[:, :, 0].add(jax.random.uniform(keys[3], (CASES, 1), minval=-7.0, maxval=7.0))

    def deepest(drop, c, a, v1, v2):
        m, _ = K.leg_manifolds(c.at[:, 1].add(-drop), a, v1, v2)
        return jnp.min(jnp.where(m.valid.any(-1), m.separation, jnp.inf))

    drops = jnp.linspace(8.0, 11.0, 3001)
    depth = jax.vmap(jax.vmap(deepest, (0, None, None, None, None)), (None, 0, 0, 0, 0))(drops, c, a, v1, v2)
    target = jax.random.uniform(keys[2], (CASES, 1), minval=-0.08, maxval=0.0)
    drop = drops[jnp.argmin(jnp.abs(depth - target), axis=1)]
    c = c.at[:, :, 1].add(-drop[:, None])
    m, _ = jax.vmap(K.leg_manifolds)(c, a, v1, v2)
    ja = jax.vmap(J.joint_angles)(a)
    limit = jnp.where(ja <= J.LOWER, J.AT_LOWER, jnp.where(ja >= J.UPPER, J.AT_UPPER, J.INACTIVE)).astype(jnp.int32)
    return c, a, m, limit


@pytest.mark.parametrize("contacts", [True, False])
def test_component_positions_match_the_stacked_sweeps(cases, contacts):
    c, a, m, limit = cases
    separation = np.where(np.asarray(m.valid).any(-1), np.asarray(m.separation), np.inf).min(axis=(1, 2))
    assert (separation < -3.0 * C.LINEAR_SLOP).sum() >= CASES // 2  # the contacts need correcting
    assert (np.asarray(limit) != J.INACTIVE).any()  # and some legs are past their limits
    normal_x = np.abs(np.asarray(m.normal)[..., 0])[np.asarray(m.valid).any(-1)]
    assert (normal_x > 0.1).sum() >= 8  # on slopes, not only the flat helipad

    def solve(fn):
        return jax.jit(jax.vmap(lambda c, a, m, limit: fn(c, a, m, limit, ITERATIONS, contacts)))(c, a, m, limit)

    c_s, a_s, solved_s = jax.device_get(solve(P._solve_positions))
    c_f, a_f, solved_f = jax.device_get(solve(FP.position_sweeps))
    assert np.abs(c_s - np.asarray(c)).max() > 1e-2  # the sweeps moved the bodies
    np.testing.assert_array_equal(solved_s, solved_f)
    assert solved_s.sum() > 0
    if contacts:
        assert solved_s.sum() < CASES  # some cases stop early, others use all the sweeps
    np.testing.assert_allclose(c_f, c_s, atol=2e-5)
    np.testing.assert_allclose(a_f, a_s, atol=2e-5)
