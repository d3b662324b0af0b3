"""MAP-Elites' champion in the algorithm and the CLI: off by default (the update as before); on, its candidates are
rows of the offspring's batch, the search runs as without them (the archive and the emitters see only the offspring),
their episodes count in the env steps, each candidate's fitness is the mean of its rows, and the policy is the
champion; a CLI run ends with it and resumes it exactly."""

import functools
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import algo_settings, make_algo, map_elites
from rlq.algos.qd import champion
from rlq.algos.qd.genotypes import make_genotype, search_frame
from rlq.algos.qd.scoring import make_keyed_scoring_fn, replica_means, replicated
from rlq.errors import ConfigError
from rlq.run.checks.validate import check_run_config
from rlq.run.programs.env_stack import make_env
from tests.helpers import compose_config, quick_sample, run_cli_in_process, run_dirs, run_emitters, stopped_at

SMALL = ("algo=map_elites", "algo.episodes=1", "algo.batch_size=8", "algo.es_fraction=0.5", "algo.es_objective=fitness")
CHAMPION = ("algo.champion.candidates=3", "algo.champion.episodes=2")


def trained(*overrides: str, updates: int = 3, small: tuple[str, ...] = SMALL):
    """The algorithm of ``small`` and ``overrides``, its state after ``updates`` iterations and each one's metrics."""
    algo, update, states, rows = _compiled(small, overrides)
    while len(rows) < updates:  # the iterations run so far are those of a shorter run: continued, not run again
        state, metrics = update(states[-1])
        states.append(state)
        rows.append({name: np.asarray(value) for name, value in metrics.items()})
    return algo, states[updates], rows[:updates]


@functools.cache
def _compiled(small: tuple[str, ...], overrides: tuple[str, ...]):
    """The algorithm, its jitted update, the states after init and after each iteration run so far, and each one's
    metrics: compiled once per test process for the tests that read them (``trained``)."""
    cfg = compose_config(*small, *overrides)
    algo = make_algo(cfg.algo, make_env(cfg), budget_env_steps=10**9)
    options = run_emitters()  # the plain and the champion's searches are compared bit for bit
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams), compiler_options=options)(jax.random.PRNGKey(0))
    return algo, jax.jit(lambda s: algo.update(s, algo.hyperparams), compiler_options=options), [state], []


