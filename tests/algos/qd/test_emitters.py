"""CMA-ME's improvement emitters: offspring shape and bounds, the improvement ranking on a hand-made
archive, and restarts of the emitters that found nothing."""

import jax
import jax.numpy as jnp
import numpy as np

from rlq.algos.qd import archive as qa
from rlq.algos.qd.emitters import IMPROVES, INVALID, NEW_CELL, NO_GAIN, ImprovementEmitter, improvement_ranks

LOW, HIGH = jnp.array([0.0, -1.0, 0.0]), jnp.array([1.0, 1.0, 3.0])
LINE = qa.Grid((4,), (0.0,), (4.0,))  # cell k holds descriptors in [k, k + 1)


def archive_of(fitness: list[float]) -> qa.Archive:
    """A 4-cell archive on LINE with these elite fitnesses (-inf: empty); elite k's genotype is (k, 0, 0)."""
    fit = jnp.asarray(fitness, jnp.float32)
    return qa.Archive(
        genotypes=jnp.zeros((4, 3)).at[:, 0].set(jnp.arange(4.0) / 4),
        fitness=fit,
        descriptors=jnp.arange(4.0)[:, None] + 0.5,
        filled=jnp.isfinite(fit),
    )


def test_offspring_have_the_batch_shape_and_stay_in_bounds():
    emitter = ImprovementEmitter(emitters=3, population=4, sigma=5.0, low=LOW, high=HIGH)
    state = jax.jit(emitter.init)(jax.random.PRNGKey(0))
    offspring = np.asarray(jax.jit(emitter.ask)(state, jax.random.PRNGKey(1)))
    assert offspring.shape == (12, 3) == (emitter.batch, 3)
    assert (offspring >= np.asarray(LOW)).all() and (offspring <= np.asarray(HIGH)).all()
    assert (offspring == np.asarray(LOW)).any() and (offspring == np.asarray(HIGH)).any()  # sigma 5 clips
    np.testing.assert_allclose(state.es.mean, np.broadcast_to([0.5, 0.0, 1.5], (3, 3)))  # the bounds' centre


def test_new_cells_rank_first_by_fitness_then_improvements_by_gain():
    archive = archive_of([1.0, 5.0, -jnp.inf, -jnp.inf])
    #              new,  new,  +3,   +0.5, -1,   invalid, -0.5
    fitness = jnp.array([-3.0, 0.0, 4.0, 5.5, 4.0, jnp.nan, 0.5])
    cells = jnp.array([2, 3, 0, 1, 1, 0, 0])
    ranks, status = improvement_ranks(fitness, cells, archive)
    assert status.tolist() == [NEW_CELL, NEW_CELL, IMPROVES, IMPROVES, NO_GAIN, INVALID, NO_GAIN]
    assert ranks.tolist() == [1, 0, 2, 3, 5, 6, 4]


def told(emitter, state, fitness, descriptors, before, after):
    offspring = emitter.ask(state, jax.random.PRNGKey(2))
    tell = jax.jit(lambda s, key, x, f, d, b, a: emitter.tell(s, key, x, f, d, LINE, b, a))
    return tell(
        state, jax.random.PRNGKey(3), offspring, jnp.asarray(fitness), jnp.asarray(descriptors)[:, None], before, after
    )


def test_an_emitter_that_improves_nothing_restarts_at_a_random_elite():
    emitter = ImprovementEmitter(emitters=2, population=3, sigma=0.3, low=LOW, high=HIGH)
    state = emitter.init(jax.random.PRNGKey(0))
    archive = archive_of([1.0, 5.0, -jnp.inf, 2.0])
    # emitter 0's offspring beat nothing (cells 0, 1, 3 below their elites); emitter 1's second reaches empty cell 2
    fitness = [0.0, 4.0, 1.0, 0.0, 0.0, 0.0]
    descriptors = [0.5, 1.5, 3.5, 0.5, 2.5, 1.5]
    new = told(emitter, state, fitness, descriptors, archive, archive)
    assert int(new.restarts) == 1
    elites = np.asarray(archive.genotypes)[np.asarray(archive.filled)]
    assert any(np.allclose(new.es.mean[0], elite) for elite in elites)  # restarted around an elite
    assert float(new.es.std[0]) == np.float32(0.3) and int(new.es.generation_counter[0]) == 0
    assert int(new.es.generation_counter[1]) == 1  # emitter 1 was told and keeps its search
    assert not any(np.allclose(new.es.mean[1], elite) for elite in elites)


def test_emitters_restart_at_the_centre_while_the_archive_is_empty():
    emitter = ImprovementEmitter(emitters=2, population=2, sigma=0.3, low=LOW, high=HIGH)
    state = emitter.init(jax.random.PRNGKey(0))
    empty = archive_of([-jnp.inf] * 4)
    new = told(emitter, state, [jnp.nan] * 4, [0.5] * 4, empty, empty)  # nothing valid, nothing inserted
    assert int(new.restarts) == 2
    np.testing.assert_allclose(new.es.mean, np.broadcast_to([0.5, 0.0, 1.5], (2, 3)))
    assert np.isfinite(np.asarray(new.es.C)).all()
