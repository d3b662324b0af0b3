"""Vectorised MJX tree computations (rlq.envs.humanoid.mjx_vectorized) on every joint type: MJX's motion DOFs
bit for bit, its body velocities to float rounding."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx
from mujoco.mjx._src import smooth as mjx_smooth

from rlq.envs.humanoid.mjx_vectorized import dof_tables, vectorized_cdof, vectorized_com_vel, velocity_tables

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::UserWarning")]

#: a free body carrying a ball-jointed, a hinged and a sliding child, plus a body with two hinges
ALL_JOINTS = """
<mujoco>
  <worldbody>
    <body name="torso" pos="0 0 1">
      <freejoint/>
      <geom type="capsule" size="0.1" fromto="0 0 0 0.3 0 0"/>
      <body name="ball" pos="0.3 0 0"><joint type="ball"/><geom type="sphere" size="0.05" pos="0.1 0 0"/></body>
      <body name="hinge" pos="0 0.2 0" euler="0 30 0">
        <joint type="hinge" axis="0 1 0"/><geom type="sphere" size="0.05" pos="0 0.1 0"/>
        <body name="slide" pos="0 0.2 0"><joint type="slide" axis="1 1 0"/><geom type="box" size="0.05 0.05 0.05"/></body>
      </body>
      <body name="two_hinges" pos="0 -0.2 0">
        <joint type="hinge" axis="1 0 0"/><joint type="hinge" axis="0 0 1"/><geom type="sphere" size="0.05" pos="0 -0.1 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def model():
    return mjx.put_model(mujoco.MjModel.from_xml_string(ALL_JOINTS))


def test_dof_tables_sort_dofs_by_what_moves_them(model):
    t = dof_tables(model)
    # free (3 translations, 3 rotations), ball (3), hinge, slide, two hinges
    np.testing.assert_array_equal(t["rotates"][:, 0], [0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 0, 1, 1])
    np.testing.assert_array_equal(t["slides"][:, 0], [0] * 10 + [1, 0, 0])
    np.testing.assert_array_equal(t["unit"][:3], np.eye(3))
    assert not t["unit"][3:].any()


def forward_both_ways(model, swap, seed: int):
    """MJX's forward pass on a random moving state of ``model``, as MJX traces it and under ``swap``
    (a new function object each time, so jit traces it again); also both jaxprs."""
    key_q, key_v = jax.random.split(jax.random.PRNGKey(seed))
    data = mjx.make_data(model)
    qpos = data.qpos + 0.3 * jax.random.normal(key_q, data.qpos.shape)
    data = data.replace(qpos=qpos, qvel=jax.random.normal(key_v, data.qvel.shape))
    expected = jax.jit(lambda d: mjx.forward(model, d))(data)
    plain = str(jax.make_jaxpr(lambda d: mjx.forward(model, d))(data))
    with swap():
        got = jax.jit(lambda d: mjx.forward(model, d))(data)
        swapped = str(jax.make_jaxpr(lambda d: mjx.forward(model, d))(data))
    return expected, got, plain, swapped


def test_cdof_is_mjx_bit_for_bit(model):
    expected, got, plain, swapped = forward_both_ways(model, vectorized_cdof, seed=0)
    assert swapped != plain
    assert float(jnp.abs(expected.cdof).max()) > 0.1
    for name in ("cdof", "cvel"):
        np.testing.assert_array_equal(np.asarray(getattr(got, name)), np.asarray(getattr(expected, name)), err_msg=name)
    # downstream, XLA fuses the two programs differently: equal up to float32 rounding
    for name in ("qacc", "qfrc_bias"):
        np.testing.assert_allclose(getattr(got, name), getattr(expected, name), rtol=1e-4, atol=1e-5, err_msg=name)


def test_mjx_scan_module_is_restored(model):
    original = mjx_smooth.scan
    with pytest.raises(RuntimeError), vectorized_cdof():
        assert mjx_smooth.scan is not original
        raise RuntimeError("tracing failed")
    assert mjx_smooth.scan is original


def test_velocity_tables_follow_the_tree(model):
    t = velocity_tables(model)
    # bodies: world, torso (free: dofs 0-5), ball (6-8), hinge (9), slide (10), two_hinges (11, 12)
    np.testing.assert_array_equal(t["body_sum"][0], np.zeros(13))
    np.testing.assert_array_equal(t["body_sum"][4], [1] * 6 + [0, 0, 0, 1, 1, 0, 0])  # slide under hinge
    np.testing.assert_array_equal(t["dof_sum"][3], [1, 1, 1, 0, 0, 0] + [0] * 7)  # free rotation after translation
    np.testing.assert_array_equal(t["dof_sum"][12], [1] * 6 + [0] * 5 + [1, 0])  # second hinge after the first
    np.testing.assert_array_equal(t["still"][:, 0], [1, 1, 1] + [0] * 10)


def test_com_vel_is_mjx_to_float_rounding(model):
    expected, got, plain, swapped = forward_both_ways(model, vectorized_com_vel, seed=1)
    assert swapped != plain
    assert float(jnp.abs(expected.cdof_dot).max()) > 0.5
    # MJX sums level by level, rlq with one matrix product: the same sums in another order
    for name in ("cvel", "cdof_dot"):
        np.testing.assert_allclose(getattr(got, name), getattr(expected, name), rtol=1e-5, atol=1e-6, err_msg=name)
    np.testing.assert_allclose(got.qacc, expected.qacc, rtol=1e-4, atol=1e-4)
