"""The parametric_segment and parametric_symmetric CPG layouts on biorobot's brittle star (MJX):
build, reset and 2 steps in one jitted program per mode (~20-35 s each on 2 CPU cores, nearly all
of it MJX compilation), on small pruned models."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("biorobot")

from rlq.controllers import oscillators as cpg  # noqa: E402
from rlq.run.programs.env_stack import make_env  # noqa: E402
from tests.helpers import compose_config  # noqa: E402

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::UserWarning")]


def reset_and_two_steps(mode: str, modulate: str, segments: int):
    cfg = compose_config(
        "env=brittle_star_undirected",
        f"env.segments_per_arm={segments}",
        "env.physics.wall_contacts=false",
        "controller=cpg",
        f"controller.mode={mode}",
        f"controller.modulate={modulate}",
        "controller.coupling=arm",
    )
    env = make_env(cfg, autoreset=False)
    space = env.action_space
    low, high = jnp.asarray(space.low), jnp.asarray(space.high)

    def run(key):
        first = env.step(env.reset(key), 0.5 * (low + high))
        return first, env.step(first, high)

    return env, jax.jit(run)(jax.random.PRNGKey(0))


def test_parametric_segment_on_the_brittle_star():
    env, (first, second) = reset_and_two_steps("parametric_segment", "at_reset", segments=2)
    assert env.action_space.shape == (cpg.parametric_segment_size(5, 2),) == (51,)
    inner = second.inner  # the outer wrappers keep their state in extras
    assert inner.cpg.phase.shape == (20,)
    np.testing.assert_allclose(inner.modulation.R, first.inner.modulation.R)  # latched at reset
    assert np.isfinite(np.asarray(second.obs)).all() and np.isfinite(float(second.reward))


def test_parametric_symmetric_on_the_brittle_star():
    env, (first, second) = reset_and_two_steps("parametric_symmetric", "every_step", segments=1)
    assert env.action_space.shape == (5,)
    inner = second.inner  # the outer wrappers keep their state in extras
    assert inner.cpg.phase.shape == (10,)
    assert float(inner.modulation.omega[0]) == pytest.approx(3 * np.pi)  # the second action (the bounds' high)
    assert float(first.inner.modulation.omega[0]) == pytest.approx(1.5 * np.pi)
    assert np.isfinite(np.asarray(second.obs)).all() and np.isfinite(float(second.reward))
