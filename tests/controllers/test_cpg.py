"""The CPG (rlq/controllers/oscillators.py) and the CPG controller wrapper, on a stand-in env (no physics)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from omegaconf import OmegaConf

from rlq.config.compose import WITHOUT_TUNED
from rlq.controllers import controller_settings
from rlq.controllers import cpg as cpg_controller
from rlq.controllers import oscillators as cpg
from rlq.envs import env_settings
from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import Box, Discrete
from tests.helpers import compose_config

N = 10  # 5 arms


def cpg_preset():
    """conf/controller/cpg.yaml as a run composes it: the declared defaults."""
    return compose_config("controller=cpg", *WITHOUT_TUNED).controller


def simulate(state, mod, weights, dt, steps, method="euler"):
    """Scan ``steps`` CPG steps; returns the final state and the phases and outputs over time."""

    def body(s, _):
        s = cpg.step(s, mod, weights, dt, 20.0, 20.0, method)
        return s, (s.phase, cpg.output(s))

    return jax.jit(lambda s: jax.lax.scan(body, s, None, length=steps))(state)


def constant(n, R=0.0, X=0.0, omega=np.pi):
    return cpg.Modulation(R=jnp.full(n, R), X=jnp.full(n, X), omega=jnp.full(n, omega), rho=jnp.zeros((n, n)))


def test_free_oscillator_runs_at_omega_and_converges_to_R_and_X():
    omega, dt = 2.5, 0.01
    state = cpg.init_state(jax.random.PRNGKey(0), 2)
    mod = constant(2, R=0.3, X=-0.2, omega=omega)
    final, (phases, outputs) = simulate(state, mod, jnp.zeros((2, 2)), dt, 400)
    slope = np.polyfit(np.arange(400) * dt, np.asarray(phases[:, 0]), 1)[0]
    assert slope == pytest.approx(omega, rel=1e-4)
    np.testing.assert_allclose(final.amplitude, 0.3, atol=1e-4)
    np.testing.assert_allclose(final.offset, -0.2, atol=1e-4)
    late = np.asarray(outputs[-200:, 0])
    assert late.max() == pytest.approx(0.1, abs=2e-3) and late.min() == pytest.approx(-0.5, abs=2e-3)


def test_reset_phases_are_small_and_the_rest_zero():
    state = cpg.init_state(jax.random.PRNGKey(3), N, 0.01)
    assert float(jnp.max(jnp.abs(state.phase))) <= 0.01 and float(jnp.std(state.phase)) > 0
    for leaf in (state.amplitude, state.amplitude_rate, state.offset, state.offset_rate):
        assert not bool(jnp.any(leaf))


@pytest.mark.parametrize("bias", [np.pi / 3, -np.pi / 2, 2.5])
def test_coupled_pair_settles_at_the_phase_bias(bias):
    mod = constant(2, R=1.0, omega=np.pi)
    mod = mod.replace(rho=jnp.array([[0.0, bias], [-bias, 0.0]]))
    weights = jnp.asarray(cpg.coupling_weights(1, "arm", 5.0))
    final, _ = simulate(cpg.init_state(jax.random.PRNGKey(1), 2), mod, weights, 0.01, 1000)
    lag = float(final.phase[1] - final.phase[0])
    assert np.angle(np.exp(1j * (lag - bias))) == pytest.approx(0.0, abs=1e-3)


def test_coupling_topologies():
    ring = cpg.coupling_weights(5, "ring", 5.0)
    arm = cpg.coupling_weights(5, "arm", 5.0)
    np.testing.assert_array_equal(ring, ring.T)
    assert set(np.unique(ring)) == {0.0, 5.0}
    assert (
        ring[0, 1] == ring[0, 2] == ring[0, 8] == ring[1, 3] == ring[1, 9] == 5.0
    )  # IP0-OOP0, IP0-IP1, IP0-IP4, OOP0-OOP1/4
    assert ring[0, 3] == 0.0 and ring.sum() == 5.0 * 2 * 15  # 15 undirected edges
    assert arm.sum() == 5.0 * 2 * 5 and arm[0, 1] == arm[8, 9] == 5.0 and arm[0, 2] == 0.0


def test_leading_arm_sets_the_tutorial_roles():
    J = jnp.asarray([0.4, 0.25] * 5)  # (IP, OOP) amplitude per arm
    for lead in range(5):
        mod = cpg.leading_arm_modulation(lead, J)
        l1, l2, r1, r2 = (lead - 1) % 5, (lead - 2) % 5, (lead + 1) % 5, (lead + 2) % 5
        ip, oop = (lambda k: 2 * k), (lambda k: 2 * k + 1)
        assert float(mod.X[oop(lead)]) == 0.25 and float(jnp.sum(jnp.abs(mod.X))) == 0.25
        assert float(mod.R[ip(lead)]) == float(mod.R[oop(lead)]) == 0.0
        for rower in (l1, l2, r1, r2):
            assert float(mod.R[ip(rower)]) == pytest.approx(0.4) and float(mod.R[oop(rower)]) == 0.25
        np.testing.assert_allclose(mod.omega, np.pi)
        np.testing.assert_allclose(mod.rho, -mod.rho.T)
        expected = {
            (ip(l1), oop(l1)): np.pi / 2,
            (ip(l2), oop(l2)): np.pi / 2,
            (oop(r1), ip(r1)): np.pi / 2,
            (oop(r2), ip(r2)): np.pi / 2,
            (ip(l1), ip(lead)): np.pi / 4,
            (oop(lead), oop(l1)): np.pi / 4,
            (ip(lead), ip(r1)): np.pi / 4,
            (oop(r1), oop(lead)): np.pi / 4,
            (ip(l2), ip(r2)): np.pi,
        }
        for (o1, o2), b in expected.items():
            assert float(mod.rho[o1, o2]) == pytest.approx(b) and float(mod.rho[o2, o1]) == pytest.approx(-b)
        assert int(jnp.sum(mod.rho != 0)) == 2 * len(expected)


def test_leading_arm_outputs_lift_the_leader_and_row_the_others():
    J = jnp.asarray([0.4, 0.25] * 5)
    mod = cpg.leading_arm_modulation(2, J)
    weights = jnp.asarray(cpg.coupling_weights(5, "ring", 5.0))
    _, (_, outputs) = simulate(cpg.init_state(jax.random.PRNGKey(0), N), mod, weights, 0.04, 200)
    late = np.asarray(outputs[-50:])
    np.testing.assert_allclose(late[:, 5], 0.25, atol=1e-3)  # leader's OOP held up
    np.testing.assert_allclose(late[:, 4], 0.0, atol=1e-3)  # leader's IP still
    for rower in (0, 1, 3, 4):
        assert np.ptp(late[:, 2 * rower]) > 0.7  # oscillates with amplitude ~0.4


def test_euler_and_rk4_agree_for_small_dt():
    mod = cpg.leading_arm_modulation(0, jnp.asarray([0.4, 0.25] * 5))
    weights = jnp.asarray(cpg.coupling_weights(5, "ring", 5.0))
    start = cpg.init_state(jax.random.PRNGKey(2), N)
    _, (_, euler) = simulate(start, mod, weights, 1e-3, 2000, "euler")
    _, (_, rk4) = simulate(start, mod, weights, 1e-3, 2000, "rk4")
    np.testing.assert_allclose(euler, rk4, atol=5e-3)


def test_parametric_genotype_layout():
    assert cpg.parametric_size(5) == 26
    low, high = cpg.parametric_bounds(5, 1.0, 1.0, 3 * np.pi)
    assert low.shape == high.shape == (26,)
    assert high[20] == pytest.approx(3 * np.pi) and low[21] == pytest.approx(-np.pi)
    params = jnp.arange(26, dtype=jnp.float32) / 100
    mod = cpg.parametric_modulation(params, 5)
    np.testing.assert_allclose(mod.R, params[:10])
    np.testing.assert_allclose(mod.X, params[10:20])
    np.testing.assert_allclose(mod.omega, params[20])
    for k in range(5):
        assert float(mod.rho[2 * k, 2 * k + 1]) == pytest.approx(float(params[21 + k]))
        assert float(mod.rho[2 * k + 1, 2 * k]) == pytest.approx(-float(params[21 + k]))


def random_genotype(low, high, seed):
    return jnp.asarray(np.random.default_rng(seed).uniform(low, high), jnp.float32)


def wrapped(angle):
    return np.angle(np.exp(1j * np.asarray(angle)))


def test_parametric_segment_genotype_layout():
    A, S = 5, 3
    n = 2 * A * S
    assert cpg.parametric_segment_size(A, S) == 71 == 30 + 30 + 1 + 5 + 5
    assert cpg.parametric_segment_size(2, 4) == 16 + 16 + 1 + 2 + 2
    low, high = cpg.parametric_segment_bounds(A, S, 0.8, 0.6, 2 * np.pi)
    assert low.shape == high.shape == (71,)
    np.testing.assert_allclose(low, [0.0] * n + [-0.6] * n + [0.0] + [-np.pi] * 10)
    np.testing.assert_allclose(high, [0.8] * n + [0.6] * n + [2 * np.pi] + [np.pi] * 10)
    params = random_genotype(low, high, 0)
    mod = cpg.parametric_segment_modulation(params, A, S)
    np.testing.assert_allclose(mod.R, params[:n])
    np.testing.assert_allclose(mod.X, params[n : 2 * n])
    np.testing.assert_allclose(mod.omega, params[2 * n])
    np.testing.assert_allclose(mod.rho, -mod.rho.T)
    bias, lag = np.asarray(params[61:66]), np.asarray(params[66:71])
    for k in range(A):
        for s in range(S):
            ip, oop = (cpg.segment_osc(k, s, kind, S) for kind in (cpg.IP, cpg.OOP))
            assert float(mod.rho[ip, oop]) == pytest.approx(bias[k])
            if s + 1 < S:
                for kind in (cpg.IP, cpg.OOP):
                    this, nxt = cpg.segment_osc(k, s, kind, S), cpg.segment_osc(k, s + 1, kind, S)
                    assert float(mod.rho[this, nxt]) == pytest.approx(lag[k])
    assert int(jnp.sum(mod.rho != 0)) == 2 * A * (S + 2 * (S - 1))  # no other biases


@pytest.mark.parametrize("layout", ["parametric", "parametric_segment"])
def test_arm_rotations_turn_the_modulation_by_whole_arms(layout):
    """Genotype row k gives arm a what arm a - k had: the modulation's oscillators move k arms on,
    with every R, X, bias and lag intact; k = 0 is the identity and the A turns are all different."""
    A, S = 5, 3
    if layout == "parametric":
        low, high = cpg.parametric_bounds(A, 1.0, 1.0, 3 * np.pi)
        rotations, per_arm = cpg.parametric_rotations(A), 2
        modulation = lambda g: cpg.parametric_modulation(g, A)  # noqa: E731
    else:
        low, high = cpg.parametric_segment_bounds(A, S, 1.0, 1.0, 3 * np.pi)
        rotations, per_arm = cpg.parametric_segment_rotations(A, S), 2 * S
        modulation = lambda g: cpg.parametric_segment_modulation(g, A, S)  # noqa: E731
    assert rotations.shape == (A, low.shape[0])
    np.testing.assert_array_equal(rotations[0], np.arange(low.shape[0]))
    assert len({tuple(row) for row in rotations}) == A
    for row in rotations:
        assert sorted(row) == list(range(low.shape[0]))
        np.testing.assert_array_equal(low[row], low)  # bounds are the same for every arm
    params = random_genotype(low, high, 1)
    base = modulation(params)
    for k in range(A):
        turned = modulation(params[rotations[k]])
        move = np.roll(np.arange(2 * A * (S if layout != "parametric" else 1)).reshape(A, per_arm), k, axis=0).ravel()
        np.testing.assert_allclose(turned.R, base.R[move])
        np.testing.assert_allclose(turned.X, base.X[move])
        np.testing.assert_allclose(turned.omega, base.omega)
        np.testing.assert_allclose(turned.rho, base.rho[np.ix_(move, move)])


def test_segment_coupling_topologies():
    A, S = 5, 3
    arm = cpg.coupling_weights(A, "arm", 5.0, S)
    ring = cpg.coupling_weights(A, "ring", 5.0, S)
    np.testing.assert_array_equal(ring, ring.T)
    assert arm.sum() == 5.0 * 2 * A * (S + 2 * (S - 1))  # per arm: S rungs IP-OOP, 2 (S - 1) along the arm
    assert ring.sum() - arm.sum() == 5.0 * 2 * 2 * A  # the first segments' IP and OOP rings
    o = lambda k, s, kind: cpg.segment_osc(k, s, kind, S)  # noqa: E731
    assert arm[o(2, 1, 0), o(2, 1, 1)] == arm[o(2, 1, 0), o(2, 2, 0)] == arm[o(2, 1, 1), o(2, 0, 1)] == 5.0
    assert arm[o(2, 0, 0), o(2, 2, 0)] == arm[o(2, 0, 0), o(2, 1, 1)] == arm[o(2, 0, 0), o(3, 0, 0)] == 0.0
    assert ring[o(4, 0, 0), o(0, 0, 0)] == ring[o(4, 0, 1), o(0, 0, 1)] == 5.0 and ring[o(4, 1, 0), o(0, 1, 0)] == 0
    assert not cpg.coupling_weights(A, "none", 5.0, S).any()
    for topology in ("ring", "arm", "none"):  # one segment per arm: the arm-level weights
        np.testing.assert_array_equal(cpg.coupling_weights(A, topology, 5.0, 1), cpg.coupling_weights(A, topology, 5.0))


def test_one_segment_per_arm_is_the_arm_layout():
    low, high = cpg.parametric_segment_bounds(5, 1, 1.0, 1.0, 3 * np.pi)
    params = random_genotype(low, high, 1)
    segment = cpg.parametric_segment_modulation(params, 5, 1)
    arm = cpg.parametric_modulation(params[:26], 5)  # the 5 lags have no segment pair to act on
    for a, b in zip(jax.tree.leaves(segment), jax.tree.leaves(arm), strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("topology", ["arm", "none"])
def test_segments_without_lag_move_as_their_arm(topology):
    """The arm's R/X repeated on every segment, zero lags, the arm's biases, the arm's start state
    on every segment: the along-arm terms are w r sin(0) = 0, so each segment follows its arm."""
    A, S, n = 5, 3, 10
    low, high = cpg.parametric_bounds(A, 1.0, 1.0, 3 * np.pi)
    arm_params = random_genotype(low, high, 2)
    per_joint = lambda x: jnp.repeat(x.reshape(A, 1, 2), S, axis=1).reshape(-1)  # noqa: E731
    seg_params = jnp.concatenate(
        [per_joint(arm_params[:n]), per_joint(arm_params[n : 2 * n]), arm_params[2 * n :], jnp.zeros(A)]
    )
    arm_start = cpg.init_state(jax.random.PRNGKey(4), n)
    seg_start = jax.tree.map(per_joint, arm_start)
    weights = lambda s: jnp.asarray(cpg.coupling_weights(A, topology, 5.0, s))  # noqa: E731
    _, (_, arm_out) = simulate(arm_start, cpg.parametric_modulation(arm_params, A), weights(1), 0.04, 300)
    _, (_, seg_out) = simulate(seg_start, cpg.parametric_segment_modulation(seg_params, A, S), weights(S), 0.04, 300)
    seg_out = np.asarray(seg_out).reshape(300, A, S, 2)
    for s in range(S):
        np.testing.assert_allclose(seg_out[:, :, s, :], np.asarray(arm_out).reshape(300, A, 2), atol=1e-5)


@pytest.mark.parametrize("method", ["euler", "rk4"])
def test_segment_coupling_settles_at_the_lags(method):
    A, S = 5, 3
    low, high = cpg.parametric_segment_bounds(A, S, 1.0, 1.0, 3 * np.pi)
    params = random_genotype(low, high, 3).at[: 2 * A * S].set(0.8)  # amplitudes set the coupling strength
    mod = cpg.parametric_segment_modulation(params, A, S)
    weights = jnp.asarray(cpg.coupling_weights(A, "arm", 5.0, S))
    final, _ = simulate(cpg.init_state(jax.random.PRNGKey(5), 2 * A * S), mod, weights, 0.04, 400, method)
    phase = np.asarray(final.phase).reshape(A, S, 2)
    bias, lag = np.asarray(params[61:66]), np.asarray(params[66:71])
    np.testing.assert_allclose(wrapped(phase[:, :, 1] - phase[:, :, 0] - bias[:, None]), 0.0, atol=1e-3)
    np.testing.assert_allclose(wrapped(phase[:, 1:, :] - phase[:, :-1, :] - lag[:, None, None]), 0.0, atol=1e-3)


def test_parametric_symmetric_genotype_layout():
    assert cpg.PARAMETRIC_SYMMETRIC_SIZE == 5
    low, high = cpg.parametric_symmetric_bounds(5, 0.8, 0.6, 2 * np.pi)
    np.testing.assert_allclose(low, [0.0, 0.0, -0.6, 0.0, -np.pi])
    np.testing.assert_allclose(high, [5.0, 0.8, 0.6, 2 * np.pi, np.pi])
    with pytest.raises(ValueError, match="controller.mode=parametric_symmetric needs 5 arms, got 4"):
        cpg.parametric_symmetric_bounds(4, 1.0, 1.0, 3 * np.pi)
    with pytest.raises(ValueError, match="needs 5 arms, got 3"):
        cpg.parametric_symmetric_modulation(jnp.array([0.0, 0.3, 0.3, 1.0, 0.5]), 3)


@pytest.mark.parametrize("lead", range(5))
def test_symmetric_layout_reproduces_the_leading_arm_pattern(lead):
    J = 0.3
    expected = cpg.leading_arm_modulation(lead, jnp.full(N, J), np.pi)
    for arm_value in (lead, lead + 0.99):  # floored to the arm index
        got = cpg.parametric_symmetric_modulation(jnp.array([arm_value, J, J, np.pi, np.pi / 2]), 5)
        for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(expected), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-6)


def test_symmetric_layout_sets_its_own_numbers():
    mod = cpg.parametric_symmetric_modulation(jnp.array([5.0, 0.4, -0.2, 2.0, 0.7]), 5)  # the bound 5 -> arm 4
    lead, l1, l2, r1, r2 = 4, 3, 2, 0, 1
    assert float(mod.X[2 * lead + 1]) == pytest.approx(-0.2) and float(jnp.sum(jnp.abs(mod.X))) == pytest.approx(0.2)
    np.testing.assert_allclose(np.asarray(mod.R).reshape(5, 2)[[l1, l2, r1, r2]], 0.4)
    assert float(mod.R[2 * lead]) == float(mod.R[2 * lead + 1]) == 0.0
    np.testing.assert_allclose(mod.omega, 2.0)
    for left in (l1, l2):
        assert float(mod.rho[2 * left, 2 * left + 1]) == pytest.approx(0.7)
    for right in (r1, r2):  # mirrored: OOP -> IP
        assert float(mod.rho[2 * right + 1, 2 * right]) == pytest.approx(0.7)
    assert float(mod.rho[2 * lead, 2 * r1]) == pytest.approx(np.pi / 4)


# ----- the controller wrapper on a stand-in env with the brittle star's actuator layout


class Layout:
    """5 arms x 3 segments, actuators ordered as biorobot's: arm, segment, (IP, OOP)."""

    arm = np.repeat(np.arange(5), 6)
    segment = np.tile(np.repeat(np.arange(3), 2), 5)
    kind = np.tile([0, 1], 15)
    high = np.where(kind == 0, 0.7854, 0.5236).astype(np.float32)
    low = -high


