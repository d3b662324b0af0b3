"""The humanoid's physics patches: off by default, refused on library versions they were not
written for, and the same physics as brax's own over a rollout."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.config.compose import WITHOUT_TUNED
from rlq.envs.humanoid.env import Humanoid
from rlq.envs.humanoid.mjx_patches import active_patches, check_versions
from rlq.errors import ConfigError
from tests.helpers import compose_config

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::UserWarning")]

PRESET_PATCHES = dict(unroll_physics="linesearch", substep_carry="mjx", vectorized_cdof=True, vectorized_com_vel=True)


def test_env_config_turns_no_patch_on_and_the_preset_turns_them_on():
    env_cfg = compose_config("env=humanoid", *WITHOUT_TUNED).env  # the env alone, not the PPO pair's recipe
    preset = compose_config("experiment=humanoid_ppo").env
    keys = ("mjx_impl", "unroll_physics", "substep_carry", "vectorized_cdof", "vectorized_com_vel", "quick_model_load")
    assert active_patches(*(env_cfg[k] for k in keys)) == []
    assert active_patches(*(preset[k] for k in keys)) == [
        "env.unroll_physics=linesearch",
        "env.substep_carry=mjx",
        "env.vectorized_cdof=true",
        "env.vectorized_com_vel=true",
        "env.quick_model_load=true",
    ]


def test_patches_are_refused_on_other_library_versions():
    active = ["env.vectorized_cdof=true"]
    check_versions(active, {"mujoco-mjx": "3.17.0", "brax": "0.14.2"})
    check_versions([], {"mujoco-mjx": "3.18.0", "brax": "0.15.0"})
    with pytest.raises(ConfigError, match=r"env.vectorized_cdof=true .*mujoco-mjx 3.18.0 is installed"):
        check_versions(active, {"mujoco-mjx": "3.18.0", "brax": "0.14.2"})
    with pytest.raises(ConfigError, match="brax 0.13.1 is installed"):
        check_versions(active, {"mujoco-mjx": "3.17.0", "brax": "0.13.1"})


def rollout(env: Humanoid, steps: int = 15):
    """``steps`` control steps of one env under fixed random torques, from the same reset."""
    actions = jax.random.uniform(jax.random.PRNGKey(1), (steps, env.action_space.shape[0]), minval=-1, maxval=1)

    def step(state, action):
        state = env.step(state, action)
        return state, (state.obs, state.inner["brax"].pipeline_state.qpos)

    return jax.jit(lambda key: jax.lax.scan(step, env.reset(key), actions)[1])(jax.random.PRNGKey(0))


def test_patched_physics_follows_brax_own_over_a_rollout():
    plain_obs, plain_qpos = rollout(Humanoid())
    patched_obs, patched_qpos = rollout(Humanoid(**PRESET_PATCHES))
    assert bool(jnp.all(jnp.isfinite(plain_qpos)))
    np.testing.assert_allclose(patched_qpos, plain_qpos, rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(patched_obs, plain_obs, rtol=1e-3, atol=1e-3)
