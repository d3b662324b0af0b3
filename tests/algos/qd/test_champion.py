"""The champion kept by re-evaluation: the best re-scored candidate, not the fittest elite; empty cells never win;
only a strictly higher re-evaluated mean replaces it; each candidate's rows are averaged; the policy plays the
fittest elite until one is scored."""

import jax.numpy as jnp
import numpy as np

from rlq.algos.qd import champion
from rlq.algos.qd.archive import Archive
from rlq.algos.qd.scoring import replica_means, replicated

#: six cells: the archive's fitness ranks cell 0 first, but the stub's re-evaluation (a genotype's first number)
#: ranks cell 1 first; the empty cells 3 and 5 hold a genotype the re-evaluation would rank above all
FIRST = jnp.array([1.0, 3.0, 2.0, 9.0, 0.5, 9.0])
ARCHIVE = Archive(
    genotypes=jnp.stack([FIRST, -FIRST], axis=1),
    fitness=jnp.array([10.0, 9.0, 8.0, -jnp.inf, 7.0, -jnp.inf]),
    descriptors=jnp.zeros((6, 2)),
    filled=jnp.array([True, True, True, False, True, False]),
)


def rescored(held: champion.Champion, genotypes: jnp.ndarray, valid: jnp.ndarray) -> champion.Champion:
    """``held`` after a re-evaluation whose fresh episodes give each genotype its first number."""
    return champion.kept(held, genotypes, valid, genotypes[:, 0])


def test_the_champion_is_the_best_rescored_candidate_not_the_fittest_elite():
    genotypes, valid = champion.fittest(ARCHIVE, 3)
    np.testing.assert_array_equal(genotypes[:, 0], [1.0, 3.0, 2.0])  # cells 0, 1, 2 by the archive's fitness
    kept = rescored(champion.empty(2), genotypes, valid)
    np.testing.assert_array_equal(kept.genotype, [3.0, -3.0])  # cell 1's elite, while cell 0's is the fittest
    assert float(kept.fitness) == 3.0


def test_empty_cells_are_scored_but_never_win():
    genotypes, valid = champion.fittest(ARCHIVE, 5)  # four elites and an empty cell
    assert valid.tolist() == [True, True, True, True, False] and float(genotypes[4, 0]) == 9.0
    np.testing.assert_array_equal(rescored(champion.empty(2), genotypes, valid).genotype, [3.0, -3.0])
    empty_archive = ARCHIVE.replace(filled=jnp.zeros(6, bool), fitness=jnp.full(6, -jnp.inf))
    genotypes, valid = champion.fittest(empty_archive, 2)
    kept = rescored(champion.empty(2), genotypes, valid)  # an iteration that starts with an empty archive
    assert not valid.any() and float(kept.fitness) == -np.inf


def test_the_es_mean_is_a_candidate_that_may_always_win():
    genotypes, valid = champion.contenders(ARCHIVE, 2, jnp.array([4.0, 0.0]))
    np.testing.assert_array_equal(genotypes[:, 0], [1.0, 3.0, 4.0])
    assert valid.tolist() == [True, True, True]
    np.testing.assert_array_equal(rescored(champion.empty(2), genotypes, valid).genotype, [4.0, 0.0])
    genotypes, valid = champion.contenders(ARCHIVE, 2, None)
    assert genotypes.shape == (2, 2) and valid.tolist() == [True, True]


def test_only_a_strictly_higher_mean_replaces_the_champion():
    held = champion.Champion(jnp.array([5.0, 5.0]), jnp.asarray(3.0))
    for genotypes, expected in (([[3.0, 0.0], [1.0, 0.0]], [5.0, 5.0]), ([[3.5, 0.0], [1.0, 0.0]], [3.5, 0.0])):
        np.testing.assert_array_equal(rescored(held, jnp.array(genotypes), jnp.ones(2, bool)).genotype, expected)


def test_each_candidate_is_the_mean_of_its_replicated_rows():
    genotypes = jnp.array([[1.0, 0.0], [2.0, 0.0]])
    rows = replicated(genotypes, 3)
    np.testing.assert_array_equal(rows[:, 0], [1.0, 1.0, 1.0, 2.0, 2.0, 2.0])  # a candidate's rows in a row
    # the first candidate's luckiest row (9) beats every row of the second, but its mean (4) does not (5)
    row_fitness = jnp.array([9.0, 0.0, 3.0, 5.0, 5.0, 5.0])
    means = replica_means(row_fitness, 3)
    np.testing.assert_allclose(means, [4.0, 5.0])
    kept = champion.kept(champion.empty(2), genotypes, jnp.ones(2, bool), means)
    np.testing.assert_array_equal(kept.genotype, [2.0, 0.0])
    assert float(kept.fitness) == 5.0


def test_the_policy_plays_the_fittest_elite_until_a_champion_is_scored():
    elite = jnp.array([1.0, 2.0])
    np.testing.assert_array_equal(champion.chosen(champion.empty(2), elite), elite)
    held = champion.Champion(jnp.array([5.0, 5.0]), jnp.asarray(-40.0))
    np.testing.assert_array_equal(champion.chosen(held, elite), [5.0, 5.0])