class RecordingEnv(Env):
    """obs = the last joint targets it received."""

    layout = Layout()
    control_timestep = 0.04
    observation_space = Box.uniform(-1, 1, 30)
    action_space = Box(tuple(Layout.low), tuple(Layout.high))

    def reset(self, key):
        return initial_state(jnp.zeros(30), jnp.zeros(()), key)

    def step(self, state: EnvState, action):
        return state.replace(obs=action, inner=state.inner + 1)


def controller(**overrides):
    cfg = OmegaConf.merge(cpg_preset(), overrides)
    return cpg_controller.wrap(
        RecordingEnv(), controller_settings(cfg), env_settings({"name": "brittle_star", "num_arms": 5})
    )


def rollout(env, actions):
    state = env.reset(jax.random.PRNGKey(0))
    states = []
    for action in actions:
        state = env.step(state, action)
        states.append(state)
    return states


def test_outputs_map_to_every_segment_of_their_arm():
    env = controller(mode="leading_arm")
    assert env.action_space == Discrete(5)
    state = rollout(env, [jnp.array(1)] * 30)[-1]
    targets = np.asarray(state.obs).reshape(5, 3, 2)  # arm, segment, (IP, OOP)
    out = np.asarray(jnp.clip(cpg.output(state.inner.cpg), -0.5236, 0.7854)).reshape(5, 2)
    for s in range(3):
        np.testing.assert_allclose(targets[:, s, :], out, atol=1e-6)
    assert targets[1, 0, 1] == pytest.approx(0.5 * 0.5236, abs=2e-3)  # leader lifts by J = 0.5 x OOP bound
    assert int(state.inner.env) == 30  # the env's own inner state is carried through


