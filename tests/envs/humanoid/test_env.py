"""brax humanoid (MJX) behind rlq's protocol, wrapped as training uses it, with domain randomisation.

MJX compiles slowly on CPU (~1 min per program), so the batched reset and step of 2 envs are
compiled once for the module and every test reuses them.
"""

import threading

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.envs.humanoid.env import TRACING, observation_size
from rlq.run.programs.env_stack import make_env
from tests.helpers import compose_config

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::UserWarning")]

RANDOMIZE = "env.randomize={friction:[0.6,1.4],gain_delta:[-5,5]}"


@pytest.fixture(scope="module")
def env():
    return make_env(compose_config("env=humanoid", RANDOMIZE))


@pytest.fixture(scope="module")
def reset(env):
    return jax.jit(jax.vmap(env.reset))


@pytest.fixture(scope="module")
def step(env):
    return jax.jit(jax.vmap(env.step))


@pytest.fixture(scope="module")
def first(reset):
    return reset(jax.random.split(jax.random.PRNGKey(0), 2))


def with_torso_height(state, z):
    """The same state with both torsos moved to height ``z`` (the step recomputes the rest)."""
    brax_state = state.inner["brax"]
    ps = brax_state.pipeline_state
    ps = ps.replace(qpos=ps.qpos.at[:, 2].set(z), q=ps.q.at[:, 2].set(z))
    return state.replace(inner={**state.inner, "brax": brax_state.replace(pipeline_state=ps)})


def test_spaces_and_reset(env, first):
    assert env.observation_space.shape == (244,)
    assert env.action_space.shape == (17,) and env.action_space.low[0] == -1.0
    assert env.max_episode_steps == 1000
    assert first.obs.shape == (2, 244) and bool(jnp.all(jnp.isfinite(first.obs)))
    assert not bool(first.done.any())
    for key in ("forward_reward", "x_velocity", "x_position", "reward_alive", "final_obs"):
        assert key in first.info
    assert "reset_cache" in first.extras  # env.reset_cache=true: AutoReset keeps the first state


def test_steps_run_healthy(first, step):
    key = jax.random.PRNGKey(1)
    state = first
    for _ in range(3):
        key, sub = jax.random.split(key)
        state = step(state, jax.random.uniform(sub, (2, 17), minval=-1, maxval=1))
    assert state.obs.shape == (2, 244) and state.reward.shape == (2,)
    assert not bool(state.done.any())
    np.testing.assert_allclose(state.info["reward_alive"], 5.0)
    assert np.all(np.asarray(state.reward) > 3.0)  # healthy 5, small forward/control terms
    assert np.all(np.asarray(state.extras["t"]) == 3)
    assert np.all(np.asarray(state.info["episode_length"]) == 3)


def test_fall_terminates_and_restarts_from_first_state(first, step):
    state = step(with_torso_height(first, 0.5), jnp.zeros((2, 17)))
    assert bool(state.terminated.all()) and not bool(state.truncated.any())
    assert np.all(np.asarray(state.info["final_obs"][:, 0]) < 1.0)  # obs[0] is the torso height
    np.testing.assert_array_equal(state.obs, first.obs)
    assert np.all(np.asarray(state.extras["t"]) == 0)


def test_time_limit_truncates(first, step):
    state = first.replace(extras={**first.extras, "t": jnp.full((2,), 999, jnp.int32)})
    state = step(state, jnp.zeros((2, 17)))
    assert bool(state.truncated.all()) and not bool(state.terminated.any())


def test_actions_outside_the_box_are_clamped_by_the_motors_and_charged_as_given(env, first, step):
    """Env.clamps_actions (algo.ars.clip_actions=false): an action of 2.5 moves the humanoid as 1 does (MuJoCo clamps
    the motors' control at 0.4), and brax charges the control cost on 0.4 x 2.5, as Humanoid-v1 did."""
    assert env.clamps_actions
    beyond, edge = step(first, jnp.full((2, 17), 2.5)), step(first, jnp.ones((2, 17)))
    np.testing.assert_array_equal(beyond.obs, edge.obs)
    np.testing.assert_allclose(edge.info["reward_quadctrl"], -0.1 * 17 * 0.4**2, rtol=1e-5)
    np.testing.assert_allclose(beyond.info["reward_quadctrl"], -0.1 * 17 * (0.4 * 2.5) ** 2, rtol=1e-5)


