"""Unrolled MJX loops (env.unroll_physics): the same results as MJX's and brax's loops, no loops traced."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from brax import envs as brax_envs
from mujoco.mjx._src import solver as mjx_solver

from rlq.envs.humanoid.env import Humanoid
from rlq.envs.humanoid.mjx_unroll import (
    mjx_carry_pipeline_step,
    state_carry_pipeline_step,
    unrolled_linesearch,
    unrolled_pipeline_step,
    unrolled_while_loop_scan,
)

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::UserWarning")]


def cond(val):
    return val[1] < 5.0


def body(val):
    return val[0] * 1.5 + 1.0, val[1] + val[0]


@pytest.mark.parametrize("start", [0.1, 1.0, 3.0, 10.0])
def test_unrolled_loop_matches_mjx_loop_one_value(start):
    """Starts that stop the loop after 1, 2, 3 trips or never (4 trips at most)."""
    init = (jnp.float32(start), jnp.float32(0.0))
    expected = mjx_solver._while_loop_scan(cond, body, init, 4)
    got = unrolled_while_loop_scan(cond, body, init, 4)
    np.testing.assert_array_equal(np.asarray(got), np.asarray(expected))


def test_unrolled_loop_matches_mjx_loop_batched_and_traces_no_loop():
    starts = jnp.array([0.1, 1.0, 3.0, 10.0])

    def run(loop):
        return jax.vmap(lambda x: loop(cond, body, (x, 0.0 * x), 4))

    np.testing.assert_array_equal(
        np.asarray(run(unrolled_while_loop_scan)(starts)), np.asarray(run(mjx_solver._while_loop_scan)(starts))
    )
    assert "scan" in str(jax.make_jaxpr(run(mjx_solver._while_loop_scan))(starts))
    assert "scan" not in str(jax.make_jaxpr(run(unrolled_while_loop_scan))(starts))


def test_linesearch_helper_is_swapped_only_inside_the_context():
    original = mjx_solver._while_loop_scan
    with pytest.raises(RuntimeError), unrolled_linesearch():
        assert mjx_solver._while_loop_scan is unrolled_while_loop_scan
        raise RuntimeError("tracing failed")
    assert mjx_solver._while_loop_scan is original


def test_unrolled_physics_step_matches_brax_in_contact():
    """A small MJX model (brax's hopper, 2 physics steps, 3 linesearch trips) pressed into the floor,
    so the constraint solver and its linesearch run: brax's scanned step and the unrolled one agree."""
    env = brax_envs.get_environment("hopper", backend="mjx", n_frames=2)
    env.sys = env.sys.tree_replace({"opt.ls_iterations": 3, "opt.iterations": 1})
    start = jax.jit(env.pipeline_init)(env.sys.init_q.at[1].set(-0.12), jnp.zeros(env.sys.nv))
    action = jnp.full(env.action_size, 0.3)
    expected = jax.jit(env.pipeline_step)(start, action)
    assert float(jnp.abs(expected._impl.efc_force).max()) > 1.0  # in contact: the solver did work

    unrolled = unrolled_pipeline_step(env)
    with unrolled_linesearch():
        jaxpr = str(jax.make_jaxpr(unrolled)(start, action))
        got = jax.jit(unrolled)(start, action)
    assert "scan" not in jaxpr and "while" not in jaxpr
    # XLA fuses the straight-line program differently: equal up to float32 rounding
    np.testing.assert_allclose(got.qpos, expected.qpos, atol=1e-6)
    np.testing.assert_allclose(got.qvel, expected.qvel, rtol=1e-5, atol=1e-5)


def test_unknown_unroll_physics_raises():
    with pytest.raises(ValueError, match="env.unroll_physics must be one of"):
        Humanoid(unroll_physics="everything")


@pytest.mark.parametrize(
    "unroll, reset_cache, step_loops, reset_loops",
    [
        ("none", True, 2, 1),
        ("linesearch", True, 1, 1),
        ("all", True, 0, 1),
        ("linesearch", False, 1, 0),
        ("all", False, 0, 0),
    ],
)
def test_humanoid_traces_the_loops_asked_for(unroll, reset_cache, step_loops, reset_loops):
    """The step holds brax's physics-step scan with MJX's linesearch scan inside; the reset's
    forward pass holds one linesearch scan. A reset that runs once per env and run (``reset_cache``)
    keeps MJX's loop whatever the step unrolls; one inside every step (auto-reset) follows the step."""
    env = Humanoid(unroll_physics=unroll, reset_cache=reset_cache)
    key = jax.random.PRNGKey(0)
    state = jax.eval_shape(env.reset, key)
    step = jax.make_jaxpr(env.step)(state, jax.ShapeDtypeStruct((17,), jnp.float32))
    assert str(step).count("scan[") == step_loops
    assert str(jax.make_jaxpr(env.reset)(key)).count("scan[") == reset_loops


@functools.cache
def moving_hopper_in_contact():
    """brax's hopper (3 physics steps per control step, 3 linesearch trips) pressed into the floor,
    moving and warm-started after two steps; the action to take next and brax's step for it."""
    env = brax_envs.get_environment("hopper", backend="mjx", n_frames=3)
    env.sys = env.sys.tree_replace({"opt.ls_iterations": 3, "opt.iterations": 1})
    start = jax.jit(env.pipeline_init)(env.sys.init_q.at[1].set(-0.12), jnp.zeros(env.sys.nv))
    brax_step = jax.jit(env.pipeline_step)
    start = brax_step(brax_step(start, jnp.full(env.action_size, -0.5)), jnp.full(env.action_size, 0.8))
    action = jnp.full(env.action_size, 0.3)
    expected = brax_step(start, action)
    assert float(jnp.abs(expected._impl.efc_force).max()) > 1.0  # in contact: the solver did work
    return env, start, action, expected


def test_state_carry_step_matches_brax_in_contact():
    """The loop that carries only the integration state gives brax's step: 3 physics steps in
    contact, from a state that is already moving and warm-started."""
    env, start, action, expected = moving_hopper_in_contact()

    step = state_carry_pipeline_step(env)
    got = jax.jit(step)(start, action)
    assert str(jax.make_jaxpr(step)(start, action)).count("scan[") == 1 + 2  # the carry loop; 2 linesearches
    for name in ("qpos", "qvel", "qacc", "qacc_warmstart", "time", "xpos", "cvel", "qfrc_constraint"):
        assert_close_at_float32_scale(getattr(got, name), getattr(expected, name), name)
    assert_close_at_float32_scale(got._impl.efc_force, expected._impl.efc_force, "efc_force")


def assert_close_at_float32_scale(got, expected, name: str) -> None:
    """Equal up to float32 rounding of sums over the vector's own magnitude: the two loops add the
    same terms in another order, so a small entry that is the difference of large ones (a constraint
    force of 1.26 out of terms near 900) carries their rounding (seen: 9e-5)."""
    scale = max(1.0, float(np.abs(np.asarray(expected)).max()))
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5 * scale, err_msg=name)


