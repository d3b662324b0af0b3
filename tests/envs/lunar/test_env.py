"""env=lunar: the JAX port of Gymnasium's LunarLander-v3, and its Box2D reference (env=lunar_box2d)."""

import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.env import OBS_HIGH, OBS_LOW, LunarLander
from rlq.envs.lunar.heuristic import heuristic, heuristic_episodes
from rlq.envs.lunar.physics import step as P
from rlq.envs.lunar.render import render_frames
from rlq.lib.spaces import Box, Discrete
from tests.helpers import fast_compile

pytestmark = pytest.mark.slow

N = 1024
DISCRETE = LunarLander()
reset_batch = jax.jit(jax.vmap(DISCRETE.reset))
step_batch = jax.jit(jax.vmap(DISCRETE.step))
step_one = jax.jit(DISCRETE.step)
reset_one = jax.jit(DISCRETE.reset_with)


def shaping(obs):
    obs = np.asarray(obs, np.float64)
    return (
        -100 * np.hypot(obs[0], obs[1]) - 100 * np.hypot(obs[2], obs[3]) - 100 * abs(obs[4]) + 10 * obs[6] + 10 * obs[7]
    )


def calm_start(height: float | None = None):
    """A flat-terrain episode with no initial push and no engine dispersion; optionally with the
    lander's lowest point lowered to ``height`` above the ground, at rest."""
    flat = jnp.full(C.CHUNKS + 1, C.HELIPAD_Y)
    state = reset_one(jax.random.PRNGKey(0), flat, jnp.zeros(2), None, jnp.zeros((1001, 2)))
    for _ in range(30):  # let the leg motors push the legs onto their limits
        state = step_one(state, jnp.int32(0))
    if height is None:
        return state
    ps = state.inner.physics
    legs = np.asarray(ps.c[1:, None, :]) + np.asarray(
        jax.vmap(_rot, in_axes=(0, None))(ps.a[1:], jnp.asarray(C.LEG_VERTS))
    )
    ground = float(state.inner.terrain_y[5])
    shift = jnp.array([0.0, ground + height - legs[..., 1].min()])
    ps = ps.replace(c=ps.c + shift, v=jnp.zeros_like(ps.v), w=jnp.zeros_like(ps.w))
    return state.replace(inner=state.inner.replace(physics=ps))


def _rot(angle, pts):
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.stack([c * pts[:, 0] - s * pts[:, 1], s * pts[:, 0] + c * pts[:, 1]], -1)


@pytest.fixture(scope="module")
def batch():
    keys = jax.random.split(jax.random.PRNGKey(0), N)
    return keys, reset_batch(keys)


def test_spaces():
    assert DISCRETE.action_space == Discrete(4)
    cont = LunarLander(continuous=True)
    assert cont.action_space == Box((-1.0, -1.0), (1.0, 1.0))
    assert DISCRETE.observation_space.shape == (8,)
    assert DISCRETE.max_episode_steps == 1000


def test_jit_vmap_1024_envs_and_stable_state_types(batch):
    keys, state = batch
    actions = jax.random.randint(jax.random.PRNGKey(1), (N,), 0, 4)
    nxt = step_batch(state, actions)
    assert nxt.obs.shape == (N, 8) and nxt.reward.shape == (N,)
    assert np.isfinite(np.asarray(nxt.obs)).all() and np.isfinite(np.asarray(nxt.reward)).all()
    first = jax.tree.map(lambda x: (x.shape, x.dtype, x.weak_type), jax.eval_shape(step_batch, state, actions))
    again = jax.tree.map(lambda x: (x.shape, x.dtype, x.weak_type), jax.eval_shape(step_batch, nxt, actions))
    assert first == again  # step's output feeds step (and auto-reset) without retracing


def test_deterministic_for_a_fixed_key(batch):
    keys, state = batch
    again = reset_batch(keys)
    assert np.array_equal(np.asarray(state.obs), np.asarray(again.obs))
    actions = jnp.full((N,), 2, jnp.int32)
    a, b = step_batch(state, actions), step_batch(again, actions)
    assert np.array_equal(np.asarray(a.obs), np.asarray(b.obs))
    terrains = np.asarray(state.inner.terrain_y)
    assert len({t.tobytes() for t in terrains}) == N  # every key its own terrain


