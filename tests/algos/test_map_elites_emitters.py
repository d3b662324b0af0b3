"""MAP-Elites' emitters and CVT archive in the algorithm and the CLI: the default iteration is plain
MAP-Elites as before, mixed batches stay in bounds and only improve the archive, the ES emitter's
candidates join the batch, and a CLI run of algo.emitter=mixed with an ES share on a CVT archive
trains, draws its archive and resumes exactly."""

import functools
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import algo_settings, make_algo, map_elites
from rlq.algos.qd import archive as qa
from rlq.algos.qd import measures, variation
from rlq.algos.qd.genotypes import make_genotype
from rlq.algos.qd.scoring import make_keyed_scoring_fn, with_one_key
from rlq.errors import ConfigError
from rlq.run.checks.validate import check_run_config
from rlq.run.programs.env_stack import make_env
from tests.helpers import (
    compose_config,
    run_cli_in_process,
    run_dirs,
    run_emitters,
    stopped_at,
    updates_that_only_improve_elites,
)

SMALL = ("algo=map_elites", "algo.episodes=1", "algo.batch_size=8")


def plain_map_elites(cfg, env, key: jax.Array, iterations: int) -> qa.Archive:
    """The MAP-Elites iteration before emitters existed, written out: uniform elites, gaussian mutation
    (uniform genotypes while the archive is empty), score, insert; with the same key splits."""
    genotype = make_genotype(cfg.algo, env)
    low, high = jnp.asarray(genotype.low), jnp.asarray(genotype.high)
    grid = map_elites.grid_of(algo_settings(cfg.algo))
    scoring_fn = with_one_key(
        make_keyed_scoring_fn(
            env,
            genotype.apply,
            1,
            descriptor_key=measures.DESCRIPTOR_KEYS["last_obs"],
            fitness="return",
            descriptor_dims=(0, 2),
        )
    )
    batch = int(cfg.algo.batch_size)

    @functools.partial(jax.jit, compiler_options=run_emitters())  # compared bit for bit with the algorithm's
    def step(archive, key):
        key, vary_key, score_key = jax.random.split(key, 3)
        select_key, _, mutate_key, random_key = jax.random.split(vary_key, 4)
        children = variation.gaussian(mutate_key, qa.select(archive, select_key, batch), cfg.algo.sigma, low, high)
        children = jnp.where(jnp.any(archive.filled), children, variation.uniform(random_key, batch, low, high))
        fitness, descriptors, _ = scoring_fn(children, score_key)
        return qa.insert(archive, grid, children, fitness, descriptors), key

    archive = qa.empty(grid, genotype.dim)
    for _ in range(iterations):
        archive, key = step(archive, key)
    return archive


@pytest.mark.slow  # compiles two MAP-Elites updates (6 s)
def test_a_config_without_the_new_keys_runs_plain_map_elites():
    cfg = compose_config(*SMALL)
    assert (cfg.algo.emitter, cfg.algo.archive.kind) == ("gaussian", "grid")
    env = make_env(cfg)
    algo = make_algo(cfg.algo, env, budget_env_steps=10**9)
    options = run_emitters()  # compared bit for bit with plain_map_elites's program
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams), compiler_options=options)(jax.random.PRNGKey(0))
    update = jax.jit(lambda s: algo.update(s, algo.hyperparams), compiler_options=options)
    for _ in range(2):
        state, metrics = update(state)
    assert state.emitter is None and "emitter-restarts" not in metrics
    expected = plain_map_elites(cfg, env, jax.random.PRNGKey(0), 2)
    for name in ("genotypes", "fitness", "descriptors", "filled"):
        np.testing.assert_array_equal(getattr(state.archive, name), getattr(expected, name))
    assert compose_config(*SMALL, "algo.variation=iso_line").algo.emitter == "iso_line"


@pytest.mark.slow
def test_mixed_batches_stay_in_bounds_and_only_improve_the_archive():
    cfg = compose_config(*SMALL, "algo.emitter=mixed", "algo.cma_emitters=2", "algo.cma_sigma=3.0")
    state, metrics = updates_that_only_improve_elites(cfg, 3)
    genotypes = np.asarray(state.archive.genotypes)[np.asarray(state.archive.filled)]
    assert ((genotypes >= -2.0) & (genotypes <= 2.0)).all()
    assert state.emitter.es.mean.shape == (2, 4)  # two CMA-ES of 2 offspring each over 4 weights
    assert int(metrics["evaluations"]) == 3 * 8 and int(metrics["emitter-restarts"]) >= 0


def test_es_candidates_join_the_batch_and_its_mean_follows_the_distance():
    cfg = compose_config(*SMALL, "algo.es_fraction=0.5", "algo.es_sigma=0.5")
    state, metrics = updates_that_only_improve_elites(cfg, 3)
    assert state.es is not None and state.emitter is None
    assert np.abs(np.asarray(state.es.mean)).max() > 0  # told three times, it left the centre
    assert int(metrics["evaluations"]) == 3 * 8
    # the 4 ES candidates are scored with the batch: their distances are the descriptor norms of real episodes
    assert 0 < float(metrics["es-objective-mean"]) <= float(metrics["es-objective-max"]) < 10
    genotypes = np.asarray(state.archive.genotypes)[np.asarray(state.archive.filled)]
    assert ((genotypes >= -2.0) & (genotypes <= 2.0)).all()
    assert compose_config(*SMALL).algo.es_fraction == 0  # no ES emitter unless asked for


