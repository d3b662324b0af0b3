"""Gym's Humanoid-v1 physics on brax's humanoid (rlq/envs/humanoid/gym_physics.py): every geom colliding, RK4,
more solver iterations; the model edits directly, and one env stepped with all three (slow: MJX on a CPU)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from brax.io import mjcf as brax_mjcf
from mujoco import mjx

from rlq.declared.envs.humanoid import CONTACTS
from rlq.envs.humanoid import gym_physics
from rlq.run.programs.env_stack import make_env
from tests.helpers import compose_config

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


@pytest.fixture(scope="module")
def brax_model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(gym_physics.BRAX_HUMANOID_XML))


def geom(model: mujoco.MjModel, name: str) -> int:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)


def test_brax_s_model_lets_only_the_feet_touch_the_floor(brax_model):
    """What env.contacts=feet (the default) keeps: every geom but the feet and the floor has contype 0."""
    touching = {
        mujoco.mj_id2name(brax_model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in np.flatnonzero(brax_model.geom_contype)
    }
    assert touching == {"right_foot", "left_foot"}
    assert brax_model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER


def test_all_contacts_make_every_geom_collide_as_in_gym_s_model(brax_model):
    model = gym_physics.gym_model("all", "euler")
    floor = geom(model, "floor")
    limbs = [g for g in range(model.ngeom) if g != floor]
    assert len(limbs) == model.ngeom - 1 > 15
    assert np.all(model.geom_contype[limbs] == 1) and np.all(model.geom_conaffinity[limbs] == 1)
    assert np.all(model.geom_condim[limbs] == 1) and np.allclose(model.geom_margin[limbs], 0.001)
    assert (model.geom_condim[floor], model.geom_conaffinity[floor]) == (3, 1)  # foot-floor contacts keep friction
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
    assert model.ngeom == brax_model.ngeom and np.array_equal(model.body_mass, brax_model.body_mass)
    assert gym_physics.gym_model("feet", "rk4").opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert np.array_equal(gym_physics.gym_model("feet", "rk4").geom_contype, brax_model.geom_contype)
    # what MJX-JAX checks every physics step: the feet's two contacts with the floor, or every pair that may touch
    assert mjx.make_data(brax_model)._impl.contact.dist.shape == (2,)
    assert mjx.make_data(model)._impl.contact.dist.shape[0] > 100


def test_a_hand_on_the_floor_touches_it_only_with_all_contacts():
    """The pose decides: the humanoid lowered until its right hand is 1 cm into the floor (MuJoCo on the CPU)."""
    counts = {}
    for contacts in CONTACTS:
        model = gym_physics.gym_model(contacts, "euler")
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        hand = geom(model, "right_hand")
        data.qpos[2] -= data.geom_xpos[hand][2] - model.geom_size[hand][0] + 0.01
        mujoco.mj_forward(model, data)
        counts[contacts] = sum(hand in (c.geom1, c.geom2) for c in data.contact[: data.ncon])
    assert counts == {"feet": 0, "all": 1}


def test_rk4_and_solver_iterations_keep_brax_s_other_mjx_settings(brax_model):
    sys = brax_mjcf.load_model(brax_model).tree_replace(
        {
            "opt.solver": mujoco.mjtSolver.mjSOL_NEWTON,
            "opt.disableflags": mujoco.mjtDisableBit.mjDSBL_EULERDAMP,
            "opt.iterations": 1,
            "opt.ls_iterations": 4,
        }
    )
    rebuilt = gym_physics.gym_system(sys, "feet", "rk4", 10)
    assert rebuilt.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert (rebuilt.opt.solver, rebuilt.opt.disableflags) == (sys.opt.solver, sys.opt.disableflags)
    assert (rebuilt.opt.iterations, rebuilt.opt.ls_iterations) == (10, 4)
    assert gym_physics.gym_system(sys, "all", "euler", None).opt.iterations == 1
    assert gym_physics.is_brax_physics("feet", "euler", None)
    assert not gym_physics.is_brax_physics("feet", "euler", 1)


@pytest.mark.parametrize(
    "contacts, integrator, iterations, key",
    [
        ("hands", "euler", None, "env.contacts"),
        ("feet", "rk45", None, "env.integrator"),
        ("feet", "euler", 0, "env.solver_iterations"),
    ],
)
def test_values_the_humanoid_cannot_take_name_their_key(contacts, integrator, iterations, key):
    """Checked as the config's declaration checks them (rlq.lib.settings.problems), before brax builds anything."""
    from rlq.envs.humanoid.env import Humanoid

    with pytest.raises(ValueError, match=key):
        Humanoid(contacts=contacts, integrator=integrator, solver_iterations=iterations)


def test_gym_physics_needs_mjx_s_jax_implementation():
    from rlq.envs.humanoid.env import Humanoid

    with pytest.raises((ValueError, ImportError), match="mjx_impl"):
        Humanoid(mjx_impl="warp", integrator="rk4")


@pytest.mark.slow
def test_the_humanoid_on_gym_s_physics_lands_and_stands_on_its_feet():
    """env.contacts=all env.integrator=rk4 env.solver_iterations=4: the env steps that physics (the model it
    runs is the rebuilt one), the humanoid drops onto its feet and stays healthy for 20 control steps with zero
    torques, and the feet carry its weight."""
    overrides = ("env=humanoid", "env.contacts=all", "env.integrator=rk4", "env.solver_iterations=4")
    env = make_env(compose_config(*overrides))
    sys = env.unwrapped.brax_env.sys
    assert sys.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4 and sys.opt.iterations == 4
    assert int(np.count_nonzero(sys.mj_model.geom_contype)) == sys.mj_model.ngeom - 1
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 2))
    step = jax.jit(jax.vmap(env.step))
    for _ in range(20):
        state = step(state, jnp.zeros((2, 17)))
    assert not bool(state.done.any()) and bool(jnp.all(jnp.isfinite(state.obs)))
    data = state.inner["brax"].pipeline_state
    feet = env.unwrapped._feet
    heights = np.asarray(data.geom_xpos[:, feet.geoms, 2]) - feet.radii - feet.floor_z
    assert np.all(np.abs(heights) < 0.01), heights