def test_observations_within_bounds(batch):
    _, state = batch
    key = jax.random.PRNGKey(2)
    for _ in range(25):
        key, sub = jax.random.split(key)
        state = step_batch(state, jax.random.randint(sub, (N,), 0, 4))
        obs = np.asarray(state.obs)
        assert (obs >= np.asarray(OBS_LOW) - 1e-6).all() and (obs <= np.asarray(OBS_HIGH) + 1e-6).all()
    assert set(np.unique(obs[:, 6:])) <= {0.0, 1.0}


@pytest.mark.parametrize("action,cost", [(0, 0.0), (1, 0.03), (2, 0.3), (3, 0.03)])
def test_reward_is_shaping_difference_minus_fuel(action, cost):
    state = calm_start()
    nxt = step_one(state, jnp.int32(action))
    expected = shaping(nxt.obs) - shaping(state.obs) - cost
    assert float(nxt.reward) == pytest.approx(expected, abs=1e-3)
    assert not bool(nxt.terminated)


def test_continuous_throttle_costs():
    env = LunarLander(continuous=True)
    flat = jnp.full(C.CHUNKS + 1, C.HELIPAD_Y)
    state = jax.jit(env.reset_with)(jax.random.PRNGKey(0), flat, jnp.zeros(2), None, jnp.zeros((10, 2)))
    step = jax.jit(env.step)
    for action, cost in [((0.5, 0.0), 0.3 * 0.75), ((-1.0, 0.75), 0.03 * 0.75), ((-1.0, 0.2), 0.0)]:
        nxt = step(state, jnp.array(action, jnp.float32))
        assert float(nxt.reward) == pytest.approx(shaping(nxt.obs) - shaping(state.obs) - cost, abs=1e-3)


def test_hull_on_the_ground_is_a_crash():
    state = calm_start(height=-0.35)  # legs 35 cm into the ground: the hull touches it
    nxt = step_one(state, jnp.int32(0))
    assert bool(nxt.terminated) and float(nxt.reward) == -100.0
    assert bool(nxt.info["crashed"]) and not bool(nxt.info["landed"])


def test_leaving_the_viewport_is_a_crash():
    state = calm_start()
    ps = state.inner.physics
    state = state.replace(inner=state.inner.replace(physics=ps.replace(c=ps.c + jnp.array([10.5, 0.0]))))
    nxt = step_one(state, jnp.int32(0))
    assert bool(nxt.terminated) and float(nxt.reward) == -100.0


def test_lander_at_rest_gets_100():
    state = calm_start(height=0.03)
    rewards = []
    for _ in range(120):
        state = step_one(state, jnp.int32(0))
        rewards.append(float(state.reward))
        if bool(state.terminated):
            break
    assert bool(state.terminated) and rewards[-1] == 100.0 and bool(state.info["landed"])
    assert np.asarray(state.obs)[6:].tolist() == [1.0, 1.0]
    assert 25 <= len(rewards) < 120  # Box2D's sleep needs 0.5 s below the tolerances


@pytest.mark.parametrize("continuous,layout", [(False, "auto"), (True, "auto"), (False, "components")])
def test_heuristic_lands_like_box2d(continuous, layout):
    """Also with the velocity sweeps' component form (a GPU's, ``fused_sweeps``) run on the CPU."""
    from rlq.envs.lunar.box2d_reference import LunarBox2D

    box2d = LunarBox2D(continuous=continuous)
    seeds = [0, 1, 2, 3]
    draws = [box2d.draws(seed, 1000) for seed in seeds]
    env = LunarLander(continuous=continuous, solver=P.SolverConfig(sweep_layout=layout))
    stack = {
        k: jnp.asarray(np.stack([d[k] for d in draws]), jnp.float32) for k in ("terrain", "init_force", "dispersion")
    }

    @jax.jit
    def run(terrain, force, dispersion):
        keys = jax.random.split(jax.random.PRNGKey(0), len(seeds))
        state = jax.vmap(lambda k, h, f, d: env.reset_with(k, h, f, None, d))(keys, terrain, force, dispersion)
        return heuristic_episodes(env, state, 1000)

    out = jax.device_get(run(stack["terrain"], stack["init_force"], stack["dispersion"]))
    assert out["landed"].all()
    reference = {False: [297.35, 260.94, 254.62, 244.50], True: [305.96, 273.89, 257.39, 248.63]}[continuous]
    assert abs(out["ret"].mean() - np.mean(reference)) < 5.0