def test_randomised_models_differ_and_lie_in_ranges(env, first):
    base = env.unwrapped.brax_env.sys
    model = first.inner["model"]
    friction = np.asarray(model["geom_friction"])
    assert friction.shape == (2,) + base.geom_friction.shape
    assert np.all((friction[..., 0] >= 0.6) & (friction[..., 0] <= 1.4))
    assert np.all(friction[:, :, 0] == friction[:, :1, 0])  # one draw per env
    assert friction[0, 0, 0] != friction[1, 0, 0]
    np.testing.assert_array_equal(
        friction[..., 1:], np.broadcast_to(base.geom_friction[:, 1:], friction[..., 1:].shape)
    )
    gain = np.asarray(model["actuator_gainprm"])[..., 0]
    delta = gain - np.asarray(base.actuator_gainprm)[:, 0]
    assert np.all((delta >= -5) & (delta <= 5)) and delta[0, 0] != delta[1, 0]
    np.testing.assert_allclose(np.asarray(model["actuator_biasprm"])[..., 1], -gain)


def test_step_uses_each_envs_model(first, step):
    # both envs in env 0's physics state, each with its own model: the same action acts differently
    same = jax.tree.map(lambda x: jnp.stack([x[0], x[0]]), first.inner["brax"])
    state = first.replace(inner={**first.inner, "brax": same}, obs=jnp.stack([first.obs[0]] * 2))
    state = step(state, jnp.full((2, 17), 0.5, jnp.float32))
    obs = np.asarray(state.obs)
    assert not np.allclose(obs[0], obs[1])


def test_one_thread_at_a_time_traces_the_patched_physics(env):
    entered, release = threading.Event(), threading.Event()

    def trace_in_a_worker():
        with env.unwrapped._physics_tracing():
            entered.set()
            release.wait(timeout=30)

    worker = threading.Thread(target=trace_in_a_worker)
    worker.start()
    assert entered.wait(timeout=30)
    assert not TRACING.acquire(blocking=False)  # a second thread would wait here
    release.set()
    worker.join()
    assert TRACING.acquire(blocking=False)
    TRACING.release()


@pytest.mark.parametrize("exclude", [True, False])
def test_the_observation_size_read_off_the_model_is_brax_s(exclude):
    from brax import envs as brax_envs

    brax_env = brax_envs.get_environment("humanoid", backend="mjx", exclude_current_positions_from_observation=exclude)
    traced = jax.eval_shape(brax_env.reset, jax.random.PRNGKey(0)).obs.shape[-1]
    assert observation_size(brax_env.sys.mj_model, exclude) == traced


def test_the_physics_is_traced_once_for_every_program():
    """init, chunk and evaluation programs reuse one trace of brax's reset and of its step (MJX's
    physics takes seconds to trace), whatever their batch sizes."""
    from rlq.envs.humanoid.env import make

    env = make(compose_config("env=humanoid", RANDOMIZE).env)  # a new env: the fixture's has traced already
    brax_env = env.brax_env
    calls = {"reset": 0, "step": 0}
    for name in calls:
        original = getattr(brax_env, name)

        def counted(*args, original=original, name=name):
            calls[name] += 1
            return original(*args)

        setattr(brax_env, name, counted)
    for n in (2, 3):
        states = jax.eval_shape(jax.vmap(env.reset), jax.random.split(jax.random.PRNGKey(0), n))
        jax.jit(jax.vmap(env.step)).lower(states, jnp.zeros((n, 17), jnp.float32))
    assert calls == {"reset": 1, "step": 1}


