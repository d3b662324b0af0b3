"""Augmented random search (algo=random_search algo.variant=ars): the step by hand, the observation
statistics from rollouts, the refusals, and CartPole learned from w = 0."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import algo_settings, ars, random_search
from rlq.envs.wrappers import TimeLimit
from rlq.lib.learning import normalize
from rlq.lib.rollout import evaluate, reference_observation, reset_batch
from rlq.run.programs.env_stack import make_env
from tests.fakes import Target
from tests.helpers import compose_config, train_run


def ars_cfg(*overrides: str):
    return algo_settings(compose_config("algo=random_search", "algo.variant=ars", *overrides).algo)


def test_step_by_hand():
    weights = jnp.zeros(2)
    deltas = jnp.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    plus, minus = jnp.array([3.0, 1.0, 0.0]), jnp.array([1.0, 2.0, 0.0])
    # top 2 by max(plus, minus): directions 0 (3) and 1 (2); returns used 3, 1, 1, 2: std sqrt(0.6875)
    stepped = ars.ars_step(weights, deltas, plus, minus, top=2, step_size=0.02)
    expected = 0.02 / (2 * np.sqrt(0.6875)) * np.array([2.0, -1.0])
    np.testing.assert_allclose(stepped, expected, rtol=1e-6)


def test_equal_returns_do_not_divide_by_zero():
    stepped = ars.ars_step(jnp.ones(2), jnp.eye(2), jnp.ones(2), jnp.ones(2), top=1, step_size=0.1)
    np.testing.assert_allclose(stepped, [1.0, 1.0])


def test_statistics_from_sums_match_the_batch_merge():
    rng = np.random.default_rng(0)
    first, second = rng.normal(2.0, 3.0, (50, 3)), rng.normal(-1.0, 0.5, (70, 3))
    by_batch = normalize.update(normalize.update(normalize.init((3,)), jnp.asarray(first)), jnp.asarray(second))
    stats = normalize.init((3,))
    for batch in (first, second):
        stats = normalize.update_from_sums(stats, len(batch), batch.sum(0), (batch**2).sum(0))
    np.testing.assert_allclose(stats.mean, by_batch.mean, rtol=1e-4)
    np.testing.assert_allclose(normalize.std(stats), normalize.std(by_batch), rtol=1e-3)
    assert float(stats.count) == 120.0
    empty = normalize.update_from_sums(stats, 0.0, jnp.zeros(3), jnp.zeros(3))
    np.testing.assert_allclose(empty.mean, stats.mean)


def test_moments_of_any_leading_shape_fold_in_as_their_totals():
    """A rollout's per-candidate, per-episode moments (ARS) and a batch's totals (ES's scoring) fold in alike."""
    rng = np.random.default_rng(1)
    count, total, squares = rng.integers(1, 9, (4, 2)), rng.normal(size=(4, 2, 3)), rng.random((4, 2, 3))
    per_episode = {"obs_count": jnp.asarray(count, jnp.float32), "obs_sum": total, "obs_sq_sum": squares}
    totals = {name: jnp.asarray(value.sum(axis=(0, 1))) for name, value in per_episode.items()}
    start = normalize.init((3,))
    expected = normalize.update_from_sums(start, count.sum(), total.sum(axis=(0, 1)), squares.sum(axis=(0, 1)))
    for moments in (per_episode, totals):
        folded = normalize.update_from_moments(start, moments)
        for a, b in zip(jax.tree.leaves(folded), jax.tree.leaves(expected), strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-6)


def test_statistics_about_a_reference_keep_a_constant_component_exact():
    """Summed about a reference, a component that never changes keeps its value as mean and normalises to exactly 0
    (raw float32 squares cancel to a rounding, which the std floor turned into inputs of a few units), and the other
    components' spread matches float64's."""
    rng = np.random.default_rng(2)
    batches = [
        np.stack([np.full(n, 8.907), 1.3 + 0.05 * rng.normal(size=n), rng.normal(size=n)], axis=1).astype(np.float32)
        for n in (40_000, 60_000, 50_000)
    ]
    ref = jnp.asarray(batches[0][0])
    stats = normalize.init((3,))
    for batch in batches:
        shifted = jnp.asarray(batch) - ref
        stats = normalize.update_from_sums(stats, len(batch), shifted.sum(0), (shifted**2).sum(0), ref)
    assert float(stats.mean[0]) == float(np.float32(8.907))
    assert float(stats.m2[0]) == 0.0
    fresh = jnp.asarray(batches[1][:5])
    np.testing.assert_array_equal(normalize.normalize(stats, fresh)[:, 0], np.zeros(5, np.float32))
    every = np.concatenate(batches).astype(np.float64)
    np.testing.assert_allclose(normalize.std(stats)[1:], every.std(0)[1:], rtol=1e-4)
    np.testing.assert_allclose(stats.mean[1:], every.mean(0)[1:], rtol=1e-4, atol=1e-4)


def test_rollout_moments_are_the_observations_acted_on():
    """Each episode's count, sum and squares are those of the observations its policy saw, first episode only."""
    env = make_env(compose_config("env=cartpole"))
    key, episodes = jax.random.PRNGKey(3), 3
    record = evaluate(env, lambda obs, k: jnp.int32(1), key, episodes, obs_moments=True)
    np.testing.assert_array_equal(record["obs_count"], record["episode_length"])
    state = reset_batch(env, jax.random.split(key)[0], episodes)
    total, squares = np.zeros((episodes, 4)), np.zeros((episodes, 4))
    running = np.ones(episodes, bool)
    while running.any():
        obs = np.asarray(state.obs)
        total[running] += obs[running]
        squares[running] += obs[running] ** 2
        state = jax.vmap(env.step)(state, jnp.ones(episodes, jnp.int32))
        running &= ~np.asarray(state.done)
    np.testing.assert_allclose(record["obs_sum"], total, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(record["obs_sq_sum"], squares, rtol=1e-5, atol=1e-5)
    ref = reference_observation(env)
    about = evaluate(env, lambda obs, k: jnp.int32(1), key, episodes, obs_moments=True, obs_ref=ref)
    count = np.asarray(about["obs_count"])[:, None]
    np.testing.assert_allclose(about["obs_sum"], total - count * np.asarray(ref), rtol=1e-5, atol=1e-5)
    centred = squares - 2 * np.asarray(ref) * total + count * np.asarray(ref) ** 2
    np.testing.assert_allclose(about["obs_sq_sum"], centred, rtol=1e-4, atol=1e-5)


def test_refusals_name_the_fix():
    env = make_env(compose_config("env=cartpole"))
    assert "algo.ars.top" in random_search.check(ars_cfg("algo.ars.top=40", "algo.ars.directions=8"), env)
    assert "genotype=policy" in random_search.check(ars_cfg("algo.genotype=action"), env)
    assert "algo.variant must be" in random_search.check(ars_cfg("algo.variant=nope"), env)
    assert random_search.check(ars_cfg(), env) is None


class ClampedTarget(Target):
    """Target, as an env that clamps out-of-range actions itself (as the humanoid's MuJoCo motors do)."""

    clamps_actions = True


def test_unclipped_actions_reach_only_an_env_that_clamps_them():
    unclipped = ars_cfg("algo.ars.clip_actions=false", "algo.episodes=1")
    assert "algo.ars.clip_actions=false" in random_search.check(unclipped, make_env(compose_config("env=cartpole")))
    assert "env=humanoid" in random_search.check(unclipped, TimeLimit(Target(), 5))
    assert random_search.check(unclipped, TimeLimit(ClampedTarget(), 5)) is None
    assert random_search.check(ars_cfg("algo.episodes=1"), TimeLimit(Target(), 5)) is None


@pytest.mark.parametrize(("clip", "expected"), [(True, [1.0]), (False, [4.0])])
def test_the_policy_hands_its_raw_output_to_a_clamping_env_when_asked(clip, expected):
    env = TimeLimit(ClampedTarget(), 5)
    cfg = ars_cfg(f"algo.ars.clip_actions={str(clip).lower()}", "algo.episodes=1", "algo.ars.normalize=false")
    algo = random_search.make(cfg, env, 10**4)
    state = algo.init(jax.random.PRNGKey(0), algo.hyperparams)
    state = state.replace(weights=jnp.array([1.5, 2.5]))  # obs (1, 1) -> 4.0, outside the Box's [-1, 1]
    np.testing.assert_allclose(algo.policy(state)(jnp.ones(2), jax.random.PRNGKey(1)), expected)


def test_the_humanoid_clamps_its_actions():
    from rlq.envs.humanoid.env import Humanoid

    assert Humanoid.clamps_actions


def test_candidates_split_over_devices_must_divide():
    assert random_search.check_env_shards(ars_cfg("algo.ars.directions=3"), 4) is not None
    assert random_search.check_env_shards(ars_cfg("algo.ars.directions=4"), 4) is None
    assert random_search.check_env_shards(algo_settings(compose_config("algo=random_search").algo), 3) is None


def test_one_iteration_moves_the_weights_and_counts_the_statistics():
    env = make_env(compose_config("env=cartpole"))
    algo = random_search.make(ars_cfg("algo.episodes=1", "algo.ars.directions=4", "algo.ars.top=2"), env, 10**6)
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    assert float(jnp.abs(state.weights).sum()) == 0.0
    state, metrics = jax.jit(lambda s: algo.update(s, algo.hyperparams))(state)
    assert float(jnp.abs(state.weights).sum()) > 0.0
    assert float(state.obs_stats.count) == float(metrics["env_steps"]) > 0
    action = algo.policy(state)(jnp.ones(4), jax.random.PRNGKey(1))
    assert int(action) in (0, 1)


def test_reward_shift_is_taken_off_every_step_the_search_ranks():
    """CartPole pays 1 per step: shifted by 1, every candidate ranks at 0, so the policy stays where it started
    while the logged return is still the env's."""
    env = make_env(compose_config("env=cartpole"))
    cfg = ars_cfg("algo.episodes=1", "algo.ars.directions=4", "algo.ars.top=2", "algo.ars.reward_shift=1.0")
    algo = random_search.make(cfg, env, 10**6)
    state, metrics = jax.jit(lambda s: algo.update(s, algo.hyperparams))(
        jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    )
    assert float(jnp.abs(state.weights).sum()) == 0.0
    assert float(metrics["generation_max_fitness"]) == 0.0
    assert float(metrics["episode_return"]) > 1.0


@pytest.mark.slow
def test_learns_cartpole(tmp_path):
    result = train_run(
        tmp_path,
        "algo=random_search",
        "algo.variant=ars",
        "algo.episodes=1",
        "algo.ars.directions=8",
        "algo.ars.top=4",
        "num_seeds=2",
        "budget.env_steps=400000",
        "eval.every_steps=0",
    )
    assert np.min(result.eval_return) >= 475, result.line()