def test_heuristic_in_jnp_matches_gymnasium():
    from gymnasium.envs.box2d.lunar_lander import heuristic as gym_heuristic

    class Fake:
        def __init__(self, continuous):
            self.continuous = continuous
            self.unwrapped = self

    rng = np.random.default_rng(0)
    for _ in range(200):
        s = rng.normal(0, 0.5, 8).astype(np.float32)
        s[6:] = rng.integers(0, 2, 2)
        assert int(heuristic(jnp.asarray(s))) == gym_heuristic(Fake(False), s)
        np.testing.assert_allclose(np.asarray(heuristic(jnp.asarray(s), True)), gym_heuristic(Fake(True), s), atol=1e-5)


def test_box2d_reference_env_and_its_draws():
    from rlq.envs.lunar.box2d_reference import LunarBox2D

    env = LunarBox2D(continuous=True)
    assert isinstance(env.action_space, Box) and not env.jittable
    draws = env.draws(7, 5)
    obs, _ = env.reset(7)
    assert obs.shape == (8,)
    for _ in range(5):
        obs, reward, terminated, truncated, _ = env.step(np.zeros(2, np.float32))
    recorded = env.recorded_draws()
    np.testing.assert_array_equal(recorded["terrain"], draws["terrain"])
    np.testing.assert_array_equal(recorded["init_force"], draws["init_force"])
    np.testing.assert_array_equal(recorded["dispersion"], draws["dispersion"])
    assert draws["terrain"].shape == (12,) and draws["dispersion"].shape == (6, 2)


def test_render_frames(batch):
    _, state = batch
    three = jax.tree.map(lambda x: x[:3], state)
    frames = render_frames(three)
    assert frames.shape == (3, 400, 600, 3) and frames.dtype == np.uint8
    colours = {tuple(c) for c in frames[0].reshape(-1, 3)[::7]}
    assert {(0, 0, 0), (255, 255, 255), (128, 102, 230)} <= colours  # sky, ground, lander
    assert DISCRETE.render(three).shape == frames.shape


def test_configs_compose_and_validate():
    from rlq.errors import ConfigError
    from rlq.run.checks.validate import check_run_config
    from rlq.run.programs.env_stack import make_env
    from tests.helpers import compose_config

    cfg = compose_config("env=lunar", "env.continuous=true", "env.solver.velocity_iterations=30")
    check_run_config(cfg)
    env = make_env(cfg)
    assert env.action_space == Box((-1.0, -1.0), (1.0, 1.0)) and env.max_episode_steps == 1000
    assert env.unwrapped.solver.velocity_iterations == 30
    host = make_env(compose_config("env=lunar_box2d"))
    assert not host.jittable and host.action_space == Discrete(4)
    with pytest.raises(ConfigError):
        check_run_config(compose_config("env=lunar_box2d"))


@pytest.mark.parametrize("field", ["velocity_iterations", "position_iterations", "unroll", "component_unroll"])
def test_solver_iterations_below_one_raise(field):
    with pytest.raises(ValueError, match="must be >= 1"):
        P.SolverConfig(**{field: 0})


@pytest.mark.parametrize("layout,field", [("stacked", "unroll"), ("components", "component_unroll")])
def test_unrolled_velocity_sweeps_give_the_same_states(layout, field):
    """env.solver.unroll (component_unroll for the component form) changes how the sweeps are
    compiled, not what they compute."""
    from rlq.run.programs.env_stack import make_env
    from tests.helpers import compose_config

    keys = jax.random.split(jax.random.PRNGKey(3), 8)
    actions = jax.random.randint(jax.random.PRNGKey(4), (40, 8), 0, 4)
    finals = []
    for unroll in (1, 3):  # 7 sweeps: two unrolled trips and a remainder
        env = make_env(
            compose_config(
                "env=lunar",
                "env.solver.velocity_iterations=7",
                "env.solver.position_iterations=10",
                f"env.solver.sweep_layout={layout}",
                f"env.solver.{field}={unroll}",
            )
        )

        def run(keys, actions, env=env):
            state = jax.vmap(env.reset)(keys)
            return jax.lax.scan(lambda s, a: (jax.vmap(env.step)(s, a), None), state, actions)[0]

        finals.append(jax.jit(run, compiler_options=fast_compile())(keys, actions))
    np.testing.assert_allclose(finals[0].obs, finals[1].obs, atol=1e-4)
    np.testing.assert_array_equal(finals[0].done, finals[1].done)


