import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from rlq.envs.wrappers import (
    ActionRepeat,
    AutoReset,
    DiscretizeObservation,
    EpisodeStats,
    ReturnWindow,
    TimeLimit,
    _select,
    window_return,
)
from rlq.lib.rollout import evaluate
from rlq.lib.spaces import Box, Discrete
from tests.fakes import Counter, RandomStart


def stack(env):
    return AutoReset(EpisodeStats(TimeLimit(env, 3)))


def test_time_limit_truncates_and_autoreset_restarts():
    env = stack(Counter())
    state = env.reset(jax.random.PRNGKey(0))
    for _ in range(3):
        state = env.step(state, jnp.array(0))
    assert bool(state.truncated) and not bool(state.terminated)
    assert float(state.info["final_obs"][0]) == 3.0
    assert float(state.obs[0]) == 0.0  # first obs of the next episode
    assert float(state.info["episode_return"]) == 3.0
    assert int(state.info["episode_length"]) == 3
    state = env.step(state, jnp.array(0))
    assert float(state.info["episode_return"]) == 1.0  # counters restarted


def test_termination_is_not_truncation():
    env = stack(Counter())
    state = env.step(env.reset(jax.random.PRNGKey(0)), jnp.array(1))
    assert bool(state.terminated) and not bool(state.truncated)


def test_evaluate_reads_each_first_episode():
    env = stack(Counter())
    record = evaluate(env, lambda obs, key: jnp.array(0), jax.random.PRNGKey(0), num_episodes=4)
    np.testing.assert_array_equal(np.asarray(record["episode_return"]), [3.0] * 4)
    assert bool(np.all(record["finished"]))


class NoisyRandomStart(RandomStart):
    """RandomStart whose rewards are drawn from the state's key, as LunarLander's engine noise is."""

    def step(self, state, action):
        key, sub = jax.random.split(state.key)
        nxt = super().step(state, action)
        return nxt.replace(reward=jax.random.uniform(sub), key=key)


def test_evaluation_steps_trace_no_reset_and_keep_the_first_episodes_numbers():
    base = NoisyRandomStart(reset_cache=False)
    env = AutoReset(EpisodeStats(TimeLimit(base, 6)))

    def policy(obs, key):
        return (jax.random.uniform(key) < 0.3).astype(jnp.int32)

    key = jax.random.PRNGKey(3)
    record = jax.jit(lambda k: evaluate(env, policy, k, num_episodes=16))(key)
    assert base.resets_traced == 1  # the batch's first reset, none inside the steps

    # the same episodes stepped with auto-reset on, as training steps them
    reset_key, run_key = jax.random.split(key)
    state = jax.vmap(env.reset)(jax.random.split(reset_key, 16))
    step_keys = jax.vmap(lambda k: jax.random.split(k, 6), out_axes=1)(jax.random.split(run_key, 16))
    first = np.full(16, np.nan)
    for t in range(6):
        state = jax.vmap(env.step)(state, jax.vmap(policy)(state.obs, step_keys[t]))
        ended = np.asarray(state.done) & np.isnan(first)
        first[ended] = np.asarray(state.info["episode_return"])[ended]
    assert base.resets_traced > 1
    np.testing.assert_array_equal(np.asarray(record["episode_return"]), first.astype(np.float32))


def test_discretize_observation_bins_and_clips():
    env = DiscretizeObservation(stack(Counter()), bins=(4,), low=(0.0,), high=(2.0,))
    assert env.observation_space == Discrete(4)
    assert int(env.index(jnp.array([0.1]))) == 0
    assert int(env.index(jnp.array([1.6]))) == 3
    assert int(env.index(jnp.array([99.0]))) == 3  # clipped into the last bin
    state = env.step(env.reset(jax.random.PRNGKey(0)), jnp.array(0))
    assert state.obs.dtype == jnp.int32


def test_discretize_mixed_radix_is_a_bijection():
    base = Counter()
    base.observation_space = Box((0.0, 0.0), (1.0, 1.0))
    env = DiscretizeObservation(base, bins=(2, 3), low=(0.0, 0.0), high=(1.0, 1.0))
    points = [jnp.array([x, y]) for x in (0.25, 0.75) for y in (0.1, 0.5, 0.9)]
    assert sorted(int(env.index(p)) for p in points) == list(range(6))


def test_cartpole_adapter_vmaps():
    from rlq.envs.cartpole import CartPole

    env = stack(CartPole())
    states = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(0), 16))
    states = jax.jit(jax.vmap(env.step))(states, jnp.zeros(16, jnp.int32))
    assert states.obs.shape == (16, 4)
    assert np.all(np.asarray(states.reward) == 1.0)


