"""rlq's CartPole: gymnax's physics, its observation bounds, and how gymnax's module is loaded."""

import json
import subprocess
import sys

import numpy as np

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


def test_cartpole_loads_without_gymnax_s_other_envs_and_a_later_import_of_gymnax_is_whole():
    found = run_python(
        "import json, sys\n"
        "import jax\n"
        "from rlq.envs.cartpole import CartPole\n"
        "env = CartPole()\n"
        "heavy = sorted(m for m in ('seaborn', 'pandas', 'matplotlib', 'scipy') if m in sys.modules)\n"
        "left = sorted(m for m in sys.modules if m.split('.')[0] == 'gymnax')\n"
        "import gymnax\n"
        "theirs, params = gymnax.make('CartPole-v1')\n"
        "key = jax.random.PRNGKey(0)\n"
        "obs, state = theirs.reset_env(key, params)\n"
        "ours = env._env.step_env(key, state, 1, env._params)[0]\n"
        "print(json.dumps({'heavy': heavy, 'left': left, 'same_step': bool((ours == theirs.step_env(key, state, 1,"
        " params)[0]).all())}))\n"
    )
    assert found == {"heavy": [], "left": [], "same_step": True}


def test_once_gymnax_is_imported_its_own_cartpole_module_is_used():
    found = run_python(
        "import json\n"
        "import gymnax.environments.classic_control.cartpole as theirs\n"
        "from rlq.envs.cartpole import CartPole\n"
        "print(json.dumps({'same_class': type(CartPole()._env) is theirs.CartPole}))\n"
    )
    assert found == {"same_class": True}