def assert_same_search(plain_state, state):
    """Archive, emitters' states and key as without the champion: only the env steps differ."""
    same = plain_state.replace(env_steps=state.env_steps)
    for a, b in zip(jax.tree.leaves(same), jax.tree.leaves(state.replace(champion=None)), strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow  # two MAP-Elites runs side by side (~10 s); the champion's choice stays in the quick tier
def test_the_champion_leaves_the_search_as_it_was_and_counts_its_episodes():
    plain, plain_state, plain_rows = trained()
    algo, state, rows = trained(*CHAMPION)
    assert plain_state.champion is None and "champion-fitness" not in plain_rows[-1]
    assert plain.steps_per_update == 8 * 1 * 500
    assert algo.steps_per_update == (8 * 1 + (3 + 1) * 2) * 500  # three elites and the ES mean, two episodes each
    assert_same_search(plain_state, state)  # archive, ES state, key: the champion changes nothing else
    for plain_row, row in zip(plain_rows, rows, strict=True):
        assert set(row) == {*plain_row, "champion-fitness"}
        assert all(np.array_equal(plain_row[k], row[k]) for k in plain_row if k != "env_steps")
        assert row["env_steps"] > plain_row["env_steps"]
    kept = [float(row["champion-fitness"]) for row in rows]
    assert kept == sorted(kept) and float(state.champion.fitness) == kept[-1]


@pytest.mark.parametrize(
    "emitters",
    quick_sample(
        [
            ("algo.es_fraction=0.5", "algo.es_objective=fitness"),
            # CMA-ME's improvement emitters, told their offspring's ranks
            ("algo.emitter=mixed", "algo.cma_emitters=2"),
        ],
        2,
        single=True,
    ),
    ids=["es", "improvement"],
)
def test_one_update_inserts_and_tells_only_the_offspring(emitters):
    small = ("algo=map_elites", "algo.episodes=1", "algo.batch_size=8", *emitters)
    _, plain_state, _ = trained(updates=1, small=small)
    _, state, rows = trained(*CHAMPION, updates=1, small=small)
    assert_same_search(plain_state, state)
    assert int(rows[0]["evaluations"]) == 8  # the offspring's, not the champion's rows


def es_mean(cfg, state) -> jax.Array:
    """The mean ``state``'s ES candidates are drawn around, as a genotype (``EsEmitter.mean``)."""
    genotype = make_genotype(cfg.algo, make_env(cfg))
    centre, scale = search_frame(cfg.algo, genotype.low, genotype.high)
    return jnp.clip(centre + scale * state.es.mean, genotype.low, genotype.high)


def candidate_means(cfg, state, genotypes: jax.Array) -> jax.Array:
    """Each candidate's mean fitness over the rows ``state``'s update scores for it: ``genotypes`` (the fittest elites,
    then the ES mean) each twice (champion.episodes=2 in rows of algo.episodes=1), on the keys after the offspring's."""
    env = make_env(cfg)
    score_rows = make_keyed_scoring_fn(env, make_genotype(cfg.algo, env).apply, 1, descriptor_key=None)
    _, vary_key, _ = jax.random.split(state.key, 3)
    keys = jax.random.split(jax.random.fold_in(vary_key, 3), 2 * len(genotypes))
    fitness, _, _ = jax.jit(score_rows, compiler_options=run_emitters())(replicated(genotypes, 2), keys)
    return replica_means(fitness, 2)


def test_the_champion_is_the_candidate_with_the_best_mean_of_the_archive_the_iteration_starts_with():
    cfg = compose_config(*SMALL, *CHAMPION)
    expected = champion.empty(4)
    for iteration in range(3):
        _, state, _ = trained(*CHAMPION, updates=iteration)  # the state the iteration starts from
        genotypes, valid = champion.fittest(state.archive, 3)  # before the iteration inserts its offspring
        genotypes = jnp.concatenate([genotypes, es_mean(cfg, state)[None]])
        valid = jnp.concatenate([valid, jnp.ones((1,), bool)])
        expected = champion.kept(expected, genotypes, valid, candidate_means(cfg, state, genotypes))
        _, state, _ = trained(*CHAMPION, updates=iteration + 1)  # after its update
        np.testing.assert_array_equal(state.champion.genotype, expected.genotype)
        np.testing.assert_allclose(state.champion.fitness, expected.fitness, rtol=1e-6)
    assert not bool(jnp.all(state.champion.genotype == es_mean(cfg, state)))  # an elite won at last


def test_the_policy_plays_the_champion_not_the_fittest_elite():
    algo, state, _ = trained(*CHAMPION)
    weights = np.asarray(state.champion.genotype)
    flipped = state.replace(archive=state.archive.replace(genotypes=-state.archive.genotypes))  # elites act otherwise
    observations = np.random.default_rng(0).normal(size=(16, 4)).astype(np.float32)
    act = jax.jit(lambda s, obs: algo.policy(s)(obs, jax.random.PRNGKey(0)))
    assert [int(act(flipped, obs)) for obs in observations] == [int(weights @ obs >= 0) for obs in observations]


@pytest.mark.parametrize(
    ("overrides", "fragment"),
    [
        (["algo.champion.candidates=-1"], "algo.champion.candidates must be an integer >= 0, got -1"),
        (["algo.champion.candidates=4", "algo.champion.episodes=0"], "algo.champion.episodes must be an integer >= 1"),
        (
            ["algo.champion.candidates=401"],
            "algo.champion.candidates=401 is more than the archive's 400 cells; give at most 400",
        ),
        (
            ["algo.archive.kind=cvt", "algo.archive.cells=50", "algo.champion.candidates=51"],
            "is more than the archive's 50 cells",
        ),
        (
            ["algo.episodes=4", "algo.champion.candidates=3", "algo.champion.episodes=6"],
            "algo.champion.episodes=6 is not a multiple of algo.episodes=4",
        ),
    ],
)
def test_bad_champion_settings_name_the_fix(overrides, fragment):
    with pytest.raises(ConfigError) as err:
        check_run_config(compose_config(*SMALL, *overrides))
    assert fragment in str(err.value)


def test_the_champion_rows_and_the_offspring_split_over_the_env_devices_together():
    def problem(*overrides: str, shards: int) -> str | None:
        return map_elites.check_env_shards(algo_settings(compose_config(*SMALL, *overrides).algo), shards)

    # 8 offspring and (3 elites and the ES mean) x 2 rows: 16 rows over 4 devices; none without the champion
    assert problem(*CHAMPION, shards=4) is None and problem(shards=8) is None
    assert problem("algo.champion.candidates=2", "algo.champion.episodes=2", shards=4) == (
        "algo.champion's 6 rows (2 candidates and the ES mean, 2 each) join algo.batch_size=8: the 14 rows scored "
        "together split over 4 devices, which does not divide them; set algo.champion.candidates so that "
        "8 + (candidates + 1) x 2 is a multiple of 4"
    )


@pytest.mark.slow  # a CLI run, stopped and resumed (12 s); the champion's update is checked in-process above
def test_cli_run_ends_with_the_champion_and_resumes_it_exactly(workdir, tmp_path):
    from rlq.store import checkpoint

    proc = run_cli_in_process(
        "train",
        "env=cartpole",
        "algo=map_elites",
        "algo.champion.candidates=4",
        "algo.champion.episodes=2",
        "algo.episodes=1",  # conf/tuned/cartpole_map_elites.yaml scores each offspring over 16
        "algo.batch_size=8",
        "budget.env_steps=24000",  # 3 iterations of (8 x 1 + 4 x 2) episodes, each counted at 500 steps
        "log_every_steps=8000",
        "checkpoint.every_steps=1",  # a checkpoint after every chunk but the last
        "eval.episodes=2",
        "video.at_end=false",
        "logger=quiet",
        cwd=workdir,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    train_rows = [r for r in rows if r["kind"] == "train" and r["seed"] == 0]
    assert len(train_rows) == 3 and train_rows[0]["champion-fitness"] is None  # the first iteration had no elite
    assert all(np.isfinite(r["champion-fitness"]) for r in train_rows[1:])
    assert [r for r in rows if r["kind"] == "eval"]
    stopped = stopped_at(run_dir, tmp_path, -1)
    proc = run_cli_in_process("resume", f"run={stopped}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    resumed = checkpoint.leaves(stopped / "checkpoints/final.msgpack")
    for a, b in zip(resumed, checkpoint.leaves(run_dir / "checkpoints/final.msgpack"), strict=True):
        np.testing.assert_array_equal(a, b)  # the champion's genotype and score among them