def test_action_repeat_sums_rewards_and_stops_at_the_end():
    base = Counter()
    base.max_episode_steps = 10
    env = ActionRepeat(base, 4)
    assert env.max_episode_steps == 3
    state = env.step(env.reset(jax.random.PRNGKey(0)), jnp.array(0))
    assert float(state.reward) == 4.0 and int(state.inner) == 4
    ended = env.step(env.reset(jax.random.PRNGKey(0)), jnp.array(1))
    assert bool(ended.terminated) and float(ended.reward) == 1.0 and int(ended.inner) == 1


def test_action_repeat_from_config_counts_decisions():
    from rlq.run.programs.env_stack import make_env
    from tests.helpers import compose_config

    env = make_env(compose_config("env=cartpole", "env.action_repeat=5"))
    assert env.max_episode_steps == 100
    state = jax.jit(env.step)(env.reset(jax.random.PRNGKey(0)), jnp.array(0))
    assert float(state.info["episode_return"]) == 5.0


@struct.dataclass
class SharedBuffers:
    """Stands in for MJX data: per-env ``qpos`` and a ``buffer`` its ``where`` never selects (as
    MuJoCo Warp's contact buffer, shared by every env of a batch)."""

    qpos: jax.Array
    buffer: jax.Array

    def where(self, done, other):
        return self.replace(qpos=jnp.where(done, other.qpos, self.qpos))


def test_select_lets_mjx_data_merge_itself():
    stepped = {"data": SharedBuffers(jnp.ones(3), jnp.full(4, 7.0)), "t": jnp.asarray(5)}
    first = {"data": SharedBuffers(jnp.zeros(3), jnp.zeros(4)), "t": jnp.asarray(0)}
    out = _select(jnp.asarray(True), first, stepped)
    np.testing.assert_array_equal(out["data"].qpos, np.zeros(3))
    np.testing.assert_array_equal(out["data"].buffer, np.full(4, 7.0))  # kept, not selected
    assert int(out["t"]) == 0
    kept = _select(jnp.asarray(False), first, stepped)
    np.testing.assert_array_equal(kept["data"].qpos, np.ones(3))


def test_return_window_keeps_the_latest_episodes_of_the_batch():
    # env 0 ends episodes of return 2 at steps 2, 4, 6 (ring of 2 keeps the last two);
    # env 1 ends one of return 1 at step 1 and one of return 5 at step 6 (time limit 5)
    env = ReturnWindow(AutoReset(EpisodeStats(TimeLimit(Counter(), 5))), 2)
    state = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(0), 2))
    step = jax.jit(jax.vmap(env.step))
    assert np.isnan(float(window_return([state.extras["return_window"]], 2)))
    for actions in [[0, 1], [1, 0], [0, 0], [1, 0], [0, 0], [1, 0]]:
        state = step(state, jnp.array(actions))
    window = state.extras["return_window"]
    np.testing.assert_array_equal(np.asarray(window["count"]), [3, 2])
    np.testing.assert_array_equal(np.sort(np.asarray(window["ended"][0])), [4, 6])  # step 2's was overwritten
    # the last 2 of the batch: both ended at step 6 (returns 2 and 5); the last 3 add step 4's 2
    assert float(window_return([window], 2)) == 3.5
    assert float(window_return([window], 3)) == 3.0
    assert float(window_return([window], 4)) == (2 + 2 + 5 + 1) / 4  # env 0's step-2 episode is gone


class PairedCounter(Counter):
    """A Counter whose ``step_and_reset`` marks the states it returns, as a lockstep env computes both at once."""

    def step_and_reset(self, state, action, key):
        nxt, fresh = super().step_and_reset(state, action, key)
        return nxt.replace(reward=nxt.reward + 10.0), fresh.replace(obs=fresh.obs - 1.0)


def test_autoreset_asks_for_the_step_and_the_reset_together_through_the_wrappers():
    env = stack(PairedCounter())
    state = env.reset(jax.random.PRNGKey(0))
    for _ in range(3):
        state = env.step(state, jnp.array(0))
    assert float(state.info["episode_return"]) == 33.0  # the env's own pair, through EpisodeStats
    assert float(state.obs[0]) == -1.0  # the new episode's first obs from the pair
    assert int(state.extras["t"]) == 0 and int(state.extras["episode_length"]) == 0
    assert bool(state.truncated)  # TimeLimit still counts the steps of the pair
    # an evaluation starts no new episode, so it asks for the step alone
    record = evaluate(env, lambda obs, key: jnp.array(0), jax.random.PRNGKey(0), num_episodes=2)
    np.testing.assert_array_equal(np.asarray(record["episode_return"]), [3.0] * 2)