def test_parametric_every_step_versus_at_reset():
    low, high = cpg.parametric_bounds(5, 1.0, 1.0, 3 * np.pi)
    first = jnp.asarray(0.5 * (low + high), jnp.float32)
    other = jnp.asarray(high, jnp.float32)
    every = controller(mode="parametric")
    latched = controller(mode="parametric", modulate="at_reset")
    assert every.action_space.shape == (26,)
    s_every = rollout(every, [first, other])[-1]
    s_latched = rollout(latched, [first, other])[-1]
    np.testing.assert_allclose(s_latched.inner.modulation.R, 0.5 * high[:10])
    np.testing.assert_allclose(s_every.inner.modulation.R, high[:10])


def test_actions_outside_the_bounds_are_clipped():
    env = controller(mode="parametric")
    state = rollout(env, [jnp.full(26, 100.0)])[-1]
    assert float(state.inner.modulation.omega[0]) == pytest.approx(3 * np.pi)
    assert bool(jnp.all(jnp.abs(state.obs) <= jnp.asarray(Layout.high) + 1e-6))


class ShuffledLayout:
    """The stand-in layout with its actuators in another order."""

    order = np.random.default_rng(0).permutation(30)
    arm, segment, kind = Layout.arm[order], Layout.segment[order], Layout.kind[order]
    high, low = Layout.high[order], Layout.low[order]


