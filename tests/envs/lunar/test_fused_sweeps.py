"""env.solver.sweep_layout: the velocity sweeps on stacked arrays or on components (fused_sweeps)."""

import jax
import numpy as np
import pytest

from rlq.envs.lunar.env import LunarLander
from rlq.envs.lunar.physics import step as P
from tests.helpers import fast_compile

pytestmark = pytest.mark.slow

STEPS, ENVS = 120, 32


@pytest.fixture(scope="module")
def trajectories():
    """Observations and leg contacts of 32 envs under random actions, per layout (the GPU presets'
    solver: 30/10 sweeps, no time-of-impact sub-step; the Box2D heuristic test covers the sub-step), compiled alike
    for a fast compile."""
    keys = jax.random.split(jax.random.PRNGKey(5), ENVS)
    actions = jax.random.randint(jax.random.PRNGKey(6), (STEPS, ENVS), 0, 4)
    out = {}
    for layout in ("auto", "stacked", "components"):
        env = LunarLander(
            solver=P.SolverConfig(velocity_iterations=30, position_iterations=10, toi=False, sweep_layout=layout)
        )

        def run(keys, actions, env=env):
            def one(state, action):
                state = jax.vmap(env.step)(state, action)
                return state, (state.obs, state.inner.leg_contact)

            return jax.lax.scan(one, jax.vmap(env.reset)(keys), actions)[1]

        out[layout] = jax.device_get(jax.jit(run, compiler_options=fast_compile())(keys, actions))
    return out


def test_auto_runs_the_stacked_sweeps_on_a_cpu(trajectories):
    for auto, stacked in zip(trajectories["auto"], trajectories["stacked"], strict=True):
        np.testing.assert_array_equal(auto, stacked)


def test_the_component_sweeps_give_the_stacked_states(trajectories):
    """The same arithmetic in Box2D's order: only float rounding differs (XLA contracts other
    products into fused multiply-adds)."""
    (obs, contact), (obs_c, contact_c) = trajectories["stacked"], trajectories["components"]
    touched = contact.any(axis=(0, 2))
    assert touched.sum() >= 8  # legs on the ground in a quarter of the envs: the contact sweeps ran
    np.testing.assert_array_equal(contact, contact_c)
    np.testing.assert_allclose(obs, obs_c, atol=5e-4)
    assert not np.array_equal(obs, obs_c)  # the two forms were both compiled, not one of them twice


def test_an_unknown_layout_is_a_clear_error():
    with pytest.raises(ValueError, match="sweep_layout must be one of auto, stacked, components, got 'fused'"):
        P.SolverConfig(sweep_layout="fused")


def _step_jaxpr(layout: str, **solver) -> str:
    env = LunarLander(
        solver=P.SolverConfig(velocity_iterations=4, position_iterations=2, sweep_layout=layout, **solver)
    )
    return str(jax.make_jaxpr(lambda key: env.step(env.reset(key), 0).obs)(jax.random.PRNGKey(0)))


def test_auto_traces_one_form_under_a_default_device():
    """``rlq train`` traces under ``jax.default_device``: ``auto`` then traces only that platform's
    form (the CPU's stacked one here); without a default device it defers the choice to lowering."""
    assert "platform_index" in _step_jaxpr("auto")
    with jax.default_device(jax.devices("cpu")[0]):
        traced = _step_jaxpr("auto")
    assert "platform_index" not in traced
    assert traced == _step_jaxpr("stacked")
    assert traced != _step_jaxpr("components")


@pytest.mark.parametrize(
    "layout,own,other", [("stacked", "unroll", "component_unroll"), ("components", "component_unroll", "unroll")]
)
def test_each_form_unrolls_by_its_own_option(layout, own, other):
    plain = _step_jaxpr(layout)
    assert _step_jaxpr(layout, **{own: 2}) != plain
    assert _step_jaxpr(layout, **{other: 2}) == plain