def test_lockstep_reset_matches_the_step_and_the_reset_apart():
    """env.lockstep_reset steps auto-reset's new episode in the same solver loops as the step: the
    same keys and flags, the same states up to float rounding, in the air and on the ground."""
    solver = P.SolverConfig(velocity_iterations=30, position_iterations=10, toi=False)  # the GPU presets'
    apart, lockstep = LunarLander(solver=solver), LunarLander(solver=solver, lockstep_reset=True)

    def one(state, inputs):
        action, reset_key = inputs
        pairs = (apart.step_and_reset(state, action, reset_key), lockstep.step_and_reset(state, action, reset_key))
        return pairs[0][0], pairs

    def run(state, actions, reset_keys):
        return jax.lax.scan(jax.vmap(one), state, (actions, reset_keys))[1]

    state = reset_batch(jax.random.split(jax.random.PRNGKey(5), 32))
    actions = jax.random.randint(jax.random.PRNGKey(6), (120, 32), 0, 4)
    reset_keys = jax.random.split(jax.random.PRNGKey(7), (120, 32))
    (nxt, fresh), (nxt_l, fresh_l) = jax.jit(run, compiler_options=fast_compile())(state, actions, reset_keys)
    for ours, theirs in ((nxt, nxt_l), (fresh, fresh_l)):
        assert jax.tree.structure(ours) == jax.tree.structure(theirs)
        np.testing.assert_array_equal(jax.random.key_data(ours.key), jax.random.key_data(theirs.key))
        np.testing.assert_array_equal(ours.terminated, theirs.terminated)
        np.testing.assert_array_equal(ours.inner.leg_contact, theirs.inner.leg_contact)
        np.testing.assert_allclose(ours.obs, theirs.obs, atol=1e-4)
        np.testing.assert_allclose(ours.reward, theirs.reward, atol=1e-3)
    np.testing.assert_array_equal(fresh.inner.terrain_y, fresh_l.inner.terrain_y)
    touched = np.asarray(nxt.inner.leg_contact).any(axis=(0, 2))
    assert touched.sum() >= 8  # legs on the ground in a quarter of the envs: the contact solver ran


def test_import_compiles_nothing():
    """The physics constants are copied to the device, not converted there: importing the env runs
    no XLA compile (each takes 15-60 ms on a GPU, on the path to a run's first program)."""
    code = "import jax; jax.config.update('jax_log_compiles', True); import rlq.envs.lunar.env"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "Compiling" not in proc.stderr, proc.stderr[-2000:]


def test_reset_cache_starts_each_env_over_from_its_first_start():
    """env.reset_cache: auto-reset's new episodes start from each env's own first start (the
    terrain, the initial push) and the step computes no reset; without it every episode is new."""
    from rlq.envs.wrappers import AutoReset, TimeLimit

    solver = P.SolverConfig(velocity_iterations=2, position_iterations=1, toi=False)
    cached = AutoReset(TimeLimit(LunarLander(solver=solver, reset_cache=True), 2))
    fresh = AutoReset(TimeLimit(LunarLander(solver=solver), 2))

    def episodes(env):
        def step(state, _):
            state = jax.vmap(env.step)(state, jnp.zeros(3, jnp.int32))
            return state, (state.obs, state.inner.terrain_y, state.done)

        first = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(3), 3))
        return first, jax.lax.scan(step, first, None, length=4)[1]

    first, (obs, terrain, done) = jax.jit(lambda: episodes(cached))()
    assert np.asarray(done)[[1, 3]].all() and not np.asarray(done)[[0, 2]].any()
    for t in (1, 3):  # the episodes that began after steps 2 and 4
        np.testing.assert_array_equal(obs[t], first.obs)
        np.testing.assert_array_equal(terrain[t], first.inner.terrain_y)
    assert len(np.unique(np.asarray(first.inner.terrain_y), axis=0)) == 3  # each env its own start
    _, (_, terrain_fresh, _) = jax.jit(lambda: episodes(fresh))()
    assert not np.array_equal(terrain_fresh[1], first.inner.terrain_y)