class ShuffledEnv(RecordingEnv):
    layout = ShuffledLayout()


@pytest.mark.parametrize("layout", [Layout(), ShuffledLayout()])
def test_every_joint_has_its_own_oscillator_in_the_segment_layout(layout):
    index = cpg_controller.oscillator_of_action(layout, per_segment=True)
    np.testing.assert_array_equal(index, cpg.segment_osc(layout.arm, layout.segment, layout.kind, 3))
    assert sorted(index) == list(range(30))
    np.testing.assert_array_equal(cpg_controller.oscillator_of_action(layout, False), 2 * layout.arm + layout.kind)


def test_a_layout_missing_a_joint_is_refused():
    class Partial:
        arm, segment, kind = Layout.arm[1:], Layout.segment[1:], Layout.kind[1:]

    with pytest.raises(ValueError, match="one actuator per arm, segment and joint kind"):
        cpg_controller.oscillator_of_action(Partial(), per_segment=True)


@pytest.mark.parametrize("env_class", [RecordingEnv, ShuffledEnv])
def test_parametric_segment_drives_each_joint_from_its_own_oscillator(env_class):
    cfg = OmegaConf.merge(cpg_preset(), {"mode": "parametric_segment", "modulate": "at_reset"})
    env = cpg_controller.wrap(
        env_class(), controller_settings(cfg), env_settings({"name": "brittle_star", "num_arms": 5})
    )
    assert env.action_space.shape == (71,) == (cpg.parametric_segment_size(5, 3),)
    X = np.linspace(-0.5, 0.5, 30)  # a distinct offset per oscillator, no oscillation
    genotype = jnp.concatenate([jnp.zeros(30), jnp.asarray(X), jnp.array([1.0]), jnp.zeros(10)])
    state = rollout(env, [genotype] + [jnp.zeros(71)] * 39)[-1]
    layout = env_class.layout
    expected = X[cpg.segment_osc(layout.arm, layout.segment, layout.kind, 3)]
    np.testing.assert_allclose(state.obs, np.clip(expected, layout.low, layout.high), atol=1e-3)
    assert state.inner.cpg.phase.shape == (30,)