def test_turned_offspring_are_their_parents_turned_by_a_whole_non_zero_number_of_arms():
    rotations = jnp.asarray([[0, 1, 2, 3], [1, 2, 3, 0], [2, 3, 0, 1], [3, 0, 1, 2]])
    parents = jnp.tile(jnp.asarray([[0.1, 0.2, 0.3, 0.4]]), (64, 1))
    low, high = jnp.zeros(4), jnp.ones(4)
    children = np.asarray(variation.turned(jax.random.PRNGKey(0), parents, rotations, 1e-6, low, high))
    turned = np.asarray(parents[0])[np.asarray(rotations)]  # (4 turns, 4)
    turns = {int(np.argmin(np.abs(turned - child).sum(axis=1))) for child in children}
    assert turns == {1, 2, 3}  # never the identity, every other turn drawn
    wide = np.asarray(variation.turned(jax.random.PRNGKey(1), parents, rotations, 5.0, low, high))
    assert wide.shape == (64, 4) and ((wide >= 0) & (wide <= 1)).all() and len(np.unique(wide)) > 4


@pytest.mark.parametrize(
    ("overrides", "fragment"),
    [
        (
            ["algo.emitter=cma"],
            "algo.emitter must be one of gaussian, iso_line, improvement, mixed, rotation, got 'cma'",
        ),
        (["algo.emitter=rotation"], "algo.emitter=rotation turns gaits by whole arms: it needs algo.genotype=action"),
        (
            ["algo.emitter=rotation", "algo.rotation_fraction=0.01"],
            "turns no offspring; give a fraction of at least 0.125",
        ),
        (["algo.rotation_fraction=0"], "algo.rotation_fraction must be a number in (0, 1], got 0"),
        (["algo.emitter=mixed", "algo.improvement_fraction=0.05"], "gives 0 improvement offspring; give a fraction"),
        (["algo.emitter=improvement", "algo.cma_emitters=3"], "set algo.cma_emitters to a divisor of 8 up to 4"),
        (["algo.emitter=improvement", "algo.cma_emitters=8"], "need an equal share of at least 2 each"),
        (["algo.improvement_fraction=1.5"], "algo.improvement_fraction must be a number in (0, 1), got 1.5"),
        (["algo.es_fraction=0.1"], "gives the ES emitter 0 offspring; it needs at least 2 (antithetic pairs)"),
        (["algo.es_fraction=1"], "algo.es_fraction must be a number in [0, 1), got 1"),
        (
            ["algo.emitter=improvement", "algo.es_fraction=0.25"],
            "algo.es_fraction=0.25 (2 offspring) and algo.emitter=improvement (8) need more than algo.batch_size=8",
        ),
        (["algo.es_fraction=0.5", "algo.es_objective=novelty"], "algo.es_objective must be one of distance, fitness"),
        (["algo.archive.kind=voronoi"], "algo.archive.kind must be one of grid, cvt, got 'voronoi'"),
        (["algo.archive.kind=cvt", "algo.archive.cvt_samples=100"], "cvt_samples=100 is below algo.archive.cells=400"),
        (
            ["algo.archive.kind=cvt", "algo.descriptor_dims=[0]"],
            "has 1 dimensions but algo.archive.low and high have 2",
        ),
    ],
)
def test_bad_emitter_and_cvt_settings_name_the_fix(overrides, fragment):
    with pytest.raises(ConfigError) as err:
        check_run_config(compose_config(*SMALL, *overrides))
    assert fragment in str(err.value)


@pytest.mark.slow
def test_cli_trains_mixed_emitters_and_an_es_on_a_cvt_archive_and_resumes_exactly(workdir, tmp_path):
    from rlq.store import checkpoint

    args = [
        *SMALL,
        "algo.emitter=mixed",
        "algo.es_fraction=0.25",
        "algo.archive.kind=cvt",
        "algo.archive.cells=50",
        "algo.archive.cvt_samples=2000",
        "algo.heatmap_every=0",
        "budget.env_steps=16000",  # 4 iterations of 8 x 500 steps
        "log_every_steps=4000",
        "checkpoint.every_steps=1",
        "eval.episodes=1",
        "video.at_end=false",
        "logger=quiet",
    ]
    proc = run_cli_in_process("train", *args, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    assert [p.name for p in (run_dir / "figures").glob("*.png")] == ["heatmap_seed0_final.png"]
    rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    train_rows = [r for r in rows if r["kind"] == "train"]
    assert train_rows and all("emitter-restarts" in r and r["archive-occupancy"] > 0 for r in train_rows)
    assert all("es-objective-max" in r for r in train_rows)
    stopped = stopped_at(run_dir, tmp_path, -1)
    proc = run_cli_in_process("resume", f"run={stopped}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    resumed = checkpoint.leaves(stopped / "checkpoints/final.msgpack")
    original = checkpoint.leaves(run_dir / "checkpoints/final.msgpack")
    assert len(original) > 10  # the archive, key, counters, the CMA-ES states and the ES's
    for a, b in zip(resumed, original, strict=True):
        np.testing.assert_array_equal(a, b)