def test_mjx_carry_step_is_brax_step_exactly():
    """The loop of bare MJX steps, brax's fields built once after it: every leaf of brax's state
    (MJX data, q, qd, x, xd, contacts) equals brax's step bit for bit, 3 physics steps in contact."""
    env, start, action, expected = moving_hopper_in_contact()

    step = mjx_carry_pipeline_step(env)
    got = jax.jit(step)(start, action)
    assert str(jax.make_jaxpr(step)(start, action)).count("scan[") == 1 + 1  # the loop; its linesearch
    expected_leaves, expected_tree = jax.tree_util.tree_flatten(expected)
    got_leaves, got_tree = jax.tree_util.tree_flatten(got)
    assert got_tree == expected_tree
    for want, have in zip(expected_leaves, got_leaves, strict=True):
        np.testing.assert_array_equal(np.asarray(have), np.asarray(want))


def test_humanoid_steps_with_brax_own_loop_unless_asked():
    assert Humanoid().brax_env.pipeline_step.__func__.__qualname__ == "PipelineEnv.pipeline_step"
    env = Humanoid(substep_carry="mjx")
    assert env.brax_env.pipeline_step.__qualname__.startswith("mjx_carry_pipeline_step")


def test_bad_substep_carry_raises():
    with pytest.raises(ValueError, match="env.substep_carry must be one of"):
        Humanoid(substep_carry="everything")
    with pytest.raises(ValueError, match="needs the physics-step loop"):
        Humanoid(substep_carry="state", unroll_physics="all")


def test_humanoid_state_carry_traces_the_last_physics_step_after_the_loop():
    """The carry loop (with its linesearch scan inside) and the last step's own linesearch scan."""
    env = Humanoid(substep_carry="state")
    state = jax.eval_shape(env.reset, jax.random.PRNGKey(0))
    step = jax.make_jaxpr(env.step)(state, jax.ShapeDtypeStruct((17,), jnp.float32))
    assert str(step).count("scan[") == 3
