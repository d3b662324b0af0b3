"""Evolution strategies (evosax): OpenAI-ES's step by hand, learning CartPole, the CLI end to end; keep=mean's mean
scored as rows of the candidates' batch, the search as without it."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import algo_settings, es
from rlq.algos.qd.genotypes import make_genotype
from rlq.algos.qd.scoring import keep_best, make_keyed_scoring_fn, with_one_key
from rlq.config.compose import compose
from rlq.lib.carry import strongly_typed
from rlq.run.checks.validate import check_run_config
from rlq.run.programs.env_stack import make_env
from rlq.run.train import train
from tests.helpers import leaf_types, quick_sample, run_cli_in_process, run_dirs, stopped_at


def algo_cfg(**overrides):
    return algo_settings(compose(["algo=es", *[f"algo.{k}={v}" for k, v in overrides.items()]]).algo)


def test_open_es_step_is_adams_first_step_on_the_centered_rank_gradient():
    cfg = algo_cfg(strategy="open_es", population=4, sigma=0.5, lr=0.1)
    strategy, params = es.make_strategy(cfg, 2)
    mean = jnp.array([1.0, -1.0])
    state = strategy.init(jax.random.PRNGKey(0), mean, params)
    x, state = strategy.ask(jax.random.PRNGKey(1), state, params)
    fitness = -np.sum(np.asarray(x) ** 2, axis=1)  # rlq maximises; evosax is told minus the fitness
    state, _ = strategy.tell(jax.random.PRNGKey(2), x, -jnp.asarray(fitness), state, params)
    z = (np.asarray(x) - np.asarray(mean)) / 0.5
    np.testing.assert_allclose(z[:2], -z[2:], atol=1e-6)  # antithetic pairs
    ranks = np.argsort(np.argsort(-fitness))  # rank 0 = best (lowest told value)
    shaped = ranks / 3 - 0.5
    grad = shaped @ z / (4 * 0.5)
    expected = np.asarray(mean) - 0.1 * np.sign(grad)  # Adam's first step: lr * g / |g|
    np.testing.assert_allclose(np.asarray(state.mean), expected, atol=1e-5)
    assert np.all(np.abs(expected - 0.0) <= np.abs(np.asarray(mean)))  # it moved toward the optimum at 0


@pytest.mark.slow
@pytest.mark.parametrize("strategy", es.STRATEGIES)
def test_each_strategy_runs_generations_and_keeps_the_best(strategy):
    env = make_env(compose(["env=cartpole"]))
    algo = es.make(algo_cfg(strategy=strategy, population=6, episodes=1), env, budget_env_steps=10**9)
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    state, metrics = jax.jit(lambda s: jax.lax.scan(lambda s, _: algo.update(s, algo.hyperparams), s, None, length=3))(
        state
    )
    best = np.asarray(metrics["best_fitness"])
    np.testing.assert_allclose(best, np.maximum.accumulate(np.asarray(metrics["generation_max_fitness"])))
    assert int(state.generation) == 3 and float(state.best_fitness) == best[-1]


@pytest.mark.parametrize("strategy", quick_sample(es.STRATEGIES, 3))
def test_the_state_keeps_its_types_through_a_generation(strategy):
    """A state whose types change after one update makes a jitted update compile twice. The jitted init's state and
    the jitted update's after it, of the generations the tests below compare (``generations``: compiled once)."""
    _, states, _ = generations(strategy, "candidate")
    state, updated = states[0], states[1]
    assert leaf_types(updated) == leaf_types(state)


@pytest.mark.parametrize("strategy", es.STRATEGIES)
def test_init_starts_the_search_at_the_width_it_is_given(strategy):
    """``sigma`` is init's hyperparameter as the update's (a sweep's member starts at its own width); the other params
    are those made outside the program (SNES's ``lr_std_init``, which its state keeps)."""
    env = make_env(compose(["env=cartpole"]))
    algo = es.make(algo_cfg(strategy=strategy, population=6, episodes=1), env, budget_env_steps=10**9)
    at = jax.jit(algo.init)(jax.random.PRNGKey(0), {**algo.hyperparams, "sigma": np.float32(0.3)})
    own = es.make(algo_cfg(strategy=strategy, population=6, episodes=1, sigma=0.3), env, budget_env_steps=10**9)
    expected = jax.jit(lambda k: own.init(k, own.hyperparams))(jax.random.PRNGKey(0))
    np.testing.assert_allclose(np.asarray(at.es.std), 0.3, rtol=1e-7)
    for a, b in zip(jax.tree.leaves(at), jax.tree.leaves(expected), strict=True):
        np.testing.assert_array_equal(a, b)


