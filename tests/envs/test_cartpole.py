"""rlq's CartPole: gymnax's physics, its observation bounds, how gymnax's module is loaded, and its keys."""

import json
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.envs.cartpole import CartPole, observation_box


def test_the_observation_box_is_gymnax_s_own():
    env = CartPole()
    space = env._env.observation_space(env._params)
    box = observation_box(env._params)
    np.testing.assert_array_equal(np.asarray(box.high, np.float32), np.asarray(space.high))
    np.testing.assert_array_equal(np.asarray(box.low, np.float32), np.asarray(space.low))


def run_python(code: str) -> dict:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # cold subprocesses
def test_cartpole_loads_without_gymnax_s_other_envs_and_gymnax_is_whole_when_asked():
    found = run_python(
        "import json, pickle, sys\n"
        "import jax\n"
        "from rlq.envs.cartpole import CartPole\n"
        "env = CartPole()\n"
        "heavy = sorted(m for m in ('seaborn', 'pandas', 'matplotlib', 'scipy') if m in sys.modules)\n"
        "state_type = type(env.reset(jax.random.PRNGKey(0)).inner)\n"
        "pickled = pickle.loads(pickle.dumps(state_type)) is state_type\n"
        "still_light = 'seaborn' not in sys.modules\n"
        "import gymnax\n"
        "import gymnax.environments.classic_control.cartpole\n"
        "from gymnax.environments.classic_control import Acrobot\n"
        "theirs, params = gymnax.make('CartPole-v1')\n"
        "print(json.dumps({'heavy': heavy, 'pickled': pickled, 'still_light': still_light,\n"
        "    'same_class': type(theirs) is type(env._env) is gymnax.environments.classic_control.cartpole.CartPole,\n"
        "    'catch': gymnax.environments.Catch.__name__, 'acrobot': Acrobot.__name__}))\n"
    )
    assert found == {
        "heavy": [],
        "pickled": True,
        "still_light": True,
        "same_class": True,
        "catch": "Catch",
        "acrobot": "Acrobot",
    }


@pytest.mark.slow  # a cold subprocess
def test_once_gymnax_is_imported_its_own_cartpole_module_is_used():
    found = run_python(
        "import json\n"
        "import gymnax.environments.classic_control.cartpole as theirs\n"
        "from rlq.envs.cartpole import CartPole\n"
        "print(json.dumps({'same_class': type(CartPole()._env) is theirs.CartPole}))\n"
    )
    assert found == {"same_class": True}


def test_steps_keep_the_key_and_auto_reset_draws_each_new_episode_from_its_key():
    env = CartPole()
    state = env.reset(jax.random.PRNGKey(0))
    nxt = env.step(state, jnp.int32(1))
    np.testing.assert_array_equal(np.asarray(nxt.key), np.asarray(state.key))  # deterministic dynamics

    keys = jax.random.split(jax.random.PRNGKey(1), 64)
    stepped, fresh = jax.vmap(env.step_and_reset, in_axes=(None, None, 0))(state, jnp.int32(1), keys)
    np.testing.assert_array_equal(np.asarray(stepped.obs), np.broadcast_to(np.asarray(nxt.obs), (64, 4)))
    starts = np.asarray(fresh.obs)
    assert np.all(np.abs(starts) <= 0.05) and len(np.unique(starts[:, 0])) == 64  # gymnax's U(-0.05, 0.05)
    assert np.all(np.asarray(fresh.inner.time) == 0)
