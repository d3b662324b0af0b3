"""The humanoid on MuJoCo Warp (env.mjx_impl=warp) through rlq's wrappers, with domain randomisation.

Warp also runs its kernels on the CPU, so this checks the integration (data template, contact
buffer, auto-reset merging) without a GPU. The first run compiles Warp's kernels (~1 min on CPU).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.envs.humanoid.env import Humanoid
from rlq.lib.rollout import evaluate
from rlq.run.programs.env_stack import make_env
from tests.helpers import compose_config

pytest.importorskip("warp")
pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::UserWarning")]


@pytest.fixture(scope="module")
def env():
    return make_env(
        compose_config(
            "env=humanoid",
            "env.mjx_impl=warp",
            "env.warp_contacts=256",
            "env.randomize={friction:[0.6,1.4],gain_delta:[-0.2,0.2]}",
        )
    )


@pytest.fixture(scope="module")
def first(env):
    return jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 2))


@pytest.fixture(scope="module")
def step(env):
    return jax.jit(jax.vmap(env.step))


def test_warp_envs_step_healthy_with_their_own_models(env, first, step):
    assert env.unwrapped.mjx_impl == "warp"
    friction = np.asarray(first.inner["model"]["geom_friction"][:, 0, 0])
    assert friction[0] != friction[1] and np.all((friction >= 0.6) & (friction <= 1.4))
    state = first
    for k in jax.random.split(jax.random.PRNGKey(1), 3):
        state = step(state, jax.random.uniform(k, (2, 17), minval=-1, maxval=1))
    assert bool(jnp.all(jnp.isfinite(state.obs))) and not bool(state.done.any())
    assert np.all(np.asarray(state.reward) > 3.0)  # healthy 5, small forward/control terms
    assert not np.allclose(state.obs, first.obs)


def test_warp_fall_terminates_and_restarts_from_first_state(first, step):
    brax_state = first.inner["brax"]
    ps = brax_state.pipeline_state
    ps = ps.replace(qpos=ps.qpos.at[:, 2].set(0.5), q=ps.q.at[:, 2].set(0.5))
    fallen = first.replace(inner={**first.inner, "brax": brax_state.replace(pipeline_state=ps)})
    state = step(fallen, jnp.zeros((2, 17)))
    assert bool(state.terminated.all())
    np.testing.assert_array_equal(state.obs, first.obs)


def test_unknown_mjx_impl_raises():
    with pytest.raises(ValueError, match="env.mjx_impl must be one of"):
        Humanoid(mjx_impl="bullet")


def test_warp_evaluates_under_a_vmap_over_seeds(env):
    """The run's evaluation program vmaps rlq's evaluate (a while_loop whose stopping test then
    differs per seed, which batches its whole carry) over seeds: Warp's batch-shared buffers must
    still reach each step unbatched (rlq.envs.mujoco.impl.with_template_buffers)."""
    policy = lambda obs, key: jnp.zeros(env.action_space.shape)  # noqa: E731
    keys = jax.random.split(jax.random.PRNGKey(2), 2)
    record = jax.jit(jax.vmap(lambda k: evaluate(env, policy, k, 2, max_steps=3)))(keys)
    assert record["finished"].shape == (2, 2) and not bool(record["finished"].any())  # 3 steps: still standing