def test_check_names_the_strategies_and_the_even_population():
    env = make_env(compose(["env=cartpole"]))
    assert "algo.strategy must be one of open_es, cma_es, snes" in es.check(algo_cfg(strategy="pso"), env)
    assert "must be even" in es.check(algo_cfg(population=5), env)
    assert es.check(algo_cfg(strategy="snes", population=5), env) is None


@pytest.mark.slow
@pytest.mark.parametrize("normalize", [False, True])
def test_cli_end_to_end_and_resume_continues_exactly(workdir, tmp_path, normalize):
    """evosax's state is checkpointed (and the observation statistics, with algo.normalize): a run resumed from an
    earlier checkpoint ends where the whole run ended."""

    from rlq.store import checkpoint

    args = [
        "algo=es",
        "algo.strategy=cma_es",
        "algo.population=4",
        "algo.episodes=1",
        f"algo.normalize={str(normalize).lower()}",
        "budget.env_steps=8000",
        "log_every_steps=2000",
        "checkpoint.every_steps=1",
        "eval.episodes=2",
        "video.at_end=false",
        "logger=quiet",
    ]
    proc = run_cli_in_process("train", *args, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    stopped = stopped_at(run_dir, tmp_path, 0)
    proc = run_cli_in_process("resume", f"run={stopped}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    resumed = checkpoint.leaves(stopped / "checkpoints/final.msgpack")
    original = checkpoint.leaves(run_dir / "checkpoints/final.msgpack")
    for a, b in zip(resumed, original, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow
def test_tuned_open_es_solves_cartpole(tmp_path):
    cfg = compose(["algo=es", "num_seeds=2", "eval.every_steps=0", "logger=quiet"])
    check_run_config(cfg)
    result = train(cfg, tmp_path)
    assert np.mean(result.eval_return) >= 475, result.line()


def test_keep_mean_scores_the_distribution_mean_and_keeps_the_best_one():
    """keep=mean: the kept genotype is a mean the strategy sampled around, and best_fitness is the best of the
    means' own scores (its mean_episodes), never a candidate's."""
    env = make_env(compose(["env=cartpole"]))
    cfg = algo_cfg(strategy="snes", population=6, episodes=1, keep="mean", mean_episodes=3)
    algo = es.make(cfg, env, budget_env_steps=10**9)
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    means, rows = [], []
    update = jax.jit(lambda s: algo.update(s, algo.hyperparams))
    for _ in range(3):
        means.append(np.asarray(state.es.mean))
        state, metrics = update(state)
        rows.append({k: float(v) for k, v in metrics.items()})
    best = int(np.argmax([row["mean_fitness"] for row in rows]))
    np.testing.assert_allclose(np.asarray(state.best_params), np.clip(means[best], -2.0, 2.0))
    assert float(state.best_fitness) == max(row["mean_fitness"] for row in rows)
    assert algo.steps_per_update == (6 * 1 + 3) * env.max_episode_steps


def test_check_names_the_keep_choices():
    env = make_env(compose(["env=cartpole"]))
    assert "algo.keep must be one of candidate, mean" in es.check(algo_cfg(keep="best"), env)
    assert "algo.mean_episodes" in es.check(algo_cfg(keep="mean", mean_episodes=0), env)
    assert es.check(algo_cfg(keep="mean", episodes=4, mean_episodes=6), env) == (
        "algo.mean_episodes=6 is not a multiple of algo.episodes=4 (algo.keep=mean plays the mean's episodes in "
        "groups of algo.episodes, beside the candidates); give a multiple of 4"
    )
    assert es.check(algo_cfg(keep="mean", episodes=4, mean_episodes=8), env) is None
    assert es.check(algo_cfg(episodes=4, mean_episodes=6), env) is None  # keep=candidate: not read


@functools.cache
def generations(strategy: str, keep: str, updates: int = 3):
    """Six candidates of two CartPole episodes (and the mean on four, with keep=mean): the algorithm, its state
    before each update and after the last, and each update's metrics."""
    env = make_env(compose(["env=cartpole"]))
    cfg = algo_cfg(strategy=strategy, population=6, episodes=2, keep=keep, mean_episodes=4)
    algo = es.make(cfg, env, budget_env_steps=10**9)
    update = jax.jit(lambda s: algo.update(s, algo.hyperparams))
    states, rows = [jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))], []
    for _ in range(updates):
        state, metrics = update(states[-1])
        states.append(state)
        rows.append({name: np.asarray(value) for name, value in metrics.items()})
    return algo, states, rows


def main_update(cfg, env):
    """``algo.keep=candidate``'s update as main had it before keep=mean's mean joined the candidates' batch (e7e2740):
    the candidates scored on the update's third key, split into one per candidate (``with_one_key``). The strategy is
    made in the update, as the update makes it from its hyperparameters (evosax's CMA-ES and SNES weights, made
    outside a trace, differ from the compiled ones in the last bits)."""
    genotype = make_genotype(cfg, env)
    low, high = jnp.asarray(genotype.low), jnp.asarray(genotype.high)
    centre, scale = es.search_frame(cfg, genotype.low, genotype.high)
    scoring_fn = with_one_key(
        make_keyed_scoring_fn(env, genotype.apply, cfg.episodes, descriptor_key=None, fitness=cfg.fitness)
    )

    def update(state: es.EsState) -> tuple[es.EsState, dict]:
        strategy, params = es.make_strategy(cfg, genotype.dim, float(cfg.lr), float(cfg.sigma))
        key, ask_key, score_key, tell_key = jax.random.split(state.key, 4)
        candidates, es_state = strategy.ask(ask_key, state.es, params)
        scored = jnp.clip(centre + scale * candidates, low, high)
        fitness, _, extras = scoring_fn(scored, score_key)
        es_state = strongly_typed(strategy.tell(tell_key, candidates, -fitness, es_state, params)[0])
        best_params, best_fitness, env_steps, metrics = keep_best(
            scored, fitness, extras, state.best_params, state.best_fitness, state.env_steps
        )
        return es.EsState(es_state, best_params, best_fitness, key, env_steps, state.generation + 1), metrics

    return update


@pytest.mark.parametrize("strategy", quick_sample(es.STRATEGIES, 3))
def test_keep_candidate_generations_are_mains_bit_for_bit(strategy):
    """The default (CartPole's recipe) plays and keeps what it did before: every leaf of the state and every metric
    of three generations is main's update's."""
    algo, states, rows = generations(strategy, "candidate")
    env = make_env(compose(["env=cartpole"]))
    update = jax.jit(main_update(algo_cfg(strategy=strategy, population=6, episodes=2), env))
    state = states[0]
    for expected, row in zip(states[1:], rows, strict=True):
        state, metrics = update(state)
        for a, b in zip(jax.tree.leaves(state), jax.tree.leaves(expected), strict=True):
            np.testing.assert_array_equal(a, b)
        assert set(metrics) == set(row) and all(np.array_equal(metrics[k], row[k]) for k in row)


@pytest.mark.parametrize("strategy", quick_sample(es.STRATEGIES, 3))
def test_keep_mean_leaves_the_search_as_it_was_and_tells_only_the_population(strategy):
    """The mean's rows are scored beside the candidates but never told: the strategy's state, the key and the
    candidates' metrics are keep=candidate's bit for bit; the env steps count the mean's episodes too."""
    _, plain, plain_rows = generations(strategy, "candidate")
    _, states, rows = generations(strategy, "mean")
    searched = [jax.tree.leaves((state.es, state.key)) for state in (plain[-1], states[-1])]
    for a, b in zip(*searched, strict=True):
        np.testing.assert_array_equal(a, b)
    for plain_row, row in zip(plain_rows, rows, strict=True):
        assert set(row) == {*plain_row, "mean_fitness"}
        for name in ("generation_max_fitness", "generation_mean_fitness", "episode_return", "episode_length"):
            np.testing.assert_array_equal(plain_row[name], row[name])
    more = [
        int(row["env_steps"]) - int(plain_row["env_steps"]) for plain_row, row in zip(plain_rows, rows, strict=True)
    ]
    mean_steps = np.diff([0, *more])  # each generation's steps of the mean's four episodes
    assert (mean_steps >= 4).all() and (mean_steps <= 4 * 500).all()


def test_the_strategy_is_told_the_population_alone(monkeypatch):
    told = []
    make_strategy = es.make_strategy

    def recording(*args, **kwargs):
        strategy, params = make_strategy(*args, **kwargs)
        tell = strategy.tell

        def tell_recorded(key, x, fitness, state, params):
            told.append((x.shape, fitness.shape))
            return tell(key, x, fitness, state, params)

        object.__setattr__(strategy, "tell", tell_recorded)
        return strategy, params

    monkeypatch.setattr(es, "make_strategy", recording)
    env = make_env(compose(["env=cartpole"]))
    algo = es.make(algo_cfg(strategy="snes", population=6, episodes=2, keep="mean", mean_episodes=8), env, 10**9)
    jax.eval_shape(algo.update, jax.eval_shape(algo.init, jax.random.PRNGKey(0), algo.hyperparams), algo.hyperparams)
    assert told == [((6, 4), (6,))]  # four rows of the mean's were scored beside them


@pytest.mark.parametrize("strategy", quick_sample(["open_es", "snes"], 2))
def test_the_mean_fitness_is_the_mean_of_its_rows(strategy):
    """Each generation scores the mean as mean_episodes / episodes rows (two of two episodes), each on a key of its
    own split from the update's fifth key, its fitness the mean of theirs."""
    algo, states, rows = generations(strategy, "mean")
    env = make_env(compose(["env=cartpole"]))
    cfg = algo_cfg(strategy=strategy, population=6, episodes=2, keep="mean", mean_episodes=4)
    score_rows = jax.jit(make_keyed_scoring_fn(env, make_genotype(cfg, env).apply, 2, descriptor_key=None))
    for state, row in zip(states[:-1], rows, strict=True):  # the state each update started from
        mean = jnp.clip(state.es.mean, -2.0, 2.0)  # a policy's weights: searched as they are
        keys = jax.random.split(jax.random.split(state.key, 5)[4], 2)
        fitness, _, _ = score_rows(jnp.stack([mean, mean]), keys)
        np.testing.assert_allclose(row["mean_fitness"], fitness.mean(), rtol=1e-6)
    assert algo.steps_per_update == (6 * 2 + 4) * env.max_episode_steps


def test_the_mean_rows_and_the_candidates_split_over_the_env_devices_together():
    def problem(shards: int, **overrides) -> str | None:
        return es.check_env_shards(algo_cfg(population=8, episodes=4, **overrides), shards)

    assert problem(4) is None and problem(4, mean_episodes=6) is None  # keep=candidate: no rows of the mean
    assert problem(4, keep="mean", mean_episodes=16) is None  # 8 candidates and 4 rows of the mean: 12 rows
    assert problem(4, keep="mean", mean_episodes=8) == (
        "algo.keep=mean's 2 rows (algo.mean_episodes=8 in groups of algo.episodes=4) join algo.population=8: the 10 "
        "rows scored together split over 4 devices, which does not divide them; set algo.mean_episodes so that 8 + "
        "mean_episodes / 4 is a multiple of 4"
    )


def test_a_constant_action_is_searched_in_its_box_mapped_to_unit_range():
    cfg = algo_cfg(genotype="action")
    low, high = np.array([0.0, -np.pi, 0.0]), np.array([1.0, np.pi, 3 * np.pi])
    centre, scale = es.search_frame(cfg, low, high)
    np.testing.assert_allclose(np.asarray(centre), [0.5, 0.0, 1.5 * np.pi], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(centre - scale), low, atol=1e-6)
    np.testing.assert_allclose(np.asarray(centre + scale), high, rtol=1e-6)
    centre, scale = es.search_frame(algo_cfg(), low, high)  # a policy's weights: as they are
    assert not np.asarray(centre).any() and (np.asarray(scale) == 1).all()


def test_normalize_is_refused_where_there_is_no_policy_to_read_observations():
    env = make_env(compose(["env=cartpole"]))
    assert es.check(algo_cfg(normalize=True, genotype="action"), env) == (
        "algo.normalize=true normalises a policy's observations: use algo.genotype=policy (or algo.normalize=false)"
    )
    assert es.check(algo_cfg(normalize=True), env) is None


def test_normalize_counts_every_observation_acted_on_and_keeps_the_statistics_the_kept_policy_was_scored_with():
    """Each generation folds in the observations of every episode it played (the candidates' and the mean's), so the
    statistics count exactly the env steps played; the kept genotype carries the statistics it was scored with."""
    env = make_env(compose(["env=cartpole"]))
    cfg = algo_cfg(strategy="snes", population=6, episodes=2, keep="mean", mean_episodes=4, normalize=True)
    algo = es.make(cfg, env, budget_env_steps=10**9)
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    update = jax.jit(lambda s: algo.update(s, algo.hyperparams))
    assert float(state.obs_stats.count) == 0.0
    for _ in range(4):
        before = state
        state, metrics = update(state)
        assert float(state.obs_stats.count) == int(metrics["env_steps"])
        improved = float(state.best_fitness) > float(before.best_fitness)
        expected = before.obs_stats if improved else before.kept_stats
        for a, b in zip(jax.tree.leaves(state.kept_stats), jax.tree.leaves(expected), strict=True):
            np.testing.assert_array_equal(a, b)
    assert float(np.max(np.abs(np.asarray(state.obs_stats.mean)))) > 0.0


def test_the_kept_policy_acts_on_normalised_observations():
    env = make_env(compose(["env=cartpole"]))
    cfg = algo_cfg(strategy="open_es", population=4, episodes=1, normalize=True, bias=False)
    algo = es.make(cfg, env, budget_env_steps=10**9)
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    stats = state.kept_stats.replace(
        mean=jnp.array([1.0, 0.0, 0.0, 0.0]), m2=jnp.array([4.0, 1.0, 1.0, 1.0]), count=jnp.float32(1.0)
    )
    weights = jnp.array([1.0, 0.0, 0.0, 0.0])  # the action's sign follows the first component alone
    state = state.replace(best_params=weights, kept_stats=stats)
    act = algo.policy(state)
    key = jax.random.PRNGKey(1)
    # raw 0.5 is below the mean 1.0: normalised it is negative, where the raw observation would be positive
    normalised = int(act(jnp.array([0.5, 0.0, 0.0, 0.0]), key))
    raw = int(make_genotype(cfg, env).policy(weights)(jnp.array([0.5, 0.0, 0.0, 0.0]), key))
    assert normalised != raw


class _Recording:
    """An evosax strategy that records the fitness it is told (evosax minimises: minus the told fitness)."""

    def __init__(self, strategy, told: list):
        self._strategy, self._told = strategy, told

    def __getattr__(self, name):
        return getattr(self._strategy, name)

    def tell(self, key, population, fitness, state, params):
        self._told.append(-np.asarray(fitness))
        return self._strategy.tell(key, population, fitness, state, params)


@pytest.mark.parametrize("shift", quick_sample([0.5, 0.0, 1.0], 3))
def test_reward_shift_is_taken_off_every_step_of_what_the_strategy_is_told(monkeypatch, shift):
    """CartPole pays 1 per step, so a candidate's return is its length: shifted by s the strategy is told (1 - s) x
    the return, while the policy is still kept by its return."""
    told: list = []
    make_strategy = es.make_strategy

    def recording(*args, **kwargs):
        strategy, params = make_strategy(*args, **kwargs)
        return _Recording(strategy, told), params

    monkeypatch.setattr(es, "make_strategy", recording)
    env = make_env(compose(["env=cartpole"]))
    algo = es.make(algo_cfg(strategy="open_es", population=6, episodes=1, reward_shift=shift), env, 10**9)
    state, metrics = algo.update(algo.init(jax.random.PRNGKey(0), algo.hyperparams), algo.hyperparams)
    (fitness,) = told
    if shift == 1.0:
        np.testing.assert_array_equal(fitness, np.zeros(6))
    else:
        returns = fitness / (1.0 - shift)
        assert returns.min() >= 8.0 and float(metrics["generation_max_fitness"]) == pytest.approx(returns.max())
    assert float(state.best_fitness) == float(metrics["generation_max_fitness"]) > 8.0


def test_reward_shift_needs_a_return_fitness():
    env = make_env(compose(["env=cartpole"]))
    assert es.check(algo_cfg(reward_shift=5.0, fitness="distance"), env) == (
        "algo.reward_shift subtracts a bonus per step from returns, and algo.fitness=distance is not a return: use "
        "algo.fitness=return (or algo.reward_shift=0)"
    )
