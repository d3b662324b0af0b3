"""`env/physics=fast` is docs/brittle_star.md's five overrides of the validated fast brittle star physics, for
both brittle star envs; the default group option is biorobot's physics. Config only: nothing compiles."""

import pytest
from omegaconf import OmegaConf

from rlq.cli.checked import check_overrides
from rlq.config.compose import WITHOUT_TUNED
from rlq.errors import ConfigError
from rlq.tools.evaluate import eval_env_config
from tests.helpers import compose_config

FIVE = [
    "env.physics.wall_contacts=false",
    "env.physics.joint_limits=false",
    "env.physics.ls_iterations=3",
    "env.time_scale=2.5",
    "env.physics_steps_per_control_step=8",
]
BIOROBOT = {
    "physics_steps_per_control_step": 10,
    "time_scale": 2.0,
    "physics": {
        "wall_contacts": True,
        "sensors": False,
        "condim": 4,
        "solver": "newton",
        "iterations": 1,
        "ls_iterations": 5,
        "cone": "pyramidal",
        "joint_limits": True,
    },
}


def physics_of(env) -> dict:
    keys = ("physics_steps_per_control_step", "time_scale", "physics")
    return {key: OmegaConf.to_container(env[key]) if key == "physics" else env[key] for key in keys}


@pytest.mark.parametrize("env", ["brittle_star", "brittle_star_undirected"])
def test_fast_is_the_five_overrides_on_the_auto_impl_and_default_is_biorobots(env):
    default = compose_config(*WITHOUT_TUNED, f"env={env}").env
    assert physics_of(default) == BIOROBOT and default.mjx_impl == "jax"
    fast = compose_config(*WITHOUT_TUNED, f"env={env}", "env/physics=fast")
    assert fast.env == compose_config(*WITHOUT_TUNED, f"env={env}", *FIVE, "env.mjx_impl=auto").env
    assert fast.env.physics.ls_iterations == 3 and fast.env.time_scale == 2.5
    tweaked = compose_config(*WITHOUT_TUNED, f"env={env}", "env/physics=fast", "env.physics.ls_iterations=4")
    assert tweaked.env.physics.ls_iterations == 4  # a single key still overrides the preset


def test_the_qd_presets_use_the_fast_physics():
    for experiment in ("brittle_star_map_elites", "brittle_star_random_search"):
        env = compose_config(f"experiment={experiment}").env
        assert env == compose_config("env=brittle_star_undirected", *FIVE, "env.mjx_impl=auto").env


def test_an_unknown_physics_option_lists_the_choices():
    with pytest.raises(ConfigError, match="default, fast"):
        check_overrides(["env=brittle_star", "env/physics=turbo"])


def test_eval_on_another_env_composes_its_physics():
    cfg = compose_config("env=cartpole")
    assert physics_of(eval_env_config(cfg, "brittle_star", []).config.env) == BIOROBOT