def test_feet_on_the_floor_are_mjx_s_contacts_with_a_distance_of_at_most_zero(env, first, step):
    """The feet-contact descriptor's flags (read off the feet's heights) equal QDax's test on MJX's contacts:
    a contact of the foot's geom with a distance <= 0. The feet start above the floor and land within steps."""
    base = env.unwrapped
    feet = jnp.asarray(base._feet.geoms)

    @jax.jit
    def flags(state):
        states = env.base_states(state)
        contact = states.inner["brax"].pipeline_state.contact
        hit = ((contact.geom1[..., None] == feet) | (contact.geom2[..., None] == feet)) & (contact.dist[..., None] <= 0)
        return jax.vmap(base.feet_on_floor)(states), jnp.any(hit, axis=1).astype(jnp.float32)

    state, seen = first, []
    for _ in range(14):
        ours, mjx = flags(state)
        np.testing.assert_array_equal(ours, mjx)
        seen.append(np.asarray(ours))
        state = step(state, jnp.zeros((2, 17)))
    assert {0.0, 1.0} == set(np.unique(seen))


def test_map_elites_on_the_humanoid_gets_the_feet_contact_wrapper():
    from rlq.envs.humanoid.feet_contact import FeetContactTime

    env = make_env(compose_config("env=humanoid", "algo=map_elites"))
    layers = []
    while hasattr(env, "env"):
        layers.append(type(env))
        env = env.env
    assert FeetContactTime in layers
    assert env.descriptor_wrappers == {"feet_contact": FeetContactTime}


def test_contact_forces_join_the_observation_carry_the_weight_and_cost_what_gym_charged():
    """``env.include_cfrc_ext_in_observation=true``: brax's 244 numbers, then each body's external contact wrench
    (torque, force); standing, the floor pushes up on the feet with about the body's weight, and on nothing else
    (it starts in the air: the feet land at the 12th step). ``env.contact_cost_weight``: brax's reward less the
    weight times those wrenches' sum of squares, at most 10; nothing before the feet land."""
    weight_of_cost = 5e-7
    env = make_env(
        compose_config(
            "env=humanoid", "env.include_cfrc_ext_in_observation=true", f"env.contact_cost_weight={weight_of_cost}"
        )
    )
    model = env.unwrapped.mj_model
    links = model.nbody - 1
    assert env.observation_space.shape == (244 + 6 * links,)
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 2))
    step = jax.jit(jax.vmap(env.step))
    assert not np.any(np.asarray(state.obs[:, 244:]))
    assert np.all(np.asarray(state.info["reward_contact"]) == 0.0)
    costs = []
    for _ in range(20):
        state = step(state, jnp.zeros((2, 17)))
        squares = np.sum(np.square(np.asarray(state.obs[:, 244:], np.float64)), axis=1)
        cost = np.minimum(weight_of_cost * squares, 10.0)
        np.testing.assert_allclose(state.reward, np.asarray(state.inner["brax"].reward) - cost, rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(state.info["reward_contact"], -cost, rtol=1e-5, atol=1e-7)
        costs.append(cost)
    assert np.all(costs[0] == 0.0) and np.all(costs[-1] > 0.0)
    assert state.obs.shape == (2, 244 + 6 * links) and not bool(state.done.any())
    np.testing.assert_array_equal(state.obs[:, :244], state.inner["brax"].obs)
    wrench = np.asarray(state.obs[:, 244:]).reshape(2, links, 6)
    feet = {int(model.geom_bodyid[g]) - 1 for g in env.unwrapped._feet.geoms}
    lifted = [body for body in range(links) if body not in feet]
    assert np.all(wrench[:, lifted] == 0.0)
    weight = float(np.sum(model.body_mass)) * 9.81
    np.testing.assert_allclose(wrench[:, sorted(feet), 5].sum(axis=1), weight, rtol=0.5)


def test_contact_forces_need_mjx_s_jax_implementation():
    from rlq.envs.humanoid.env import Humanoid

    with pytest.raises((ValueError, ImportError), match="mjx_impl"):
        Humanoid(mjx_impl="warp", contact_forces=True)
    with pytest.raises((ValueError, ImportError), match="mjx_impl"):
        Humanoid(mjx_impl="warp", contact_cost_weight=5e-7)


def test_a_negative_contact_cost_is_refused_with_its_key():
    from rlq.envs.humanoid.env import Humanoid

    with pytest.raises(ValueError, match="env.contact_cost_weight must be"):
        Humanoid(contact_cost_weight=-1.0)