def test_parametric_symmetric_controller():
    every = controller(mode="parametric_symmetric")
    latched = controller(mode="parametric_symmetric", modulate="at_reset")
    assert every.action_space == Box((0.0, 0.0, -1.0, 0.0, -np.pi), (5.0, 1.0, 1.0, 3 * np.pi, np.pi))
    first, other = jnp.array([2.5, 0.3, 0.2, np.pi, 1.0]), jnp.array([9.0, 0.5, -0.1, 1.0, -1.0])
    s_latched = rollout(latched, [first, other])[-1]
    s_every = rollout(every, [first, other])[-1]
    for got, genotype in ((s_latched, first), (s_every, jnp.array([5.0, 0.5, -0.1, 1.0, -1.0]))):  # clipped
        expected = cpg.parametric_symmetric_modulation(genotype, 5)
        for a, b in zip(jax.tree.leaves(got.inner.modulation), jax.tree.leaves(expected), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-6)
    assert s_every.inner.cpg.phase.shape == (10,)


@pytest.mark.parametrize(
    "controller_overrides, env_cfg, fragment",
    [
        (
            {},
            {"name": "cartpole"},
            "controller=cpg needs a brittle star env (env=brittle_star or env=brittle_star_undirected)",
        ),
        (
            {"mode": "walk"},
            {"name": "brittle_star"},
            "controller.mode must be one of leading_arm, parametric, parametric_segment, parametric_symmetric, decentralised",
        ),
        ({"leading_arm": 5}, {"name": "brittle_star"}, "controller.leading_arm must be null or an arm index 0..4"),
        ({"integrator": "rk2"}, {"name": "brittle_star"}, "controller.integrator must be one of euler, rk4"),
        ({}, {"name": "brittle_star", "num_arms": 4}, "controller.mode=leading_arm needs 5 arms"),
        (
            {"mode": "parametric_symmetric"},
            {"name": "brittle_star", "num_arms": 3},
            "controller.mode=parametric_symmetric needs 5 arms, got env.num_arms=3",
        ),
    ],
)
def test_check_names_the_fix(controller_overrides, env_cfg, fragment):
    cfg = OmegaConf.merge(cpg_preset(), controller_overrides)
    problem = cpg_controller.check(controller_settings(cfg), env_settings(env_cfg))
    assert problem is not None and fragment in problem and "\n" not in problem


def test_check_accepts_the_defaults():
    cfg = cpg_preset()
    undirected = env_settings({"name": "brittle_star_undirected", "num_arms": 5})
    assert cpg_controller.check(controller_settings(cfg), undirected) is None
    segment = controller_settings(OmegaConf.merge(cfg, {"mode": "parametric_segment"}))
    assert cpg_controller.check(segment, env_settings({"name": "brittle_star", "num_arms": 3})) is None
